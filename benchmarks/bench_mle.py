"""Per-fit cost of the Simulation 1 MLE variants against the GMWM; prints a table only.

Usage: python benchmarks/bench_mle.py [--reps 10] [--sizes 10000 ... 160000] [--statsmodels 2]
[--gmwm-starts 8]

Per T, ``--reps`` seeded Simulation 1 signals. For each: the GMWM fit as the study runs it (one
``gmwm.fit`` call on the raw signal, WV included, CI weights, ``--gmwm-starts`` starts), the same
fit of the single model (``nested=False``, the paper's estimator; it counts how often its
objective equals the default's), then the
Kalman-filter MLE (``gmwm_studies.mle.fit_mle``, backend "kalman") from its own moment start, from
statsmodels' start values, and from the GMWM estimate. ``--statsmodels K`` also times the
statsmodels-filter backend from the GMWM estimate on the first K signals (slow). Prints wall and
process-CPU seconds (mean and median), convergence counts, the largest log-likelihood gap between
the backends, and the load average before and after (wall times scale with other jobs on the
cores; CPU time is the steadier number).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gmwm import fit
from gmwm.model import Model
from gmwm_studies.mle import fit_mle

SPEC = "WN+RW+AR1+SIN"
TRUTH = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
         "SIN[1].beta": 0.35, "RW[1].gamma2": 4e-4}
BETA = TRUTH["SIN[1].beta"]


def timed(f, *args, **kw):
    w, c = time.perf_counter(), time.process_time()
    out = f(*args, **kw)
    return out, time.perf_counter() - w, time.process_time() - c


def row(label: str, wall: list[float], cpu: list[float], extra: str = "") -> str:
    return (f"  {label:<22} wall mean {np.mean(wall):7.3f} median {np.median(wall):7.3f} | "
            f"CPU mean {np.mean(cpu):7.3f} median {np.median(cpu):7.3f}  {extra}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=10)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 20_000, 40_000, 80_000, 160_000])
    ap.add_argument("--statsmodels", type=int, default=0, metavar="K")
    ap.add_argument("--gmwm-starts", type=int, default=8)
    args = ap.parse_args()

    model = Model(SPEC)
    theta = model.theta(TRUTH)
    # first calls compile the numba kernels (WV, filter); keep them out of the timings
    x0 = model.simulate(theta, 4096, np.random.default_rng(0))
    fit(x0, model, n_starts=1)
    fit_mle(x0, BETA, n_starts=1)
    fit_mle(x0, BETA, n_starts=1, own_starts="default")
    print(f"load average before: {os.getloadavg()}")
    for n in args.sizes:
        res: dict[str, tuple[list, list, list, list]] = {}

        def add(key: str, wall: float, cpu: float, ok: bool, ll: float = np.nan,
                res: dict = res) -> None:
            for lst, v in zip(res.setdefault(key, ([], [], [], [])), (wall, cpu, ok, ll),
                              strict=True):
                lst.append(v)

        same: list[bool] = []
        for rep in range(args.reps):
            x = model.simulate(theta, n, np.random.default_rng([n, rep]))
            g, w, c = timed(fit, x, model, n_starts=args.gmwm_starts, seed=rep)
            add("GMWM (incl. WV)", w, c, bool(g.converged))
            # the paper's estimator: one model's multistart search, without the nested submodel
            # search of the default (which only guarantees "never worse than a submodel")
            g1, w, c = timed(fit, x, model, n_starts=args.gmwm_starts, seed=rep, nested=False)
            add("GMWM single model", w, c, bool(g1.converged))
            same.append(abs(g1.objective - g.objective) <= 1e-6 * g.objective)
            start = model.as_dict(model.canonical(np.asarray(g.params, float)))
            for key, kw in (("MLE own moment start", {}),
                            ("MLE statsmodels start", {"own_starts": "default"}),
                            ("MLE GMWM start", {"start": start})):
                m, w, c = timed(fit_mle, x, BETA, n_starts=1, **kw)
                add(key, w, c, m.converged, m.loglike)
            if rep < args.statsmodels:
                m, w, c = timed(fit_mle, x, BETA, start, n_starts=1, backend="statsmodels")
                add("MLE GMWM start (sm)", w, c, m.converged, m.loglike)
        print(f"T = {n}: {args.reps} signals; single-model GMWM objective equal to the default's "
              f"(1e-6 relative) in {sum(same)}/{len(same)}")
        best = np.nanmax(np.array([r[3][:args.reps] for k, r in res.items() if not k.endswith("(sm)")]),
                         axis=0)
        for key, (wall, cpu, ok, ll) in res.items():
            ll = np.asarray(ll)
            extra = f"converged {sum(ok)}/{len(ok)}"
            if np.isfinite(ll).any():
                gap = best[:len(ll)] - ll
                extra += f", ll below best > 1: {int(np.sum(gap > 1))}"
                if key.endswith("(sm)"):
                    kf = np.asarray(res["MLE GMWM start"][3][:len(ll)])
                    extra += f", max |ll(sm) - ll(kalman)| {np.max(np.abs(ll - kf)):.1e}"
            print(row(key, wall, cpu, extra), flush=True)
        g = np.median(res["GMWM (incl. WV)"][0])
        print("  speed-up (median wall MLE / GMWM): "
              + ", ".join(f"{k[4:]} {np.median(r[0]) / g:.1f}" for k, r in res.items()
                          if k.startswith("MLE")), flush=True)
    print(f"load average after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
