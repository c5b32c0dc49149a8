"""The optimiser on hard cases: the default reaches the best objective known (found offline by an
exhaustive search, benchmarks/hard_cases.py --update), and nested models are monotone."""

import itertools
import json
from pathlib import Path

import pytest

import gmwm
from conftest import load_benchmark
from gmwm.model import Model

BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
hc = load_benchmark("hard_cases")

BEST = json.loads((BENCH / "hard_cases_best.json").read_text())
FAST = [cid for cid in BEST if not cid.startswith("navchip")]
NAVCHIP_FAST = ["navchip_gyroscope_X|WN+2*AR1+RW", "navchip_gyroscope_Z|WN+2*AR1+RW",
                "navchip_gyroscope_Y|QN+WN+AR1+RW", "navchip_accelerometer_X|WN+AR1+RW"]
NAVCHIP_FAST += [f"navchip_{s}_{a}|QN+WN+2*GM+RW+DR" for s in ("gyroscope", "accelerometer")
                 for a in "XYZ"]


def _wv(cid: str):
    name = cid.split("|")[0]
    if name.startswith("boot_"):
        return hc.boot_wv(name)[0]
    if name in hc.sim2_names():
        return hc.sim2_wv(name)[0]
    if name.startswith("navchip_"):
        if not hc.NAVCHIP.exists():
            pytest.skip("Navchip data not available (../shared/data)")
        _, sensor, axis = name.split("_")
        from gmwm_studies.data import load_navchip_wv

        return load_navchip_wv(hc.NAVCHIP, sensor, axis)
    return hc.simulated_wv(name)


@pytest.mark.parametrize("cid", FAST + NAVCHIP_FAST)
def test_default_fit_reaches_the_best_known_objective(cid):
    wv, spec = _wv(cid), cid.split("|")[1]
    res = gmwm.fit(wv, spec, se_cov="gaussian")
    best = BEST[cid]
    assert res.objective <= best * (1 + 1e-6) + 1e-12, (res.objective, best)


@pytest.mark.parametrize("cid", ["negative_phi|QN+WN+AR1+RW", "vanishing|WN+2*AR1+RW",
                                 "navchip_gyroscope_X|QN+WN+AR1+RW",
                                 "sin_next_to_ar1|2*AR1+WN+RW+SIN",
                                 "navchip_accelerometer_X|QN+WN+2*GM+RW+DR"])
def test_nested_chain_is_monotone(cid):
    # every submodel ends at or above its supersets: the objective never rises with the model
    wv, spec = _wv(cid), cid.split("|")[1]
    objs = {s: gmwm.fit(wv, s, se_cov="gaussian").objective
            for s in hc.all_submodels(spec) + [spec]}
    for big, small in itertools.permutations(objs, 2):
        cb = Model(big).components
        cs = Model(small).components
        count = lambda cc: {n: sum(c.process.name == n for c in cc) for n in
                            {c.process.name for c in cc}}
        if all(count(cb).get(k, 0) >= v for k, v in count(cs).items()):
            assert objs[big] <= objs[small] * (1 + 1e-9) + 1e-15, (big, small, objs)


def test_spurious_sin_is_reseated():
    # Simulation 2, replicate 2: the search used to stop 22 % above the best known, with a
    # sinusoid below the noise at beta ~ 6e-4 while the phi ~ 1 AR1 absorbed the slow one
    # (truth: SIN[2] alpha 1.5e-3, beta 8e-6); re-seating the weak sinusoid finds the slow one
    cid = "sim2_20240601_2|2*AR1+2*SIN"
    wv, spec = _wv(cid), cid.split("|")[1]
    res = gmwm.fit(wv, spec, se_cov="gaussian")
    assert res.objective <= BEST[cid] * (1 + 1e-6), (res.objective, BEST[cid])
    est = res.as_dict()
    assert 4e-6 < est["SIN[2].beta"] < 1.6e-5 and 7.5e-4 < est["SIN[2].alpha"] < 3e-3, est


def test_negative_phi_is_found():
    wv = hc.simulated_wv("negative_phi")
    res = gmwm.fit(wv, "WN+AR1+RW", se_cov="gaussian")
    assert -0.7 < res.as_dict()["AR1[1].phi"] < -0.5


@pytest.mark.parametrize("spec, n_nodes", [
    # QN, WN, RW, DR linear; 2 GM shaped: {2, 1, 0 GM} x (all linear, or one linear dropped)
    ("QN+WN+2*GM+RW+DR", 3 * (1 + 4)),
    # no linear component: every shaped submodel, 3 x 3 - 1
    ("2*AR1+2*SIN", 8),
])
def test_nested_search_size(spec, n_nodes):
    # linear-drop submodels are searched with shaped drops only below them; a change of the
    # lattice (e.g. back to all 2^L linear subsets: 47 nodes for the Navchip model) shows here
    wv = hc.boot_wv("boot_navchip_gyroscope_X_28")[0] if "GM" in spec else \
        hc.simulated_wv("sim2_like")
    res = gmwm.fit(wv, spec, se_cov="gaussian")
    assert res.diagnostics["n_models_searched"] == n_nodes
    assert gmwm.fit(wv, spec, se_cov="gaussian", nested=False).diagnostics[
        "n_models_searched"] == 1
