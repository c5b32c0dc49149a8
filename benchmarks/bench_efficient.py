"""CI weights against the efficient two-step GMWM on the components that only show at the last
scales: Simulation 3's random walk and Simulation 2's slow sinusoid.

The models are the quick profile's rescalings (config/quick.yaml: T = 2^17, the slow parts sped
up so that their WV shares at the largest scales match the full-scale study's), so a few dozen
replicates run in minutes. Printed per weighting: boundary count (RW at 0 / slow SIN absorbed:
its beta off by more than 50 %), relative bias and relative SD of the slow parameter, seconds.

    python benchmarks/bench_efficient.py [--R 40]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import gmwm
from gmwm.model import Model

SIM3 = ("AR1+WN+RW+SIN", {"AR1[1].phi": 0.9997083, "AR1[1].sigma2": 9e-6, "WN[1].sigma2": 8e-4,
                          "RW[1].gamma2": 1.2288e-7, "SIN[1].alpha": 0.025,
                          "SIN[1].beta": 0.056}, "RW[1].gamma2")
SIM2 = ("2*AR1+2*SIN", {"AR1[1].phi": 0.1107083, "AR1[1].sigma2": 5.278666e-4,
                        "AR1[2].phi": 0.9998400124, "AR1[2].sigma2": 9.598512e-10,
                        "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
                        "SIN[2].alpha": 0.0015, "SIN[2].beta": 2.56e-4}, "SIN[2].beta")


def run(case, T: int, R: int, weights: str) -> dict[str, float]:
    spec, truth, key = case
    m = Model(spec)
    theta = m.theta(truth)
    i = m.param_names.index(key)
    vals, lost, secs = [], 0, 0.0
    for r in range(R):
        wv = gmwm.wvar(m.simulate(theta, T, np.random.default_rng([7, r])))
        t0 = time.perf_counter()
        res = gmwm.fit(wv, m, weights=weights, se_cov="gaussian")
        secs += time.perf_counter() - t0
        v = res.params[i]
        vals.append(v)
        lost += (v == 0) if key.startswith("RW") else abs(v / theta[i] - 1) > 0.5
    v = np.array(vals)
    return {"lost": int(lost), "bias": float(v.mean() / theta[i] - 1),
            "sd": float(v.std(ddof=1) / theta[i]), "s_per_fit": secs / R}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--R", type=int, default=40)
    ap.add_argument("--T", type=int, default=2**17)
    args = ap.parse_args()
    for name, case in (("Simulation 3 RW", SIM3), ("Simulation 2 slow SIN beta", SIM2)):
        for weights in ("ci", "efficient"):
            out = run(case, args.T, args.R, weights)
            print(f"{name:<28} {weights:<9} lost {out['lost']:>3}/{args.R}  rel. bias "
                  f"{out['bias']:+.3f}  rel. SD {out['sd']:.3f}  {out['s_per_fit']:.2f} s/fit",
                  flush=True)


if __name__ == "__main__":
    main()
