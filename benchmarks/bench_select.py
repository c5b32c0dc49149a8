"""Benchmark: how often model selection (gmwm.select.rank_models) picks the generating model.

Run: ``python benchmarks/bench_select.py [--reps 20] [--lengths 14 17 20] [--ring 1]``.
For each generating model and length T = 2^k, ``reps`` seeded signals are simulated; each is
ranked over the candidate set :func:`gmwm.select.auto_candidates` of the generating model
(``--ring 1``: only the candidates one component away - one removed or one added -, the default
to keep the run short; ``--ring 2``: the full automatic set, two removals too). Both criteria are
read off the same fits: WIC (penalty factor 2) and WIC-log (factor log T). Prints one Markdown
row per (model, T): hit rates, the most frequent wrong pick, and the median seconds per
replicate (WV + all candidate fits).
"""

from __future__ import annotations

import argparse
import collections
import time

import numpy as np

import gmwm
from gmwm.model import Model, parse_model
from gmwm.select import auto_candidates, rank_models, rerank

_TWO_AR1 = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.95, "AR1[1].sigma2": 0.02,
            "AR1[2].phi": 0.999, "AR1[2].sigma2": 4e-5}
# label -> (generating model, parameters)
SCENARIOS = {
    "WN+RW": ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4}),
    "WN+AR1": ("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995, "AR1[1].sigma2": 1e-3}),
    "QN+WN+RW": ("QN+WN+RW", {"QN[1].Q2": 1.0, "WN[1].sigma2": 0.1, "RW[1].gamma2": 1e-6}),
    # the RW reaches 32 % of the WV only at level 19 (T = 2^20): not identifiable here
    "WN+2*AR1+RW(1e-9)": ("WN+2*AR1+RW", {**_TWO_AR1, "RW[1].gamma2": 1e-9}),
    "WN+AR1+SIN": ("WN+AR1+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.995,
                                  "AR1[1].sigma2": 1e-3, "SIN[1].alpha": 0.3,
                                  "SIN[1].beta": 0.1}),
    # the RW dominates from level 16 on (last, so the seeds of the others do not move)
    "WN+2*AR1+RW": ("WN+2*AR1+RW", {**_TWO_AR1, "RW[1].gamma2": 1e-7}),
}


def distance(a: str, b: str) -> int:
    ca, cb = parse_model(a), parse_model(b)
    return sum(abs(ca.get(k, 0) - cb.get(k, 0)) for k in set(ca) | set(cb))


def run(spec: str, truth: dict, k: int, reps: int, ring: int, sid: int) -> dict:
    model = Model(spec)
    theta = model.theta(truth)
    cands = [c for c in auto_candidates(spec) if distance(c, spec) <= ring]
    T = 2**k
    hits = {"wic": 0, "wic-log": 0}
    wrong = {"wic": collections.Counter(), "wic-log": collections.Counter()}
    secs, failed = [], 0
    for r in range(reps):
        rng = np.random.default_rng(np.random.SeedSequence([2026, sid, k, r]))
        x = model.simulate(theta, T, rng)
        t0 = time.perf_counter()
        ranking = rank_models(gmwm.wvar(x), cands)
        secs.append(time.perf_counter() - t0)
        failed += len(ranking.skipped)
        for crit in ("wic", "wic-log"):
            best = rerank(ranking, crit).best
            if best.model == model.spec:
                hits[crit] += 1
            else:
                wrong[crit][best.model] += 1
    return {"cands": len(cands), "hits": hits, "wrong": wrong, "secs": secs, "failed": failed}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--lengths", type=int, nargs="+", default=[14, 17, 20], metavar="K",
                    help="signal lengths T = 2^K")
    ap.add_argument("--ring", type=int, default=1, choices=(1, 2))
    ap.add_argument("--models", nargs="+", default=list(SCENARIOS))
    args = ap.parse_args()
    print("| generating model | T | candidates | reps | WIC hits | WIC-log hits | "
          "most frequent wrong pick (WIC / WIC-log) | median s per replicate |")
    print("|---|---|---|---|---|---|---|---|")
    t_all = time.perf_counter()
    for sid, label in enumerate(SCENARIOS):
        if label not in args.models:
            continue
        spec, truth = SCENARIOS[label]
        for k in args.lengths:
            res = run(spec, truth, k, args.reps, args.ring, sid)
            w = [(f"{c.most_common(1)[0][0]} ({c.most_common(1)[0][1]})" if c else "-")
                 for c in res["wrong"].values()]
            print(f"| {label} | 2^{k} | {res['cands']} | {args.reps} | {res['hits']['wic']} | "
                  f"{res['hits']['wic-log']} | {w[0]} / {w[1]} | "
                  f"{np.median(res['secs']):.2f} |"
                  + (f" ({res['failed']} candidate fits skipped)" if res["failed"] else ""),
                  flush=True)
    print(f"\ntotal {time.perf_counter() - t_all:.0f} s")


if __name__ == "__main__":
    main()
