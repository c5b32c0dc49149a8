"""End-to-end CLI timings: `gmwm --help` and `gmwm wv x.npy --json` on 1e7 samples against a plain
NumPy script computing a naive cumulative-sum WV of the same file; with `--latency`, the three
answers issue 39 sets goals for instead (`gmwm report` of the README's one-hour 200 Hz bag and of
the EuRoC V101 file, `gmwm plan`'s README example), each with the report's own breakdown;
`--vs CMD` times a second CLI (e.g. `PYTHONPATH=<other tree>/src python -m gmwm` in a wrapper)
with its runs alternating with the first's, so that a before/after pair sees the same load.

    python benchmarks/bench_cli.py [--n 10000000] [--runs 5] [--workdir /tmp/gmwm_bench_cli]
    python benchmarks/bench_cli.py --latency [--runs 5] [--euroc PATH] [--cli CMD] [--vs CMD]

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


#: the latency goals of issue 39 [s wall, 2-core VM]
GOALS = {"report_bag": 3.0, "report_euroc": 2.0, "plan": 1.0}
PLAN = ["plan", "--datasheet", "mti-1", "--sensor", "gyroscope", "--freq", "100",
        "--target", "BI=10%"]


def _breakdown(runs: list[dict]) -> dict[str, float]:
    """Medians over runs of the report's ``seconds`` (``gmwm report --json``): this process's
    phases (read, check, fits = waiting for the axes, verdict, write) and, summed over the
    axes in whichever process ran them, choose, page, identifiability, draw."""
    keys = [k for k, v in runs[0].items() if not isinstance(v, dict)]
    out = {k: statistics.median(r[k] for r in runs) for k in keys}
    for k in runs[0].get("axes", {}):
        out[f"axes.{k}"] = statistics.median(r["axes"][k] for r in runs)
    return out


def latency(args: argparse.Namespace, gmwm: str) -> None:
    """``--latency``: wall and CPU (this command and its worker processes) of each answer, median
    of ``--runs`` after a warm-up run, and the report's breakdown."""
    work = Path(args.workdir)
    repo = Path(__file__).resolve().parent.parent
    bag = work / "imu.bag"
    if not bag.exists():
        subprocess.run([sys.executable, str(repo / "examples" / "make_imu_bag.py"), str(bag)],
                       check=True, stdout=subprocess.DEVNULL)
    cases = {"report_bag": ([gmwm, "report", str(bag), "-o", str(work / "calib_bag"),
                             "--json"], "one-hour 200 Hz bag (README quickstart)")}
    euroc = Path(args.euroc)
    if euroc.exists():
        cases["report_euroc"] = ([gmwm, "report", str(euroc), "-o", str(work / "calib_euroc"),
                                  "--json"], "EuRoC V101 imu0 (146 s, 200 Hz)")
    else:
        print(f"# {euroc} absent: the EuRoC case is skipped")
    cases["plan"] = ([gmwm, *PLAN], "README plan example")
    clis = [("A: ", gmwm), ("B: ", args.vs)] if args.vs else [("", gmwm)]
    print(f"# load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} before, "
          f"{os.cpu_count()} cores, {args.runs} runs after a warm-up"
          + (f"; A = {gmwm}, B = {args.vs}, their runs alternating" if args.vs else ""))
    print("| command | wall median [min, max] s | CPU median s | goal s | breakdown (medians, s) |")
    print("|---|---|---|---|---|")
    for key, (cmd, what) in cases.items():
        timed: dict[str, list] = {tag: [] for tag, _ in clis}
        parts: dict[str, list] = {tag: [] for tag, _ in clis}
        for i in range(args.runs + 1):
            for tag, cli in clis:
                c = [cli, *cmd[1:]]
                before = resource.getrusage(resource.RUSAGE_CHILDREN)
                t0 = time.perf_counter()
                run = subprocess.run(c, capture_output=True, text=True, check=False)
                wall = time.perf_counter() - t0
                after = resource.getrusage(resource.RUSAGE_CHILDREN)
                if run.returncode not in (0, 4, 5):
                    raise SystemExit(f"{' '.join(c)} failed ({run.returncode}): "
                                     f"{run.stderr[-500:]}")
                if i == 0:
                    continue  # the warm-up: file cache, Numba's cache files
                timed[tag].append((wall, (after.ru_utime - before.ru_utime)
                                   + (after.ru_stime - before.ru_stime)))
                if "--json" in c and "seconds" in json.loads(run.stdout):  # older trees: none
                    parts[tag].append(json.loads(run.stdout)["seconds"])
        for tag, _ in clis:
            walls = [w for w, _ in timed[tag]]
            split = (", ".join(f"{k} {v:.2f}" for k, v in _breakdown(parts[tag]).items())
                     if parts[tag] else "")
            print(f"| {tag}{what} | {statistics.median(walls):.2f} [{min(walls):.2f}, "
                  f"{max(walls):.2f}] | {statistics.median(c for _, c in timed[tag]):.2f} "
                  f"| {GOALS[key]:g} | {split} |")
    print(f"# load average {' '.join(f'{v:.2f}' for v in os.getloadavg())} after")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10_000_000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--workdir", default="/tmp/gmwm_bench_cli")
    ap.add_argument("--cli", default=None,
                    help="command that runs the CLI (default: the installed 'gmwm'); e.g. a wrapper "
                         "running another checkout")
    ap.add_argument("--vs", default=None,
                    help="with --latency: a second command running the CLI (e.g. a wrapper "
                         "running another checkout), its runs alternating with the first's, so "
                         "that both see the same load")
    ap.add_argument("--latency", action="store_true",
                    help="time the report of the one-hour bag and of EuRoC V101, and gmwm plan")
    ap.add_argument("--euroc", default=str(Path(__file__).resolve().parent.parent.parent / "shared"
                                            / "data" / "external" / "euroc-kimera-v101" / "mav0"
                                            / "imu0" / "data.csv"))
    args = ap.parse_args()
    import numpy as np

    work = Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    gmwm = args.cli or shutil.which("gmwm") or "gmwm"
    if args.latency:
        import gmwm as _pkg

        subprocess.run([sys.executable, "-m", "compileall", "-q",
                        str(Path(_pkg.__file__).parent)], check=True)
        latency(args, gmwm)
        return
    x_path, naive = work / f"x{args.n}.npy", work / "naive_wv.py"
    if not x_path.exists():
        np.save(x_path, np.random.default_rng(1).standard_normal(args.n))
    naive.write_text(NAIVE)
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
