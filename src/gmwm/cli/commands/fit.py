"""``gmwm fit``: fit a composite model to every requested channel of a recording or a WV table
(one :func:`gmwm.fit` call per channel with the command's :class:`gmwm.settings.FitSettings`),
print the estimates, datasheet coefficients, warnings and, with ``--datasheet``, the verdicts; and
the fitting of channels it shares with ``gmwm report`` (:func:`fit_columns`, :func:`fit_status`,
:func:`attach_verdicts`)."""

from __future__ import annotations

import argparse
import dataclasses
import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, TextIO

import numpy as np

from gmwm.cli.inputs import Inputs, models_by_column, read_fit_data
from gmwm.cli.outputs import plot_channels, save_plot
from gmwm.cli.parser import EXIT_NOT_CONVERGED, EXIT_OK
from gmwm.errors import InputError
from gmwm.formatting import fit_json, fit_text, fit_warnings, json_text


@dataclass(frozen=True)
class ColumnFit:
    """One channel's fit: the result, the signal unit ('' unknown), its datasheet coefficients
    (:func:`gmwm.datasheet.datasheet`), the identifiability check (``--check``) and the datasheet
    verdict (``--datasheet``, :func:`gmwm.sensor_datasheet.judge`), None when not asked for."""

    result: Any
    units: str
    datasheet: dict[str, Any]
    check: Any = None
    verdict: dict[str, Any] | None = None
    choice: Any = None
    readings: dict[str, Any] | None = None  # IEEE 952 readings, when a worker computed them


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    sheet = load_datasheet(args)
    got, fits = fit_columns(args, err)
    multi = args.columns is not None
    fits = attach_verdicts(fits, sheet, err, multi)
    if args.plot and sheet is not None:
        _plot_with_datasheet(fits, args.plot)
    elif args.plot:
        from gmwm.plots import plot_wv

        plot_channels(fits, lambda f, ax, c: plot_wv(f.result.wv, result=f.result, ax=ax,
                                                     units=f.units), args.plot)
    st = got.stationarity
    if args.json:
        objs = {c: fit_json(f.result, source=args.input, units=f.units, datasheet=f.datasheet,
                            check=f.check, verdict=f.verdict) for c, f in fits.items()}
        for c, f in fits.items():
            if f.choice is not None:
                objs[c]["model_choice"] = choice_json(f.choice)
        obj = ({"command": "fit", "input": args.input, "fits": objs} if multi
               else next(iter(objs.values())))
        if st is not None:
            obj["stationarity"] = st.to_json_dict()
        out.write(json_text(obj))
    else:
        if st is not None and st.used not in (None, (0, st.n)):
            out.write(f"recording part used: {st.used_text()}\n")
        out.write("\n\n".join(
            ("" if f.choice is None else choice_text(f.choice) + "\n")
            + fit_text(f.result, source=args.input, name=c if multi else None, units=f.units,
                       datasheet=f.datasheet, check=f.check, verdict=f.verdict)
            for c, f in fits.items()) + "\n")
    return fit_status(fits, err, multi)


def fit_settings(args: argparse.Namespace) -> Any:
    """The :class:`gmwm.settings.FitSettings` of the command line (validated before the input
    is read). Weights, starts and reweighting are set only when given (see the parser)."""
    from gmwm.settings import FitSettings

    options: dict[str, Any] = {"method": args.method, "seed": args.seed, "levels": args.levels}
    if getattr(args, "robust", False):
        options.update(robust=True, eff=args.eff)
    given = {"weights": args.weights, "n_starts": args.n_starts, "reweight": args.reweight}
    options.update({k: v for k, v in given.items() if v is not None})
    return FitSettings.of(**options)


def fit_columns(args: argparse.Namespace, err: TextIO, require_time: str | None = None,
                while_waiting: Callable[[Inputs], None] | None = None,
                figures: str | None = None, drawn: list[Any] | None = None
                ) -> tuple[Inputs, dict[str, ColumnFit]]:
    """Read the input (:func:`gmwm.cli.inputs.read_fit_data`) and fit every channel with its
    model; every model is parsed before the first fit. ``while_waiting(inputs)``: run in this
    process while worker processes choose the channels' models (the report's warm-up).
    ``figures``: a report directory in which the workers that choose the models also draw
    each channel's WV figure as soon as it is chosen (a report without a datasheet verdict);
    the files drawn are appended to ``drawn``."""
    import gmwm
    from gmwm.datasheet import datasheet
    from gmwm.model import Model

    settings = fit_settings(args)
    from gmwm.calibrate import start_warm_server, stop_warm_server

    if _several_choices(args):
        start_warm_server()  # loads the fitting stack while this process reads the input
    try:  # the server is stopped whatever happens: no process outlives the command
        got = read_fit_data(args, err, require_time)
        specs = models_by_column(args.model, list(got.data))
        auto = {c for c, m in specs.items() if m.strip().lower() == AUTO}
        if auto and settings.method != "gmwm":
            raise InputError(f"the automatic model choice fits GMWM candidates; with --method "
                             f"{settings.method} give a model")
        models = {c: Model(specs[c], freq=got.freq) for c in got.data if c not in auto}
        # a streamed channel's result is completed below (_streamed): its figure waits for that
        draw: dict[str, str] = {}
        if figures is not None:
            from gmwm.report import wv_figure_path

            draw = {c: str(wv_figure_path(figures, c)) for c in auto if c not in got.streamed}
        chosen = _choose_parallel(args, {c: got.data[c] for c in got.data if c in auto},
                                  settings, got.freq, got.units,
                                  None if while_waiting is None else lambda: while_waiting(got),
                                  draw)
    finally:
        stop_warm_server()
    fits = {}
    for c, d in got.data.items():
        # a WV (a table, streamed, pooled segments) is already cut to --levels
        s = settings if isinstance(d, np.ndarray) else settings.replace(levels=None)
        choice = None
        page: dict[str, Any] = {}  # what a worker computed for the report page
        if c in auto:
            choice, files, page = chosen.get(c) or (
                _choose(args, c, d, s, got.freq, got.units[c]), [], None)
            page = page or {}
            res = choice.result
            if drawn is not None:
                drawn.extend(files)
        else:
            args.progress(f"fitting {models[c].spec} to {c}")
            res = gmwm.fit(d, models[c], settings=s, freq=got.freq)
        if c in got.streamed:
            res = _streamed(res, got.streamed[c])
        check = None
        if getattr(args, "check", False):
            from gmwm import identify

            args.progress(f"identifiability check of {c}")
            check = identify.check(res)
        units = got.units[c]
        sheet = page.get("datasheet") or datasheet(res, units or None)
        fits[c] = ColumnFit(res, units, sheet, check, choice=choice,
                            readings=page.get("readings"))
    return got, fits


#: the model argument that asks for the automatic choice (gmwm.automodel.choose_model)
AUTO = "auto"


def _several_choices(args: argparse.Namespace) -> bool:
    """Whether this command will probably choose the models of several channels at once (a
    report, or several --columns, with an automatic model somewhere): then the worker processes
    are worth warming beside the reading (:func:`gmwm.calibrate.start_warm_server`)."""
    if AUTO not in str(getattr(args, "model", "")).lower():
        return False
    return args.command == "report" or "," in str(getattr(args, "columns", None) or "")


def _choose(args: argparse.Namespace, name: str, data: Any, settings: Any, freq: float | None,
            units: str) -> Any:
    """The automatic model choice of one channel (:func:`gmwm.automodel.choose_model`): the
    sensor kind from its unit; without one every sum of the candidate terms is tried."""
    from gmwm.automodel import choose_model
    from gmwm.units import unit_system

    kind = unit_system(units or None).sensor if units else None
    args.progress(f"choosing the model of {name}"
                  + (f" ({kind})" if kind else " (no sensor unit: every candidate sum)"))
    choice = choose_model(
        data, freq=freq, kind=kind, levels=settings.levels, robust=settings.robust,
        eff=settings.eff, seed=settings.seed,
        n_starts=settings.n_starts if args.n_starts is not None else None,
        progress=lambda i, n, m: args.progress(f"{name}: candidate {i}/{n}: {m}"))
    return choice


def _choose_parallel(args: argparse.Namespace, data: dict[str, Any], settings: Any,
                     freq: float | None, units: dict[str, str],
                     while_waiting: Callable[[], None] | None = None,
                     figures: Mapping[str, str] | None = None
                     ) -> dict[str, tuple[Any, list[Any], dict[str, Any] | None]]:
    """The automatic choices of several channels at once, one worker process per core
    (:func:`gmwm.calibrate.calibrate_imus`' executor: a choice is mostly Python, which threads
    would serialise): channel -> (choice, report figure files drawn, page values or None); {}
    with one channel or one core (then :func:`_choose` runs each, with per-candidate progress).
    The choices are the same as one after the other (seeded). ``while_waiting`` runs here once
    the choices are submitted. ``figures``: channel -> the report WV figure its worker draws
    after the choice, with the channel's datasheet (:func:`gmwm.calibrate._choose_and_draw`)."""
    from gmwm.calibrate import _choose_and_draw, _executor, available_cores, warm_server_running

    n = min(len(data), available_cores())
    if n < 2:
        return {}
    args.progress(f"choosing the models of {len(data)} channels in {n} parallel processes")
    opts: dict[str, Any] = {"seed": settings.seed, "robust": settings.robust, "eff": settings.eff}
    if args.n_starts is not None:
        opts["n_starts"] = settings.n_starts
    with _executor("process", n, warm=True) as pool:
        futures: dict[str, Any] = {}

        def submit() -> None:
            for c, d in data.items():
                fig = None if c not in (figures or {}) else (figures[c], c)
                futures[c] = pool.submit(_choose_and_draw, d, freq, settings.levels, opts,
                                         units.get(c) or None, fig)

        if warm_server_running() and while_waiting is not None:
            # the warm server answers the first submission once it has loaded the fitting
            # stack: submit from a thread and do this process's own work meanwhile (no fork
            # from this process, so its threads are safe)
            thread, failed = _thread(submit)
            while_waiting()
            thread.join()
            if failed:
                raise failed[0]
        else:
            submit()
            if while_waiting is not None:
                while_waiting()
        out = {}
        for c, f in futures.items():
            out[c] = f.result()
            args.progress(f"{c}: {out[c][0].headline()}")
    return out


def _thread(fn: Callable[[], None]) -> tuple[threading.Thread, list[BaseException]]:
    """``fn`` started in a thread; the list receives its exception, if any."""
    failed: list[BaseException] = []

    def body() -> None:
        try:
            fn()
        except BaseException as exc:  # noqa: BLE001 - re-raised by the caller after join
            failed.append(exc)

    thread = threading.Thread(target=body, daemon=True)
    thread.start()
    return thread, failed


def choice_json(choice: Any) -> dict[str, Any] | None:
    """The automatic choice without its fit (the fit is the surrounding JSON): the ranking, the
    goodness-of-fit p-values, notes and warnings (:meth:`gmwm.automodel.Choice.to_json_dict`)."""
    if choice is None:
        return None
    obj = choice.to_json_dict()
    obj.pop("result", None)
    return obj


def choice_text(choice: Any) -> str:
    """The automatic choice's headline, ranking table, notes and warning (its
    :meth:`~gmwm.automodel.Choice.summary` without the fit's own summary)."""
    return choice.summary().split("\n\n", 1)[0]


def _streamed(res: Any, channel: Any) -> Any:
    """A fit of a streamed channel's WV with what the WV does not hold: the sign of a drift (from
    the signal's first and last samples, as :func:`gmwm.fit` takes it from a signal) and the
    seconds the streamed WV took."""
    if res.settings.method != "avsm":
        res = res.with_drift_sign(channel.drift_sign)
    return dataclasses.replace(res, seconds_wv=channel.seconds)


def fit_status(fits: dict[str, ColumnFit], err: TextIO, multi: bool) -> int:
    """The fits' warnings on stderr (prefixed by the channel when ``multi``); exit status 3 when
    a fit did not converge."""
    status = EXIT_OK
    for name, f in fits.items():
        prefix = f"{name}: " if multi else ""
        if f.choice is not None and not f.choice.passed:
            err.write(f"gmwm: warning: {prefix}{f.choice.warnings[0]}\n")
        err.writelines(f"gmwm: warning: {prefix}{w}\n" for w in fit_warnings(f.result))
        if not f.result.converged:
            msg = str(f.result.message).strip().splitlines()
            err.write(f"gmwm: warning: {prefix}the optimizer did not converge"
                      + (f" ({msg[0]})" if msg else "")
                      + "; treat the estimate with care (exit status 3)\n")
            status = EXIT_NOT_CONVERGED
    return status


# -- sensor datasheets (fit, report) ------------------------------------------------------------
def load_datasheet(args: argparse.Namespace) -> Any:
    """The sensor datasheet of ``--datasheet`` (:func:`gmwm.sensor_datasheet.load_datasheet`),
    or None."""
    if not getattr(args, "datasheet", None):
        return None
    from gmwm.sensor_datasheet import load_datasheet as load

    return load(args.datasheet)


def attach_verdicts(fits: dict[str, ColumnFit], sheet: Any, err: TextIO, multi: bool
                    ) -> dict[str, ColumnFit]:
    """The fits with their datasheet verdicts; a column the datasheet does not cover (no section
    for its sensor type) gets a warning, a column without a known unit is an error."""
    if sheet is None:
        return fits
    from gmwm.sensor_datasheet import judge
    from gmwm.units import parse_unit

    out = {}
    for name, f in fits.items():
        parsed = parse_unit(f.units) if f.units else None
        if parsed is None:
            raise InputError(f"--datasheet: give the unit of {name} with --units (e.g. deg/s or "
                             "m/s^2) to tell a gyroscope from an accelerometer")
        if parsed[2] not in sheet.sensors:
            err.write(f"gmwm: warning: {name + ': ' if multi else ''}the datasheet "
                      f"{sheet.where} has no {parsed[2]} section: no verdict\n")
            out[name] = f
            continue
        out[name] = dataclasses.replace(f, verdict=judge(f.result, sheet, f.units))
    if all(f.verdict is None for f in out.values()):
        raise InputError(f"--datasheet {sheet.where}: no fitted column is of a sensor type it "
                         f"describes ({', '.join(sheet.sensors)})")
    return out


def _plot_with_datasheet(fits: dict[str, ColumnFit], path: str) -> None:
    """Per column one row: WV with the fit and the datasheet's WV; Allan deviation with the
    datasheet's."""
    from gmwm.plots import add_datasheet_line, channel_grid, plot_av, plot_wv
    from gmwm.wv import AllanVariance

    fig, axes = channel_grid(2 * len(fits), ncols=2)
    for i, (name, f) in enumerate(fits.items()):
        res, v = f.result, f.verdict
        ax_wv, ax_ad = axes[2 * i], axes[2 * i + 1]
        plot_wv(res.wv, result=res, ax=ax_wv, units=f.units)
        plot_av(AllanVariance.from_wv(res.wv), deviation=True, ax=ax_ad, units=f.units)
        if v is not None:
            c = v["curves"]
            add_datasheet_line(ax_wv, c["scales_s"], c["wv"], v["label"])
            add_datasheet_line(ax_ad, c["tau_s"], c["adev"], v["label"])
        if len(fits) > 1:
            ax_wv.set_title(f"{name}: WV")
            ax_ad.set_title(f"{name}: Allan deviation")
    save_plot(fig, path)
