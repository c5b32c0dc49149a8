"""Cost of one Monte Carlo signal: `Model.simulate` (reference) against `Model.simulate_fast`.

The models and true parameters are the studies' own, read from `config/config.yaml`; each signal
is followed by its WV (`gmwm.wvar`), as in `simulate_wv`. Prints nanoseconds per sample (best of
`--repeat` after one warm-up call that loads the Numba kernels), wall and CPU.

    python benchmarks/bench_simulate.py [--n 4194304] [--repeat 3] [--studies sim2 sim3 ...]
"""
from __future__ import annotations

import argparse
import os
import pathlib
from functools import partial

import numpy as np
import yaml
from bench_wv import best_time  # the benchmarks' shared timer (a sibling script)

import gmwm

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_STUDIES = ("stim300_gyro", "stim300_accel", "sim3", "sim2", "misspec")


def _study(name: str) -> tuple[str, gmwm.Model, np.ndarray]:
    """The study's model string, model and true theta (from config/config.yaml)."""
    study = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())["studies"][name]
    model = gmwm.Model(study["model"])
    return study["model"], model, model.theta(dict(study["truth"]))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=2**22, help="samples per signal (default 2^22)")
    parser.add_argument("--repeat", type=int, default=3, help="timed calls per case (best kept)")
    parser.add_argument("--studies", nargs="+", default=list(DEFAULT_STUDIES))
    args = parser.parse_args()
    n = args.n
    print(f"T = {n}, best of {args.repeat}, load average {os.getloadavg()[0]:.2f}; ns per sample "
          "(wall / CPU)")
    print(f"{'study':15s} {'model':18s} {'simulate':>15s} {'simulate_fast':>15s} {'ratio':>6s} "
          f"{'wvar':>13s}")
    for name in args.studies:
        spec, model, theta = _study(name)
        ref = best_time(partial(model.simulate, theta, n, 1), args.repeat)
        fast = best_time(partial(model.simulate_fast, theta, n, 1), args.repeat)
        wv = best_time(partial(gmwm.wvar, model.simulate_fast(theta, n, 2)), args.repeat)
        ns = 1e9 / n
        print(f"{name:15s} {spec:18.18s} "
              f"{ref[0] * ns:6.1f} / {ref[1] * ns:6.1f} {fast[0] * ns:6.1f} / {fast[1] * ns:6.1f} "
              f"{ref[0] / fast[0]:6.2f} {wv[0] * ns:5.1f} / {wv[1] * ns:5.1f}")


if __name__ == "__main__":
    main()
