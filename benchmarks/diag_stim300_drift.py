"""Why does the closed-form GMWM put the STIM-300 accelerometer's rate ramp R at 0 so often at the
short length (T = 2.5e6 at 250 Hz)? Fits the same simulated WVs with the study's gmwm_cf (CI
weights, 2 re-weightings), the same with efficient weights, and ARMAV, and counts R = 0.

    python benchmarks/diag_stim300_drift.py [--replicates 60]

Seeds 1000 + r; about 1 s per replicate on an idle core.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import yaml

import gmwm
from gmwm.model import Model
from gmwm_studies.stim300 import fit_wv

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--replicates", type=int, default=60)
    args = ap.parse_args()
    cfg = yaml.safe_load((ROOT / "config" / "config.yaml").read_text())
    study = cfg["studies"]["stim300_accel"]
    model = Model(study["model"])
    theta = model.theta(study["truth"])
    k = model.param_names.index("DR[1].omega")
    estimators = {
        "gmwm_cf (CI weights, 2 reweightings)": cfg["estimators"]["gmwm_cf"],
        "gmwm_cf, efficient weights": {**cfg["estimators"]["gmwm_cf"], "weights": "efficient",
                                      "reweight": 0},
        "armav (delta-method weights)": cfg["estimators"]["armav"],
    }
    values: dict[str, list[float]] = {name: [] for name in estimators}
    t0 = time.perf_counter()
    for r in range(args.replicates):
        x = model.simulate(theta, min(study["n_samples"]), np.random.default_rng(1000 + r))
        wv = gmwm.wvar(x, freq=study["freq"])
        for name, settings in estimators.items():
            values[name].append(fit_wv(wv, model, settings, seed=r)[0][k])
    print(f"{args.replicates} replicates at T = {min(study['n_samples']):,}, "
          f"{time.perf_counter() - t0:.0f} s")
    truth = theta[k]
    for name, v in values.items():
        v = np.asarray(v)
        at0 = int(np.sum(v <= 1e-8 * truth))
        print(f"{name:40s} R at 0: {at0:3d}/{len(v)}  mean/truth {v.mean() / truth:.3f}  "
              f"sd/truth {v.std(ddof=1) / truth:.3f}")


if __name__ == "__main__":
    main()
