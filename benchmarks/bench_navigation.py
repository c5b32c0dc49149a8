"""Cost of the paper-000 misspecification study and navigation emulation, per replicate/iteration.

Usage: python benchmarks/bench_navigation.py [--chunks 1 5 25] [--T 2879999] [--reps 3]
Prints (wall and CPU seconds, best of --reps after a warm-up):
* misspecification, per replicate at T: simulate Table 5, Haar WV, fit Model 1, fit Model 2
  (the config's gmwm estimator settings: weights ci, 8 starts);
* navigation, per iteration: the EKF emulation (235 s at 100 Hz, two filters per iteration)
  vectorised over chunks of the given sizes;
and the projected single-core time of the full study (500 replicates / iterations).
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

import gmwm
from gmwm.model import Model
from gmwm_studies import misspec as ms
from gmwm_studies import navigation as nv

CFG = {"gyro_axes": ["x", "y", "z"], "accel_vrw": 0.1, "gnss_sd": 1.0,
       "initial_sd": {"position": 1.0, "velocity": 0.1, "roll_pitch": 0.5, "yaw": 1.0}}
FIT = {"weights": "ci", "n_starts": 8, "reweight": 0}


def best(fn: Callable[[], object], reps: int) -> tuple[float, float, object]:
    out = fn()
    wall, cpu = [], []
    for _ in range(reps):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu), out


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--chunks", type=int, nargs="+", default=[1, 5, 25])
    ap.add_argument("--T", type=int, default=2_879_999)
    ap.add_argument("--reps", type=int, default=3)
    a = ap.parse_args()

    model = Model("AR1+RW+2*SIN")
    theta = model.theta(ms.TABLE5)
    rng = np.random.default_rng(1)
    w_sim, c_sim, x = best(lambda: model.simulate(theta, a.T, rng), a.reps)
    w_wv, c_wv, wv = best(lambda: gmwm.wvar(x), a.reps)
    w_f1, c_f1, _ = best(lambda: gmwm.fit(wv, "AR1+RW", seed=2, **FIT), a.reps)
    w_f2, c_f2, _ = best(lambda: gmwm.fit(wv, "AR1+RW+2*SIN", seed=2, **FIT), a.reps)
    per_rep = c_sim + c_wv + c_f1 + c_f2
    print(f"misspec per replicate at T = {a.T}: simulate {w_sim:.3f}/{c_sim:.3f} s, "
          f"WV {w_wv:.3f}/{c_wv:.3f} s, fit Model 1 {w_f1:.3f}/{c_f1:.3f} s, "
          f"fit Model 2 {w_f2:.3f}/{c_f2:.3f} s (wall/CPU); 500 replicates: "
          f"{500 * per_rep / 60:.1f} CPU min")

    tr = nv.make_trajectory()
    setup = nv.filter_setup(CFG, 100.0)
    steps = nv.gnss_schedule(tr)
    th = nv.convert_basic(np.array([ms.TABLE5[p] for p in ms.BASIC_PARAMS]), 200.0, 100.0)
    for n in a.chunks:
        fp = np.stack([np.stack([th * [1, 2, 0.5], th])] * n)
        w, c, _ = best(lambda fp=fp, n=n: nv.emulate(tr, setup, th, fp, range(n), "bench", 1,
                                                     steps), max(1, a.reps - 2))
        print(f"navigation chunk of {n:3d} iterations (2 filters each, {len(tr.gyro)} IMU "
              f"samples): {w:.2f}/{c:.2f} s wall/CPU, {c / n:.3f} CPU s per iteration; "
              f"500 iterations: {500 * c / n / 60:.1f} CPU min")


if __name__ == "__main__":
    main()
