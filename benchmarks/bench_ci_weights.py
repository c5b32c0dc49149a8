"""GMWM weights from the new WV intervals, for the later decision on the default weights.

Usage: python benchmarks/bench_ci_weights.py [--reps 100] [--T 65536] [--models WN+RW ...]

The estimator's default ``weights="ci"`` is the inverse squared width of the eta_3 interval
(``WaveletVariance.eta3_ci``; unchanged when the interval default became ``"mixture"``). This
prints, per model, the parameters' RMSE (relative to the truth) of GMWM fits on the same
replicates with

* ``ci``: the default (eta_3 widths);
* ``ci-mixture``: inverse squared widths of the default (mixture) interval;
* ``gaussian``: ``eta3_j / (2 nu_hat_j^2)``;
* ``gaussian-mixture``: ``ci_edof_j / (2 nu_hat_j^2)`` (the mixture EDF).

The alternatives are passed as diagonal covariances of ``nu_hat`` (``weights=V``: the weight is
V^-1; the standard errors are not compared here). One fit per replicate, ``n_starts=4``,
``nested=False``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import gmwm
from gmwm.model import Model

MODELS = {
    "WN+RW": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5}),
    "WN+AR1+RW": ("WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                                "RW[1].gamma2": 1e-6}),
    "QN+WN+RW": ("QN+WN+RW", {"QN[1].Q2": 1.0, "WN[1].sigma2": 0.1, "RW[1].gamma2": 1e-7}),
}
KINDS = ("ci", "ci-mixture", "gaussian", "gaussian-mixture")


def weights_for(wv: gmwm.WaveletVariance, kind: str) -> str | np.ndarray:
    if kind in ("ci", "gaussian"):
        return kind
    if kind == "ci-mixture":
        return np.diag((wv.ci_high - wv.ci_low) ** 2)
    return np.diag(2.0 * wv.variance**2 / wv.ci_edof)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--T", type=int, default=2**16)
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    args = ap.parse_args()
    t0, load0 = time.perf_counter(), os.getloadavg()[0]
    print(f"R = {args.reps}, T = {args.T}; parameter RMSE / truth (and relative to 'ci')")
    for name in args.models:
        spec, values = MODELS[name]
        model = Model(spec)
        theta = model.theta(values)
        rng = np.random.default_rng(7)
        est = {k: [] for k in KINDS}
        for _ in range(args.reps):
            wv = gmwm.wvar(model.simulate_fast(theta, args.T, rng))
            for k in KINDS:
                res = gmwm.fit(wv, model, weights=weights_for(wv, k), n_starts=4, nested=False)
                est[k].append(res.params)
        print(f"\n{name}: " + ", ".join(f"{n} = {v:g}" for n, v in zip(model.param_names, theta,
                                                                         strict=True)))
        ref = None
        for k in KINDS:
            e = np.asarray(est[k])
            rmse = np.sqrt(np.mean((e / theta - 1.0) ** 2, axis=0))
            ref = rmse if ref is None else ref
            cells = "  ".join(f"{n} {r:.3f} ({r / q:.2f})" for n, r, q in zip(
                model.param_names, rmse, ref, strict=True))
            print(f"  {k:17s} {cells}")
    print(f"\n{time.perf_counter() - t0:.0f} s wall, load average {load0:.1f} before / "
          f"{os.getloadavg()[0]:.1f} after on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
