"""Several IMUs in one run: serial fits vs worker processes vs threads (gmwm.calibrate).

Two simulated 6-axis IMUs (WN+RW gyroscope and accelerometer axes, 200 Hz, ``--n`` samples
each, as .npz files read with :func:`gmwm.readers.read_recording`) are calibrated by
:func:`gmwm.calibrate.calibrate_imus` with ``workers=1`` (in this process), and with
``--workers`` worker processes and threads. For each: wall time and CPU time (this process and
its children), minimum over ``--repeat`` runs, and the number of cores available. On a shared
machine run it when idle or compare CPU time; the parameters of every variant are checked equal.

    python benchmarks/bench_multi_imu.py [--n 262144] [--model WN+RW] [--workers 2] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import resource
import tempfile
import time
from pathlib import Path

import numpy as np

from gmwm.calibrate import available_cores, calibrate_imus
from gmwm.model import Model
from gmwm.readers import read_recording

FS = 200.0


def _imu(path: Path, n: int, scale: float, seed: int) -> Path:
    rng = np.random.default_rng(seed)
    gm = Model("WN+RW", freq=FS)
    g = gm.theta({"WN[1].sigma2": (scale * 1e-3) ** 2 * FS, "RW[1].gamma2": (scale * 1e-5) ** 2 / FS})
    a = gm.theta({"WN[1].sigma2": (scale * 2e-2) ** 2 * FS, "RW[1].gamma2": (scale * 1e-4) ** 2 / FS})
    cols = {f"g{k}": gm.simulate(g, n, rng) for k in "xyz"}
    cols |= {f"a{k}": gm.simulate(a, n, rng) for k in "xyz"}
    np.savez(path, t_s=np.arange(n) / FS, **cols)
    return path


def _cpu() -> float:
    s, c = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return s.ru_utime + s.ru_stime + c.ru_utime + c.ru_stime


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=2 ** 18)
    ap.add_argument("--model", default="WN+RW")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    units = {**dict.fromkeys(["gx", "gy", "gz"], "rad/s"), **dict.fromkeys(["ax", "ay", "az"],
                                                                          "m/s^2")}
    with tempfile.TemporaryDirectory() as d:
        recs = {f"/imu{i}": read_recording(_imu(Path(d) / f"imu{i}.npz", args.n, 1.0 + i, i),
                                           columns="all", units=units) for i in range(2)}
        opts = {"seed": 1}
        calibrate_imus(recs, args.model, fit_options=opts, workers=1)  # compile / load kernels
        print(f"cores available: {available_cores()}, load average: {os.getloadavg()}")
        ref = None
        for label, kw in (("serial", {"workers": 1}),
                          ("processes", {"workers": args.workers, "executor": "process"}),
                          ("threads", {"workers": args.workers, "executor": "thread"})):
            walls, cpus = [], []
            for _ in range(args.repeat):
                c0, t0 = _cpu(), time.perf_counter()
                out = calibrate_imus(recs, args.model, fit_options=opts, **kw)
                walls.append(time.perf_counter() - t0)
                cpus.append(_cpu() - c0)
            params = np.concatenate([a["result"].params for s in out.values()
                                     for a in s.axes.values()])
            ref = params if ref is None else ref
            same = np.array_equal(params, ref)
            print(f"{label:10s} wall {min(walls):7.2f} s  cpu {min(cpus):7.2f} s  "
                  f"(12 axes of {args.n} samples; parameters equal to serial: {same})")


if __name__ == "__main__":
    main()
