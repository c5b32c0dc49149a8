"""Benchmark: classical vs robust GMWM on contaminated simulations, and the robust WV's cost.

Run: ``python benchmarks/bench_robust.py [--reps 20] [--eff 0.6] [--no-timing | --timing-only]``.
Signals of T = 2^16 samples from WN+RW and WN+AR1, clean or contaminated by
* ``burst``: five bursts of 64 samples of N(0, 30^2) added (0.5 % of the samples),
* ``outliers``: 1 % of the samples shifted by +-20 (isolated outliers),
are fitted by GMWM on the classical WV and on the robust WV (``wvar(x, robust=True, eff)``).
Prints the median estimate (and the 10-90 % range) of every parameter, then the wall time of the
classical and robust WV for T = 2^16, 2^20 and 1e7 (best of 3, after a warm-up call).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gmwm
from gmwm.model import Model

MODELS = {
    "WN+RW": {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4},
    "WN+AR1": {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995, "AR1[1].sigma2": 1e-3},
}


def contaminate(x: np.ndarray, kind: str, rng: np.random.Generator) -> np.ndarray:
    x = x.copy()
    if kind == "burst":
        for s in rng.choice(x.size - 64, 5, replace=False):
            x[s:s + 64] += 30.0 * rng.standard_normal(64)
    elif kind == "outliers":
        idx = rng.choice(x.size, x.size // 100, replace=False)
        x[idx] += 20.0 * rng.choice([-1.0, 1.0], idx.size)
    return x


def _fit(data, model):
    try:
        return gmwm.fit(data, model, se_cov="gaussian")  # SEs are not used here
    except TypeError:
        return gmwm.fit(data, model)


def accuracy(reps: int, eff: float) -> None:
    print("| model | contamination | estimator | parameter: truth -> median [10 %, 90 %] |")
    print("|---|---|---|---|")
    for mi, (spec, truth) in enumerate(MODELS.items()):
        model = Model(spec)
        theta = model.theta(truth)
        for ki, kind in enumerate(("clean", "burst", "outliers")):
            est = {"classical": [], "robust": []}
            for r in range(reps):
                rng = np.random.default_rng(np.random.SeedSequence([11, mi, ki, r]))
                x = contaminate(model.simulate(theta, 2**16, rng), kind, rng)
                est["classical"].append(_fit(x, model).params)
                est["robust"].append(_fit(gmwm.wvar(x, robust=True, eff=eff), model).params)
            for name, values in est.items():
                a = np.array(values)
                q = np.quantile(a, [0.1, 0.5, 0.9], axis=0)
                cells = [f"{p}: {t:.4g} -> {q[1, i]:.4g} [{q[0, i]:.3g}, {q[2, i]:.3g}]"
                         for i, (p, t) in enumerate(zip(model.param_names, theta, strict=True))]
                print(f"| {spec} | {kind} | {name} | " + "; ".join(cells) + " |", flush=True)


def timing(eff: float) -> None:
    print("\n| T | classical WV wall / CPU [s] | robust WV wall / CPU [s] | ratio (CPU) |")
    print("|---|---|---|---|")
    rng = np.random.default_rng(1)
    gmwm.wvar(rng.standard_normal(4096), robust=True)  # compile / load the kernels
    for T in (2**16, 2**20, 10**7):
        x = rng.standard_normal(T).cumsum() * 1e-2 + rng.standard_normal(T)
        best = {"c": (np.inf, np.inf), "r": (np.inf, np.inf)}
        for _ in range(3):
            for key, kw in (("c", {}), ("r", {"robust": True, "eff": eff})):
                w0, c0 = time.perf_counter(), time.process_time()
                gmwm.wvar(x, **kw)
                cur = (time.perf_counter() - w0, time.process_time() - c0)
                best[key] = min(best[key], cur, key=lambda t: t[1])
        c, r = best["c"], best["r"]
        print(f"| {T:.3g} | {c[0]:.4f} / {c[1]:.4f} | {r[0]:.3f} / {r[1]:.3f} | "
              f"{r[1] / max(c[1], 1e-9):.0f} |", flush=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--eff", type=float, default=0.6)
    ap.add_argument("--no-timing", action="store_true")
    ap.add_argument("--timing-only", action="store_true")
    args = ap.parse_args()
    if not args.timing_only:
        accuracy(args.reps, args.eff)
    if not args.no_timing:
        timing(args.eff)


if __name__ == "__main__":
    main()
