"""Benchmark gmwm.wv.wvar against a straightforward NumPy cumulative-sum implementation.

Usage: python benchmarks/bench_wv.py [--big] [--repeat 3] [--tune]
Prints, per signal length T: best-of-N wall and CPU time of ``wvar`` (all default levels, CI included) after a
warm-up call, the same for the NumPy baseline, the wall-time ratio, the agreement between the two, and the
peak extra memory of each (tracemalloc, in units of the signal's size), and the CPU time of the WV
sums alone with the C kernel (gmwm._haar) and with its Numba twin (gmwm._wvkernels). Then, in
separate processes, the import of gmwm.wv, the first wvar call (the C kernel's load) and the Numba
kernel's first call with a cold and with a warm on-disk cache (fresh NUMBA_CACHE_DIR).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from functools import partial

import numpy as np

from gmwm.wv import _layout, _Workspace, kernel_name, wvar


def numpy_cumsum_wv(x: np.ndarray, levels: int) -> np.ndarray:
    """Baseline: global cumulative sum, W = (S_t - 2 S_{t-m} + S_{t-2m}) / tau, one level at a time."""
    S = np.concatenate(([0.0], np.cumsum(x - x.mean())))
    T = x.size
    out = np.empty(levels)
    for j in range(1, levels + 1):
        tau, m = 2**j, 2 ** (j - 1)
        w = (S[tau:] - 2.0 * S[m:T + 1 - m] + S[:T + 1 - tau]) / tau
        out[j - 1] = np.dot(w, w) / w.size
    return out


def best_time(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Best wall and best CPU seconds over ``repeat`` calls after a warm-up call (CPU time is the
    fairer number when other processes share the cores)."""
    fn()                                        # warm-up (JIT / cache load, page faults)
    wall, cpu = [], []
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return min(wall), min(cpu)


def peak_extra_bytes(fn: Callable[[], object]) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


_COMPILE_SNIPPET = """
import time, numpy as np
t0 = time.perf_counter()
from gmwm.wv import _Workspace, wvar
t1 = time.perf_counter()
x = np.random.default_rng(0).standard_normal(5000)
wvar(x)
t2 = time.perf_counter()
from gmwm._wvkernels import wv_sums
ws = _Workspace(5000, 11)
wv_sums(x, 11, ws.n_block, np.zeros(11), ws.buf_a, ws.buf_b, ws.v_l, ws.pan_a, ws.pan_b)
t3 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f} {t3 - t2:.3f}")
"""


def first_call_times() -> tuple[float, float, float, float]:
    """(import s, first wvar call s, Numba kernel's first call s with a cold cache, the same
    with a warm cache)."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        runs = []
        for _ in range(2):
            out = subprocess.run([sys.executable, "-c", _COMPILE_SNIPPET], env=env, check=True,
                                 capture_output=True, text=True).stdout.split()
            runs.append(tuple(float(v) for v in out))
    return runs[1][0], runs[1][1], runs[0][2], runs[1][2]


def kernel_cpu(x: np.ndarray, J: int, repeat: int) -> tuple[float, float]:
    """Best CPU seconds of the WV sums alone: (C kernel, Numba kernel), same workspace; nan for
    the C kernel when it is not built."""
    from gmwm import _wvkernels

    try:
        from gmwm._haar import wv_sums as c_sums
    except ImportError:
        c_sums = None
    ws = _Workspace(x.size, J)
    out = []
    for kern in (c_sums, _wvkernels.wv_sums):
        if kern is None:
            out.append(float("nan"))
            continue
        call = partial(kern, x, J, ws.n_block, np.zeros(J), ws.buf_a, ws.buf_b, ws.v_l, ws.pan_a,
                       ws.pan_b)
        out.append(best_time(call, repeat)[1])
    return out[0], out[1]


def bench_row(T: int, rng: np.random.Generator, repeat: int) -> str:
    """One table row for a RW(1) + WN(1e-4) + offset signal of T samples (the numerically hard case)."""
    x = 1e3 + np.cumsum(rng.standard_normal(T)) + 1e-2 * rng.standard_normal(T)
    J = int(np.floor(np.log2(T))) - 1
    ours = partial(wvar, x)
    base = partial(numpy_cumsum_wv, x, J)
    t_ours, t_np = best_time(ours, repeat), best_time(base, repeat)
    diff = np.max(np.abs(ours().variance / base() - 1.0))
    mem_ours, mem_np = peak_extra_bytes(ours) / x.nbytes, peak_extra_bytes(base) / x.nbytes
    c_cpu, nb_cpu = kernel_cpu(x, J, repeat)
    return (f"{T:>9.0e} {J:>3} {t_ours[0]:>7.3f} / {t_ours[1]:>6.3f} {t_np[0]:>8.3f} / "
            f"{t_np[1]:>6.3f} {t_np[0] / t_ours[0]:>6.1f} {diff:>12.1e} {mem_ours:>8.2f}x "
            f"{mem_np:>8.2f}x {c_cpu:>8.3f} {nb_cpu:>8.3f}")


def tune(T: int, repeat: int) -> None:
    """CPU seconds of the kernel alone for a grid of (L, block/2**L, panel) layouts around the default."""
    x = np.cumsum(np.random.default_rng(1).standard_normal(T))
    J = int(np.floor(np.log2(T))) - 1
    L0, _, p0 = _layout(T, J)
    print(f"T={T:.0e}, J={J}, default L={L0}, block=8*2**L, panel={p0}")
    for L in sorted({max(1, L0 - 2), L0 - 1, L0, min(J, L0 + 1), min(J, L0 + 2)}):
        for factor in (4, 8, 16):
            for panel in (4, 8, 16):
                ws = _Workspace(T, J, L, factor << L, panel)
                cpu = best_time(partial(ws.sums, x, J), repeat)[1]
                print(f"  L={L:>2} block={factor:>2}*2**L panel={panel:>2}: {cpu:.4f} s cpu")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--big", action="store_true", help="also T = 1e8 (needs ~6 GB, ~1 min)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tune", action="store_true", help="time kernel layouts at T = 1e7 only")
    args = parser.parse_args(argv)
    if args.tune:
        tune(10**7, args.repeat)
        return 0
    sizes = [10**6, 10**7] + ([10**8] if args.big else [])
    rng = np.random.default_rng(12345)
    print(f"{'T':>9} {'J':>3} {'wvar wall/cpu s':>16} {'numpy wall/cpu s':>17} {'ratio':>6} "
          f"{'max rel diff':>12} {'mem wvar':>9} {'mem numpy':>9} {'C cpu':>8} {'numba cpu':>8}")
    print(f"# wvar uses the {kernel_name()} kernel; C / numba cpu = the WV sums alone")
    for T in sizes:
        print(bench_row(T, rng, args.repeat), flush=True)
    t_imp, first, cold, warm = first_call_times()
    print(f"import gmwm.wv: {t_imp:.3f} s; first wvar call ({kernel_name()} kernel): {first:.3f} s; "
          f"Numba kernel's first call: {cold:.2f} s with a cold cache (compile), {warm:.2f} s "
          "with a warm cache")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
