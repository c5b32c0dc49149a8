"""Benchmark gmwm.wvcov.wv_covariance on the paper-000 Simulation 1-3 models (docs/METHODS.md §12.5).

Usage: python benchmarks/bench_wvcov.py [--T 10000000] [--levels 22] [--repeat 7]
Prints, per model: median and min wall and CPU seconds of one call after a warm-up call (JIT cache
load), the smallest eigenvalue of the correlation matrix and the adjacent-scale correlations at a
few levels. CPU time is the fairer number when other processes share the cores.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gmwm.model import Model
from gmwm.wvcov import wv_correlation, wv_covariance

SIMULATIONS = {
    "sim1": ("WN+AR1+RW+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                               "RW[1].gamma2": 4e-4, "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35}),
    "sim2": ("2*AR1+2*SIN", {"AR1[1].phi": 0.1107083, "AR1[1].sigma2": 5.278666e-4,
                             "AR1[2].phi": 0.999995, "AR1[2].sigma2": 3e-11,
                             "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
                             "SIN[2].alpha": 0.0015, "SIN[2].beta": 8e-6}),
    "sim3": ("AR1+WN+RW+SIN", {"AR1[1].phi": 0.9997083, "AR1[1].sigma2": 9e-6,
                               "WN[1].sigma2": 8e-4, "RW[1].gamma2": 3e-11,
                               "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056}),
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=int, default=10**7)
    ap.add_argument("--levels", type=int, default=22)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    scales = 2.0 ** np.arange(1, args.levels + 1)
    print(f"T={args.T}, J={args.levels}, repeat={args.repeat}, load average "
          f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores")
    for name, (spec, values) in SIMULATIONS.items():
        model = Model(spec)
        theta = model.theta(values)
        V = wv_covariance(model, theta, scales, args.T)        # warm-up
        wall, cpu = [], []
        for r in range(args.repeat):
            # another length per repeat: wv_covariance remembers its results, and the cost does
            # not depend on T (only on the scales), so each call computes
            t0, c0 = time.perf_counter(), time.process_time()
            V = wv_covariance(model, theta, scales, args.T + 1 + r)
            wall.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
        R = wv_correlation(V)
        adj = np.diag(R, 1)
        print(f"{name} {spec:16s} wall median {np.median(wall) * 1e3:7.1f} ms (min "
              f"{min(wall) * 1e3:6.1f})  cpu median {np.median(cpu) * 1e3:7.1f} ms (min "
              f"{min(cpu) * 1e3:6.1f})  min eig(corr) {np.linalg.eigvalsh(R).min():.2e}  "
              f"adj corr j=1,6,11,16,21: {np.round(adj[[0, 5, 10, 15, 20]], 3).tolist()}")


if __name__ == "__main__":
    main()
