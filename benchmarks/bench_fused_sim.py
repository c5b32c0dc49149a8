"""Cost of one Monte Carlo replicate's WV: NumPy's generator (`Model.simulate_fast` + `wvar`)
against the fused pass `gmwm.fused.simulate_wv` (own generator, no full-length signal).

The models and true parameters are the studies' own (`config/config.yaml`). Also times the
building blocks at the same T: NumPy's `standard_normal`, `cumsum` and `wvar` of a materialised
signal. Prints nanoseconds per sample, best of `--repeat` after a warm-up call (Numba loads),
wall and CPU, with the load average before and after. The WV kernel runs on one thread, as in a
pipeline job (`GMWM_NUM_THREADS=1`, set by `workflow/scripts/wflog.py`).

    nice -n 5 python benchmarks/bench_fused_sim.py [--n 10000000] [--repeat 3] [--studies ...]
"""
from __future__ import annotations

import os

os.environ.setdefault("GMWM_NUM_THREADS", "1")  # before gmwm reads it (a job's setting)

import argparse
import pathlib
import time
from collections.abc import Callable

import numpy as np
import yaml

import gmwm
from gmwm import _simkernels, fused

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_STUDIES = ("stim300_gyro", "stim300_accel", "sim3", "sim2", "misspec")


def _best(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Best (wall, CPU) seconds of ``repeat`` calls after one warm-up call."""
    fn()
    wall = cpu = np.inf
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = min(wall, time.perf_counter() - w0)
        cpu = min(cpu, time.process_time() - c0)
    return wall, cpu


def _study(name: str) -> tuple[str, gmwm.Model, np.ndarray]:
    study = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["studies"][name]
    model = gmwm.Model(study["model"])
    return study["model"], model, model.theta(dict(study["truth"]))


def _blocks(n: int, rep: int, rng: np.random.Generator
            ) -> list[tuple[str, tuple[float, float]]]:
    """The building blocks at length ``n``: (label, (wall, CPU) seconds)."""
    x = rng.standard_normal(n).cumsum()
    z = np.empty(1 << 15)

    def blocks() -> None:  # the block size simulate_fast draws with
        for s in range(0, n, z.size):
            rng.standard_normal(out=z[:min(z.size, n - s)])

    state = _simkernels.seed_state(rng)

    def own_blocks() -> None:
        for s in range(0, n, z.size):
            _simkernels.fill_normals(state, z[:min(z.size, n - s)], _simkernels.ZIG_K,
                                     _simkernels.ZIG_W, _simkernels.ZIG_F)

    return [("numpy standard_normal (blocks of 2^15)", _best(blocks, rep)),
            ("fused generator's normals (blocks of 2^15)", _best(own_blocks, rep)),
            ("numpy cumsum", _best(lambda: np.cumsum(x), rep)),
            ("wvar (classical kernel, 1 thread)", _best(lambda: gmwm.wvar(x, ci="eta3"), rep))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=10_000_000, help="samples (default 1e7)")
    parser.add_argument("--repeat", type=int, default=3, help="timed calls per case (best kept)")
    parser.add_argument("--studies", nargs="+", default=list(DEFAULT_STUDIES))
    args = parser.parse_args()
    n, rep = args.n, args.repeat
    load0 = os.getloadavg()[0]
    print(f"T = {n}, best of {rep}, GMWM_NUM_THREADS={os.environ['GMWM_NUM_THREADS']}, "
          f"load average {load0:.2f} at start; ns per sample, wall / CPU")
    rng = np.random.default_rng(1)
    for label, (w, c) in _blocks(n, rep, rng):
        print(f"  {label:44s} {w / n * 1e9:6.2f} / {c / n * 1e9:6.2f}")
    print("| study | model | simulate_fast + wvar | fused simulate_wv | ratio (wall) |")
    print("|---|---|---|---|---|")
    for name in args.studies:
        spec, model, theta = _study(name)
        w_np, c_np = _best(lambda m=model, t=theta: gmwm.wvar(m.simulate_fast(t, n, rng),
                                                              ci="eta3"), rep)
        w_f, c_f = _best(lambda m=model, t=theta: fused.simulate_wv(m, t, n, rng), rep)
        print(f"| {name} | {spec} | {w_np / n * 1e9:.2f} / {c_np / n * 1e9:.2f} | "
              f"{w_f / n * 1e9:.2f} / {c_f / n * 1e9:.2f} | {w_np / w_f:.2f} |")
    print(f"load average {os.getloadavg()[0]:.2f} at the end (numbers under load are indicative)")


if __name__ == "__main__":
    main()
