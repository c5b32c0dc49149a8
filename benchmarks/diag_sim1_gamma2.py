"""Diagnostic: where the Simulation 1 GMWM's gamma2 bias comes from; prints a table.

Usage: python benchmarks/diag_sim1_gamma2.py [--T 160000] [--reps 100] [--first 0] [--paired]

Default mode: the study's own replicates (``replicate_rng("sim1", T, r, 20240601)``, ids
``first .. first + reps - 1``) fitted like the study (8 starts, WV included) with CI weights,
CI weights plus 1 or 2 re-weighting passes, Gaussian weights (``eta_j / (2 nu_hat_j^2)``) with
and without a re-weighting pass, and fixed "oracle" weights (Gaussian variances at the TRUE model
WV, so not data-dependent). ``--paired``: the same WN + RW + AR1 noise fitted without a sinusoid
(model WN+RW+AR1) and with a deterministic sinusoid added (WN+RW+AR1+SIN), CI and oracle weights,
to isolate the sinusoid's role. Prints relative bias (z = bias / MC SE) and relative SD of sigma2,
phi, the AR1 innovation variance and gamma2, and the paired gamma2 differences.
"""

from __future__ import annotations

import argparse

import numpy as np

from gmwm import fit
from gmwm.model import Model
from gmwm.wv import wvar
from gmwm_studies.seeds import replicate_rng, replicate_seed

TRUTH = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
         "SIN[1].beta": 0.35, "RW[1].gamma2": 4e-4}
KEYS = ("WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2")
SEED = 20240601


def oracle(model: Model, theta: np.ndarray, wv) -> np.ndarray:
    """Diagonal covariance 2 nu_j(theta0)^2 / eta_j at the true WV: fixed weights."""
    return np.diag(2.0 * model.wv(theta, wv.scales) ** 2 / wv.edof)


def estimate(res, model: Model) -> list[float]:
    d = model.as_dict(model.canonical(np.asarray(res.params, float)))
    return [d[k] for k in KEYS]


def study_replicates(T: int, reps: range) -> dict[str, list]:
    model = Model("WN+RW+AR1+SIN")
    theta = model.theta(TRUTH)
    out: dict[str, list] = {}
    for r in reps:
        seed = replicate_seed("sim1", T, r, SEED, stream=1)
        wv = wvar(model.simulate(theta, T, replicate_rng("sim1", T, r, SEED)))
        for key, kw in (("ci", {}), ("ci_reweight1", {"reweight": 1}),
                        ("ci_reweight2", {"reweight": 2}), ("gaussian", {"weights": "gaussian"}),
                        ("gaussian_reweight1", {"weights": "gaussian", "reweight": 1}),
                        ("oracle_fixed", {"weights": oracle(model, theta, wv)})):
            out.setdefault(key, []).append(estimate(fit(wv, model, seed=seed, n_starts=8, **kw),
                                                    model))
    return out


def paired(T: int, reps: range) -> dict[str, list]:
    full = Model("WN+RW+AR1+SIN")
    nosin = Model("WN+RW+AR1")
    th_full = full.theta(TRUTH)
    th_nosin = nosin.theta({k: v for k, v in TRUTH.items() if not k.startswith("SIN")})
    out: dict[str, list] = {}
    for r in reps:
        rng = replicate_rng("sim1_paired", T, r, SEED)
        seed = replicate_seed("sim1_paired", T, r, SEED, stream=1)
        noise = nosin.simulate(th_nosin, T, rng)
        x = noise + TRUTH["SIN[1].alpha"] * np.sin(TRUTH["SIN[1].beta"] * np.arange(T)
                                                   + rng.uniform(0.0, 2.0 * np.pi))
        for key, model, theta, sig in (("nosin", nosin, th_nosin, noise), ("sin", full, th_full, x)):
            wv = wvar(sig)
            out.setdefault(f"{key}_ci", []).append(
                estimate(fit(wv, model, seed=seed, n_starts=8), model))
            out.setdefault(f"{key}_oracle", []).append(
                estimate(fit(wv, model, seed=seed, n_starts=8, weights=oracle(model, theta, wv)),
                         model))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=int, default=160_000)
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--first", type=int, default=0)
    ap.add_argument("--paired", action="store_true")
    args = ap.parse_args()
    reps = range(args.first, args.first + args.reps)
    out = (paired if args.paired else study_replicates)(args.T, reps)
    truth = np.array([TRUTH[k] for k in KEYS])
    print(f"T = {args.T}, replicates {reps.start}..{reps.stop - 1}: relative bias % (z) and "
          f"relative SD % of sigma2, phi, AR1 innovation variance, gamma2")
    for key, rows in out.items():
        est = np.array(rows)
        bias = est.mean(axis=0) - truth
        se = est.std(axis=0, ddof=1) / np.sqrt(len(est))
        sd = est.std(axis=0, ddof=1) / truth
        print(f"{key:>20} " + "  ".join(f"{100 * bias[i] / truth[i]:+6.2f} (z {bias[i] / se[i]:+5.1f})"
                                        f" sd {100 * sd[i]:5.2f}" for i in range(4)))
    g = {k: np.array(v)[:, 3] / TRUTH["RW[1].gamma2"] for k, v in out.items()}
    pairs = ((("sin_ci", "nosin_ci"), ("sin_oracle", "nosin_oracle")) if args.paired else
             (("ci", "oracle_fixed"), ("ci", "ci_reweight1"), ("ci_reweight1", "oracle_fixed")))
    for a, b in pairs:
        d = g[a] - g[b]
        print(f"paired gamma2 difference {a} - {b}: {100 * d.mean():+.2f} % of truth "
              f"(z {d.mean() / (d.std(ddof=1) / np.sqrt(len(d))):+.1f})")


if __name__ == "__main__":
    main()
