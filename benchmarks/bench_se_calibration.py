"""Calibration of GMWM standard errors: empirical SD of the estimates / mean reported SE.

For each model, R seeded replicates are simulated and fitted; the ratio is printed per parameter
for the default SEs (model covariance of the WV estimate, between-scale correlation, SIN only via
its cross term) and for the old Gaussian diagonal (``se_cov="gaussian"``), with CI weights and
with the efficient two-step weights. A ratio near 1 means calibrated; its Monte Carlo error is
about 1/sqrt(2R).

    python benchmarks/bench_se_calibration.py [--R 120] [--T 65536]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gmwm
from gmwm.model import Model

CASES = {
    "WN+RW+AR1": {"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975,
                  "AR1[1].sigma2": 0.03},
    "AR1+WN+SIN": {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                   "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35},
    "QN+WN+RW+DR": {"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-3,
                    "DR[1].omega": 1e-3},
}


def calibration(spec: str, truth: dict[str, float], T: int, R: int, weights: str = "ci",
                se_cov: str = "model", seed: int = 0) -> dict[str, np.ndarray]:
    """Estimates, SEs and convergence of R replicates (streams keyed by (seed, replicate))."""
    m = Model(spec)
    theta = m.theta(truth)
    est, se, ok = [], [], []
    for r in range(R):
        x = m.simulate(theta, T, np.random.default_rng([seed, r]))
        res = gmwm.fit(x, m, weights=weights, se_cov=se_cov)
        est.append(res.params)
        se.append(res.se)
        ok.append(res.converged and not res.diagnostics["at_boundary"])
    return {"names": m.param_names, "theta": theta, "est": np.array(est), "se": np.array(se),
            "ok": np.array(ok)}


def ratio(out: dict[str, np.ndarray]) -> np.ndarray:
    """Empirical SD / mean SE over the converged interior replicates."""
    e, s = out["est"][out["ok"]], out["se"][out["ok"]]
    return e.std(axis=0, ddof=1) / np.nanmean(s, axis=0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=int, default=120)
    ap.add_argument("--T", type=int, default=2**16)
    args = ap.parse_args()
    print(f"T = {args.T}, R = {args.R}; ratio = empirical SD / mean SE "
          f"(MC error ~ {1 / np.sqrt(2 * args.R):.2f})")
    for spec, truth in CASES.items():
        for weights, se_cov in (("ci", "model"), ("ci", "gaussian"), ("efficient", "model")):
            t0 = time.perf_counter()
            out = calibration(spec, truth, args.T, args.R, weights, se_cov)
            r = ratio(out)
            cells = "  ".join(f"{n}={v:.2f}" for n, v in zip(out["names"], r, strict=True))
            rel_bias = (out["est"][out["ok"]].mean(0) - out["theta"]) / out["theta"]
            print(f"{spec:<12} weights={weights:<9} se_cov={se_cov:<8} n={out['ok'].sum():>3}  "
                  f"{cells}  | max |rel. bias| {np.max(np.abs(rel_bias)):.3f}  "
                  f"({time.perf_counter() - t0:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
