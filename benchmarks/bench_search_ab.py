"""A/B of the GMWM search between two source trees on simulated WVs of the study models.

The hard-case suite (hard_cases.py) checks the default against an exhaustive search on 34 cases;
this script checks a changed search against the previous one on many replicates of the models the
studies fit, with their settings (n_starts 8, CI and efficient weights, ARMAV, single model):

    python benchmarks/bench_search_ab.py make  wvs.pkl              # simulate the WVs once
    PYTHONPATH=<tree A>/src python benchmarks/bench_search_ab.py fit wvs.pkl a.json
    PYTHONPATH=<tree B>/src python benchmarks/bench_search_ab.py fit wvs.pkl b.json
    python benchmarks/bench_search_ab.py compare a.json b.json

``compare`` prints per model and setting how often B ends above A's objective (by > 1e-6
relative), how often below, and the median CPU time per fit of each. With efficient weights the
objective depends on the first step's estimate, so A and B minimise different functions there.
"""

from __future__ import annotations

import json
import pickle
import sys
import time
from collections import defaultdict

import numpy as np

#: name -> (model, truth, T, freq)
CASES = {
    "sim2": ("2*AR1+2*SIN", {"AR1[1].phi": 0.1107083, "AR1[1].sigma2": 0.0005278666,
                             "AR1[2].phi": 0.999995, "AR1[2].sigma2": 3e-11,
                             "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
                             "SIN[2].alpha": 0.0015, "SIN[2].beta": 8e-06}, 2**20, 1.0),
    "sim3": ("AR1+RW+WN+SIN", {"WN[1].sigma2": 0.0008, "AR1[1].phi": 0.9997083,
                               "AR1[1].sigma2": 9e-06, "SIN[1].alpha": 0.025,
                               "SIN[1].beta": 0.056, "RW[1].gamma2": 3e-11}, 2**20, 1.0),
    "sim1": ("WN+RW+AR1+SIN", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                               "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35,
                               "RW[1].gamma2": 0.0004}, 40000, 1.0),
    "misspec": ("AR1+RW+2*SIN", {"AR1[1].phi": 0.1851173, "AR1[1].sigma2": 0.03559081,
                                 "SIN[1].alpha": 0.3235864, "SIN[1].beta": 1.199147,
                                 "SIN[2].alpha": 0.1359012, "SIN[2].beta": 0.1357501,
                                 "RW[1].gamma2": 8.692479e-10}, 2**20, 1.0),
    "accel": ("QN+WN+RW+DR", {"QN[1].Q2": 2.0025625e-07, "WN[1].sigma2": 1.5340277777777778e-4,
                              "RW[1].gamma2": 1.6222993827160493e-10,
                              "DR[1].omega": 1.2777777777777777e-08}, 2**20, 250.0),
}

#: name -> fitted (model, settings) as the studies fit them
FITS = {
    "sim2": [("2*AR1+2*SIN", {"n_starts": 8}),
             ("2*AR1+2*SIN", {"n_starts": 8, "weights": "efficient"})],
    "sim3": [("AR1+RW+WN+SIN", {"n_starts": 8}),
             ("AR1+RW+WN+SIN", {"n_starts": 8, "weights": "efficient"}),
             ("AR1+RW+WN+SIN", {})],
    "sim1": [("WN+RW+AR1+SIN", {"n_starts": 8, "nested": False})],
    "misspec": [("AR1+RW", {"n_starts": 8}), ("AR1+RW+2*SIN", {"n_starts": 8})],
    "accel": [("QN+WN+RW+DR", {"method": "armav", "n_starts": 1}),
              ("QN+WN+RW+DR", {"method": "armav", "weights": "identity", "n_starts": 1}),
              ("WN+RW", {"method": "armav", "n_starts": 1})],
}


def make(path: str, reps: int = 20) -> None:
    import gmwm
    from gmwm.model import Model

    out = {}
    for name, (spec, truth, T, freq) in CASES.items():
        m = Model(spec, freq)
        for r in range(reps):
            x = m.simulate(m.theta(truth), T, np.random.default_rng([777, r, len(name)]))
            out[(name, r)] = gmwm.wvar(x, freq=freq)
    with open(path, "wb") as fh:
        pickle.dump(out, fh)


def fit(wv_path: str, out_path: str) -> None:
    import gmwm

    with open(wv_path, "rb") as fh:
        wvs = pickle.load(fh)
    res = {}
    for (name, r), wv in wvs.items():
        for i, (spec, kw) in enumerate(FITS[name]):
            t0 = time.process_time()
            try:
                f = gmwm.fit(wv, spec, se_cov="gaussian", **kw)
                res[f"{name}|{i}|{r}"] = [f.objective, time.process_time() - t0, bool(f.converged)]
            except Exception as err:  # noqa: BLE001 - a crash is a result here
                res[f"{name}|{i}|{r}"] = [float("nan"), time.process_time() - t0, str(err)]
    with open(out_path, "w") as fh:
        json.dump(res, fh)


def compare(a_path: str, b_path: str) -> None:
    with open(a_path) as fh:
        a = json.load(fh)
    with open(b_path) as fh:
        b = json.load(fh)
    groups = defaultdict(list)
    for k in b:
        name, i, _ = k.split("|")
        groups[(name, int(i))].append((a[k], b[k]))
    for (name, i), v in sorted(groups.items()):
        oa = np.array([x[0][0] for x in v])
        ob = np.array([x[1][0] for x in v])
        rel = (ob - oa) / oa
        errors = sum(isinstance(x[0][2], str) for x in v), sum(isinstance(x[1][2], str) for x in v)
        spec, kw = FITS[name][i]
        print(f"{name:8s} {spec:16s} {json.dumps(kw):48s} B worse {int(np.sum(rel > 1e-6)):2d} "
              f"better {int(np.sum(rel < -1e-6)):2d} of {len(v)}; crashes A/B {errors[0]}/{errors[1]};"
              f" CPU s per fit A {np.median([x[0][1] for x in v]):.3f} "
              f"B {np.median([x[1][1] for x in v]):.3f}")


if __name__ == "__main__":
    cmd = sys.argv[1] if len(sys.argv) > 1 else ""
    if cmd == "make":
        make(sys.argv[2])
    elif cmd == "fit":
        fit(sys.argv[2], sys.argv[3])
    elif cmd == "compare":
        compare(sys.argv[2], sys.argv[3])
    else:
        sys.exit(__doc__)
