"""Selection penalty calibration: is the generating model ranked first where its components are
real, and which penalty factor k of ``objective + k * optimism`` does it?

    python benchmarks/selection_penalty.py [--reps 100] [--lengths 14 17 20] [--jobs 1]
        [--settings LABEL ...] [--evidence R] [--write]

Design. Generating models typical of gyroscopes and accelerometers (:func:`settings`), each
weak component set to an *expected* z-value of 4 at every length where that is reachable (scale
parameter / its sandwich SE at the truth; ``bench_selection.calibrate``; where the z-value
saturates below 4 at a length, e.g. a random walk beside a slow AR1 in a short record, the base
value is kept), so that most replicates hold it at 3 SE or more and some do not. Each replicate is
ranked once (:func:`gmwm.select.rank_models`: CI weights,
the goodness-of-fit test on every candidate, accepted candidates first) over the candidates one
component away from the generating model; the pick of each penalty factor is read off the same
fits. The generating model is then refitted with :func:`gmwm.fit`'s defaults and its
components' *realised* z-values (scale estimate / standard error) sort the replicate:

* "qualifying": every component of the generating model is >= 3 SE from 0 in that fit. The
  target: the generating model ranked first in >= 90 % of the qualifying replicates of every
  (model, length) cell;
* the others (a component below 3 SE): reported, not targeted (no rule can both keep a
  component the data hardly see and refuse spurious ones).
* "qualifying, z + shown" (a second column, the same replicates narrowed): in addition, for each
  component whose z-value is not a detection statistic (:data:`NONREGULAR`: a sinusoid's
  amplitude, a GM's or AR1's variance: at scale 0 the frequency, beta or phi is not identified,
  the fit maximises over it, and |scale| / SE is inflated where the data hold no such component),
  the candidate without it is rejected by the goodness-of-fit test at the library's level
  (:data:`gmwm.gof.ALPHA`, 1 %): the data show it.
  A component the test cannot tell from its absence is one no criterion can be asked to keep.

``--evidence R`` tabulates what the data say about each non-regular component: among the
z-qualifying replicates, the share whose model without it passes the goodness-of-fit test, the
objective drop D = objective(without) - objective(with), and D's 95 % quantile under R
replicates simulated without it (the other components at their generating values; both models
fitted): a likelihood-ratio-type check calibrated by simulation, beside the test-based column.

Rules (:data:`RULES`), each read off the same fits: the criterion alone (accepted candidates
first; the ranking before the parsimony step), the library's rule (:func:`gmwm.select.order`:
then the first-ranked candidate loses each SIN/GM/AR1 component whose removal gives a candidate
the goodness-of-fit test accepts) and, for comparison, that step on every component type.

Reported: per cell, rule and penalty, the hit rate among qualifying replicates with its Monte
Carlo SE, and the confusion tables of the chosen penalties under the library's rule (what was
picked instead: a component dropped, one added, other). Each replicate's ranked candidates
(objective, penalty, p-value) and z-values are cached in ``--cache`` (default
``benchmarks/selection_penalty.json``, keyed by the cell's generating values and candidates), so
a rerun with another rule or penalty costs no fit; ``--refit`` ignores it (after a change of the
estimator). ``--write`` replaces this benchmark's section of ``benchmarks/README.md``.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_selection as bs

import gmwm
from gmwm.atomic import write_json_atomic
from gmwm.gof import ALPHA as GOF_ALPHA
from gmwm.model import Model, parse_model, spec_of
from gmwm.processes import PROCESSES
from gmwm.select import PARSIMONY, RankedModel, order, rank_models
from gmwm.wv import wvar

#: penalty factors compared: constants and the named criteria's (gmwm.criteria)
PENALTIES = {"k=2 (wic)": lambda T: 2.0, "k=3": lambda T: 3.0, "k=4": lambda T: 4.0,
             "k=2loglogT (wic-hq)": lambda T: 2.0 * math.log(math.log(T)),
             "k=logT (wic-log)": lambda T: math.log(T)}
Z_EXPECTED = 4.0
Z_QUALIFY = 3.0
#: components whose z-value is not a detection statistic: at scale 0 their shape parameter (a
#: sinusoid's frequency, a GM's beta, an AR1's phi) is not identified, the fit maximises over it,
#: and |scale| / SE is inflated under "no such component" (a non-regular test, Davies' problem)
NONREGULAR = ("SIN", "GM", "AR1")
#: level of the "the data show it" qualifier (the goodness-of-fit test of the model without it):
#: the library's, at which the ranking splits
ALPHA_SHOWN = GOF_ALPHA
#: ranking rules compared on the same fits, as (component types of the parsimony step, level of
#: the goodness-of-fit test): the criterion alone (accepted candidates first; the rule before the
#: parsimony step), the library's rule (:func:`gmwm.select.order`: the parsimony step on
#: SIN/GM/AR1) and, for comparison, the step on every component type, and the library's rule with
#: the test at 5 % (the library's level before 2026-11-29: a test that rejects true models
#: more often)
RULES = {"criterion only": ((), GOF_ALPHA), "parsimony (library)": (PARSIMONY, GOF_ALPHA),
         "parsimony, every component": (tuple(PROCESSES), GOF_ALPHA),
         "parsimony, test at 5 %": (PARSIMONY, 0.05)}
#: the rule the target is judged on (the library's)
LIBRARY_RULE = "parsimony (library)"
#: per-replicate results (the ranked candidates' objective, penalty, p-value; the z-values):
#: a rerun with the same settings reads them instead of refitting
CACHE = HERE / "selection_penalty.json"


@dataclass(frozen=True)
class Setting:
    label: str
    spec: str
    base: dict[str, float]
    weak: tuple[str, ...]          # components calibrated to Z_EXPECTED
    freq: float = 1.0

    def truth(self, T: int) -> tuple[Model, np.ndarray]:
        model = Model(self.spec, self.freq)
        theta = model.theta(self.base)
        for comp in self.weak:
            try:
                theta = bs.calibrate(model, theta, comp, Z_EXPECTED, T)
            except ValueError:  # saturated at this length: the base value, the filter decides
                pass
        return model, theta


def settings() -> list[Setting]:
    """Seven IMU-like generating models (gyroscope: WN + bias instability as GM/AR1 + RW, a slow
    sinusoid; accelerometer: WN + RW, quantization; a short-record model without RW)."""
    wn_rw = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}
    return [
        Setting("accel WN+RW", "WN+RW", wn_rw, ("RW[1]",)),
        Setting("accel QN+WN+RW", "QN+WN+RW", {"QN[1].Q2": 0.3, **wn_rw}, ("QN[1]", "RW[1]")),
        Setting("gyro WN+AR1+RW", "WN+AR1+RW", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995,
                                                 "AR1[1].sigma2": 2e-3, "RW[1].gamma2": 1e-6},
                ("RW[1]",)),
        Setting("gyro WN+GM+RW (100 Hz)", "WN+GM+RW", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
            "RW[1].gamma2": 1e-9}, ("GM[1]", "RW[1]"), 100.0),
        Setting("gyro WN+2*GM+RW (100 Hz)", "WN+2*GM+RW", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 5.0, "GM[1].sigma2": 2e-6, "GM[2].beta": 0.05,
            "GM[2].sigma2": 1e-6, "RW[1].gamma2": 1e-10}, ("GM[1]", "GM[2]", "RW[1]"), 100.0),
        Setting("gyro WN+SIN+RW", "WN+SIN+RW", {
            "WN[1].sigma2": 1.0, "SIN[1].alpha": 0.1, "SIN[1].beta": 2 * math.pi / 2000,
            "RW[1].gamma2": 1e-6}, ("SIN[1]", "RW[1]")),
        Setting("short WN+GM (100 Hz)", "WN+GM", {
            "WN[1].sigma2": 1e-4, "GM[1].beta": 1.0, "GM[1].sigma2": 1e-6}, ("GM[1]",), 100.0),
    ]


def realised_z(result) -> list[float]:
    """|scale estimate| / SE of every component of a fit (0 at the boundary, NaN: no SE)."""
    theta, se = np.asarray(result.params, float), np.asarray(result.se, float)
    out = []
    for c in result.model.components:
        i = c.start + c.process.scale_index
        out.append(0.0 if theta[i] == 0 else
                   float(abs(theta[i]) / se[i]) if np.isfinite(se[i]) and se[i] > 0 else np.nan)
    return out


def pick(entries, k: float, parsimony: tuple[str, ...] = (), alpha: float = GOF_ALPHA) -> str:
    """The first-ranked model under penalty factor k by the library's ordering
    (:func:`gmwm.select.order`: candidates the test accepts at ``alpha`` first, by criterion,
    near ties to fewer parameters; then the parsimony step on the component types
    ``parsimony``, none: off)."""
    rebuilt = [RankedModel(e.model, e.objective + k * e.penalty, e.objective, e.penalty,
                           e.n_params, e.converged, p_value=e.p_value) for e in entries]
    return order(rebuilt, alpha, parsimony)[0][0].model


def stored(entries) -> list[list]:
    """The cached form of ranked candidates: [model, objective, penalty, n_params, converged,
    p_value] (non-finite numbers as None)."""
    def num(v: float) -> float | None:
        return float(v) if np.isfinite(v) else None

    return [[e.model, num(e.objective), num(e.penalty), int(e.n_params), bool(e.converged),
             num(e.p_value)] for e in entries]


def restored(rows: list[list]) -> list[RankedModel]:
    def num(v: float | None) -> float:
        return float("nan") if v is None else float(v)

    return [RankedModel(m, np.nan, num(o), num(p), n, c, p_value=num(pv))
            for m, o, p, n, c, pv in rows]


def picks_of(entries, T: int) -> dict[tuple[str, str], str]:
    return {(rule, name): pick(entries, f(T), kinds, alpha)
            for rule, (kinds, alpha) in RULES.items() for name, f in PENALTIES.items()}


def dropped_spec(spec: str, kind: str) -> dict[str, int]:
    """Component counts of ``spec`` with one ``kind`` component removed."""
    counts = dict(parse_model(spec))
    counts[kind] -= 1
    return {k: v for k, v in counts.items() if v > 0}


def drop_evidence(entries, spec: str) -> dict[str, tuple[float, float, float]]:
    """Per non-regular component type of ``spec``: (D, p, dpen) where D = objective(spec without
    one such component) - objective(spec), p is the goodness-of-fit p-value of the model without
    it and dpen = penalty(spec) - penalty(without) (the criterion keeps the component when
    D > k * dpen), read off the ranked candidates (NaN when that candidate is missing or
    failed)."""
    full = next((e for e in entries if parse_model(e.model) == parse_model(spec)), None)
    out = {}
    for kind in parse_model(spec):
        if kind not in NONREGULAR:
            continue
        sub = next((e for e in entries if parse_model(e.model) == dropped_spec(spec, kind)), None)
        out[kind] = ((sub.objective - full.objective, sub.p_value, full.penalty - sub.penalty)
                     if sub and full else (np.nan, np.nan, np.nan))
    return out


def replicate(args: tuple[Setting, int, int]) -> dict:
    """Rank replicate r of a cell and refit its generating model: the cached record (ranked
    candidates as :func:`stored`, realised z-values)."""
    setting, T, r = args
    model, theta = setting.truth(T)
    cands = bs.candidates(model.spec)
    key = sum(map(ord, setting.label))
    x = model.simulate_fast(theta, T, np.random.default_rng([2040, key, T, r]))
    wv = wvar(x, freq=setting.freq)
    ranking = rank_models(wv, cands, parsimony=())
    z = realised_z(gmwm.fit(wv, model.spec))
    return {"entries": stored(ranking.ranked), "z": [None if np.isnan(v) else v for v in z]}


def judge(setting: Setting, T: int, record: dict) -> dict:
    """Picks of every rule and penalty and the qualifiers of one cached replicate."""
    entries = restored(record["entries"])
    z = np.array([np.nan if v is None else v for v in record["z"]], dtype=float)
    qualifies = bool(np.all(np.nan_to_num(z) >= Z_QUALIFY))
    evidence = drop_evidence(entries, setting.spec)
    # second qualifier: also, the model without each non-regular component is rejected by the
    # goodness-of-fit test (the data show that component; a missing test does not qualify)
    shown = qualifies and all(ev[1] < ALPHA_SHOWN for ev in evidence.values())
    gen = next((e for e in entries if parse_model(e.model) == parse_model(setting.spec)), None)
    # no rule ranks the generating model first where the test rejects it (or it failed)
    gen_rejected = gen is None or gen.rejected(ALPHA_SHOWN)
    return {"picks": picks_of(entries, T), "z": z, "qualifies": qualifies, "shown": shown,
            "shown_acc": shown and not gen_rejected, "evidence": evidence,
            "gen_rejected": gen_rejected}


def cell_key(setting: Setting, T: int) -> str:
    """Cache key of a cell: label, length, and the generating values and candidates (a changed
    setting is refitted)."""
    model, theta = setting.truth(T)
    return (f"{setting.label}|{T}|{setting.freq:g}|"
            + ",".join(f"{v:.12g}" for v in theta) + "|" + ",".join(bs.candidates(model.spec)))


def load_cache(path: Path) -> tuple[dict, dict]:
    """(cells: key -> {replicate: record}, timing: key -> {seconds, n, load} of the run that
    fitted them)."""
    import json

    try:
        got = json.loads(path.read_text())
    except FileNotFoundError:
        return {}, {}
    return got.get("cells", {}), got.get("timing", {})


def null_drop(args: tuple[Setting, int, int, str]) -> tuple[float, float, float, float]:
    """(D, p, dpen, z) on a replicate simulated *without* one ``kind`` component (the generating
    values of the others; its last ``kind`` component removed): D = objective(without) -
    objective(with) is one draw of D's null distribution, p the goodness-of-fit p-value of the
    (true) model without it, dpen as in :func:`drop_evidence`, z the realised z-value of that
    (absent) component in the fit with it. Both fits as in :func:`replicate`."""
    setting, T, r, kind = args
    model, theta = setting.truth(T)
    counts = dropped_spec(model.spec, kind)
    n_kind = parse_model(model.spec)[kind]
    drop = f"{kind}[{n_kind}]."
    sub = Model(spec_of(counts), setting.freq)
    vals = {n: v for n, v in model.as_dict(theta).items() if not n.startswith(drop)}
    key = sum(map(ord, setting.label))
    x = sub.simulate_fast(sub.theta(vals), T, np.random.default_rng([2041, key, T, r]))
    ranking = rank_models(wvar(x, freq=setting.freq), [model.spec, sub.spec])
    full = next((e for e in ranking.ranked if e.model == model.spec), None)
    z = (realised_z(full.result)[[c.name for c in model.components].index(f"{kind}[{n_kind}]")]
         if full is not None else np.nan)
    return (*drop_evidence(ranking.ranked, model.spec)[kind], z)


def describe(gen: str, got: str) -> str:
    if got == gen:
        return "generating"
    cg, cs = parse_model(gen), parse_model(got)
    drop = [k for k in cg if cs.get(k, 0) < cg[k]]
    add = [k for k in cs if cs[k] > cg.get(k, 0)]
    parts = [f"drops {'+'.join(drop)}"] if drop else []
    parts += [f"adds {'+'.join(add)}"] if add else []
    return ", ".join(parts) or got


#: "z + shown, gen. accepted" narrows "z + shown" to the replicates whose generating model the test
#: accepts: what the ranking rule gets right where the test's size does not decide for it
QUALIFIERS = {"z": "qualifies", "z + shown": "shown", "z + shown, gen. accepted": "shown_acc"}


def evidence_rows(s: Setting, kexp: int, reps: list[dict], null_reps: int, pool) -> list[tuple]:
    """Per non-regular component of ``s``: (label, 2^k, kind, n qualifying by z, share of them
    whose model without it passes the goodness-of-fit test, quartiles of D over them, D's null
    95 % quantile from ``null_reps`` replicates without it, share of them with D above it, the
    number of null replicates, the test's rejection rate of the true model among them, and the
    hit rates of the penalties among the z-qualifying replicates with D above the quantile)."""
    T = 2**kexp
    q = [rep for rep in reps if rep["qualifies"]]
    out = []
    for kind in reps[0]["evidence"]:
        work = [(s, T, r, kind) for r in range(null_reps)]
        draws = np.array(list(pool.map(null_drop, work)) if pool
                         else list(map(null_drop, work)))
        null, size = draws[:, 0], float(np.mean(draws[:, 1] < ALPHA_SHOWN))
        z_null = float(np.mean(np.nan_to_num(draws[:, 3]) >= Z_QUALIFY))
        # the criterion's own false-inclusion rate: null replicates where it keeps the component
        spurious = {name: float(np.mean(draws[:, 0] > f(T) * draws[:, 2]))
                    for name, f in PENALTIES.items()}
        q95 = float(np.nanquantile(null, 0.95))
        d = np.array([rep["evidence"][kind][0] for rep in q])
        p = np.array([rep["evidence"][kind][1] for rep in q])
        above = [rep for rep, di in zip(q, d, strict=True) if di > q95]
        hits = {name: (np.mean([rep["picks"][("criterion only", name)] == s.spec
                                for rep in above]) if above else np.nan) for name in PENALTIES}
        out.append((s.label, kexp, kind, len(q),
                    float(np.mean(p >= ALPHA_SHOWN)) if q else np.nan,
                    np.nanquantile(d, [0.25, 0.5, 0.75]) if q else [np.nan] * 3, q95,
                    float(np.mean(d > q95)) if q else np.nan, len(null), size, hits, z_null,
                    spurious))
        print(f"{s.label:<28} T=2^{kexp} {kind}: null D q95 {q95:.3g}  "
              f"qualifying D > q95 {out[-1][7]:.2f}", flush=True)
    return out


def evidence_table(rows: list[tuple]) -> list[str]:
    lines = [("Evidence for each non-regular component (replicates qualifying by z): the share "
              f"whose model without it passes the goodness-of-fit test at {ALPHA_SHOWN:g}; the "
              "objective drop D = objective(without) - objective(with); D's 95 % quantile when the data "
              "hold no such component (R replicates simulated without it at the generating "
              "values of the others, both models fitted; beside it the share of those where the "
              "test rejects the true model without it: the size of the \"shown\" qualifier); "
              "the share of qualifying replicates whose D exceeds it, and the hit rate of each "
              "penalty among those (a likelihood-ratio-type qualifier calibrated by simulation). "
              "Under the null also: the share of fits with the (absent) component where its "
              "z-value is >= 3, and per penalty the share where D > k * (penalty difference), "
              "i.e. the criterion alone would keep the absent component."),
             "", ("| generating model | T | component | qualifying (z) | without it passes GOF | "
                  "D quartiles | null D q95 (R; GOF size) | D > null q95 | hit among them | "
                  "null: z >= 3 | null: criterion keeps it |"),
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for label, kexp, kind, nq, passes, dq, q95, above, nn, size, hits, zn, spur in rows:
        hit = ", ".join(f"{n.split(' ')[0]} {h:.2f}" for n, h in hits.items()
                        if np.isfinite(h)) or "–"
        keeps = ", ".join(f"{n.split(' ')[0]} {v:.2f}" for n, v in spur.items())
        lines.append(f"| {label} | 2^{kexp} | {kind} | {nq} | {passes:.2f} | "
                     + " / ".join(f"{v:.3g}" for v in dq) + f" | {q95:.3g} ({nn}; {size:.2f}) | "
                     f"{above:.2f} | {hit} | {zn:.2f} | {keeps} |")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=100)
    ap.add_argument("--lengths", type=int, nargs="+", default=[14, 17, 20], metavar="K")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--settings", nargs="+", default=None)
    ap.add_argument("--chosen", nargs="+", default=["k=2 (wic)", "k=2loglogT (wic-hq)"],
                    help="penalties of the confusion tables (under the library's rule)")
    ap.add_argument("--evidence", type=int, default=0, metavar="R",
                    help="also simulate R replicates without each non-regular component (null "
                         "distribution of the objective drop D) and tabulate the evidence")
    ap.add_argument("--cache", type=Path, default=CACHE,
                    help=f"per-replicate results, read and extended (default {CACHE.name})")
    ap.add_argument("--refit", action="store_true", help="ignore the cache (it is rewritten)")
    ap.add_argument("--write", action="store_true")
    args = ap.parse_args()
    chosen = [s for s in settings() if args.settings is None or s.label in args.settings]
    t0, cpu0 = time.perf_counter(), time.process_time()
    rows, confusion, skipped, ev_rows = [], {}, [], []
    cache, timing = ({}, {}) if args.refit else load_cache(args.cache)
    n_fitted, keys = 0, []
    pool = ProcessPoolExecutor(args.jobs) if args.jobs > 1 else None
    try:
        for s in chosen:
            for kexp in args.lengths:
                T = 2**kexp
                try:
                    s.truth(T)
                except ValueError as err:
                    skipped.append(f"{s.label} at T = 2^{kexp}: {err}")
                    print(f"{s.label} T=2^{kexp}: skipped: {err}", flush=True)
                    continue
                key = cell_key(s, T)
                keys.append(key)
                got = cache.setdefault(key, {})
                work = [(s, T, r) for r in range(args.reps) if str(r) not in got]
                if work:
                    t1 = time.perf_counter()
                    records = list(pool.map(replicate, work)) if pool else \
                        list(map(replicate, work))
                    got.update({str(w[2]): rec for w, rec in zip(work, records, strict=True)})
                    n_fitted += len(work)
                    before = timing.get(key, {"seconds": 0.0, "n": 0, "load": []})
                    timing[key] = {"seconds": before["seconds"] + time.perf_counter() - t1,
                                   "n": before["n"] + len(work),
                                   "load": [*before["load"], round(os.getloadavg()[0], 1)]}
                    # after every cell: an interrupted run keeps what it fitted
                    write_json_atomic(args.cache, {"commit": bs.commit(), "cells": cache,
                                                   "timing": timing}, indent=None)
                reps = [judge(s, T, got[str(r)]) for r in range(args.reps)]
                for qname, field in QUALIFIERS.items():
                    q = [rep for rep in reps if rep[field]]
                    for rule in RULES:
                        hits = {name: (np.mean([rep["picks"][(rule, name)] == s.spec
                                                for rep in q]) if q else np.nan)
                                for name in PENALTIES}
                        rows.append((s, kexp, qname, rule, len(reps), len(q), hits,
                                     sum(rep["gen_rejected"] for rep in q)))
                        print(f"{s.label:<28} T=2^{kexp} [{qname}; {rule}]: qualifying "
                              f"{len(q)}/{len(reps)}  "
                              + "  ".join(f"{n} {h:.2f}" for n, h in hits.items()), flush=True)
                    for name in args.chosen:
                        confusion[(s.label, kexp, qname, name)] = Counter(
                            describe(s.spec, rep["picks"][(LIBRARY_RULE, name)]) for rep in q)
                if args.evidence and reps[0]["evidence"]:
                    ev_rows += evidence_rows(s, kexp, reps, args.evidence, pool)
    finally:
        if pool:
            pool.shutdown()
    lines = table(rows, confusion)
    if skipped:
        lines += ["", "Not reachable (skipped): " + "; ".join(skipped) + "."]
    if ev_rows:
        lines += [""] + evidence_table(ev_rows)
    print("\n".join(lines))
    timed = [timing[k] for k in keys if k in timing]
    fit_s, fit_n = sum(t["seconds"] for t in timed), sum(t["n"] for t in timed)
    loads = [v for t in timed for v in t["load"]]
    untimed = sum(len(cache[k]) for k in keys) - fit_n
    print(f"fits: {fit_s:.0f} s wall for {fit_n} replicates (1-minute load after each cell "
          f"{min(loads, default=np.nan):.1f}-{max(loads, default=np.nan):.1f}); {untimed} "
          f"replicates without a recorded time; this run fitted {n_fitted}", flush=True)
    if args.write:
        ev = f" --evidence {args.evidence}" if args.evidence else ""
        head = (f"Generated by `python benchmarks/selection_penalty.py --reps {args.reps} "
                f"--lengths {' '.join(map(str, args.lengths))} --jobs {args.jobs}{ev} --write` "
                f"(commit {bs.commit()}; the fits, cached in `benchmarks/{args.cache.name}`: "
                f"{fit_s:.0f} s wall for {fit_n} replicates at a 1-minute load of "
                f"{min(loads, default=np.nan):.1f}-{max(loads, default=np.nan):.1f} after each "
                f"cell" + (f", {untimed} more without a recorded time" if untimed else "")
                + f"; this run fitted {n_fitted} and took {time.perf_counter() - t0:.0f} s wall, "
                f"{time.process_time() - cpu0:.0f} s CPU in the main process). Weak "
                f"components at an expected z of {Z_EXPECTED:g}. Two qualifiers: \"z\", every "
                f"component of the generating model is >= {Z_QUALIFY:g} SE from 0 in its "
                "default fit (the issue's); \"z + shown\", in addition the model without each "
                "component whose z-value is not a detection statistic "
                f"({', '.join(NONREGULAR)}: at scale 0 its frequency, beta or phi is not "
                "identified, the fit maximises over it and |scale| / SE is inflated) is rejected "
                f"by the goodness-of-fit test at {ALPHA_SHOWN:g} (the data show that component; "
                "the target is judged on this one). hit = share of qualifying replicates "
                "ranking the generating model first (MC SE in brackets); candidates one "
                "component away; every rule ranks the candidates the goodness-of-fit test "
                f"accepts at {GOF_ALPHA:g} first. Rules, on the same fits: \"criterion only\" "
                "(before the parsimony step), \"parsimony (library)\" (`gmwm.select.order`: the "
                "first-ranked candidate loses each SIN/GM/AR1 whose removal gives an accepted "
                "candidate), \"parsimony, every component\" (the same step on every component "
                "type), \"parsimony, test at 5 %\" (the library's rule with the test's level "
                "at 0.05 for both the split and the step, the library's level before 2026-11-29: "
                "a test rejecting true models more often). \"gen. rejected\": qualifying "
                f"replicates whose generating model the test rejects at {ALPHA_SHOWN:g}, which no "
                "rule at that level can rank first "
                "(the test's size, issue 40 item 6); the qualifier \"z + shown, gen. "
                "accepted\" leaves them out.\n")
        bs.write_section(head + "\n" + "\n".join(lines), "selection_penalty")


def table(rows, confusion) -> list[str]:
    names = list(PENALTIES)
    lines = ["| generating model | T | qualifier | rule | qualifying / R | gen. rejected | "
             + " | ".join(names) + " |", "|" + "---|" * (6 + len(names))]
    for s, kexp, qname, rule, n, nq, hits, n_rej in rows:
        cells = []
        for name in names:
            h = hits[name]
            cells.append("–" if not np.isfinite(h) else
                         f"{h:.2f} ({math.sqrt(h * (1 - h) / nq):.2f})")
        lines.append(f"| {s.label} | 2^{kexp} | {qname} | {rule} | {nq} / {n} | {n_rej} | "
                     + " | ".join(cells) + " |")
    lines += ["", "Lowest hit rate over the cells:", "",
              "| qualifier | rule | " + " | ".join(names) + " |",
              "|" + "---|" * (2 + len(names))]
    for qname in QUALIFIERS:
        for rule in RULES:
            worst = [min((r[6][name] for r in rows if r[2] == qname and r[3] == rule
                          and np.isfinite(r[6][name])), default=np.nan) for name in names]
            lines.append(f"| {qname} | {rule} | " + " | ".join(f"{w:.2f}" for w in worst)
                         + " |")
    for name in dict.fromkeys(k[3] for k in confusion):
        lines += ["", (f"Confusion of `{name}` under the library's rule ({LIBRARY_RULE}; "
                       "qualifying replicates: what was ranked first):"), "",
                  "| generating model | T | qualifier | picks |", "|---|---|---|---|"]
        for (label, kexp, qname, nm), cnt in confusion.items():
            if nm != name:
                continue
            total = sum(cnt.values())
            picks = "; ".join(f"{what} {c / total:.2f}" for what, c in cnt.most_common())
            lines.append(f"| {label} | 2^{kexp} | {qname} | {picks} |")
    return lines


if __name__ == "__main__":
    sys.exit(main())
