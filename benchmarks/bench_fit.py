"""Benchmark: simulation, WV and GMWM fit cost per replicate for the papers' models.

Run: ``python benchmarks/bench_fit.py [--reps 20] [--big]``. Prints, per model and length,
the median (and 90 % quantile) wall time of simulation, WV and fit (the fit timed after the WV
is computed, as in the project's target "a fit of the Simulation 1 model takes at most 50 ms median").
Measure on an idle machine: wall times scale with whatever else runs on the cores; the fit's
process CPU time (single-threaded) is the steadier number on a shared machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gmwm
from gmwm.model import Model

MODELS = {
    "Sim 1 (WN+RW+AR1+SIN)": ("WN+RW+AR1+SIN", {
        "WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
        "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35}),
    "Sim 2 (2*AR1+2*SIN)": ("2*AR1+2*SIN", {
        "AR1[1].phi": 0.1107083, "AR1[1].sigma2": 5.278666e-4, "AR1[2].phi": 0.999995,
        "AR1[2].sigma2": 3e-11, "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
        "SIN[2].alpha": 0.0015, "SIN[2].beta": 8e-6}),
    "Sim 3 (AR1+RW+WN+SIN)": ("AR1+RW+WN+SIN", {
        "AR1[1].phi": 0.9997083, "AR1[1].sigma2": 9e-6, "WN[1].sigma2": 8e-4,
        "RW[1].gamma2": 3e-11, "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056}),
    "STIM-300 accel (QN+WN+RW+DR)": ("QN+WN+RW+DR", {
        "QN[1].Q2": 2.0026e-7, "WN[1].sigma2": 1.5340e-4, "RW[1].gamma2": 1.6223e-10,
        "DR[1].omega": 1.2778e-8}),
}


def bench(label: str, spec: str, truth: dict, T: int, reps: int) -> None:
    model = Model(spec)
    theta = model.theta(truth)
    t_sim, t_wv, t_fit, c_fit, nc = [], [], [], [], 0
    for r in range(reps):
        t0 = time.perf_counter()
        x = model.simulate(theta, T, np.random.default_rng(r))
        t1 = time.perf_counter()
        wv = gmwm.wvar(x)
        t2 = time.perf_counter()
        c2 = time.process_time()
        res = gmwm.fit(wv, model)
        t3 = time.perf_counter()
        c_fit.append(time.process_time() - c2)
        t_sim.append(t1 - t0)
        t_wv.append(t2 - t1)
        t_fit.append(t3 - t2)
        nc += not res.converged
    q = lambda a, p: 1e3 * np.quantile(a, p)
    print(f"| {label} | {T:.2e} | {reps} | {q(t_sim, .5):8.1f} | {q(t_wv, .5):7.1f} | "
          f"{q(t_fit, .5):7.1f} | {q(t_fit, .9):7.1f} | {q(c_fit, .5):7.1f} | {nc} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--big", action="store_true", help="also T = 1e7 (Sims 2-3, 2 reps)")
    args = ap.parse_args()
    gmwm.wvar(np.random.default_rng(0).standard_normal(4096))  # JIT warm-up, not timed
    print("| model | T | reps | simulate ms (median) | WV ms | fit ms (median) | fit ms (p90) "
          "| fit CPU ms (median) | not converged |")
    print("|---|---|---|---|---|---|---|---|---|")
    label = "Sim 1 (WN+RW+AR1+SIN)"
    for T in (10_000, 160_000):
        bench(label, *MODELS[label], T, args.reps)
    bench("STIM-300 accel (QN+WN+RW+DR)", *MODELS["STIM-300 accel (QN+WN+RW+DR)"], 2_500_000,
          max(args.reps // 4, 2))
    if args.big:
        for label in ("Sim 1 (WN+RW+AR1+SIN)", "Sim 2 (2*AR1+2*SIN)", "Sim 3 (AR1+RW+WN+SIN)"):
            bench(label, *MODELS[label], 10_000_000, 2)


if __name__ == "__main__":
    main()
