"""Not a timing: do the studies' estimates move by more than Monte Carlo error when the replicate
signals come from the fused simulator (`simulator: fused`, its own generator) instead of
`Model.simulate_fast` (NumPy's normals)?

For each study that simulates through `simulate_wv_chunk` (Simulations 2 and 3, both STIM-300
sensors, misspecification), at the quick profile's sizes and truths (`config/quick.yaml` merged
over `config/config.yaml`) but with `--reps` replicates: the same replicate ids simulated both
ways, then every study estimator fitted to each cached WV (`montecarlo.fit_chunk`, or
`stim300.fit_chunk` for STIM-300; the misspecification study is compared on its WVs only).
Per parameter: mean and SD of the converged estimates under each simulator, the difference of
the means in units of its Monte Carlo SE (z; two independent samples) and the ratio of the SDs
(SE ~ sqrt(1/(R-1)) for Gaussian estimates), the medians and the p-value of the two-sample
Kolmogorov-Smirnov test (the estimates of the harder designs are heavy-tailed: a few replicates
on another optimum move a mean or an SD by more than its nominal SE, not the distribution); per
WV level, the same z for the mean of log WV. Under "same distribution" the |z| are ~N(0, 1) and
the KS p-values uniform: a handful of |z| > 2 or p < 0.05 among ~100 is chance.

    nice -n 5 python benchmarks/compare_simulators.py [--reps 64] [--studies ...] [--json PATH]
"""
from __future__ import annotations

import argparse
import copy
import json
import os
import pathlib
import time
from typing import Any

import numpy as np
import yaml
from scipy import stats

from gmwm_studies import montecarlo, stim300

ROOT = pathlib.Path(__file__).resolve().parents[1]
DEFAULT_STUDIES = ("sim2", "sim3", "stim300_gyro", "stim300_accel", "misspec")


def _merge(base: dict, over: dict) -> dict:
    out = copy.deepcopy(base)
    for key, value in over.items():
        out[key] = _merge(out[key], value) if isinstance(value, dict) and isinstance(
            out.get(key), dict) else value
    return out


def quick_config() -> dict:
    """config/quick.yaml merged over config/config.yaml (as Snakemake merges them)."""
    full = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    return _merge(full, yaml.safe_load((ROOT / "config" / "quick.yaml").read_text()))


def _z(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float, float, float]:
    """(mean a, sd a, mean b, sd b, z of the mean difference, SD ratio b/a)."""
    ma, mb = a.mean(), b.mean()
    sa, sb = a.std(ddof=1), b.std(ddof=1)
    se = np.sqrt(sa**2 / a.size + sb**2 / b.size)
    z = (mb - ma) / se if se > 0 else 0.0
    return ma, sa, mb, sb, z, sb / sa if sa > 0 else np.nan


def compare(name: str, study: dict, cfg: dict, reps: int) -> dict[str, Any]:
    T = int(study["n_samples"][0])
    ids = list(range(reps))
    kw = {"study": name, "base_seed": int(study.get("seed", cfg["seed"])),
          "levels": study.get("levels")}
    chunks, seconds = {}, {}
    for sim in ("fast", "fused"):
        t0 = time.process_time()
        chunks[sim] = montecarlo.simulate_wv_chunk(study["model"], study["truth"], T, ids,
                                                   simulator=sim, **kw)
        seconds[sim] = time.process_time() - t0
    out: dict[str, Any] = {"study": name, "model": study["model"], "T": T, "reps": reps,
                           "simulate_cpu_s": seconds, "wv": [], "estimates": []}
    la, lb = np.log(chunks["fast"].variances), np.log(chunks["fused"].variances)
    for j in range(la.shape[1]):
        ma, sa, mb, sb, z, r = _z(la[:, j], lb[:, j])
        out["wv"].append({"level": j + 1, "mean_log_fast": ma, "mean_log_fused": mb, "z": z,
                          "sd_ratio": r})
    if study["kind"] == "misspec":
        return out
    for est in study["estimators"]:
        settings = cfg["estimators"][est]
        ds = {}
        for sim, ch in chunks.items():
            if study["kind"] == "stim300":
                ds[sim] = stim300.fit_chunk(ch, settings, est, freq=float(study["freq"]))
            else:
                ds[sim] = montecarlo.fit_chunk(ch, settings, est)
        for k, par in enumerate(ds["fast"]["parameter"].values):
            va = ds["fast"]["estimate"].values[:, k][ds["fast"]["converged"].values]
            vb = ds["fused"]["estimate"].values[:, k][ds["fused"]["converged"].values]
            va, vb = va[np.isfinite(va)], vb[np.isfinite(vb)]
            ma, sa, mb, sb, z, r = _z(va, vb)
            out["estimates"].append({"estimator": est, "parameter": str(par),
                                     "truth": float(ds["fast"]["truth"].values[k]),
                                     "n_fast": int(va.size), "n_fused": int(vb.size),
                                     "mean_fast": ma, "sd_fast": sa, "mean_fused": mb,
                                     "sd_fused": sb, "z_mean": z, "sd_ratio": r,
                                     "median_fast": float(np.median(va)),
                                     "median_fused": float(np.median(vb)),
                                     "ks_p": float(stats.ks_2samp(va, vb).pvalue)})
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=64)
    parser.add_argument("--studies", nargs="+", default=list(DEFAULT_STUDIES))
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args()
    cfg = quick_config()
    print(f"load average {os.getloadavg()[0]:.2f} at start, {args.reps} replicates per simulator")
    results = []
    for name in args.studies:
        res = compare(name, cfg["studies"][name], cfg, args.reps)
        results.append(res)
        zw = np.array([w["z"] for w in res["wv"]])
        print(f"\n## {name} ({res['model']}, T = {res['T']}): simulate+WV CPU "
              f"fast {res['simulate_cpu_s']['fast']:.2f} s, fused "
              f"{res['simulate_cpu_s']['fused']:.2f} s; mean log WV z per level: max |z| "
              f"{np.abs(zw).max():.2f}, {int(np.sum(np.abs(zw) > 2))}/{zw.size} above 2")
        if res["estimates"]:
            print("| estimator | parameter | truth | mean fast (SD) | mean fused (SD) | z | "
                  "SD ratio | median fast | median fused | KS p |")
            print("|---|---|---|---|---|---|---|---|---|---|")
            for e in res["estimates"]:
                print(f"| {e['estimator']} | {e['parameter']} | {e['truth']:.4g} | "
                      f"{e['mean_fast']:.4g} ({e['sd_fast']:.3g}) | {e['mean_fused']:.4g} "
                      f"({e['sd_fused']:.3g}) | {e['z_mean']:+.2f} | {e['sd_ratio']:.2f} | "
                      f"{e['median_fast']:.4g} | {e['median_fused']:.4g} | {e['ks_p']:.2f} |")
    zs = np.array([e["z_mean"] for r in results for e in r["estimates"]]
                  + [w["z"] for r in results for w in r["wv"]])
    ps = np.array([e["ks_p"] for r in results for e in r["estimates"]])
    if ps.size:
        print(f"\nKS p-values: {ps.size}, below 0.05: {int(np.sum(ps < 0.05))} (chance "
              f"{0.05 * ps.size:.1f}), below 0.01: {int(np.sum(ps < 0.01))} (chance "
              f"{0.01 * ps.size:.2f}), smallest {ps.min():.3f}")
    print(f"\nall z: {zs.size}, |z| > 2: {int(np.sum(np.abs(zs) > 2))} (chance: "
          f"{0.0455 * zs.size:.1f}), |z| > 3: {int(np.sum(np.abs(zs) > 3))} (chance "
          f"{0.0027 * zs.size:.2f}); load average {os.getloadavg()[0]:.2f} at the end")
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps(results, indent=1, default=float) + "\n")


if __name__ == "__main__":
    main()
