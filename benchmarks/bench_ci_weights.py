"""GMWM weights from the eta_3 against the mixture WV intervals: the evidence for the default.

Usage: python benchmarks/bench_ci_weights.py [--cases sim1_1e4 sim3 hard navchip ...] [--reps R]
       [--T 65536] [--models WN+RW ...] [--workers 2] [--json PATH] [--from-json PATH] [--write]

The estimator's ``weights="ci"`` is the inverse squared width of a WV interval
(:func:`gmwm.inference.weight_matrix`). Weightings compared on the same replicates (same seeds):

* ``ci-eta3``: widths of the eta_3 interval (EDF ``max(M_j / 2**j, 1)``);
* ``ci-mixture``: widths of the mixture-EDF interval (:mod:`gmwm.wvci`, the default interval);
* ``efficient``: the two-step ``V^-1`` weights (reference; its first step uses ``"ci"``).

Cases (``--cases``; default all but the toy models):

* ``toy``: the three models of ``--models`` at ``--T`` (one fit, 4 starts, not nested);
* ``sim1_1e4``, ``sim1_1.6e5``: Simulation 1 of [Vibration] (config/config.yaml ``sim1``) at
  T = 1e4 and 1.6e5, fitted as the study does (``gmwm_single``: 8 starts, not nested);
* ``sim2``, ``sim3``: Simulations 2 and 3 at the studies' full T (2.88e6, 1e7), fitted as the
  studies do (``gmwm``: 8 starts, nested);
* ``stim300_gyro``, ``stim300_accel``: the [GMWFM] STIM-300 truths at T = 2.5e6 (the study's
  shorter length), the default fit; ``*_cf``: the study's ``gmwm_cf`` (2 re-weightings with
  the model WV, which then set the final weights);
* ``hard``: the hard-case suite (benchmarks/hard_cases.py): the default fit's objective against
  the best known for the same weighting (the stored exhaustive search for the default weights
  :data:`gmwm.inference.CI_WEIGHTS`; for the others ``--n-random`` projected random starts plus a 16-start fit under the fit's final Omega);
* ``navchip``: the six real Navchip axes with ``QN+WN+2*GM+RW+DR`` and the study's fit settings
  (config ``navchip.fit``): estimates, their difference in the ``ci-eta3`` fit's SEs, the GOF
  p-value.

Per Monte Carlo case and parameter: relative bias and RMSE (``est / truth - 1``) and the number
of replicates with the component at the boundary 0. ``--write`` renders the table into this
benchmark's section of ``benchmarks/README.md``; a plain run only prints it.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import sys
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

import gmwm
from gmwm.inference import CI_WEIGHTS
from gmwm.model import Model
from gmwm.settings import FitSettings

HERE = Path(__file__).resolve().parent
CONFIG = HERE.parent / "config" / "config.yaml"
SEED = 20261125
WEIGHTINGS = ("ci-eta3", "ci-mixture", "efficient")

MODELS = {
    "WN+RW": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5}),
    "WN+AR1+RW": ("WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                                "RW[1].gamma2": 1e-6}),
    "QN+WN+RW": ("QN+WN+RW", {"QN[1].Q2": 1.0, "WN[1].sigma2": 0.1, "RW[1].gamma2": 1e-7}),
}
#: Monte Carlo cases built from the studies: name -> (study, T, estimator or None, default R)
STUDY_CASES = {
    "sim1_1e4": ("sim1", 10_000, "gmwm_single", 200),
    "sim1_1.6e5": ("sim1", 160_000, "gmwm_single", 200),
    "sim2": ("sim2", 2_879_999, "gmwm", 60),
    "sim3": ("sim3", 10_000_000, "gmwm", 100),
    "stim300_gyro": ("stim300_gyro", 2_500_000, None, 200),
    "stim300_gyro_cf": ("stim300_gyro", 2_500_000, "gmwm_cf", 200),
    "stim300_accel": ("stim300_accel", 2_500_000, None, 200),
    "stim300_accel_cf": ("stim300_accel", 2_500_000, "gmwm_cf", 200),
}
ALL_CASES = ("toy", *STUDY_CASES, "hard", "navchip")
NAVCHIP_MODEL = "QN+WN+2*GM+RW+DR"


@dataclass
class MCCase:
    name: str
    spec: str
    truth: dict[str, float]
    T: int
    freq: float
    settings: dict = field(default_factory=dict)
    reps: int = 100
    key: str = ""   # seeds: cases of one key and T (a study's fitting variants) share replicates

    @property
    def model(self) -> Model:
        return Model(self.spec, self.freq)


def mc_cases(names: list[str], reps: int | None, toy_T: int, toy_models: list[str]
             ) -> list[MCCase]:
    cfg = yaml.safe_load(CONFIG.read_text())
    out = []
    for name in names:
        if name == "toy":
            out += [MCCase(f"toy {m}", MODELS[m][0], MODELS[m][1], toy_T, 1.0,
                           {"n_starts": 4, "nested": False}, reps or 100, m) for m in toy_models]
        elif name in STUDY_CASES:
            study, T, est, r = STUDY_CASES[name]
            st = cfg["studies"][study]
            settings = dict(cfg["estimators"][est]) if est else {}
            settings.pop("weights", None)
            out.append(MCCase(name, st["model"], st["truth"], T, float(st.get("freq", 1.0)),
                              settings, reps or r, study))
    return out


# -- workers (forked: the cases are module globals set before the pool starts) ----------------------
_CASES: dict[str, MCCase] = {}


def _fit_all(wv: gmwm.WaveletVariance, model: Model, settings: dict,
             weightings: tuple[str, ...]) -> dict[str, dict]:
    # se_cov="gaussian": the estimates do not depend on it, and it skips the model covariance
    # and the GOF test, which only the standard errors need
    out = {}
    for w in weightings:
        res = gmwm.fit(wv, model, settings=FitSettings(weights=w, se_cov="gaussian", **settings))
        out[w] = {"params": res.params.tolist(), "converged": bool(res.converged)}
    return out


def _mc_unit(job: tuple[str, int, tuple[str, ...]]) -> tuple[str, int, dict]:
    name, rep, weightings = job
    case = _CASES[name]
    model = case.model
    rng = np.random.default_rng([SEED, zlib.crc32(case.key.encode()), case.T, rep])
    x = model.simulate_fast(model.theta(case.truth), case.T, rng)
    wv = gmwm.wvar(x, freq=case.freq)
    return name, rep, _fit_all(wv, model, case.settings, weightings)


def _hard_unit(job: tuple[str, str, int]) -> tuple[str, str, dict]:
    import hard_cases as hc

    from gmwm.inference import Problem

    cid, w, n_random = job
    wv, spec = _hard_wv(cid)
    res = gmwm.fit(wv, spec, weights=w)
    best = float(res.objective)
    if w in ("ci", CI_WEIGHTS):  # hard_cases_best.json holds the default weights' best known
        stored = json.loads(hc.BEST_FILE.read_text())
        best = min(best, stored.get(cid, best))
    else:
        # the exhaustive search of hard_cases.best_known under this fit's final Omega
        model = Model(spec, wv.freq)
        prob = Problem(model, wv, res.weights, "gmwm")
        rng = np.random.default_rng(0)
        cov = np.linalg.inv(res.weights)
        best = min(best, gmwm.fit(wv, model, weights=cov, n_starts=16, nested=False,
                                  se_cov="gaussian").objective)
        for _ in range(n_random):
            sol = prob.solve(hc._random_theta(model, wv, prob.white, rng))
            if np.isfinite(sol.objective):
                best = min(best, float(sol.objective))
    return cid, w, {"objective": float(res.objective), "best": best,
                    "at_zero": _n_at_zero(res.model, res.params)}


def _hard_wv(cid: str) -> tuple[gmwm.WaveletVariance, str]:
    import hard_cases as hc

    from gmwm_studies.data import load_navchip_wv

    name, spec = cid.split("|")
    if name.startswith("boot_"):
        return hc.boot_wv(name)[0], spec
    if name.startswith("navchip_"):
        _, sensor, axis = name.split("_")
        return load_navchip_wv(_navchip_csv(), sensor, axis), spec
    return hc.simulated_wv(name), spec


def _navchip_csv() -> Path:
    from gmwm_studies.data import load_registry

    return Path(load_registry()["local_dir_resolved"]) / "wv" / "navchip_wv.csv"


def _navchip_unit(job: tuple[str, str, str]) -> tuple[str, str, dict]:
    from gmwm_studies.data import load_navchip_wv

    sensor, axis, w = job
    cfg = yaml.safe_load(CONFIG.read_text())["navchip"]
    settings = dict(cfg["fit"])
    settings.pop("weights", None)
    wv = load_navchip_wv(_navchip_csv(), sensor, axis)
    res = gmwm.fit(wv, cfg["model"], freq=wv.freq, weights=w, **settings)
    return f"{sensor} {axis}", w, {
        "names": res.model.param_names, "params": res.params.tolist(), "se": res.se.tolist(),
        "p_value": float(res.gof.p_value), "objective": float(res.objective),
        "converged": bool(res.converged), "at_zero": _n_at_zero(res.model, res.params)}


def _n_at_zero(model: Model, theta: np.ndarray) -> list[str]:
    """Components whose scale parameter is at the boundary 0."""
    return [c.name for c in model.components if theta[c.start + c.process.scale_index] == 0]


# -- driver -----------------------------------------------------------------------------------------
def _map(fn, jobs: list, workers: int):
    if workers <= 1 or len(jobs) <= 1:
        yield from map(fn, jobs)
        return
    with mp.get_context("fork").Pool(workers) as pool:
        yield from pool.imap_unordered(fn, jobs, chunksize=1)


def run(args: argparse.Namespace) -> dict:
    sys.path.insert(0, str(HERE))  # hard_cases.py beside this script
    cases = mc_cases(args.cases, args.reps, args.T, args.models)
    _CASES.update({c.name: c for c in cases})
    weightings = tuple(args.weightings)
    out: dict = {"mc": {}, "hard": {}, "navchip": {}, "weightings": list(weightings)}
    jobs = [(c.name, r, weightings) for c in cases for r in range(c.reps)]
    # the expensive cases first, so that the two workers finish together
    jobs.sort(key=lambda j: -_CASES[j[0]].T)
    raw: dict[str, dict[int, dict]] = {c.name: {} for c in cases}
    for n_done, (name, rep, fits) in enumerate(_map(_mc_unit, jobs, args.workers), 1):
        raw[name][rep] = fits
        if n_done % 50 == 0:
            print(f"  {n_done}/{len(jobs)} replicates", file=sys.stderr, flush=True)
    for c in cases:
        out["mc"][c.name] = {"spec": c.spec, "truth": c.truth, "T": c.T, "reps": c.reps,
                             "settings": c.settings, "freq": c.freq,
                             "fits": [raw[c.name][r] for r in range(c.reps)]}
    if "hard" in args.cases:
        import hard_cases as hc

        cids = [cid for cid, _, _ in hc.cases(navchip=False)]
        if _navchip_csv().exists():
            cids += [f"navchip_{s}_{a}|{m}" for s in ("gyroscope", "accelerometer")
                     for a in "XYZ" for m in hc.NAVCHIP_MODELS]
        jobs = [(cid, w, args.n_random) for cid in cids for w in weightings]
        for cid, w, r in _map(_hard_unit, jobs, args.workers):
            out["hard"].setdefault(cid, {})[w] = r
        out["hard_n_random"] = args.n_random
        out["hard_stored"] = CI_WEIGHTS
    if "navchip" in args.cases and _navchip_csv().exists():
        jobs = [(s, a, w) for s in ("gyroscope", "accelerometer") for a in "XYZ"
                for w in weightings]
        for ch, w, r in _map(_navchip_unit, jobs, args.workers):
            out["navchip"].setdefault(ch, {})[w] = r
    return out


# -- tables -----------------------------------------------------------------------------------------
def mc_summary(case: dict, weightings: list[str]) -> dict[str, dict]:
    model = Model(case["spec"], case["freq"])
    theta = model.theta(case["truth"])
    scale_idx = {c.start + c.process.scale_index for c in model.components}
    out = {}
    for w in weightings:
        est = np.array([f[w]["params"] for f in case["fits"]])
        rel = est / theta - 1.0
        at0 = (est == 0.0).sum(axis=0)
        out[w] = {"bias": rel.mean(axis=0), "rmse": np.sqrt((rel**2).mean(axis=0)),
                  "at0": np.where([i in scale_idx for i in range(len(theta))], at0, -1),
                  "any0": int(np.any(est[:, sorted(scale_idx)] == 0.0, axis=1).sum()),
                  "nonconv": int(sum(not f[w]["converged"] for f in case["fits"]))}
    return out


def render(res: dict, header: str) -> str:
    ws = res["weightings"]
    ref = ws[0]
    lines = [header, ""]
    if res["mc"]:
        lines += [("Summary per Monte Carlo case: the geometric mean over the parameters of the "
                  f"relative RMSE as a ratio to `{ref}` (< 1: better), the largest such ratio "
                  "(its parameter), the replicates with some component at the boundary 0, and "
                  "fits not converged."), "",
                  "| case | T | R | " + " | ".join(f"`{w}` RMSE ratio (max) | `{w}` at 0"
                                                   for w in ws) + " |",
                  "|---|---|---|" + "---|---|" * len(ws)]
        for name, case in res["mc"].items():
            s = mc_summary(case, ws)
            model = Model(case["spec"], case["freq"])
            cells = []
            for w in ws:
                ratio = s[w]["rmse"] / s[ref]["rmse"]
                k = int(np.argmax(ratio))
                gm = float(np.exp(np.mean(np.log(ratio))))
                cells.append(f"{gm:.2f} ({ratio[k]:.2f} {model.param_names[k]})")
                nc = f", {s[w]['nonconv']} n.c." if s[w]["nonconv"] else ""
                cells.append(f"{s[w]['any0']}{nc}")
            lines.append(f"| {name} | {case['T']:.3g} | {case['reps']} | " + " | ".join(cells)
                         + " |")
        lines += ["", ("Per parameter: relative bias / relative RMSE / replicates with the "
                  "component at 0 (scale parameters only)."), ""]
        for name, case in res["mc"].items():
            s = mc_summary(case, ws)
            model = Model(case["spec"], case["freq"])
            theta = model.theta(case["truth"])
            sett = ", ".join(f"{k}={v}" for k, v in case["settings"].items()) or "defaults"
            lines += [(f"**{name}** ({case['spec']}, T = {case['T']:.3g}, R = {case['reps']}; "
                      f"fit: {sett})"), "",
                      "| parameter | truth | " + " | ".join(f"`{w}`" for w in ws) + " |",
                      "|---|---|" + "---|" * len(ws)]
            for i, pn in enumerate(model.param_names):
                cells = []
                for w in ws:
                    a0 = s[w]["at0"][i]
                    cells.append(f"{s[w]['bias'][i]:+.3f} / {s[w]['rmse'][i]:.3f}"
                                 + (f" / {a0}" if a0 >= 0 else ""))
                lines.append(f"| {pn} | {theta[i]:.4g} | " + " | ".join(cells) + " |")
            lines.append("")
    if res["hard"]:
        lines += [(f"Hard-case suite ({len(res['hard'])} cases, default fit per weighting): "
                  "cases whose objective is within 1e-6 (relative) of the best known for that "
                  "weighting, the largest relative excess, and component-boundary totals. Best "
                  f"known: `{res.get('hard_stored')}` the stored exhaustive search "
                  "(hard_cases_best.json, 256 random starts), the "
                  f"others {res.get('hard_n_random')} random projected starts + a 16-start fit "
                  "under the fit's final Omega."), "",
                  "| weighting | at best known | largest excess (case) | components at 0 |",
                  "|---|---|---|---|"]
        for w in ws:
            rows = [(cid, r[w]) for cid, r in res["hard"].items() if w in r]
            exc = [((r["objective"] - r["best"]) / r["best"], cid) for cid, r in rows]
            worst = max(exc)
            n_ok = sum(e <= 1e-6 for e, _ in exc)
            n0 = sum(len(r["at_zero"]) for _, r in rows)
            lines.append(f"| `{w}` | {n_ok}/{len(rows)} | {worst[0]:.1e} ({worst[1]}) | {n0} |")
        lines.append("")
    if res["navchip"]:
        lines += [(f"Navchip ({NAVCHIP_MODEL}, real WVs, the study's fit settings): per axis the "
                  f"estimates' differences from `{ref}` in `{ref}` standard errors (median and "
                  "largest |.|, its parameter), components at 0, GOF p-value."), "",
                  "| axis | " + " | ".join(f"`{w}` diff/SE (max) | `{w}` at 0 | `{w}` GOF p"
                                          for w in ws) + " |",
                  "|---|" + "---|---|---|" * len(ws)]
        for ch, r in res["navchip"].items():
            base = r[ref]
            p0, se0 = np.array(base["params"]), np.array(base["se"])
            cells = []
            for w in ws:
                d = (np.array(r[w]["params"]) - p0) / se0
                ad = np.where(np.isfinite(d), np.abs(d), 0.0)
                k = int(np.argmax(ad))
                cells.append("-" if w == ref else
                             f"{np.median(ad):.2f} ({d[k]:+.1f} {base['names'][k]})")
                cells.append(",".join(r[w]["at_zero"]) or "none")
                cells.append(f"{r[w]['p_value']:.2g}")
            lines.append(f"| {ch} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=[c for c in ALL_CASES if c != "toy"],
                    choices=ALL_CASES)
    ap.add_argument("--reps", type=int, default=None,
                    help="replicates of every Monte Carlo case (default: per case, see the table)")
    ap.add_argument("--T", type=int, default=2**16, help="length of the toy cases")
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS),
                    help="toy models")
    ap.add_argument("--weightings", nargs="+", default=list(WEIGHTINGS),
                    choices=["ci", *WEIGHTINGS, "gaussian"])
    ap.add_argument("--n-random", type=int, default=32,
                    help="random starts of the hard cases' best-known search (non-stored)")
    ap.add_argument("--workers", type=int, default=min(2, len(os.sched_getaffinity(0))))
    ap.add_argument("--json", type=Path, help="also store the raw fits here")
    ap.add_argument("--from-json", type=Path, help="render stored fits instead of running")
    ap.add_argument("--write", action="store_true",
                    help="write the tables into benchmarks/README.md")
    args = ap.parse_args()
    from readme_section import load, machine, update_section

    if args.from_json:
        res = json.loads(args.from_json.read_text())
    else:
        load0, t0 = load(), time.perf_counter()
        res = run(args)
        cpu = sum(getattr(resource.getrusage(who), f)
                  for who in (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
                  for f in ("ru_utime", "ru_stime"))
        res["run"] = {"command": "python benchmarks/bench_ci_weights.py " + " ".join(sys.argv[1:]),
                      "machine": machine(), "wall": time.perf_counter() - t0, "cpu": cpu,
                      "load_before": load0, "load_after": load(), "workers": args.workers}
        if args.json:
            args.json.write_text(json.dumps(res) + "\n")
    r = res["run"]
    header = (f"Generated by `{r['command']}` ({r['machine']}; {r['wall']:.0f} s wall, "
              f"{r['cpu']:.0f} s CPU, {r['workers']} worker(s), load average {r['load_before']} "
              f"before, {r['load_after']} after). Seeds fixed: every weighting fits the same "
              "replicates.")
    text = render(res, header)
    print(text)
    if args.write:
        update_section("bench_ci_weights", text)


if __name__ == "__main__":
    main()
