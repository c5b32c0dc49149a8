"""Benchmark the Haar WV kernel (gmwm.wv) against one memory pass and a NumPy cumulative sum.

Usage: python benchmarks/bench_wv.py [--big] [--repeat 5] [--tune] [--readme]

Per signal length T (1e6, 1e7; 1e8 with --big), RW(1) + WN(1e-4) on a 1e3 offset, all default
levels: best-of-N wall and CPU seconds (after a warm-up call) of

* ``wvar`` (CI included, the default thread count) and of the WV sums alone with the C kernel on
  1 thread and on all usable threads, and with its Numba twin (one thread);
* one read pass over the signal (``x.sum()``) and ``np.cumsum`` (a read and a write pass): the
  kernel's cost is reported as a multiple of the read pass;
* a NumPy global-cumulative-sum WV (the numerically poor textbook method) and its relative
  difference from ``wvar`` (its own rounding error);

then, in separate processes, the import of gmwm.wv, the first wvar call and the Numba kernel's
first call with a cold and with a warm on-disk cache. The C and Numba sums are checked to be
identical to the bit. --tune times kernel layouts (L, block, panel) at T = 1e7; --readme writes the
table into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial

import numpy as np

from gmwm.wv import Workspace, default_layout, kernel_name, n_threads, wvar


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


_COMPILE_SNIPPET = """
import time, numpy as np
t0 = time.perf_counter()
from gmwm.wv import Workspace, wvar
t1 = time.perf_counter()
x = np.random.default_rng(0).standard_normal(5000)
wvar(x)
t2 = time.perf_counter()
from gmwm import _wvkernels
ws = Workspace(5000, 11)
s = np.zeros(11)
st = ws.store()
_wvkernels.phase1(x, 0, 0, 5000, x[0], ws.n_block, ws.block, s, st, 0, ws.rows, ws.panel)
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


def bench_row(T: int, rng: np.random.Generator, repeat: int) -> dict[str, float]:
    """Timings for a RW(1) + WN(1e-4) + offset signal of T samples (the numerically hard case)."""
    from gmwm import _wvkernels

    try:
        from gmwm import _haar
    except ImportError:
        _haar = None
    x = 1e3 + np.cumsum(rng.standard_normal(T)) + 1e-2 * rng.standard_normal(T)
    J = int(np.floor(np.log2(T))) - 1
    ws = Workspace(T, J)
    nt = n_threads(T)
    row = {"T": T, "J": J, "threads": nt}
    row["wvar"] = best_time(partial(wvar, x), repeat)
    row["read"] = best_time(x.sum, repeat)
    buf = np.empty_like(x)
    row["cumsum"] = best_time(partial(np.cumsum, x, out=buf), repeat)
    if _haar is not None:
        row["c1"] = best_time(partial(ws.sums, x, J, 1, kern=_haar), repeat)
        row["cN"] = best_time(partial(ws.sums, x, J, nt, kern=_haar), repeat)
        same = np.array_equal(ws.sums(x, J, nt, kern=_haar), ws.sums(x, J, kern=_wvkernels))
    else:
        row["c1"] = row["cN"] = (float("nan"), float("nan"))
        same = True
    row["numba"] = best_time(partial(ws.sums, x, J, kern=_wvkernels), max(1, repeat // 2))
    row["identical"] = same
    base = partial(numpy_cumsum_wv, x, J)
    row["numpy"] = best_time(base, max(1, repeat // 2))
    row["diff"] = float(np.max(np.abs(wvar(x).variance / base() - 1.0)))
    return row


def tune(T: int, repeat: int) -> None:
    """CPU seconds of the kernel alone (one thread) for a grid of (L, block/2**L, panel) layouts
    around the default."""
    x = np.cumsum(np.random.default_rng(1).standard_normal(T))
    J = int(np.floor(np.log2(T))) - 1
    L0, _, p0 = default_layout(T, J)
    print(f"T={T:.0e}, J={J}, default L={L0}, block=8*2**L, panel={p0}")
    for L in sorted({max(1, L0 - 2), L0 - 1, L0, min(J, L0 + 1), min(J, L0 + 2)}):
        for factor in (4, 8, 16):
            for panel in (4, 8, 16):
                ws = Workspace(T, J, L, factor << L, panel)
                cpu = best_time(partial(ws.sums, x, J, 1), repeat)[1]
                print(f"  L={L:>2} block={factor:>2}*2**L panel={panel:>2}: {cpu:.4f} s cpu")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--big", action="store_true", help="also T = 1e8 (needs ~3 GB)")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--tune", action="store_true", help="time kernel layouts at T = 1e7 only")
    parser.add_argument("--readme", action="store_true", help="write the table into README.md")
    args = parser.parse_args(argv)
    if args.tune:
        tune(10**7, args.repeat)
        return 0
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from readme_section import load, machine, update_section

    load_before = load()
    sizes = [10**6, 10**7] + ([10**8] if args.big else [])
    rng = np.random.default_rng(12345)
    rows = []
    for T in sizes:
        rows.append(bench_row(T, rng, args.repeat))
        print(f"T = {T:.0e} done", flush=True)
    t_imp, first, cold, warm = first_call_times()
    load_after = load()
    head = ("| T | J | `wvar` wall / CPU [s] | C kernel, 1 thread: wall [s] | C kernel, "
            "threads: wall [s] | Numba twin (1 thread) wall [s] | one read pass (`x.sum()`) "
            "wall [s] | `np.cumsum` wall [s] | C kernel (threads) / read pass, wall | "
            "C == Numba bits | NumPy cumsum WV wall [s] (rel. diff) |")
    lines = [head, "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(
            f"| {r['T']:.0e} | {r['J']} | {r['wvar'][0]:.4f} / {r['wvar'][1]:.4f} | "
            f"{r['c1'][0]:.4f} | {r['cN'][0]:.4f} ({r['threads']}) | {r['numba'][0]:.4f} | "
            f"{r['read'][0]:.4f} | {r['cumsum'][0]:.4f} | {r['cN'][0] / r['read'][0]:.1f} | "
            f"{'yes' if r['identical'] else 'NO'} | {r['numpy'][0]:.3f} ({r['diff']:.1e}) |")
    text = (f"`python benchmarks/bench_wv.py{' --big' if args.big else ''} --repeat "
            f"{args.repeat}`: best of {args.repeat} after a warm-up call; {machine()}; "
            f"`wvar` uses the {kernel_name()} kernel; load average {load_before} before, "
            f"{load_after} after.\n\n" + "\n".join(lines) + "\n\n"
            f"* Start-up (separate processes): `import gmwm.wv` {t_imp:.3f} s; first `wvar` call "
            f"{first:.3f} s (mostly the import of scipy.special for the CI); the Numba twin's "
            f"first call {cold:.2f} s with a cold cache (compilation), {warm:.2f} s with a warm "
            "one.\n")
    print(text)
    if args.readme:
        update_section("bench_wv", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
