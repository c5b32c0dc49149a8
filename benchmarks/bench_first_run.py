"""First against second `gmwm fit` after a fresh `pip install` (a benchmark: prints, never fails).

Usage: python benchmarks/bench_first_run.py [--runs 3] [--extras test] [--no-baseline] [--readme]

Copies the repository's tracked files to a temporary directory, installs them in a fresh virtual
environment (`pip install -e COPY[extras]`, as the README says), writes a 1e5-sample signal with
NumPy alone, then runs `gmwm fit x.npy 'WN+RW+AR1'` 1 + --runs times and prints the first run's wall
and CPU time against the best later run and their ratio. The baseline (a second environment
installed with GMWM_NO_PRECOMPILE=1) shows what the install-time compilation saves. NUMBA_CACHE_DIR
is removed from the environment (it would bypass the cache built at install). --readme writes
the table into benchmarks/README.md.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from readme_section import load, machine, run_measured, update_section

REPO = Path(__file__).resolve().parents[1]
SIGNAL = ("import numpy as np; r = np.random.default_rng(0); n = 100_000; "
          "x = r.standard_normal(n) + np.cumsum(0.01 * r.standard_normal(n)); "
          "e = r.standard_normal(n); a = np.zeros(n)\n"
          "for t in range(1, n): a[t] = 0.99 * a[t - 1] + 0.1 * e[t]\n"
          "np.save('x.npy', x + a)")


def copy_tracked(dst: Path) -> None:
    files = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True,
                           check=True).stdout.decode().split("\0")
    for f in filter(None, files):
        src = REPO / f
        if src.is_file():
            (dst / f).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / f)


def variant(tmp: Path, name: str, extras: str, runs: int, precompile: bool) -> dict[str, object]:
    src, venv = tmp / f"src-{name}", tmp / f"venv-{name}"
    copy_tracked(src)
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    if not precompile:
        env["GMWM_NO_PRECOMPILE"] = "1"
    target = f"{src}[{extras}]" if extras else str(src)
    t0 = time.perf_counter()
    inst = run_measured([str(venv / "bin" / "pip"), "install", "-q", "-e", target], env=env)
    install_s = time.perf_counter() - t0
    if inst["code"] != 0:
        raise SystemExit(f"pip install failed:\n{inst['err'][-3000:]}")
    env.pop("GMWM_NO_PRECOMPILE", None)
    work = tmp / f"work-{name}"
    work.mkdir()
    subprocess.run([str(venv / "bin" / "python"), "-c", SIGNAL], cwd=work, env=env, check=True)
    gmwm = str(venv / "bin" / "gmwm")
    results = []
    for _ in range(runs + 1):
        r = run_measured([gmwm, "fit", "x.npy", "WN+RW+AR1", "--json"], env=env, cwd=str(work))
        if r["code"] not in (0, 3):
            raise SystemExit(f"gmwm fit failed:\n{r['err'][-2000:]}")
        results.append(r)
    first, later = results[0], results[1:]
    return {"name": name, "install_s": install_s, "first": first,
            "warm_wall": min(r["wall"] for r in later), "warm_cpu": min(r["cpu"] for r in later),
            "note": "compiling numerical kernels" in str(first["err"])}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="warm runs after the first")
    parser.add_argument("--extras", default="", help="pip extras to install, e.g. test")
    parser.add_argument("--no-baseline", action="store_true",
                        help="skip the environment installed with GMWM_NO_PRECOMPILE=1")
    parser.add_argument("--readme", action="store_true", help="write the table into README.md")
    args = parser.parse_args(argv)
    load_before = load()
    tmp = Path(tempfile.mkdtemp(prefix="gmwm-first-run-"))
    rows = []
    try:
        plan = [("install-time cache", True)] + ([] if args.no_baseline
                                                 else [("GMWM_NO_PRECOMPILE=1", False)])
        for name, pre in plan:
            print(f"installing ({name}) ...", flush=True)
            rows.append(variant(tmp, name.split()[0].replace("=", "_"), args.extras, args.runs,
                                pre) | {"label": name})
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    load_after = load()
    header = ("| install | pip install [s] | first `gmwm fit` wall / CPU [s] | best of the next "
              f"{args.runs} wall / CPU [s] | ratio first / warm, wall (CPU) | compile note on "
              "stderr |")
    lines = [header, "|---|---|---|---|---|---|"]
    for r in rows:
        f = r["first"]
        lines.append(f"| {r['label']} | {r['install_s']:.0f} | {f['wall']:.2f} / {f['cpu']:.2f} | "
                     f"{r['warm_wall']:.2f} / {r['warm_cpu']:.2f} | "
                     f"{f['wall'] / r['warm_wall']:.2f} ({f['cpu'] / r['warm_cpu']:.2f}) | "
                     f"{'yes' if r['note'] else 'no'} |")
    table = "\n".join(lines)
    text = (f"`python benchmarks/bench_first_run.py --runs {args.runs}"
            f"{' --extras ' + args.extras if args.extras else ''}`: fresh virtual environment, "
            f"`pip install -e` of the tracked files, `gmwm fit x.npy 'WN+RW+AR1'` on 1e5 samples. "
            f"{machine()}; load average {load_before} before, {load_after} after.\n\n{table}\n")
    print(text)
    if args.readme:
        update_section("bench_first_run", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
