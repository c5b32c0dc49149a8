"""Selection penalty calibration: is the generating model ranked first where its components are
real, and which penalty factor k of ``objective + k * optimism`` does it?

    python benchmarks/selection_penalty.py [--reps 100] [--lengths 14 17 20] [--jobs 1] [--write]

Design. Generating models typical of gyroscopes and accelerometers (:func:`settings`), each
weak component set to an *expected* z-value of 4 at every length where that is reachable (scale
parameter / its sandwich SE at the truth; ``bench_selection.calibrate``; where the z-value
saturates below 4 at a length, e.g. a random walk beside a slow AR1 in a short record, the base
value is kept), so that most replicates hold it at 3 SE or more and some do not. Each replicate is ranked once (:func:`gmwm.select.rank_models`: CI weights,
the goodness-of-fit test on every candidate, accepted candidates first) over the candidates one
component away from the generating model; the pick of each penalty factor is read off the same
fits. The generating model is then refitted with :func:`gmwm.fit`'s defaults and its
components' *realised* z-values (scale estimate / standard error) sort the replicate:

* "qualifying": every component of the generating model is >= 3 SE from 0 in that fit. The
  target: the generating model ranked first in >= 90 % of the qualifying replicates of every
  (model, length) cell;
* the others (a component below 3 SE): reported, not targeted (no rule can both keep a
  component the data hardly see and refuse spurious ones).

Reported: per cell and penalty, the hit rate among qualifying replicates with its Monte Carlo
SE, and the confusion table of the chosen penalty (what was picked instead: a component dropped,
one added, other). ``--write`` replaces this benchmark's section of ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_selection as bs

import gmwm
from gmwm.model import Model, parse_model
from gmwm.select import rank_models
from gmwm.wv import wvar

#: penalty factors compared: constants and the named criteria's (gmwm.criteria)
PENALTIES = {"k=2 (wic)": lambda T: 2.0, "k=3": lambda T: 3.0, "k=4": lambda T: 4.0,
             "k=2loglogT (wic-hq)": lambda T: 2.0 * math.log(math.log(T)),
             "k=logT (wic-log)": lambda T: math.log(T)}
Z_EXPECTED = 4.0
Z_QUALIFY = 3.0


@dataclass(frozen=True)
class Setting:
    label: str
    spec: str
    base: dict[str, float]
    weak: tuple[str, ...]          # components calibrated to Z_EXPECTED
    freq: float = 1.0

    def truth(self, T: int) -> tuple[Model, np.ndarray]:
        model = Model(self.spec, self.freq)
        theta = model.theta(self.base)
        for comp in self.weak:
            try:
                theta = bs.calibrate(model, theta, comp, Z_EXPECTED, T)
            except ValueError:  # saturated at this length: the base value, the filter decides
                pass
        return model, theta


def settings() -> list[Setting]:
    """Seven IMU-like generating models (gyroscope: WN + bias instability as GM/AR1 + RW, a slow
    sinusoid; accelerometer: WN + RW, quantization; a short-record model without RW)."""
    wn_rw = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}
    return [
        Setting("accel WN+RW", "WN+RW", wn_rw, ("RW[1]",)),
        Setting("accel QN+WN+RW", "QN+WN+RW", {"QN[1].Q2": 0.3, **wn_rw}, ("QN[1]", "RW[1]")),
        Setting("gyro WN+AR1+RW", "WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995,
                                                 "AR1[1].sigma2": 2e-3, "RW[1].gamma2": 1e-6},
                ("RW[1]",)),
        Setting("gyro WN+GM+RW (100 Hz)", "WN+GM+RW", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
            "RW[1].gamma2": 1e-9}, ("GM[1]", "RW[1]"), 100.0),
        Setting("gyro WN+2*GM+RW (100 Hz)", "WN+2*GM+RW", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 5.0, "GM[1].sigma2": 2e-6, "GM[2].beta": 0.05,
            "GM[2].sigma2": 1e-6, "RW[1].gamma2": 1e-10}, ("GM[1]", "GM[2]", "RW[1]"), 100.0),
        Setting("gyro WN+SIN+RW", "WN+SIN+RW", {
            "WN[1].sigma2": 1.0, "SIN[1].alpha": 0.1, "SIN[1].beta": 2 * math.pi / 2000,
            "RW[1].gamma2": 1e-6}, ("SIN[1]", "RW[1]")),
        Setting("short WN+GM (100 Hz)", "WN+GM", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 1.0, "GM[1].sigma2": 1e-6}, ("GM[1]",), 100.0),
    ]


def realised_z(result) -> list[float]:
    """|scale estimate| / SE of every component of a fit (0 at the boundary, NaN: no SE)."""
    theta, se = np.asarray(result.params, float), np.asarray(result.se, float)
    out = []
    for c in result.model.components:
        i = c.start + c.process.scale_index
        out.append(0.0 if theta[i] == 0 else
                   float(abs(theta[i]) / se[i]) if np.isfinite(se[i]) and se[i] > 0 else np.nan)
    return out


def pick(entries, k: float) -> str:
    """The first-ranked model under penalty factor k: accepted candidates (goodness of fit)
    first, then by criterion; near-equal criteria (relative 1e-7) go to fewer parameters (the
    rule of :func:`gmwm.select.rank_models`)."""
    def crit(e) -> float:
        return e.objective + k * e.penalty

    best = min(entries, key=lambda e: (e.rejected(), crit(e)))
    tol = 1e-7 * abs(crit(best)) + 1e-300
    ties = [e for e in entries
            if e.rejected() == best.rejected() and crit(e) - crit(best) <= tol]
    return min(ties, key=lambda e: e.n_params).model


def replicate(args: tuple[Setting, int, int]) -> dict:
    setting, T, r = args
    model, theta = setting.truth(T)
    cands = bs.candidates(model.spec)
    key = sum(map(ord, setting.label))
    x = model.simulate_fast(theta, T, np.random.default_rng([2040, key, T, r]))
    wv = wvar(x, freq=setting.freq)
    ranking = rank_models(wv, cands)
    picks = {name: pick(ranking.ranked, f(T)) for name, f in PENALTIES.items()}
    z = realised_z(gmwm.fit(wv, model.spec))
    return {"picks": picks, "z": z, "qualifies": bool(np.all(np.nan_to_num(z) >= Z_QUALIFY))}


def describe(gen: str, got: str) -> str:
    if got == gen:
        return "generating"
    cg, cs = parse_model(gen), parse_model(got)
    drop = [k for k in cg if cs.get(k, 0) < cg[k]]
    add = [k for k in cs if cs[k] > cg.get(k, 0)]
    parts = [f"drops {'+'.join(drop)}"] if drop else []
    parts += [f"adds {'+'.join(add)}"] if add else []
    return ", ".join(parts) or got


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--lengths", type=int, nargs="+", default=[14, 17, 20], metavar="K")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--settings", nargs="+", default=None)
    ap.add_argument("--chosen", default="k=2loglogT (wic-hq)", help="penalty of the confusion table")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    chosen = [s for s in settings() if args.settings is None or s.label in args.settings]
    t0, cpu0 = time.perf_counter(), time.process_time()
    rows, confusion, skipped = [], {}, []
    pool = ProcessPoolExecutor(args.jobs) if args.jobs > 1 else None
    try:
        for s in chosen:
            for kexp in args.lengths:
                T = 2**kexp
                try:
                    s.truth(T)
                except ValueError as err:
                    skipped.append(f"{s.label} at T = 2^{kexp}: {err}")
                    print(f"{s.label} T=2^{kexp}: skipped: {err}", flush=True)
                    continue
                work = [(s, T, r) for r in range(args.reps)]
                reps = list(pool.map(replicate, work)) if pool else list(map(replicate, work))
                q = [rep for rep in reps if rep["qualifies"]]
                hits = {name: (np.mean([rep["picks"][name] == s.spec for rep in q]) if q
                               else np.nan) for name in PENALTIES}
                rows.append((s, kexp, len(reps), len(q), hits))
                confusion[(s.label, kexp)] = Counter(
                    describe(s.spec, rep["picks"][args.chosen]) for rep in q)
                print(f"{s.label:<28} T=2^{kexp}: qualifying {len(q)}/{len(reps)}  " + "  ".join(
                    f"{n} {h:.2f}" for n, h in hits.items()), flush=True)
    finally:
        if pool:
            pool.shutdown()
    lines = table(rows, confusion, args.chosen)
    if skipped:
        lines += ["", "Not reachable (skipped): " + "; ".join(skipped) + "."]
    print("\n".join(lines))
    if args.write:
        head = (f"Generated by `python benchmarks/selection_penalty.py --reps {args.reps} "
                f"--lengths {' '.join(map(str, args.lengths))} --jobs {args.jobs} --write` "
                f"(commit {bs.commit()}, {time.perf_counter() - t0:.0f} s wall, "
                f"{time.process_time() - cpu0:.0f} s CPU in the main process, 1-minute load "
                f"{os.getloadavg()[0]:.1f} at the end). Weak components at an expected z of "
                f"{Z_EXPECTED:g}; a replicate qualifies when every component of the generating "
                f"model is >= {Z_QUALIFY:g} SE from 0 in its default fit; hit = share of "
                "qualifying replicates ranking the generating model first (MC SE in brackets); "
                "candidates one component away; accepted candidates (goodness of fit at 0.05) "
                "ranked first.\n")
        bs.write_section(head + "\n" + "\n".join(lines), "selection_penalty")


def table(rows, confusion, chosen: str) -> list[str]:
    names = list(PENALTIES)
    lines = ["| generating model | T | qualifying / R | " + " | ".join(names) + " |",
             "|" + "---|" * (3 + len(names))]
    for s, kexp, n, nq, hits in rows:
        cells = []
        for name in names:
            h = hits[name]
            cells.append("–" if not np.isfinite(h) else
                         f"{h:.2f} ({math.sqrt(h * (1 - h) / nq):.2f})")
        lines.append(f"| {s.label} | 2^{kexp} | {nq} / {n} | " + " | ".join(cells) + " |")
    worst = {name: min((r[4][name] for r in rows if np.isfinite(r[4][name])), default=np.nan)
             for name in names}
    lines += ["", "Lowest hit rate over the cells: " + ", ".join(
        f"{n} {w:.2f}" for n, w in worst.items()) + "."]
    lines += ["", f"Confusion of `{chosen}` (qualifying replicates: what was ranked first):", "",
              "| generating model | T | picks |", "|---|---|---|"]
    for (label, kexp), cnt in confusion.items():
        total = sum(cnt.values())
        picks = "; ".join(f"{what} {c / total:.2f}" for what, c in cnt.most_common())
        lines.append(f"| {label} | 2^{kexp} | {picks} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
