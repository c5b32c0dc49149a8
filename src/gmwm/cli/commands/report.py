"""``gmwm report``: calibrate the IMU(s) of a recording (:func:`gmwm.calibrate.calibrate`: one
topic, several ``--topic`` or ``--topic all``) and write the calibration report
(:func:`gmwm.report.write_calibration`: Markdown, HTML, figures and the filter configuration
files of ``--export``, default the Kalibr ``imu.yaml``, with ``--inflate`` factors). A topic that
cannot be calibrated is listed with its reason while the others are; exit status 4 then. A topic
refused for motion (beyond ``--motion-share``, without ``--allow-motion``) is not fitted: its page
shows the WVs and says why, and the verdict line and ``--json`` (``"not_fitted"``) say so; exit
status 5, as for any configuration not written."""

from __future__ import annotations

import argparse
import time
from typing import Any, TextIO

from gmwm.cli.commands.fit import calibrate_input, calibration_status, choice_json
from gmwm.formatting import fit_json, json_text


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    result, files = calibrate_and_write(args, err)
    if args.json:
        out.write(json_text(report_json(args, result, files)))
    else:
        shown = [str(p) for p in files if p.suffix in (".md", ".html", ".yaml", ".json")]
        if result.several:
            done = list(result.calibrated)
            failed = result.failed
            out.write(f"report of {len(done)} IMUs ({', '.join(done)}) of {args.input}"
                      + (f", {len(failed)} not calibrated ({', '.join(failed)})" if failed
                         else "") + " written to: " + ", ".join(shown) + "\n")
        else:
            sec = result.only()
            out.write(f"report of {len(sec.axes) or len(sec.unfitted)} axes of {args.input}"
                      + (" (not fitted: refused for motion)" if sec.not_fitted else "")
                      + " written to: " + ", ".join(shown) + "\n")
    return verdicts(result, err, calibration_status(result, err, True))


def calibrate_and_write(args: argparse.Namespace, err: TextIO) -> tuple[Any, list[Any]]:
    """What ``gmwm report ARGS`` does before it prints: the input calibrated
    (:func:`gmwm.cli.commands.fit.calibrate_input`) and the report and configuration files
    written (:func:`gmwm.report.write_calibration`); (the
    :class:`gmwm.calibrate.CalibrationResult`, the files written). The fleet's jobs call it too
    (:mod:`gmwm.fleet.job`), so a unit is calibrated exactly as the command would."""
    from gmwm.exports import parse_inflation, parse_targets
    from gmwm.report import FigureDrawer, report_dir, warm_up, write_calibration

    targets = parse_targets(args.export)  # bad targets or factors before any fit
    inflation = parse_inflation(args.inflate)
    one = not getattr(args, "topics", None)
    drawn: list[Any] = []  # the stationarity timeline, drawn while the axes are fitted
    # without a datasheet verdict to draw on them, the WV figures (and the datasheet
    # coefficients) come from the workers that fit the axes
    in_workers = not getattr(args, "datasheet", None)

    def while_waiting(prepared: Any) -> None:
        if one:
            st = next(iter(prepared.values())).stationarity
            drawn.extend(warm_up(st, args.output, fit=not in_workers))

    result = calibrate_input(
        args, err, require_time="a calibration report", readings=True,
        draw=FigureDrawer(str(report_dir(args.output))) if in_workers else None,
        while_waiting=while_waiting, fit_refused=False)
    args.progress(f"writing the report to {args.output}")
    started = time.perf_counter()
    files = write_calibration(args.output, result, title=args.title, targets=targets,
                              inflation=inflation, drawn=drawn,
                              rostopic=getattr(args, "rostopic", None))
    result.seconds["write"] = time.perf_counter() - started
    return result, list(files)


def verdicts(result: Any, err: TextIO, status: int) -> int:
    """The terminal's last line(s): each calibrated topic's configuration verdict
    (:class:`gmwm.verdict.Verdict`); exit status 5 when a configuration was not written."""
    from gmwm.cli.errors import as_flags
    from gmwm.cli.parser import EXIT_NO_CONFIGURATION, EXIT_SOME_FAILED

    refused = False
    for t, sec in result.calibrated.items():
        v = sec.verdict
        if v is None:
            continue
        who = f"{t}: " if result.several else ""
        err.write(f"gmwm: {who}{as_flags(v.line())}\n")
        refused = refused or not v.written
    if refused and status != EXIT_SOME_FAILED:  # a missing file outranks a warning
        return EXIT_NO_CONFIGURATION
    return status


def _fits(args: argparse.Namespace, axes: Any) -> dict[str, Any]:
    return {c: fit_json(a.result, source=args.input, units=a.units, datasheet=a.datasheet,
                        verdict=a.verdict)
            | ({} if a.choice is None else {"model_choice": choice_json(a.choice)})
            for c, a in axes.items()}


def _verdict_json(sec: Any) -> dict[str, Any]:
    """The topic's configuration verdict as the terminal's last line says it: ``"verdict"``
    (status, line, reasons, caveats); nothing when there is none."""
    from gmwm.cli.errors import as_flags

    v = sec.verdict
    if v is None:
        return {}
    return {"verdict": {"status": v.status, "line": as_flags(v.line()),
                        "reasons": [as_flags(r) for r in v.reasons],
                        "caveats": [as_flags(c) for c in v.caveats]}}


def _not_fitted(sec: Any) -> dict[str, Any]:
    """A topic refused for motion and not fitted: ``"not_fitted"``, the reason and per axis its
    unit and WV (:meth:`gmwm.wv.WaveletVariance.to_dict`); nothing for a fitted topic."""
    if not sec.not_fitted:
        return {}
    return {"not_fitted": {"reason": sec.not_fitted,
                           "axes": {c: {"units": a.units, "wv": a.wv.to_dict()}
                                    for c, a in sec.unfitted.items()}}}


def report_json(args: argparse.Namespace, result: Any, files: Any) -> dict[str, Any]:
    """``--json``: per axis the fit, its datasheet and choice (a topic refused for motion and
    not fitted: no fits, ``"not_fitted"`` with the reason and the WVs); the verdict; several
    topics: per topic (the failed ones under ``"failed"``, topic -> reason)."""
    obj: dict[str, Any] = {"command": "report", "input": args.input,
                           "files": [str(p) for p in files], "seconds": result.seconds}
    if not result.several:
        sec = result.only()
        obj["fits"] = _fits(args, sec.axes)
        obj.update(_not_fitted(sec))
        obj.update(_verdict_json(sec))
        if sec.stationarity is not None:
            obj["stationarity"] = sec.stationarity.to_json_dict()
        return obj
    obj["imus"] = {t: {"stationarity": None if s.stationarity is None
                       else s.stationarity.to_json_dict(), "fits": _fits(args, s.axes),
                       **_not_fitted(s), **_verdict_json(s)}
                   for t, s in result.calibrated.items()}
    obj["failed"] = result.failed
    return obj
