"""``gmwm report``: fit every axis of an IMU recording and write the calibration report
(:func:`gmwm.report.write_report`: Markdown, HTML, figures and the filter configuration files of
``--export``, default the Kalibr ``imu.yaml``, with ``--inflate`` factors)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TextIO

from gmwm.cli.commands.fit import (
    attach_verdicts,
    choice_json,
    fit_columns,
    fit_status,
    load_datasheet,
)
from gmwm.formatting import fit_json, fit_warnings, json_text, spans


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.exports import parse_inflation, parse_targets
    from gmwm.report import write_report

    targets = parse_targets(args.export)  # bad targets or factors before any fit
    inflation = parse_inflation(args.inflate)
    sheet = load_datasheet(args)
    got, fits = fit_columns(args, err, require_time="a calibration report")
    fits = attach_verdicts(fits, sheet, err, True)
    args.progress(f"writing the report to {args.output}")
    axes = {c: {"result": f.result, "units": f.units, "warnings": fit_warnings(f.result),
                "datasheet": f.datasheet, "verdict": f.verdict, "choice": f.choice}
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
                         topic=rec.topic if rec is not None and rec.format.startswith("ros")
                         else None)
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
