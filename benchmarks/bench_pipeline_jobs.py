"""Per-job CPU of representative pipeline jobs, each in a fresh process as Snakemake runs it.

For each Monte Carlo study that simulates through `simulate_wv` (Simulations 2 and 3, both
STIM-300 sensors, misspecification) the script runs, in order, the study's first `simulate_wv`
job at its longest T, then every fit job on that chunk (`fit` per estimator, `stim300_fit`,
`misspec_fit` per fitted model): the same library calls as the workflow scripts, with the
parameters of `config/config.yaml` (or `--config`, merged over it like Snakemake's
`--configfile`). Each job is a child process started with `python -c` (imports and Numba cache
loads included, one thread for every library as `workflow/scripts/wflog.py` sets); its CPU is
the parent's `getrusage(RUSAGE_CHILDREN)` difference (exact, user + system), with its wall time.

`--replicates K` runs each job twice, on the first K and the first 2K replicates of the chunk
(the full chunk of a full-scale job takes 0.5-3 min): the difference gives the CPU per
replicate, the rest the job's fixed cost (imports, Numba cache loads, first calls), and the two
the job's CPU extrapolated to the full chunk. The rest of the
studies (Simulation 1, SVO, bootstrap coverage, navigation, uncertainty, Allan) are not covered:
their per-job CPU is in the archive's `timings.csv` (`cpu_s`) of a full run.

    nice -n 5 python benchmarks/bench_pipeline_jobs.py [--replicates 5] [--studies ...]
        [--config config/quick.yaml] [--simulator fused] [--json PATH]
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np
import yaml

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_STUDIES = ("sim2", "sim3", "stim300_gyro", "stim300_accel", "misspec")
THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS",
           "VECLIB_MAXIMUM_THREADS", "NUMBA_NUM_THREADS", "GMWM_NUM_THREADS")

SIMULATE = """
from gmwm_studies.montecarlo import simulate_wv_chunk
from gmwm_studies.store import write_wv_chunk
a = {args!r}
write_wv_chunk(a["out"], simulate_wv_chunk(a["model"], a["truth"], a["T"], a["reps"],
               study=a["study"], base_seed=a["seed"], levels=a["levels"],
               simulator=a["simulator"]))
"""
FIT = """
from gmwm_studies.montecarlo import fit_chunk
from gmwm_studies.store import read_wv_chunk, write_dataset
a = {args!r}
write_dataset(fit_chunk(read_wv_chunk(a["wv"]), a["settings"], a["estimator"]), a["out"])
"""
STIM300_FIT = """
from gmwm_studies.stim300 import fit_chunk_all, write_estimates
from gmwm_studies.store import read_wv_chunk
a = {args!r}
write_estimates(a["out"], fit_chunk_all(read_wv_chunk(a["wv"]), a["estimators"], a["freq"]))
"""
MISSPEC_FIT = """
from gmwm_studies.misspec import fit_model_chunk
from gmwm_studies.store import read_wv_chunk, write_dataset
a = {args!r}
write_dataset(fit_model_chunk(read_wv_chunk(a["wv"]), a["spec"], a["label"], a["settings"],
              estimator=a["estimator"]), a["out"])
"""
EMPTY = """
import gmwm_studies.montecarlo, gmwm_studies.store
"""


def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for key, value in over.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(
            out.get(key), dict) else value
    return out


def load_config(path: str | None) -> dict:
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    if path:
        cfg = _merge(cfg, yaml.safe_load(pathlib.Path(path).read_text()))
    return cfg


#: the library checkout the jobs import (``--src``: e.g. another worktree's, for before/after)
SRC = [str(ROOT / "src")]


def run_job(code: str, args: dict[str, Any] | None = None) -> tuple[float, float]:
    """(CPU, wall) seconds of ``code`` (formatted with ``args``) in a fresh child process."""
    env = dict(os.environ, PYTHONPATH=SRC[0])
    env.update({name: "1" for name in THREADS})
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-c", code.format(args=args or {})], env=env, check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def study_jobs(name: str, cfg: dict, k: int | None, simulator: str | None, tmp: pathlib.Path
               ) -> list[dict[str, Any]]:
    s = cfg["studies"][name]
    chunk = int(s.get("chunk_size", cfg["chunk_size"]))
    n_reps = min(chunk, int(s["replicates"])) if k is None else min(k, chunk)
    T = max(int(t) for t in s["n_samples"])
    wv = str(tmp / f"{name}.h5")
    sim = simulator or s.get("simulator", "fast")
    jobs = [("simulate_wv", SIMULATE, {
        "out": wv, "model": s["model"], "truth": s["truth"], "T": T, "reps": list(range(n_reps)),
        "study": name, "seed": int(s.get("seed", cfg["seed"])), "levels": s.get("levels"),
        "simulator": sim})]
    if s["kind"] == "stim300":
        jobs.append(("stim300_fit", STIM300_FIT, {
            "wv": wv, "out": str(tmp / f"{name}_fit.nc"), "freq": float(s["freq"]),
            "estimators": {e: cfg["estimators"][e] for e in s["estimators"]}}))
    elif s["kind"] == "misspec":
        for label, spec in s["fit_models"].items():
            for est in s["estimators"]:
                jobs.append((f"misspec_fit {label} {est}", MISSPEC_FIT, {
                    "wv": wv, "out": str(tmp / f"{name}_{label}_{est}.nc"), "spec": spec,
                    "label": label, "settings": cfg["estimators"][est], "estimator": est}))
    else:
        for est in s["estimators"]:
            jobs.append((f"fit {est}", FIT, {"wv": wv, "out": str(tmp / f"{name}_{est}.nc"),
                                             "settings": cfg["estimators"][est],
                                             "estimator": est}))
    rows = []
    for rule, code, args in jobs:
        cpu, wall = run_job(code, args)
        rows.append({"study": name, "rule": rule, "T": T, "replicates": n_reps, "chunk": chunk,
                     "simulator": sim if rule == "simulate_wv" else "", "cpu_s": cpu,
                     "wall_s": wall})
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--replicates", type=int, help="replicates per job (default: the chunk)")
    parser.add_argument("--studies", nargs="+", default=list(DEFAULT_STUDIES))
    parser.add_argument("--config", help="a config file merged over config/config.yaml")
    parser.add_argument("--simulator", choices=("fused", "fast", "reference"),
                        help="override the studies' simulator")
    parser.add_argument("--json", help="write the rows here")
    parser.add_argument("--src", help="the src/ directory the jobs import (default: this "
                        "checkout's; another commit's for a before/after)")
    args = parser.parse_args()
    if args.src:
        SRC[0] = str(pathlib.Path(args.src).resolve())
    print(f"jobs import {SRC[0]}")
    cfg = load_config(args.config)
    print(f"load average {os.getloadavg()[0]:.2f} at start; CPU = getrusage of each job's "
          "process (user + system)")
    start_cpu, start_wall = run_job(EMPTY)
    print(f"start-up of an empty job (imports of gmwm_studies.montecarlo and .store): "
          f"{start_cpu:.2f} s CPU, {start_wall:.2f} s wall")
    k = args.replicates
    with tempfile.TemporaryDirectory() as tmp:
        rows = [r for name in args.studies
                for r in study_jobs(name, cfg, k, args.simulator, pathlib.Path(tmp))]
        if k is not None:
            twice = [r for name in args.studies
                     for r in study_jobs(name, cfg, 2 * k, args.simulator, pathlib.Path(tmp))]
    print("| study | job | T | replicates (chunk) | CPU s | wall s | CPU s per replicate | "
          "fixed CPU s | CPU s of the chunk |")
    print("|---|---|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows):
        if k is None:
            per, fixed, n_run, cpu, wall = np.nan, np.nan, r["replicates"], r["cpu_s"], r["wall_s"]
            full = r["cpu_s"]
        else:
            r2 = twice[i]
            per = (r2["cpu_s"] - r["cpu_s"]) / (r2["replicates"] - r["replicates"])
            fixed = r["cpu_s"] - per * r["replicates"]
            full = fixed + per * r["chunk"]
            n_run = f"{r['replicates']}+{r2['replicates']}"
            cpu, wall = r["cpu_s"] + r2["cpu_s"], r["wall_s"] + r2["wall_s"]
        r.update(cpu_per_replicate_s=per, fixed_cpu_s=fixed, cpu_chunk_s=full)
        sim = f" ({r['simulator']})" if r["simulator"] else ""
        print(f"| {r['study']} | {r['rule']}{sim} | {r['T']} | {n_run} ({r['chunk']}) | "
              f"{cpu:.2f} | {wall:.2f} | {per:.3f} | {fixed:.2f} | {full:.1f} |")
    print(f"load average {os.getloadavg()[0]:.2f} at the end (numbers under load are indicative)")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"startup_cpu_s": start_cpu,
                                                       "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
