"""Per-study cost of a full pipeline run against an earlier run's, from their archives.

    python benchmarks/pipeline_cost_table.py RUN_ARCHIVE BASELINE_ARCHIVE [--wall SECONDS]

Reads each archive's ``timings.csv`` (one row per job: ``seconds``, the job's wall time as
Snakemake's benchmark records it, and since issue 39 ``cpu_s``, the job's exact CPU from
``wflog``) and prints a Markdown table: per study, the core-minutes of job wall time of both runs
(the only measure both have), their ratio, and the run's exact CPU core-minutes; then the totals
and, with ``--wall``, the run's wall time against the sum of its jobs' (how well two cores were
used). Writes nothing.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

#: archive study labels -> the study names of docs/pipeline.md
LABELS = {"case1": "SVO case 1", "case2": "SVO case 2", "sim1": "Simulation 1",
          "sim2": "Simulation 2", "sim3": "Simulation 3", "sim3_coverage": "Simulation 3 coverage",
          "stim300_accel": "STIM-300 accelerometer", "stim300_gyro": "STIM-300 gyroscope",
          "uncertainty": "uncertainty", "misspec": "misspecification",
          "navigation": "navigation", "navchip": "Navchip", "allan": "Allan chapter"}


def _per_study(archive: Path) -> pd.DataFrame:
    t = pd.read_csv(archive / "timings.csv")
    cols = {"wall": ("seconds", "sum"), "jobs": ("seconds", "size")}
    if "cpu_s" in t:
        cols["cpu"] = ("cpu_s", lambda s: s.sum(min_count=1))
    return t.groupby("study").agg(**cols) / pd.Series({"wall": 60.0, "jobs": 1.0, "cpu": 60.0})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path)
    ap.add_argument("baseline", type=Path)
    ap.add_argument("--wall", type=float, default=None, help="the run's wall time [s]")
    args = ap.parse_args()
    new, old = _per_study(args.run), _per_study(args.baseline)
    studies = sorted(set(new.index) | set(old.index),
                     key=lambda s: -float(new["wall"].get(s, 0.0)))
    print(f"| study | {args.baseline.name} jobs | job wall [core-min] | {args.run.name} jobs "
          "| job wall [core-min] | ratio | exact CPU [core-min] |")
    print("|---|---|---|---|---|---|---|")

    def cell(frame: pd.DataFrame, s: str, col: str, fmt: str = ".1f") -> str:
        v = frame[col].get(s) if col in frame else None
        return "-" if v is None or pd.isna(v) else format(float(v), fmt)

    for s in studies:
        a, b = old["wall"].get(s), new["wall"].get(s)
        ratio = f"{b / a:.2f}" if a and b else "-"
        print(f"| {LABELS.get(s, s)} | {cell(old, s, 'jobs', '.0f')} | {cell(old, s, 'wall')} | "
              f"{cell(new, s, 'jobs', '.0f')} | {cell(new, s, 'wall')} | {ratio} | "
              f"{cell(new, s, 'cpu')} |")
    tot_old, tot_new = old["wall"].sum(), new["wall"].sum()
    cpu = f"{new['cpu'].sum():.1f}" if "cpu" in new else "-"
    print(f"| **total** | {int(old['jobs'].sum())} | {tot_old:.1f} | {int(new['jobs'].sum())} | "
          f"{tot_new:.1f} | {tot_new / tot_old:.2f} | {cpu} |")
    if args.wall:
        print(f"\nRun wall time {args.wall / 60:.1f} min; its jobs' wall times sum to "
              f"{tot_new:.1f} core-min, {tot_new / (args.wall / 60):.2f} cores busy on average.")


if __name__ == "__main__":
    main()
