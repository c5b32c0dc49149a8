"""Benchmark the virtual-gyroscope code (gmwm.virtual, exported as gmwm.svo) and project the paper-003 study's cost.

Usage: python benchmarks/bench_svo.py [--T 1044000] [--repeat 3] [--n-boot 500] [--block-const 10]
Prints best-of-N wall and CPU seconds (after a warm-up call) of the steps of one replicate at the
paper's size (p = 6, J = 19): simulating a Case 1 / Case 2 array, the fused WCCV, the wvar of the six
columns (reference), the SVO coefficients, RDVG, the MBB covariance (n_boot draws), a WN+RW GMWM fit
of a virtual WV, the MBB of both schemes in one pass (``mbb_svo_draws_schemes``, what a coverage
replicate runs); then the projected CPU time of the full svo study (config/config.yaml sizes):
per case 50 x (1 + 10) arrays (simulate + WCCV), 50 x 10 x 4 GMWM fits, and the coverage study
(1000 x (simulate + WCCV + the MBB of its schemes)) for each coverage case.

BLAS runs single-threaded unless OPENBLAS_NUM_THREADS etc. are set, as in the pipeline's jobs
(Snakemake sets them to the rule's ``threads: 1``); with 2 OpenBLAS threads the (T, 6) @ (6, 6)
products of the simulation cost ~10x more CPU (spinning threads).
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np

import gmwm
from gmwm.virtual import (
    block_length,
    mbb_svo_draws,
    mbb_svo_draws_schemes,
    rdvg,
    svo_coef,
    svo_weights,
)
from gmwm.wccv import wccv
from gmwm_studies.svo_study import case


def best(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Best wall and CPU seconds over ``repeat`` calls after one warm-up call."""
    fn()
    walls, cpus = [], []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        walls.append(time.perf_counter() - w0)
        cpus.append(time.process_time() - c0)
    return min(walls), min(cpus)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=int, default=1044000)
    ap.add_argument("--levels", type=int, default=19)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--n-boot", type=int, default=500)
    ap.add_argument("--block-const", type=float, default=10.0)
    ap.add_argument("--train", type=int, default=50)
    ap.add_argument("--test", type=int, default=10)
    ap.add_argument("--coverage", type=int, default=1000)
    ap.add_argument("--coverage-cases", type=int, default=1)
    ap.add_argument("--schemes", type=int, default=2, help="MBB schemes per coverage replicate")
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    J = a.levels
    X = case("case1").simulate(a.T, rng)
    W = wccv(X, J)
    om = svo_weights("short", J)
    block = block_length(a.T, a.block_const)
    rows = {
        "simulate case1": lambda: case("case1").simulate(a.T, rng),
        "simulate case2": lambda: case("case2").simulate(a.T, rng),
        "wccv (fused, p = 6)": lambda: wccv(X, J),
        "wvar x 6 columns": lambda: [gmwm.wvar(X[:, i], J) for i in range(6)],
        "svo coefficients": lambda: svo_coef(W.cov, om),
        "rdvg": lambda: rdvg(W),
        f"MBB ({a.n_boot} draws, l = {block})":
            lambda: mbb_svo_draws(X, W.cov, om, a.n_boot, block, np.random.default_rng(2)),
        f"MBB time scheme ({a.n_boot} draws)":
            lambda: mbb_svo_draws(X, W.cov, om, a.n_boot, block, np.random.default_rng(2), "time"),
        "MBB paper + time, one pass": lambda: mbb_svo_draws_schemes(
            X, W.cov, om, a.n_boot, block,
            [("paper", np.random.default_rng(2)), ("time", np.random.default_rng(2))]),
        "GMWM WN+RW fit of a virtual WV": lambda: gmwm.fit(W.combine(np.full(6, 1 / 6)), "WN+RW",
                                                            n_starts=1),
    }
    t = {}
    print(f"T = {a.T}, p = 6, J = {J}; best of {a.repeat} after a warm-up call")
    print(f"{'step':<40} {'wall [s]':>9} {'CPU [s]':>9}")
    for name, fn in rows.items():
        wall, cpu = best(fn, a.repeat)
        t[name] = cpu
        print(f"{name:<40} {wall:9.3f} {cpu:9.3f}")
    sim = 0.5 * (t["simulate case1"] + t["simulate case2"])
    arr = sim + t["wccv (fused, p = 6)"]
    train = a.train * ((1 + a.test) * arr + 3 * t["svo coefficients"] + t["rdvg"]
                       + 4 * a.test * t["GMWM WN+RW fit of a virtual WV"])
    mbb = (t["MBB paper + time, one pass"] if a.schemes == 2
           else a.schemes * t[f"MBB ({a.n_boot} draws, l = {block})"])
    cov = a.coverage * (t["simulate case1"] + t["wccv (fused, p = 6)"] + mbb)
    total = 2 * train + a.coverage_cases * cov
    print(f"\nprojected CPU: training/test per case {train / 60:.1f} min "
          f"({train / a.train:.1f} s per training replicate), coverage per case {cov / 60:.1f} min "
          f"({cov / a.coverage:.2f} s per replicate); total (2 cases, {a.coverage_cases} coverage "
          f"case) {total / 3600:.2f} CPU h = {total / 7200:.2f} h on 2 idle cores")


if __name__ == "__main__":
    main()
