"""The default model chosen by the data (gmwm.automodel.choose_model) on IMU-like truths.

    python benchmarks/bench_automodel.py [--reps 40] [--log2n 20] [--truths ...] [--write]

Design. R seeded replicates of each truth (``Model.simulate_fast``), 200 Hz, T = 2^log2n rows
(default 2^20, 87 min), every axis given to :func:`gmwm.automodel.choose_model` with its sensor
kind and the defaults (WIC, 5 % goodness-of-fit level, up to 3 GM, SIN when the WV shows a
bump). Truths (gyroscope in deg/s, accelerometer in m/s^2):

* ``gyro WN+GM+RW``: ARW 0.3 deg/sqrt(h), bias instability as a GM (sigma 5 deg/h, correlation
  time 30 s), RRW 3 deg/h/sqrt(h) -- the gyroscope on which the old default WN+RW reads the GM
  as a random walk;
* ``accel WN+RW``: VRW 0.05 m/s/sqrt(h), AccRW 2e-5 m/s^3/sqrt(Hz);
* ``gyro WN+2*GM+RW``: as the first with a second, fast GM (sigma 20 deg/h, 1 s);
* ``gyro WN+SIN+RW``: ARW 0.3 deg/sqrt(h), a 2 Hz vibration of amplitude 0.05 deg/s, RRW 3.

Reported per truth: the share of choices containing each true component (at least as many of
it), the share equal to the truth, the share with a component type (or an extra GM) the truth
lacks, the share whose choice the goodness-of-fit test rejects (every candidate rejected), the
share of replicates where SIN candidates were tried, the coverage of the true white-noise and
random-walk coefficients by the chosen fit's 95 % datasheet intervals (a chosen model without
the term does not cover) and the median upper end of the random-walk interval over the truth
(how informative a covering interval is), the same random-walk coverage of a plain WN+RW fit (the old default)
for comparison, and the CPU seconds of one ``choose_model`` call (median and max; numba kernels
compiled beforehand). ``--write`` replaces this benchmark's section of ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gmwm
from gmwm.automodel import choose_model
from gmwm.datasheet import datasheet
from gmwm.model import Model, parse_model

F = 200.0
DEG_H = 1 / 3600.0          # deg/h in deg/s


@dataclass(frozen=True)
class Truth:
    label: str
    kind: str
    units: str
    spec: str
    values: dict[str, float]
    white: float    # true ARW / VRW in datasheet units
    walk: float     # true RRW / AccRW in datasheet units

    @property
    def model(self) -> Model:
        return Model(self.spec, F)

    @property
    def theta(self) -> np.ndarray:
        return self.model.theta(self.values)


def truths() -> list[Truth]:
    wn = (0.3 / 60) ** 2 * F                    # ARW 0.3 deg/sqrt(h)
    rw = (3 * DEG_H / 60) ** 2 / F              # RRW 3 deg/h/sqrt(h)
    gm = {"GM[1].beta": 1 / 30.0, "GM[1].sigma2": (5 * DEG_H) ** 2}
    return [
        Truth("gyro WN+GM+RW", "gyroscope", "deg/s", "WN+GM+RW",
              {"WN[1].sigma2": wn, **gm, "RW[1].gamma2": rw}, 0.3, 3.0),
        Truth("accel WN+RW", "accelerometer", "m/s^2", "WN+RW",
              {"WN[1].sigma2": (0.05 / 60) ** 2 * F, "RW[1].gamma2": 2e-5**2 / F}, 0.05,
              2e-5 * 3600 * 60),
        Truth("gyro WN+2*GM+RW", "gyroscope", "deg/s", "WN+2*GM+RW",
              {"WN[1].sigma2": wn, "GM[1].beta": 1.0, "GM[1].sigma2": (20 * DEG_H) ** 2,
               "GM[2].beta": 1 / 30.0, "GM[2].sigma2": (5 * DEG_H) ** 2, "RW[1].gamma2": rw},
              0.3, 3.0),
        Truth("gyro WN+SIN+RW", "gyroscope", "deg/s", "WN+SIN+RW",
              {"WN[1].sigma2": wn, "SIN[1].alpha": 0.05, "SIN[1].beta": 2 * np.pi * 2 / F,
               "RW[1].gamma2": rw}, 0.3, 3.0),
    ]


def _term(ds: dict, prefixes: tuple[str, ...]) -> dict | None:
    return next((v for k, v in ds.items() if k.split("[")[0] in prefixes), None)


def _covers(entry: dict | None, truth: float) -> bool:
    if entry is None or entry.get("ci95") is None:
        return False
    lo, hi = entry["ci95"]
    return lo is not None and hi is not None and lo <= truth <= hi


def _upper(entry: dict | None) -> float:
    ci = None if entry is None else entry.get("ci95")
    return float("nan") if not ci or ci[1] is None else float(ci[1])


def replicate(truth: Truth, i: int, r: int, n: int) -> dict:
    x = truth.model.simulate_fast(truth.theta, n, rng=np.random.default_rng([71, i, r]))
    c0 = time.process_time()
    c = choose_model(x, freq=F, kind=truth.kind)
    cpu = time.process_time() - c0
    ds = datasheet(c.result, truth.units)
    old = datasheet(gmwm.fit(x, "WN+RW", freq=F), truth.units)
    got, want = parse_model(c.model.spec), parse_model(truth.spec)
    slow = lambda d: d.get("GM", 0) + d.get("AR1", 0)
    return {
        "model": c.model.spec,
        "contains": {k: (slow(got) if k == "GM" else got.get(k, 0)) >= v for k, v in want.items()},
        "exact": c.model.spec == Model(truth.spec).spec,
        "spurious": sorted({k for k, v in got.items() if v and not want.get(k)}
                           | ({"GM"} if slow(got) > slow(want) else set())),
        "rejected": not c.passed,
        "sin_tried": c.bump is not None,
        "white": _covers(_term(ds, ("ARW", "VRW", "WN")), truth.white),
        "walk": _covers(_term(ds, ("RRW", "AccRW", "RW")), truth.walk),
        "walk_old": _covers(_term(old, ("RRW", "AccRW", "RW")), truth.walk),
        "walk_hi": _upper(_term(ds, ("RRW", "AccRW", "RW"))) / truth.walk,
        "cpu": cpu,
        "n_fitted": len(c.ranking.ranked),
    }


def summarise(truth: Truth, reps: list[dict]) -> dict:
    mean = lambda key: float(np.mean([r[key] for r in reps]))
    comps = parse_model(truth.spec)
    spur: dict[str, int] = {}
    for r in reps:
        for k in r["spurious"]:
            spur[k] = spur.get(k, 0) + 1
    cpu = np.array([r["cpu"] for r in reps])
    picks: dict[str, int] = {}
    for r in reps:
        picks[r["model"]] = picks.get(r["model"], 0) + 1
    return {
        "contains": {k: float(np.mean([r["contains"][k] for r in reps])) for k in comps},
        "exact": mean("exact"),
        "any_spurious": float(np.mean([bool(r["spurious"]) for r in reps])),
        "spurious": {k: v / len(reps) for k, v in sorted(spur.items())},
        "rejected": mean("rejected"), "sin_tried": mean("sin_tried"),
        "white": mean("white"), "walk": mean("walk"), "walk_old": mean("walk_old"),
        "walk_hi": float(np.nanmedian([r["walk_hi"] for r in reps])),
        "cpu_median": float(np.median(cpu)), "cpu_max": float(cpu.max()),
        "fitted": float(np.mean([r["n_fitted"] for r in reps])),
        "picks": dict(sorted(picks.items(), key=lambda kv: -kv[1])),
    }


def table(rows: list[tuple[Truth, dict]], reps: int, n: int) -> list[str]:
    head = ("| truth | contains (share per true component) | = truth | spurious (share) | "
            "GOF rejects choice | SIN tried | white cov. | walk cov. | walk 95 % upper / truth "
            "(median) | walk cov. WN+RW fit | candidates fitted | CPU s/axis median (max) |")
    lines = [head, "|" + "---|" * 12]
    for t, s in rows:
        contains = ", ".join(f"{k} {v:.2f}" for k, v in s["contains"].items())
        spur = (f"{s['any_spurious']:.2f}" + (" (" + ", ".join(
            f"{k} {v:.2f}" for k, v in s["spurious"].items()) + ")" if s["spurious"] else ""))
        lines.append(f"| {t.label} | {contains} | {s['exact']:.2f} | {spur} | "
                     f"{s['rejected']:.2f} | {s['sin_tried']:.2f} | {s['white']:.2f} | "
                     f"{s['walk']:.2f} | {s['walk_hi']:.3g} | {s['walk_old']:.2f} | {s['fitted']:.1f} | "
                     f"{s['cpu_median']:.2f} ({s['cpu_max']:.2f}) |")
    lines += ["", "Choices: " + "; ".join(
        f"{t.label}: " + ", ".join(f"{m} {k}" for m, k in s["picks"].items()) for t, s in rows)
        + f" (of {reps} replicates, T = {n})."]
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=40)
    ap.add_argument("--log2n", type=int, default=20)
    ap.add_argument("--truths", nargs="+", default=None, help="labels (default: all)")
    ap.add_argument("--write", action="store_true",
                    help="replace this benchmark's section of benchmarks/README.md")
    args = ap.parse_args()
    n = 2**args.log2n
    chosen = [(i, t) for i, t in enumerate(truths())
              if args.truths is None or t.label in args.truths]
    # compile the kernels once, outside the measured calls
    for _, t in chosen:
        choose_model(t.model.simulate_fast(t.theta, 2**12, rng=0), freq=F, kind=t.kind)
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    rows = []
    for i, t in chosen:
        reps = [replicate(t, i, r, n) for r in range(args.reps)]
        s = summarise(t, reps)
        rows.append((t, s))
        print(f"{t.label}: {s}", flush=True)
    lines = table(rows, args.reps, n)
    print("\n".join(lines))
    load1 = os.getloadavg()[0]
    if args.write:
        from readme_section import machine, update_section

        head = (f"Generated by `python benchmarks/bench_automodel.py --reps {args.reps} --log2n "
                f"{args.log2n} --write` ({machine()}; {time.perf_counter() - t0:.0f} s wall, "
                f"1-minute load {load0:.1f} at the start, {load1:.1f} at the end). "
                "Coverage: share of 95 % datasheet intervals of the chosen fit containing the "
                "true white-noise (ARW/VRW) and random-walk (RRW/AccRW) coefficient; the last "
                "coverage column is that of a plain WN+RW fit (the old default). CPU: process "
                "time of one choose_model call per axis.\n")
        update_section("bench_automodel", head + "\n" + "\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
