"""``gmwm fit``: fit a composite model to every requested channel of a recording or a WV table
(one :func:`gmwm.fit` call per channel with the command's :class:`gmwm.settings.FitSettings`),
print the estimates, datasheet coefficients, warnings and, with ``--datasheet``, the verdicts; and
what it shares with ``gmwm report``: the command line passed to :func:`gmwm.calibrate.calibrate`
(:func:`calibrate_input`) and the warnings and exit status of its result
(:func:`calibration_status`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from typing import Any, TextIO

from gmwm.cli.errors import as_flags
from gmwm.cli.inputs import read_fit_data, wanted_columns
from gmwm.cli.outputs import plot_channels, save_plot
from gmwm.cli.parser import EXIT_NOT_CONVERGED, EXIT_OK, EXIT_SOME_FAILED
from gmwm.formatting import fit_json, fit_text, fit_warnings, json_text


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    result = calibrate_input(args, err, require_time=None)
    topic = result.only()
    fits = topic.axes
    multi = args.columns is not None
    sheet = any(f.verdict is not None for f in fits.values())
    if args.plot and sheet:
        _plot_with_datasheet(fits, args.plot)
    elif args.plot:
        from gmwm.plots import plot_wv

        plot_channels(fits, lambda f, ax, c: plot_wv(f.result.wv, result=f.result, ax=ax,
                                                     units=f.units), args.plot)
    st = topic.stationarity
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
    return calibration_status(result, err, multi)


def fit_options(args: argparse.Namespace) -> dict[str, Any]:
    """The fit options of the command line (:meth:`gmwm.settings.FitSettings.of` keywords;
    validated by :func:`gmwm.calibrate.calibrate` before the input is read). Weights, starts and
    reweighting are set only when given (see the parser)."""
    options: dict[str, Any] = {"method": args.method, "seed": args.seed, "levels": args.levels}
    if getattr(args, "robust", False):
        options.update(robust=True, eff=args.eff)
    given = {"weights": args.weights, "n_starts": args.n_starts, "reweight": args.reweight}
    options.update({k: v for k, v in given.items() if v is not None})
    return options


def calibrate_input(args: argparse.Namespace, err: TextIO, *, require_time: str | None,
                    readings: bool = False, draw: Any = None,
                    while_waiting: Callable[[Any], None] | None = None,
                    fit_refused: bool = True) -> Any:
    """The :class:`gmwm.calibrate.CalibrationResult` of the command line: the input (a
    recording, or a WV table / streamed input / raw binary as :func:`gmwm.cli.inputs.
    read_fit_data` gives it) and its options passed to :func:`gmwm.calibrate.calibrate`; its
    messages printed. ``readings``, ``draw``, ``while_waiting``, ``fit_refused``: as
    ``calibrate`` takes them."""
    from gmwm.calibrate import calibrate, start_warm_server, stop_warm_server

    options = fit_options(args)
    sheet = load_datasheet(args)
    topics = getattr(args, "topics", None)

    def say(msg: str) -> None:
        if msg.startswith(("warning: ", "note: ")):
            err.write(f"gmwm: {as_flags(msg)}\n")
        else:
            args.progress(msg)

    if several_choices(args):
        start_warm_server()  # loads the fitting stack while this process reads the input
    try:  # the server is stopped whatever happens: no process outlives the command
        got = None if topics else read_fit_data(args, err, require_time)
        source: Any = args.input if got is None else got
        return calibrate(
            source, args.model,
            topics=("all" if topics == ["all"] else list(topics)) if topics else args.topic,
            columns=wanted_columns(args), dataset=args.dataset, freq=args.freq,
            time_unit=args.time_unit, units=getattr(args, "units", None) or None,
            levels=args.levels, gaps=args.gaps, start_s=args.start, end_s=args.end,
            segment=args.segment, strict=args.strict, fit=options, sheet=sheet,
            check=getattr(args, "check", False), readings=readings, draw=draw,
            require_time=require_time, name=args.input, progress=say,
            while_waiting=while_waiting,
            motion_share=getattr(args, "motion_share", 0.05),
            allow_motion=getattr(args, "allow_motion", False), fit_refused=fit_refused)
    finally:
        stop_warm_server()


#: the model argument that asks for the automatic choice (gmwm.automodel.choose_model)
AUTO = "auto"


def several_choices(args: argparse.Namespace) -> bool:
    """Whether this command will probably choose the models of several channels at once (a
    report, or several --columns, with an automatic model somewhere): then the worker processes
    are worth warming beside the reading (:func:`gmwm.calibrate.start_warm_server`)."""
    if AUTO not in str(getattr(args, "model", "")).lower():
        return False
    return args.command == "report" or "," in str(getattr(args, "columns", None) or "")


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


def calibration_status(result: Any, err: TextIO, multi: bool) -> int:
    """The fits' warnings on stderr (prefixed by the channel when ``multi``, by the topic too
    when there are several) and the exit status: 3 when a fit did not converge, 4 when a topic
    could not be calibrated (its reason was printed when it failed; one line sums them up)."""
    status = EXIT_OK
    several = len(result.topics) > 1
    for topic, sec in result.calibrated.items():
        for name, f in sec.axes.items():
            prefix = f"{topic} {name}: " if several else f"{name}: " if multi else ""
            if f.choice is not None and not f.choice.passed:
                err.write(f"gmwm: warning: {prefix}{f.choice.warnings[0]}\n")
            err.writelines(f"gmwm: warning: {prefix}{as_flags(w)}\n"
                           for w in fit_warnings(f.result))
            if not f.result.converged:
                msg = str(f.result.message).strip().splitlines()
                err.write(f"gmwm: warning: {prefix}the optimizer did not converge"
                          + (f" ({msg[0]})" if msg else "")
                          + "; treat the estimate with care (exit status 3)\n")
                status = EXIT_NOT_CONVERGED
    failed = result.failed
    if failed:
        err.write(f"gmwm: warning: {len(failed)} of {len(result.topics)} topics not calibrated "
                  f"({', '.join(failed)}): see the report (exit status 4)\n")
        status = EXIT_SOME_FAILED
    return status


# -- sensor datasheets (fit, report) ------------------------------------------------------------
def load_datasheet(args: argparse.Namespace) -> Any:
    """The sensor datasheet of ``--datasheet`` (:func:`gmwm.sensor_datasheet.load_datasheet`),
    or None."""
    if not getattr(args, "datasheet", None):
        return None
    from gmwm.sensor_datasheet import load_datasheet as load

    return load(args.datasheet)


def _plot_with_datasheet(fits: Mapping[str, Any], path: str) -> None:
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
