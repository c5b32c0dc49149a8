"""End-to-end CLI timings: `gmwm --help` and `gmwm wv x.npy --json` on 1e7 samples against a plain
NumPy script computing a naive cumulative-sum WV of the same file.

    python benchmarks/bench_cli.py [--n 10000000] [--runs 5] [--workdir /tmp/gmwm_bench_cli]

Whole processes are timed from outside with `farm-bench` (paired A/B runs, median of --runs) when it
is installed, else with `subprocess` wall and child CPU times (median). The signal and the NumPy
script are written to --workdir (never to the repository). Also prints the CLI's own split of the
WV time (`seconds_first_call`: loading the compiled kernel; `seconds`: the steady-state WV) and the
import time of `gmwm.cli`, `gmwm.cli.commands.wv` (what `gmwm wv` imports), `gmwm` and `gmwm.wv`.
Tests never assert on these numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

NAIVE = '''"""Naive Haar WV of a .npy signal with NumPy cumulative sums (the yardstick)."""
import sys

import numpy as np

x = np.load(sys.argv[1])
T = x.size
J = int(np.floor(np.log2(T))) - 1
c = np.concatenate([[0.0], np.cumsum(x)])
out = []
for j in range(1, J + 1):
    tau, m = 2 ** j, 2 ** (j - 1)
    later = c[tau:] - c[m:T + 1 - m]          # sum of the last m samples
    earlier = c[m:T + 1 - m] - c[:T + 1 - tau]  # sum of the m samples before
    w = (later - earlier) / tau
    out.append(float(np.mean(w * w)))
print(out)
'''


def _timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and child CPU seconds of one run of ``cmd`` (output discarded)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _median_runs(cmd: list[str], runs: int) -> tuple[float, float]:
    _timed(cmd)  # warm-up: file cache, numba cache files
    res = [_timed(cmd) for _ in range(runs)]
    return statistics.median(r[0] for r in res), statistics.median(r[1] for r in res)


def _farm(cmd: list[str], runs: int, vs: list[str] | None = None) -> str:
    argv = ["farm-bench", "-n", str(runs), "--timeout", "900"]
    if vs:
        argv += ["--vs", " ".join(vs)]
    out = subprocess.run(argv + ["--", *cmd], capture_output=True, text=True, check=False)
    return (out.stdout + out.stderr).strip()


def _import_seconds(module: str) -> float:
    code = f"import time; t = time.perf_counter(); import {module}; print(time.perf_counter() - t)"
    vals = [float(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                 check=True).stdout) for _ in range(3)]
    return statistics.median(vals)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000_000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--workdir", default="/tmp/gmwm_bench_cli")
    ap.add_argument("--cli", default=None,
                    help="command that runs the CLI (default: the installed 'gmwm'); e.g. a wrapper "
                         "running another checkout")
    args = ap.parse_args()
    import numpy as np

    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    x_path, naive = work / f"x{args.n}.npy", work / "naive_wv.py"
    if not x_path.exists():
        np.save(x_path, np.random.default_rng(1).standard_normal(args.n))
    naive.write_text(NAIVE)
    gmwm = args.cli or shutil.which("gmwm") or "gmwm"
    cli = [gmwm, "wv", str(x_path), "--json", "--quiet"]
    base = [sys.executable, str(naive), str(x_path)]
    # an installed package has its bytecode; an editable checkout run with PYTHONDONTWRITEBYTECODE
    # (as on the dev machine) would recompile gmwm/cli/*.py, wv.py, ... in every process (~0.1 s)
    import gmwm as _pkg

    subprocess.run([sys.executable, "-m", "compileall", "-q", str(Path(_pkg.__file__).parent)],
                   check=True)
    print(f"# load average {os.getloadavg()[0]:.1f} / {os.cpu_count()} cores, T = {args.n}, "
          f"bytecode compiled for {Path(_pkg.__file__).parent}")
    for module in ("gmwm.cli", "gmwm.cli.commands.wv", "gmwm", "gmwm.wv"):
        print(f"import {module}: {_import_seconds(module):.3f} s (median of 3 fresh processes)")
    obj = json.loads(subprocess.run(cli, capture_output=True, text=True, check=True).stdout)
    print(f"gmwm wv --json ({obj['wv_kernel']} kernel): WV + CI {obj['seconds']:.3f} s (includes the "
          f"wait for scipy.special, imported beside it in {obj['seconds_import_scipy']:.3f} s), "
          f"first call (kernel load) {obj['seconds_first_call']:.3f} s, read "
          f"{obj['seconds_read']:.3f} s")
    from gmwm.wv import kernel_name, wvar

    x = np.load(x_path)
    wvar(x)
    steady = []
    for _ in range(3):
        t0 = time.perf_counter()
        wvar(x)
        steady.append(time.perf_counter() - t0)
    print(f"steady state in one process ({kernel_name()} kernel): wvar of {args.n} samples "
          f"{statistics.median(steady):.3f} s (median of 3, after a warm-up call)")
    if shutil.which("farm-bench"):
        print("## gmwm --help")
        print(_farm([gmwm, "--help"], args.runs))
        print("## A = gmwm wv x.npy --json, B = naive NumPy cumsum WV script")
        print(_farm(cli, args.runs, vs=base))
        return
    help_wall, help_cpu = _median_runs([gmwm, "--help"], args.runs)
    cli_wall, cli_cpu = _median_runs(cli, args.runs)
    base_wall, base_cpu = _median_runs(base, args.runs)
    print(f"gmwm --help: wall {help_wall:.3f} s, cpu {help_cpu:.3f} s")
    print(f"gmwm wv --json: wall {cli_wall:.3f} s, cpu {cli_cpu:.3f} s")
    print(f"naive NumPy:    wall {base_wall:.3f} s, cpu {base_cpu:.3f} s")
    print(f"speed-up (naive / CLI): wall {base_wall / cli_wall:.2f}x, cpu {base_cpu / cli_cpu:.2f}x")


if __name__ == "__main__":
    main()
