"""``gmwm fleet INPUTS... -o OUT``: every recording of a fleet of IMUs calibrated as ``gmwm
report`` would, by a Snakemake workflow (:mod:`gmwm.fleet.run`), then the fleet table
(:mod:`gmwm.fleet.core`, :mod:`gmwm.fleet.output`).

:func:`register` adds the parser (standard library only: ``gmwm --help`` stays light)."""

from __future__ import annotations

import argparse
import importlib.util
import json
from pathlib import Path
from typing import Any, TextIO

__all__ = ["register", "run"]

_DESCRIPTION = """\
Calibrate every recording of a fleet of IMUs exactly as 'gmwm report' would (same defaults, same
refusals) and build the fleet table: per unit and coefficient (noise density, random walk, bias
instability per axis) the value with its 95 % interval; per coefficient the fleet's typical value,
the spread between units (tau, on the log scale, separated from each unit's own estimation error
by a random-effects model, with its Q-profile interval) and the 95 % prediction interval of a new
unit; the units out of family (their interval outside that band) with the reason; per unit with
recordings on several dates the drift per year. Recordings that fail (unreadable, too short, no
static stretch) are listed with their one-line reason; they never stop the fleet.

INPUTS: recordings, folders (searched recursively), glob patterns (quote them), or a manifest
CSV (columns path, and optionally unit, date (YYYY-MM-DD), topic, datasheet, temperature).
Unit identity: the manifest's 'unit'; else a file name '<unit>_<YYYY-MM-DD>...' gives the unit
and the date; else the file name without its suffix is the unit.

Each recording uses its longest static stretch ('gmwm report --segment longest-static'); one
shorter than --min-static seconds is listed as failed. Terms that length cannot identify (the
'gmwm plan' rule at the fitted values) or at the boundary 0 are reported as such, never as
numbers, and left out of the fleet estimate.

OUT/units/<unit>/<recording>/ holds each report and configuration files; OUT/fleet.html,
fleet.md, fleet.csv, fleet_summary.csv and fleet.json the table. The inputs are never written.
Run by Snakemake (local cores, or --profile DIR, e.g. profiles/slurm): incremental (a new or
changed recording, by content hash, reruns its job and the table; changed settings rerun
everything) and resumable (a killed run continues with the same command)."""

_EPILOG = """\
examples:
  gmwm fleet recordings/ --columns all --units gx,gy,gz=rad/s --units ax,ay,az=m/s^2 -o fleet
  gmwm fleet manifest.csv --datasheet mti-1 --cores 2 -o fleet
  gmwm fleet 'logs/**/*.ulg' --profile profiles/slurm -o fleet

exit status: 0 the table was written (failed recordings are listed in it, and named on stderr);
1 a problem with the inputs, or the workflow failed; 2 a usage error."""


def register(sub: Any, formatter: Any) -> None:
    """Add the ``fleet`` subcommand to the ``gmwm`` parser's subparsers ``sub``."""
    p = sub.add_parser("fleet", formatter_class=formatter,
                       help="a fleet of IMUs in one command: every recording calibrated, the "
                            "fleet table, out-of-family units, drift",
                       description=_DESCRIPTION, epilog=_EPILOG)
    p.add_argument("inputs", nargs="+", metavar="INPUT",
                   help="recordings, folders, glob patterns or a manifest CSV")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output folder (created; never inside an input folder)")
    p.add_argument("--model", default="auto",
                   help="model of every axis, as for 'gmwm report' (default auto)")
    p.add_argument("--columns", default=None, metavar="C1,C2,...|all",
                   help="columns of table recordings (as 'gmwm report --columns')")
    p.add_argument("--units", action="append", default=[], metavar="[COLS=]UNIT",
                   help="signal units, as 'gmwm report --units' (repeatable)")
    p.add_argument("--freq", type=float, default=None, help="sampling frequency in Hz")
    p.add_argument("--topic", default=None, help="bag or ULog topic (a manifest's overrides it)")
    p.add_argument("--datasheet", default=None, metavar="NAME|FILE",
                   help="sensor datasheet for the verdicts (a manifest's overrides it)")
    p.add_argument("--export", default="kalibr,json", metavar="TARGETS",
                   help="configuration files per recording (json is always added: the table "
                        "reads it)")
    p.add_argument("--report-arg", action="append", default=[], metavar="ARG",
                   help="one more 'gmwm report' argument for every recording (repeatable, e.g. "
                        "--report-arg=--gaps --report-arg=longest)")
    p.add_argument("--min-static", type=float, default=None, metavar="S",
                   help="shortest static stretch calibrated [s] (default 60)")
    p.add_argument("--method-re", choices=("pm", "dl"), default="pm",
                   help="between-unit variance estimator: Paule-Mandel or DerSimonian-Laird")
    p.add_argument("--cores", type=int, default=None,
                   help="local cores for the jobs (default: all this machine allows)")
    p.add_argument("--profile", default=None, metavar="DIR",
                   help="Snakemake profile (e.g. profiles/slurm); replaces --cores")
    p.add_argument("--group-size", type=int, default=None, metavar="N",
                   help="recordings per submitted job (Snakemake group 'calibrate'; default 20 "
                        "with --profile, 1 locally)")
    p.add_argument("--dry-run", "-n", action="store_true",
                   help="show the jobs Snakemake would run, run nothing")
    p.add_argument("--compare", default=None, metavar="ARCHIVE",
                   help="an earlier run's archive folder (OUT/archive/<time>/), its OUT, or its "
                        "fleet.json: list the units whose coefficients moved beyond their "
                        "intervals (OUT/compare.md, .csv, .json)")
    p.add_argument("--json", action="store_true", help="print the fleet table's JSON on stdout")
    p.add_argument("--quiet", "-q", action="store_true",
                   help="no progress lines on stderr (shown only on a terminal anyway)")


def _inside(a: Path, b: Path) -> bool:
    try:
        a.relative_to(b)
        return True
    except ValueError:
        return False


def run(args: argparse.Namespace, out: TextIO, err: TextIO) -> int:
    from gmwm.errors import InputError

    missing = [m for m in ("statsmodels", "snakemake") if importlib.util.find_spec(m) is None]
    if missing:
        raise InputError(f"gmwm fleet needs {' and '.join(missing)}: install the pipeline extra "
                         "(pip install 'gmwm[pipeline]')")
    from gmwm.fleet.collect import find_recordings
    from gmwm.fleet.run import MIN_STATIC_S, FleetSettings, prepare, run_workflow

    if args.cores is not None and args.cores < 1:
        raise InputError(f"--cores {args.cores}: give at least 1")
    dest = Path(args.output).resolve()
    if dest.exists() and not dest.is_dir():
        raise InputError(f"--output {args.output} exists and is not a folder")
    old_table = _old_table(args.compare) if args.compare else None
    recs = find_recordings(args.inputs)
    for r in recs:
        if _inside(r.path.resolve(), dest):
            raise InputError(f"the input {r.path} is inside --output {args.output}: give "
                             "recordings from outside the output folder")
    for item in args.inputs:
        p = Path(item).resolve()
        if p.is_dir() and _inside(dest, p):
            raise InputError(f"--output {args.output} is inside the input folder {item}: the "
                             "fleet never writes into its inputs")
    settings = FleetSettings(model=args.model, columns=args.columns, units=tuple(args.units),
                             freq=args.freq, topic=args.topic, datasheet=args.datasheet,
                             export=args.export,
                             min_static_s=MIN_STATIC_S if args.min_static is None
                             else args.min_static,
                             method_re=args.method_re, report_args=tuple(args.report_arg))
    args.progress(f"{len(recs)} recordings of {len({r.unit for r in recs})} units: hashing")
    prep = prepare(recs, dest, settings)
    if prep.changed:
        args.progress(f"{len(prep.changed)} new or changed recordings")
    cores = args.cores
    if cores is None and args.profile is None:
        from gmwm.calibrate import available_cores

        cores = available_cores()
    args.progress("running the workflow (log: " + str(dest / ".fleet" / "snakemake.log") + ")")
    group = args.group_size if args.group_size is not None else (20 if args.profile else 1)
    if group < 1:
        raise InputError(f"--group-size {group}: give at least 1")
    extra = ["--group-components", f"calibrate={group}"] if group > 1 else []
    code = run_workflow(dest, prep.config, cores=cores, profile=args.profile,
                        dry_run=args.dry_run, extra=extra, log=out if args.dry_run else None)
    if code != 0:
        raise InputError(f"the fleet workflow failed (Snakemake exit status {code}): see "
                         f"{dest / '.fleet' / 'snakemake.log'}")
    if args.dry_run:
        return 0
    table = json.loads((dest / "fleet.json").read_text(encoding="utf-8"))
    moved = None
    if args.compare:
        from gmwm.fleet.core import compare_units
        from gmwm.fleet.output import write_compare

        rows = compare_units(old_table, table)
        write_compare(dest, rows, str(args.compare))
        moved = sorted({f"{r['unit']} {r['coefficient']}" for r in rows if r["moved"]})
    err.writelines(f"gmwm: warning: {f['unit']}/{f['recording']}: {f['reason']}\n"
                   for f in table["failed"])
    if args.json:
        out.write(json.dumps(table, indent=2) + "\n")
        return 0
    units = {u["unit"] for u in table["units"]} | {f["unit"] for f in table["failed"]}
    odd = sorted({u["unit"] for u in table["units"] if u["status"] == "out of family"})
    drifting = sorted({f"{d['unit']} {d['coefficient']}" for d in table["drift"]
                       if d["flagged"]})
    out.write(f"fleet of {len(units)} units ({len(recs)} recordings, {len(table['failed'])} "
              f"failed) written to {dest / 'fleet.html'}, fleet.md, fleet.csv, "
              f"fleet_summary.csv, fleet.json\n")
    out.write(f"out of family: {', '.join(odd) if odd else 'none'}; drifting: "
              f"{', '.join(drifting) if drifting else 'none'}\n")
    if moved is not None:
        out.write(f"moved since {args.compare}: {', '.join(moved) if moved else 'none'} "
                  f"({dest / 'compare.md'})\n")
    return 0


def _old_table(where: str) -> dict[str, Any]:
    """The fleet.json of ``--compare`` (a file, an archive folder, or an earlier OUT)."""
    from gmwm.errors import InputError

    p = Path(where)
    if p.is_dir():
        p = p / "fleet.json"
    try:
        obj = json.loads(p.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(f"--compare {where}: no readable fleet.json ({exc})") from None
    if not isinstance(obj, dict) or "units" not in obj:
        raise InputError(f"--compare {where}: not a fleet table (no 'units')")
    return obj
