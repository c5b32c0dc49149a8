"""Does the default fit reach the best known objective on a whole class of replicates?

    python benchmarks/search_class.py [--reps 200 100 100] [--models sim2 weak_sin gm_rw_short]
                                      [--jobs 2] [--json out.json] [--baseline old.json] [--write]
    python benchmarks/search_class.py --jobs 2 --json benchmarks/search_class.json --write  # full

Issue 40, item 5: the default fit's objective against the best objective known from a search
with 10x the default budget, on fresh replicates (seeds of this script, not the studies') of
three designs with weak components (:func:`designs`):

* ``sim2``: Simulation 2 as the study runs it (config/config.yaml ``studies.sim2``: model
  2*AR1+2*SIN, its truth, T = 1e7, simulator ``fused``: :func:`gmwm.fused.simulate_wv` on the
  replicate stream :func:`gmwm_studies.seeds.replicate_rng` ``("sim2", T, r, 4040)``; the WV
  rebuilt with the eta_3 interval as a cached chunk is; fitted with the settings of
  ``estimators.gmwm`` (CI-eta3 weights, 8 starts, no reweighting) and the starts' seed from
  stream 1 of the replicate, as :func:`gmwm_studies.montecarlo.fit_chunk` does). Base seed 4040
  instead of the study's 20240601: the same design with other signals.
* ``weak_sin``: a weak slow SIN beside two AR1s, 2*AR1+SIN at T = 2^18 (AR1 phi 0.6 with
  sigma2 1 and phi 0.9999 with sigma2 1e-5; the SIN's period 5000 samples, on the slow AR1's
  time scale of 1e4 samples: the pattern of Simulation 2's hard cases, a slow SIN that the
  phi ~ 1 AR1 can absorb), its amplitude set to an expected z-value of 4
  (``bench_selection.calibrate``: alpha 0.068); :func:`gmwm.fit`'s defaults.
* ``gm_rw_short``: WN + GM + RW at 100 Hz with a short record (T = 2^16, 11 min), GM (beta
  0.5 Hz) and RW both at an expected z-value of 4; :func:`gmwm.fit`'s defaults.

The last two are simulated by :func:`gmwm.fused.simulate_wv` too, on the stream
``SeedSequence([4040, k, r])`` (k = 1, 2 the design), the fit's seed from
``SeedSequence([4040, k, r, 1])``. The Simulation 2 fit is the study's: with ``--simulator
fast`` (``simulate_fast`` + ``wvar``, the committed record's simulator before config switched to
``fused``) and base seed 20240601, replicate 0's default objective is the committed one
(0.1098025721, reports/sim2/replicates/estimates_T10000000.csv).

The 10x search (per replicate, on the default fit's own objective: same WV, same weight matrix
Omega, :meth:`gmwm.GMWMResult.problem`), with n0 = the default's ``n_starts``:

1. :func:`gmwm.fit` with the same settings and seed but ``n_starts = 10 n0`` (the library's
   own nested search, ten times the starts per node; ``estimate_only``: no SEs or test; its
   Omega is checked to be the default's);
2. bounded solves from the truth, the default's estimate and the 10x fit's estimate;
3. ``10 n0`` random projected starts (every shape uniform over its domain, the linear
   parameters by NNLS: ``hard_cases._random_theta``), each solved;
4. for every SIN, a profile over its frequency (24 log-spaced values from 0.25 / tau_J to 3;
   the other parameters solved with it fixed, from the truth and both estimates), the best 8
   points of each profile freed and solved (``audit_sim2_misses.hard_search``).

Best known = the minimum of all of these and of the default's objective (so never above it). A
replicate *reaches* when its default objective <= best (1 + 1e-6); the share at 1e-9 and the
largest relative excess are reported too. CPU per fit is ``time.process_time`` of the default
:func:`gmwm.fit` call (standard errors and goodness of fit included, as the study runs it) in
a worker that already ran one fit of the design (no import or compilation cost); the 10x CPU
covers steps 1-4. Missing replicates are listed by id and their WVs are in ``--json`` so they
can be stored as hard cases. ``--write`` replaces this benchmark's section of
``benchmarks/README.md``; a plain run modifies no tracked file.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import bench_selection as bs
from audit_sim2_misses import hard_search
from readme_section import update_section

import gmwm
from gmwm.fused import simulate_wv
from gmwm.model import Model
from gmwm.settings import FitSettings
from gmwm.wv import WaveletVariance, wvar
from gmwm_studies.montecarlo import (
    STUDY_WV_CI,
    check_truth,
    estimator_settings,
    simulate_replicate,
)
from gmwm_studies.seeds import replicate_rng, replicate_seed

#: base seed of this script's replicates (the studies use 20240601)
BASE_SEED = 4040
#: budget factor of the best-known search
FACTOR = 10
#: SIN frequency profile points (audit_sim2_misses.py's default)
N_PROFILE = 24
#: a replicate reaches the best known objective within this relative excess ...
TOL = 1e-6
#: ... and, reported beside, within this one
TOL_TIGHT = 1e-9
Z_EXPECTED = 4.0
DEFAULT_REPS = {"sim2": 200, "weak_sin": 100, "gm_rw_short": 100}


@dataclass(frozen=True)
class Design:
    """One generating model, its length and the settings of its default fit."""

    name: str
    label: str
    spec: str
    truth: dict[str, float]
    T: int
    freq: float
    settings: FitSettings
    weak: tuple[str, ...] = ()   # components calibrated to an expected z of Z_EXPECTED
    key: int = 0                 # 0: the study's seed machinery (sim2); k > 0: SeedSequence

    def model(self) -> Model:
        return Model(self.spec, self.freq)

    def theta(self, T: int | None = None) -> np.ndarray:
        """The truth (canonical order), weak components calibrated at length ``T``."""
        model = self.model()
        th = model.theta(self.truth)
        for comp in self.weak:
            th = bs.calibrate(model, th, comp, Z_EXPECTED, T or self.T)
        return th

    def rng(self, r: int, T: int) -> np.random.Generator:
        if self.key == 0:
            return replicate_rng("sim2", T, r, BASE_SEED)
        return np.random.default_rng(np.random.SeedSequence([BASE_SEED, self.key, r]))

    def fit_seed(self, r: int, T: int) -> int:
        if self.key == 0:
            return replicate_seed("sim2", T, r, BASE_SEED, stream=1)
        state = np.random.SeedSequence([BASE_SEED, self.key, r, 1]).generate_state(1, np.uint64)
        return int(state[0] >> np.uint64(1))


def designs() -> dict[str, Design]:
    """The three designs (module docstring)."""
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    s2 = cfg["studies"]["sim2"]
    check_truth(s2["model"], s2["truth"])
    sim2 = Design("sim2", "Simulation 2 (2*AR1+2*SIN, study settings)", s2["model"],
                  {k: float(v) for k, v in s2["truth"].items()}, int(s2["n_samples"][0]), 1.0,
                  estimator_settings(cfg["estimators"][s2["estimators"][0]]))
    default = FitSettings.of()
    weak_sin = Design("weak_sin", "weak SIN beside AR1s (2*AR1+SIN)", "2*AR1+SIN",
                      {"AR1[1].phi": 0.6, "AR1[1].sigma2": 1.0, "AR1[2].phi": 0.9999,
                       "AR1[2].sigma2": 1e-5, "SIN[1].alpha": 0.02,
                       "SIN[1].beta": 2 * math.pi / 5000}, 2**18, 1.0, default, ("SIN[1]",), 1)
    gm_rw = Design("gm_rw_short", "GM + RW, short record (WN+GM+RW, 100 Hz)", "WN+GM+RW",
                   {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
                    "RW[1].gamma2": 1e-9}, 2**16, 100.0, default, ("GM[1]", "RW[1]"), 2)
    return {d.name: d for d in (sim2, weak_sin, gm_rw)}


def replicate_wv(design: Design, theta: np.ndarray, r: int, T: int,
                 simulator: str = "fused") -> WaveletVariance:
    """Replicate ``r``'s WV, rebuilt as a study's cached WV is (``simulator``: ``"fused"``, the
    fused simulation + WV pass of config/config.yaml, or ``"fast"``, ``simulate_fast`` + ``wvar``
    as the committed Simulation 2 record and ``audit_sim2_misses.py`` use)."""
    J = int(T).bit_length() - 2  # gmwm_studies.montecarlo.simulate_wv_chunk: floor(log2 T) - 1
    if simulator == "fused":
        v = simulate_wv(design.model(), theta, T, design.rng(r, T), J)
    else:
        x = simulate_replicate(design.model(), theta, T, design.rng(r, T), simulator)
        v = wvar(x, levels=J, ci=STUDY_WV_CI).variance
        del x
    tau = 2.0 ** np.arange(1, v.size + 1)
    return WaveletVariance.from_table(tau, v, n_samples=T, freq=design.freq, ci=STUDY_WV_CI)


def replicate(design: Design, theta: np.ndarray, r: int, T: int | None = None,
              factor: int = FACTOR, n_profile: int = N_PROFILE, simulator: str = "fused") -> dict:
    """Default fit and best known objective (the ``factor``-x search) of one replicate."""
    T = T or design.T
    model = design.model()
    c0 = time.process_time()
    wv = replicate_wv(design, theta, r, T, simulator)
    cpu_sim = time.process_time() - c0
    seed = design.fit_seed(r, T)
    c0 = time.process_time()
    res = gmwm.fit(wv, model, settings=design.settings, seed=seed)
    cpu_default = time.process_time() - c0
    prob = res.problem()
    default = float(res.objective)

    c0 = time.process_time()
    wide = gmwm.fit(wv, model, settings=design.settings.replace(
        n_starts=factor * design.settings.n_starts), seed=seed, estimate_only=True)
    if not np.allclose(wide.problem().omega, prob.omega, rtol=1e-12, atol=0):
        raise RuntimeError(f"{design.name} replicate {r}: the {factor}x fit has another Omega")
    wide_obj = float(prob.objective(np.asarray(wide.params, float)))
    starts = [np.array(theta, float), np.array(res.params, float), np.array(wide.params, float)]
    found, theta_best, wins = hard_search(prob, starts, factor * design.settings.n_starts,
                                          n_profile, seed % 2**32)
    cpu_search = time.process_time() - c0
    cands = {"default": (default, np.array(res.params, float)),
             "wide_fit": (wide_obj, np.array(wide.params, float)),
             "hard_search": (float(found), model.canonical(theta_best))}
    how = min(cands, key=lambda k: cands[k][0])
    best, best_theta = cands[how]
    if best >= default * (1 - 1e-12):  # a tie at rounding level: the default is the best
        how, best, best_theta = "default", default, cands["default"][1]
    excess = default / best - 1 if best > 0 else (0.0 if default == best else math.inf)
    return {"model": design.name, "replicate": int(r), "T": int(T), "base_seed": BASE_SEED,
            "simulator": simulator, "truth": model.as_dict(theta),
            "default": default, "best": float(best), "excess": float(excess),
            "reaches": bool(excess <= TOL), "reaches_tight": bool(excess <= TOL_TIGHT),
            "best_from": how, "wide_fit": wide_obj, "hard_search_improved_by": wins,
            "cpu_simulate": cpu_sim, "cpu_default": cpu_default, "cpu_search": cpu_search,
            "default_params": res.as_dict(), "best_params": model.as_dict(best_theta),
            "variance": [float(v) for v in wv.variance], "freq": design.freq}


# -- parallel driver -------------------------------------------------------------------------

_DESIGNS: dict[str, Design] = {}
_THETAS: dict[str, np.ndarray] = {}


def _init(names: list[str], thetas: dict[str, list[float]]) -> None:
    """Worker set-up: the designs, and one fit of each at a small T (imports, compiled kernels
    and caches loaded before any timed fit)."""
    all_designs = designs()
    for n in names:
        _DESIGNS[n] = all_designs[n]
        _THETAS[n] = np.asarray(thetas[n], float)
        d = _DESIGNS[n]
        gmwm.fit(replicate_wv(d, _THETAS[n], 10**6, 2**14), d.model(), settings=d.settings,
                 seed=0)


def _task(item: tuple[str, int, str]) -> dict:
    name, r, simulator = item
    try:
        return replicate(_DESIGNS[name], _THETAS[name], r, simulator=simulator)
    except Exception as exc:  # noqa: BLE001 -- one failed replicate is reported, not fatal
        return {"model": name, "replicate": int(r), "error": f"{type(exc).__name__}: {exc}"}


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k / n."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    den = 1 + z * z / n
    mid = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    return (max(0.0, mid - half), min(1.0, mid + half))


def summary(design: Design, rows: list[dict]) -> dict:
    errors = [r for r in rows if "error" in r]
    rows = [r for r in rows if "error" not in r]
    n = len(rows)
    if n == 0:
        raise SystemExit(f"{design.name}: every replicate failed: "
                         + "; ".join(r["error"] for r in errors[:3]))
    k = sum(r["reaches"] for r in rows)
    worst = max(rows, key=lambda r: r["excess"])
    cd = np.array([r["cpu_default"] for r in rows])
    cs = np.array([r["cpu_search"] for r in rows])
    return {"model": design.name, "label": design.label, "spec": design.spec, "T": design.T,
            "freq": design.freq, "n_starts": design.settings.n_starts,
            "weights": design.settings.weights, "replicates": n, "reaching": int(k),
            "share": k / n, "wilson95": wilson(k, n),
            "reaching_tight": int(sum(r["reaches_tight"] for r in rows)),
            "largest_excess": worst["excess"], "largest_excess_replicate": worst["replicate"],
            "cpu_default_median": float(np.median(cd)), "cpu_default_mean": float(cd.mean()),
            "cpu_search_median": float(np.median(cs)), "cpu_search_mean": float(cs.mean()),
            "misses": [r["replicate"] for r in rows if not r["reaches"]],
            "errors": {r["replicate"]: r["error"] for r in errors}}


def table(sums: list[dict]) -> list[str]:
    lines = [("| design | fit settings | T | R | reach (1e-6) | share [95 % Wilson] | reach (1e-9) | largest "
              "excess (replicate) | default CPU/fit median / mean [s] | 10x search CPU/fit "
              "median / mean [s] |"), "|---|---|---|---|---|---|---|---|---|---|"]
    for s in sums:
        lo, hi = s["wilson95"]
        lines.append(
            f"| {s['label']} | {s['weights']} weights, {s['n_starts']} starts | {s['T']:,} | {s['replicates']} | {s['reaching']} | "
            f"{100 * s['share']:.1f} % [{100 * lo:.1f}, {100 * hi:.1f}] | "
            f"{s['reaching_tight']} | {s['largest_excess']:.2g} ({s['largest_excess_replicate']}) "
            f"| {s['cpu_default_median']:.3f} / {s['cpu_default_mean']:.3f} | "
            f"{s['cpu_search_median']:.2f} / {s['cpu_search_mean']:.2f} |")
    lines.append("")
    for s in sums:
        lines.append(f"Missing replicates of {s['model']} (base seed {BASE_SEED}): "
                     + (", ".join(map(str, s["misses"])) or "none") + ".")
        if s["errors"]:
            lines.append(f"Failed replicates of {s['model']} (not counted above): " + "; ".join(
                f"{r}: {e}" for r, e in s["errors"].items()) + ".")
    return lines


def compare(rows: list[dict], baseline: dict) -> list[str]:
    """Lines comparing this run's default fits with a baseline run's (``--json`` of another
    commit) on the replicates both ran: CPU per fit (ratio of the medians and of the means) and
    the objectives (lower, equal within 1e-9 relative, higher). Replicates match on design,
    truth, length, simulator and seed."""
    def key(r: dict) -> tuple:  # the same replicate: design, truth, length, simulator, seed
        return (r["model"], r["replicate"], r["T"], r.get("simulator"), r.get("base_seed"),
                tuple(sorted((r.get("truth") or {}).items())))

    old = {key(r): r for r in baseline["rows"] if "error" not in r}
    rows = [r for r in rows if "error" not in r]
    lines = ["", f"Against the baseline run (commit {baseline.get('commit', '?')}):", "",
             ("| design | replicates | default CPU/fit median ratio | mean ratio | objective "
              "lower / equal (1e-9) / higher | largest relative rise |"), "|---|---|---|---|---|---|"]
    for m in dict.fromkeys(r["model"] for r in rows):
        pairs = [(r, old[key(r)]) for r in rows if r["model"] == m and key(r) in old]
        if not pairs:
            continue
        new_cpu = np.array([a["cpu_default"] for a, _ in pairs])
        old_cpu = np.array([b["cpu_default"] for _, b in pairs])
        rel = np.array([a["default"] / b["default"] - 1 for a, b in pairs])
        lines.append(f"| {m} | {len(pairs)} | {np.median(new_cpu) / np.median(old_cpu):.2f} | "
                     f"{new_cpu.mean() / old_cpu.mean():.2f} | {int((rel < -1e-9).sum())} / "
                     f"{int((abs(rel) <= 1e-9).sum())} / {int((rel > 1e-9).sum())} | "
                     f"{max(rel.max(), 0.0):.2g} |")
    return lines


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", choices=list(DEFAULT_REPS), default=list(DEFAULT_REPS))
    ap.add_argument("--reps", type=int, nargs="+", default=None,
                    help="replicates per design (one number for all, or one per --models; "
                    "default 200 for sim2, 100 for the others)")
    ap.add_argument("--first", type=int, default=0, help="first replicate id")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--simulator", choices=["fused", "fast"], default="fused",
                    help="fused: config/config.yaml's (default); fast: simulate_fast + wvar, the "
                    "committed Simulation 2 record's and audit_sim2_misses.py's")
    ap.add_argument("--json", type=Path, help="write every row and the summaries here")
    ap.add_argument("--baseline", type=Path, help="a --json of another commit: compare CPU "
                    "per default fit and objectives on the replicates both ran")
    ap.add_argument("--write", action="store_true",
                    help="replace this benchmark's section of benchmarks/README.md")
    args = ap.parse_args()
    if args.reps is None:
        reps = [DEFAULT_REPS[m] for m in args.models]
    elif len(args.reps) in (1, len(args.models)):
        reps = args.reps * len(args.models) if len(args.reps) == 1 else args.reps
    else:
        ap.error("--reps takes one number or one per --models")
    t0, cpu0, load0 = time.perf_counter(), time.process_time(), os.getloadavg()[0]
    all_designs = designs()
    thetas = {m: all_designs[m].theta() for m in args.models}
    for m in args.models:
        d = all_designs[m]
        print(f"{m}: {d.spec}, T = {d.T}, {d.freq:g} Hz, truth "
              + ", ".join(f"{k} {v:.4g}" for k, v in d.model().as_dict(thetas[m]).items()),
              flush=True)
    work = [(m, r, args.simulator) for m, n in zip(args.models, reps, strict=True)
            for r in range(args.first, args.first + n)]
    init = (args.models, {m: list(map(float, t)) for m, t in thetas.items()})
    rows: list[dict] = []
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs, initializer=_init, initargs=init) as pool:
            it = pool.map(_task, work)
            for row in it:
                rows.append(row)
                _progress(row)
    else:
        _init(*init)
        for item in work:
            rows.append(_task(item))
            _progress(rows[-1])
    sums = [summary(all_designs[m], [r for r in rows if r["model"] == m]) for m in args.models]
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0  # serial: the replicates ran in this process
    if args.jobs > 1:  # the workers' replicates (their warm-up fits not counted)
        cpu += sum(r["cpu_simulate"] + r["cpu_default"] + r["cpu_search"] for r in rows
                   if "error" not in r)
    lines = table(sums)
    if args.baseline:
        lines += compare(rows, json.loads(args.baseline.read_text()))
    print("\n".join(lines))
    print(f"wall {wall:.0f} s, CPU {cpu:.0f} s (with --jobs > 1 the workers' warm-up is not "
          f"counted), load "
          f"{load0:.2f} at the start, {os.getloadavg()[0]:.2f} at the end")
    if args.json:
        tmp = args.json.with_suffix(args.json.suffix + ".tmp")
        tmp.write_text(json.dumps({"_about": __doc__.splitlines()[0], "commit": bs.commit(),
                                   "load": [load0, os.getloadavg()[0]], "wall": wall,
                                   "cpu": cpu, "base_seed": BASE_SEED,
                                   "factor": FACTOR, "tol": TOL, "tol_tight": TOL_TIGHT,
                                   "summaries": sums, "rows": rows}, indent=1) + "\n")
        os.replace(tmp, args.json)
    if args.write:
        head = (f"Generated by `python benchmarks/search_class.py {' '.join(sys.argv[1:])}` "
                f"(commit {bs.commit()}, "
                f"{wall:.0f} s wall, {cpu:.0f} s CPU, 1-minute load "
                f"{load0:.1f} at the start and {os.getloadavg()[0]:.1f} at the end). Fresh "
                f"replicates (base seed {BASE_SEED}); reach = default objective <= best known "
                f"x (1 + {TOL:g}), tight: x (1 + {TOL_TIGHT:g}); best known = the {FACTOR}x search of the script's docstring (the "
                f"{FACTOR}x-start fit, solves from the truth and both estimates, {FACTOR} x "
                "n_starts random projected starts, each SIN's frequency profile) on the "
                "default's own objective. CPU per fit: `time.process_time` of one "
                "`gmwm.fit` (SEs and goodness of fit included), per worker after a warm-up fit.\n")
        update_section("search_class", head + "\n" + "\n".join(lines))
    return 0


def _progress(row: dict) -> None:
    if "error" in row:
        print(f"{row['model']:<12} rep {row['replicate']:4d}: FAILED {row['error']}", flush=True)
        return
    print(f"{row['model']:<12} rep {row['replicate']:4d}: default {row['default']:.10g} best "
          f"{row['best']:.10g} ({row['best_from']}) excess {row['excess']:.2e} cpu "
          f"{row['cpu_default']:.2f} / {row['cpu_search']:.2f} s"
          + ("" if row["reaches"] else "  <- miss"), flush=True)


if __name__ == "__main__":
    sys.exit(main())
