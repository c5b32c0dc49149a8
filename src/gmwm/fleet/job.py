"""The fleet workflow's jobs (``python -m gmwm.fleet.job calibrate|table --config FILE``), run by
``gmwm/data/fleet.smk``: one recording's calibration, or the fleet table. A job exits 0 even when
its recording fails (the failure is in its status.json, and the table lists it): one bad file
never stops the fleet."""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import io
import json
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["main", "report"]


def report(argv: list[str]) -> tuple[int, dict[str, Any] | None, str]:
    """One recording calibrated as ``gmwm report ARGV`` calibrates it, in this process: argv
    parsed by gmwm's own parser (its defaults and usage refusals), then the command's
    :func:`gmwm.cli.commands.report.calibrate_and_write` (the library's one calibration path,
    :func:`gmwm.calibrate.calibrate`, and :func:`gmwm.report.write_calibration`): (exit status,
    the report's ``--json`` object or None, stderr's lines as the command would print them). The status follows ``gmwm report``: 0, 1 an input error, 2 a
    usage error, 3 not converged, 4 a topic not calibrated, 5 no configuration written.

    Inputs that are not recordings are refused: a WV table and raw binary (``--dtype``). A large
    .npy / HDF5 file is streamed as ``gmwm report`` streams it."""
    from gmwm.cli import one_line, python_warnings
    from gmwm.cli.errors import as_flags
    from gmwm.cli.parser import EXIT_ERROR, EXIT_USAGE, UsageError, build_parser, check_args
    from gmwm.errors import GMWMError

    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):  # argparse prints its usage error there
            args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return (exc.code if isinstance(exc.code, int) else EXIT_USAGE), None, err.getvalue()
    args.progress = lambda _msg: None  # the job is quiet: Snakemake's log shows the jobs
    obj: dict[str, Any] | None = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            check_args(args)
            code, obj = _calibrate(args, err)
        except UsageError as exc:
            err.write(f"gmwm: error: {as_flags(one_line(exc))} (see 'gmwm report --help')\n")
            code = EXIT_USAGE
        except (GMWMError, OSError) as exc:
            err.write(f"gmwm: error: {as_flags(one_line(exc))}\n")
            code = EXIT_ERROR
        finally:  # as the command line prints them: after the command's own lines
            python_warnings(caught, err, False)
    return code, obj, err.getvalue()


def _calibrate(args: argparse.Namespace, err: io.StringIO) -> tuple[int, dict[str, Any]]:
    """What ``gmwm report`` does with a recording: the command's own
    :func:`gmwm.cli.commands.report.calibrate_and_write`, its verdict lines and its ``--json``
    object. The fleet calibrates recordings only: a WV table or raw binary is refused."""
    from gmwm.cli.commands.fit import calibration_status
    from gmwm.cli.commands.report import calibrate_and_write, report_json, verdicts
    from gmwm.errors import InputError
    from gmwm.readers.tables import is_wv_table

    if args.dtype is not None:
        raise InputError(f"{args.input}: raw binary (--dtype) is not a fleet recording")
    if not Path(args.input).exists():
        raise InputError(f"file not found: {args.input}")
    if is_wv_table(Path(args.input)):
        raise InputError(f"{args.input} is a WV table, not a recording: the fleet calibrates "
                         "recordings")
    result, files = calibrate_and_write(args, err)
    status = verdicts(result, err, calibration_status(result, err, True))
    return status, report_json(args, result, files)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m gmwm.fleet.job")
    p.add_argument("what", choices=("calibrate", "table"))
    p.add_argument("--config", required=True)
    p.add_argument("--key", default=None)
    args = p.parse_args(argv)
    cfg = json.loads(Path(args.config).read_text(encoding="utf-8"))
    out = Path(cfg["out"])
    from gmwm.fleet.run import FleetSettings

    raw = json.loads((out / ".fleet" / "settings.json").read_text(encoding="utf-8"))
    raw["units"], raw["report_args"] = tuple(raw["units"]), tuple(raw["report_args"])
    settings = FleetSettings(**raw)
    if args.what == "calibrate":
        from gmwm.atomic import write_json_atomic
        from gmwm.fleet.run import calibrate_recording

        rec = cfg["recordings"][args.key]
        try:
            calibrate_recording(rec["path"], out / "units" / args.key, settings, report=report,
                                topic=rec["topic"], datasheet=rec["datasheet"],
                                content=rec["sha256"])
        except Exception as exc:  # noqa: BLE001 (a bug must not block the table: listed instead)
            line = (str(exc).strip().splitlines() or [""])[0]
            write_json_atomic(out / "units" / args.key / "status.json",
                              {"ok": False, "recording": rec["path"],
                               "reason": f"internal error ({type(exc).__name__}: {line}); "
                                         "please report it"})
        return 0
    from gmwm.fleet.collect import Recording
    from gmwm.fleet.output import build_and_write

    recs = [Recording(Path(r["path"]), r["unit"], r["name"],
                      _dt.date.fromisoformat(r["date"]) if r["date"] else None, r["topic"],
                      r["datasheet"], r["temperature"]) for r in cfg["recordings"].values()]
    build_and_write(out, recs, settings, config=cfg)
    return 0


if __name__ == "__main__":
    sys.exit(main())
