"""The fleet workflow's jobs (``python -m gmwm.fleet.job calibrate|table --config FILE``), run by
``gmwm/data/fleet.smk``: one recording's calibration, or the fleet table. A job exits 0 even when
its recording fails (the failure is in its status.json, and the table lists it): one bad file
never stops the fleet."""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main", "report"]


def report(argv: list[str]) -> tuple[int, str, str]:
    """``gmwm report`` in this process: (exit status, stdout, stderr). The job is the layer above
    the command line (nothing imports this module: Snakemake runs it)."""
    import contextlib
    import io

    from gmwm.cli import main as cli_main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli_main(argv)
    return code, out.getvalue(), err.getvalue()


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
