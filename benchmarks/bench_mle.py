"""Time per Kalman-filter MLE fit (gmwm.mle.fit_mle) on Simulation 1 signals; prints a table only.

Usage: python benchmarks/bench_mle.py [--reps 2] [--sizes 10000 20000 40000 80000 160000]
[--starts 1 2] [--statsmodels]

Each fit starts from the truth perturbed by ~20 % (a stand-in for the GMWM estimate the pipeline
passes). ``--statsmodels`` also times statsmodels' own ``fit`` (exog regressors, lbfgs) from the same
start, for reference (slow: tens of seconds at T = 1.6e5).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from scipy.signal import lfilter

from gmwm.mle import fit_mle

BETA = 0.35
TRUTH = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03}


def simulate(n: int, rng: np.random.Generator) -> np.ndarray:
    """Simulation 1: WN + RW + AR1 (stationary start) + 0.85 sin(0.35 t + U)."""
    phi, s2ar = TRUTH["AR1[1].phi"], TRUTH["AR1[1].sigma2"]
    w = rng.normal(0.0, np.sqrt(s2ar), n)
    w[0] = rng.normal(0.0, np.sqrt(s2ar / (1.0 - phi**2)))
    ar = lfilter([1.0], [1.0, -phi], w)
    rw = np.cumsum(rng.normal(0.0, np.sqrt(TRUTH["RW[1].gamma2"]), n))
    wn = rng.normal(0.0, np.sqrt(TRUTH["WN[1].sigma2"]), n)
    return wn + rw + ar + 0.85 * np.sin(BETA * np.arange(n) + rng.uniform(0.0, 2.0 * np.pi))


def perturbed_start(rng: np.random.Generator) -> dict[str, float]:
    start = {k: v * np.exp(0.2 * rng.normal()) for k, v in TRUTH.items() if k != "AR1[1].phi"}
    start["AR1[1].phi"] = 0.97
    return start


def statsmodels_fit_seconds(x: np.ndarray, start: dict[str, float]) -> tuple[float, float]:
    from statsmodels.tsa.statespace.structural import UnobservedComponents

    t = BETA * np.arange(x.size)
    model = UnobservedComponents(x, level="llevel", autoregressive=1, use_exact_diffuse=True,
                                 exog=np.column_stack([np.cos(t), np.sin(t)]))
    p0 = [start["WN[1].sigma2"], start["RW[1].gamma2"], start["AR1[1].sigma2"], start["AR1[1].phi"],
          0.0, 0.85]
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = model.fit(start_params=p0, disp=0, cov_type="none")
    return time.perf_counter() - t0, float(res.llf)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=2)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 20_000, 40_000, 80_000, 160_000])
    ap.add_argument("--starts", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--statsmodels", action="store_true")
    args = ap.parse_args()

    print(f"{'T':>7} {'n_starts':>8} {'s/fit':>8} {'min':>7} {'max':>7} {'converged':>9}  winners"
          f"{'   statsmodels s/fit (dllf)' if args.statsmodels else ''}")
    for n in args.sizes:
        data = []
        for rep in range(args.reps):
            rng = np.random.default_rng([n, rep])
            data.append((simulate(n, rng), perturbed_start(rng)))
        for n_starts in args.starts:
            secs, conv, winners, lls = [], 0, [], []
            for x, start in data:
                res = fit_mle(x, BETA, start, n_starts=n_starts)
                secs.append(res.seconds)
                conv += res.converged
                winners.append(res.start)
                lls.append(res.loglike)
            extra = ""
            if args.statsmodels and n_starts == args.starts[-1]:
                sm = [statsmodels_fit_seconds(x, s) for x, s in data]
                dllf = max(ll - sm_ll for ll, (_, sm_ll) in zip(lls, sm, strict=True))
                extra = f"   {np.mean([s for s, _ in sm]):8.2f} ({dllf:+.1e})"
            print(f"{n:>7} {n_starts:>8} {np.mean(secs):8.2f} {min(secs):7.2f} {max(secs):7.2f} "
                  f"{conv:>4}/{len(data):<4}  {','.join(winners)}{extra}", flush=True)


if __name__ == "__main__":
    main()
