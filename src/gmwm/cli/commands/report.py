"""``gmwm report``: fit every axis of an IMU recording and write the calibration report
(:func:`gmwm.report.write_report`: Markdown, HTML, figures and the filter configuration files of
``--export``, default the Kalibr ``imu.yaml``, with ``--inflate`` factors)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any, TextIO

from gmwm.cli.commands.fit import (
    _several_choices,
    attach_verdicts,
    choice_json,
    fit_columns,
    fit_status,
    load_datasheet,
)
from gmwm.formatting import fit_json, fit_warnings, json_text, spans


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.exports import parse_inflation, parse_targets
    from gmwm.report import _outdir, warm_up, write_report

    targets = parse_targets(args.export)  # bad targets or factors before any fit
    inflation = parse_inflation(args.inflate)
    sheet = load_datasheet(args)
    if getattr(args, "topics", None):
        return _several(args, out, err, targets, inflation, sheet)
    drawn: list[Path] = []  # the stationarity timeline, drawn while the axes are fitted
    # without a datasheet verdict to draw on them, the WV figures (and the datasheet
    # coefficients) come from the workers that choose the models, as each axis is chosen
    in_workers = sheet is None
    got, fits = fit_columns(args, err, require_time="a calibration report",
                            while_waiting=lambda g: drawn.extend(warm_up(
                                g.stationarity, args.output, fit=not in_workers)),
                            figures=str(_outdir(args.output)) if in_workers else None,
                            drawn=drawn)
    fits = attach_verdicts(fits, sheet, err, True)
    args.progress(f"writing the report to {args.output}")
    axes = {c: {"result": f.result, "units": f.units, "warnings": fit_warnings(f.result),
                "datasheet": f.datasheet, "verdict": f.verdict, "choice": f.choice,
                "readings": f.readings}
            for c, f in fits.items()}
    st = got.stationarity
    if st is not None:  # each flagged axis says so in its own section and in the summary
        a, b = st.used or (0, st.n)
        for c, axis in axes.items():
            segs = [s for s in st.segments_in(a, b) if c in s.channels]
            if segs:
                where = spans(st, segs, more="more ranges")
                note = (f"not static in {where} (see Stationarity): the coefficients include "
                        "that motion")
                axis["warnings"] = [*axis["warnings"], note]
    rec, gaps = got.recording, got.gaps
    timing = None
    if rec is not None and rec.time is not None:
        timing = [f"Recording ({rec.format}{', topic ' + rec.topic if rec.topic else ''}): "
                  + rec.time.summary()]
        if gaps is not None and gaps.message:
            timing.append(gaps.message)
    files = write_report(args.output, axes, source=args.input,
                         title=args.title or f"Calibration report: {Path(args.input).name}",
                         timing=timing, stationarity=st, targets=targets, inflation=inflation,
                         # a bag's topic is the filter's rostopic; a ULog topic is not a ROS one
                         topic=getattr(args, "rostopic", None) or (
                             rec.topic if rec is not None and rec.format.startswith("ros")
                             else None), drawn=drawn)
    if args.json:
        obj = {"command": "report", "input": args.input, "files": [str(p) for p in files],
               "fits": {c: fit_json(f.result, source=args.input, units=f.units,
                                    datasheet=f.datasheet, verdict=f.verdict)
                        | ({} if f.choice is None else {"model_choice": choice_json(f.choice)})
                        for c, f in fits.items()}}
        if st is not None:
            obj["stationarity"] = st.to_json_dict()
        out.write(json_text(obj))
    else:
        shown = [str(p) for p in files if p.suffix in (".md", ".html", ".yaml", ".json")]
        out.write(f"report of {len(fits)} axes of {args.input} written to: "
                  + ", ".join(shown) + "\n")
    return fit_status(fits, err, True)


def _several(args: argparse.Namespace, out: TextIO, err: TextIO, targets: Any, inflation: Any,
             sheet: Any) -> int:
    """``--topic all`` / several ``--topic``: every IMU of one file on one page
    (:func:`gmwm.calibrate.calibrate_imus`, :func:`gmwm.report.write_multi_report`), one
    configuration folder per topic."""
    from gmwm.calibrate import start_warm_server, stop_warm_server

    topics = "all" if args.topics == ["all"] else list(args.topics)
    if _several_choices(args):
        start_warm_server()  # loads the fitting stack while this process reads the file
    try:  # the server is stopped whatever happens: no process outlives the command
        return _several_imus(args, out, err, targets, inflation, sheet, topics)
    finally:
        stop_warm_server()


def _several_imus(args: argparse.Namespace, out: TextIO, err: TextIO, targets: Any,
                  inflation: Any, sheet: Any, topics: Any) -> int:
    """:func:`_several` once the warm server is started: read, calibrate, write."""
    from gmwm.calibrate import calibrate_imus, stop_warm_server
    from gmwm.cli.inputs import models_by_column, units_by_column, wanted_columns
    from gmwm.readers import read_recordings
    from gmwm.report import write_multi_report
    from gmwm.sensor_datasheet import judge

    args.progress(f"reading {args.input} ({'every IMU topic' if topics == 'all' else topics})")
    recs = read_recordings(args.input, topics, columns=wanted_columns(args), freq=args.freq)
    units = {t: {c: (u or None) for c, u in units_by_column(args, list(r.channels), r.units)
                 .items()} for t, r in recs.items()}
    models = {t: models_by_column(args.model, list(r.channels)) for t, r in recs.items()}
    first = next(iter(models.values()))
    # one model spec applies to every topic, whatever its channels (a phone's Gyroscope gx..gz,
    # its Accelerometer ax..az)
    model = args.model if "=" not in args.model or all(m == first for m in models.values()) \
        else first
    options = {"method": args.method, "seed": args.seed}
    options.update({k: v for k, v in {"weights": args.weights, "n_starts": args.n_starts,
                                      "reweight": args.reweight}.items() if v is not None})

    def say(msg: str) -> None:
        if msg.startswith("warning: "):
            err.write(f"gmwm: {msg}\n")
        else:
            args.progress(msg)

    imus = calibrate_imus(recs, model, units=units, levels=args.levels, gaps=args.gaps,
                          start_s=args.start, end_s=args.end, segment=args.segment,
                          strict=args.strict, fit_options=options, progress=say,
                          executor="process")  # choices are mostly Python: threads serialise
    stop_warm_server()  # not needed any more: free its memory before the page is drawn
    status = 0
    for topic, sec in imus.items():
        for c, axis in sec.axes.items():
            res = axis["result"]
            if sheet is not None and axis["units"]:
                from gmwm.datasheet import parse_unit

                kind = parse_unit(axis["units"])
                if kind is not None and kind[2] in sheet.sensors:
                    axis["verdict"] = judge(res, sheet, axis["units"])
            choice = axis.get("choice")
            if choice is not None and not choice.passed:
                err.write(f"gmwm: warning: {topic} {c}: {choice.warnings[0]}\n")
            err.writelines(f"gmwm: warning: {topic} {c}: {w}\n" for w in fit_warnings(res))
            if not res.converged:
                err.write(f"gmwm: warning: {topic} {c}: the optimizer did not converge; treat "
                          "the estimate with care (exit status 3)\n")
                status = 3
    args.progress(f"writing the report to {args.output}")
    files = write_multi_report(args.output, imus, source=args.input,
                               title=args.title or f"Calibration report: {Path(args.input).name}",
                               targets=targets, inflation=inflation)
    if args.json:
        obj = {"command": "report", "input": args.input, "files": [str(p) for p in files],
               "imus": {t: {"stationarity": None if s.stationarity is None
                            else s.stationarity.to_json_dict(),
                            "fits": {c: fit_json(a["result"], source=args.input,
                                                 units=a["units"], datasheet=a["datasheet"],
                                                 verdict=a.get("verdict"))
                                     | ({} if a.get("choice") is None
                                        else {"model_choice": choice_json(a["choice"])})
                                     for c, a in s.axes.items()}}
                        for t, s in imus.items()}}
        out.write(json_text(obj))
    else:
        shown = [str(p) for p in files if p.suffix in (".md", ".html", ".yaml", ".json")]
        out.write(f"report of {len(imus)} IMUs ({', '.join(imus)}) of {args.input} written to: "
                  + ", ".join(shown) + "\n")
    return status
