"""Design against estimator (gmwm_studies.design): asymptotic SEs at the truth and the design
probabilities of the counted events, beside the observed counts."""

from __future__ import annotations

import json
import math
from statistics import NormalDist

import numpy as np
import pandas as pd
import pytest

from gmwm.model import Model
from gmwm.plan import predict
from gmwm_studies.counts import study_counts
from gmwm_studies.design import (
    _power,
    audit_counts,
    design_counts,
    limit_weights,
    navchip_design,
    study_design,
    write_design,
)

PHI = NormalDist().cdf
T, J = 2**14, 12
TRUTH = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6}
ESTIMATORS = {"gmwm": {"method": "gmwm", "weights": "ci-eta3", "reweight": 0},
              "gmwm_eff": {"method": "gmwm", "weights": "efficient"},
              "avsm": {"method": "avsm"}}


def toy_table() -> tuple[pd.DataFrame, dict]:
    """Six WN + RW fits per estimator: RW at 0 in two (one not converged), off by a factor 2 in
    four of the five converged."""
    rw = [1e-6, 0.0, 3e-6, 0.4e-6, 0.0, 2.5e-6]
    conv = [1, 1, 1, 1, 0, 1]
    rows = []
    for est in ("gmwm", "gmwm_eff", "avsm"):
        for r, (g, c) in enumerate(zip(rw, conv, strict=True)):
            rows.append({"replicate": r, "estimator": est, "T": T, "J": J, "WN[1].sigma2": 1.0,
                         "RW[1].gamma2": g, "objective": 0.0, "converged": c,
                         "at_boundary": "RW[1].gamma2" if g == 0 else ""})
    return pd.DataFrame(rows), {"model": "WN+RW", "truth": TRUTH, "T": T, "J": J}


def test_limit_weights_follow_the_estimator():
    assert limit_weights(ESTIMATORS["gmwm"]) == "ci-eta3"
    assert limit_weights(ESTIMATORS["gmwm_eff"]) == "efficient"
    assert limit_weights({"method": "gmwm", "weights": "ci-eta3", "reweight": 2}) == "gaussian"
    assert limit_weights({"method": "armav"}) is None and limit_weights({"method": "avsm"}) is None
    assert limit_weights({}) == "ci"  # the library default


def test_power_is_the_degree_of_the_wv_in_the_scale_parameter():
    model = Model("QN+WN+AR1+GM+RW+DR+SIN", freq=10.0)
    values = {"QN[1].Q2": 1e-3, "WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1,
              "GM[1].beta": 0.5, "GM[1].sigma2": 0.2, "RW[1].gamma2": 1e-6, "DR[1].omega": 1e-4,
              "SIN[1].alpha": 0.3, "SIN[1].beta": 0.05}
    theta = model.theta(values)
    assert {c.process.name: _power(model, c, theta) for c in model.components} == {
        "QN": 1, "WN": 1, "AR1": 1, "GM": 1, "RW": 1, "DR": 2, "SIN": 2}


def test_study_design_against_plan_and_counts():
    df, rec = toy_table()
    rows = study_design("toy", df, rec, ESTIMATORS)
    assert {r["estimator"] for r in rows} == {"gmwm", "gmwm_eff"}  # the AVSM has no sandwich
    counts = {c.name: c.value for c in study_counts("toy", df, rec, "")}
    model = Model("WN+RW")
    for est, w in (("gmwm", "ci-eta3"), ("gmwm_eff", "efficient")):
        pred = predict(model, TRUTH, T, levels=J, weights=w)
        (rw,) = [r for r in rows if r["estimator"] == est and r["parameter"] == "RW[1].gamma2"]
        rse = pred.rse["RW[1].gamma2"]
        assert rw["weights"] == w and rw["rse"] == pytest.approx(rse)
        assert rw["p_le0"] == pytest.approx(PHI(-1 / rse))
        assert rw["p_factor2_normal"] == pytest.approx(PHI(-0.5 / rse) + PHI(-1 / rse))
        assert rw["p_factor2_lognormal"] == pytest.approx(2 * PHI(-math.log(2) / rse))
        assert rw["n"] == 5  # converged fits
        assert rw["observed_at_zero"] == counts[f"toy.{est}.at_boundary.RW1.gamma2"] == 1
        assert rw["observed_factor2"] == 4  # 0, 3e-6, 0.4e-6, 2.5e-6
        assert 0 <= rw["binom_p_at_zero"] <= 1


def test_sinusoid_joint_miss_and_quadratic_amplitude():
    model = Model("WN+SIN")
    truth = {"WN[1].sigma2": 1.0, "SIN[1].alpha": 0.05, "SIN[1].beta": 0.01}
    df = pd.DataFrame({"replicate": [0, 1], "estimator": "gmwm", "T": T, "J": J,
                       "WN[1].sigma2": 1.0, "SIN[1].alpha": [0.05, 0.2],
                       "SIN[1].beta": [0.01, 0.01], "objective": 0.0, "converged": 1,
                       "at_boundary": ""})
    rec = {"model": "WN+SIN", "truth": truth, "T": T, "J": J}
    rows = {r["parameter"]: r for r in study_design("toy", df, rec, ESTIMATORS)}
    pred = predict(model, truth, T, levels=J, weights="ci-eta3")
    a, b = rows["SIN[1].alpha"], rows["SIN[1].beta"]
    # the WV is quadratic in alpha: P(alpha^2 estimate <= 0) with rse(alpha^2) = 2 rse(alpha)
    assert a["power"] == 2 and a["p_le0"] == pytest.approx(PHI(-1 / (2 * pred.rse["SIN[1].alpha"])))
    assert b["p_le0"] != b["p_le0"]  # not a scale parameter: no boundary probability
    joint = rows["SIN[1] (alpha or beta)"]
    assert joint["observed_factor2"] == 1  # the counts' SIN1.factor2_miss
    for q in ("p_factor2_normal", "p_factor2_lognormal"):
        lo, hi = max(a[q], b[q]), a[q] + b[q]
        assert lo - 3e-3 <= joint[q] <= hi + 3e-3, (q, lo, joint[q], hi)


def test_navchip_truth_at_zero_and_counts(tmp_path):
    est = pd.DataFrame([{"fit": "gyroscope_X", "WN[1].sigma2": 1e-6, "RW[1].gamma2": 1e-12,
                         "DR[1].omega": 0.0}])
    draws = pd.DataFrame({"fit": "gyroscope_X", "draw": range(4), "converged": [1, 1, 1, 0],
                          "WN[1].sigma2": [1e-6, 1.1e-6, 0.9e-6, np.nan],
                          "RW[1].gamma2": [1e-12, 0.0, 3e-12, np.nan],
                          "DR[1].omega": [0.0, 1e-9, 0.0, np.nan]})
    rows = navchip_design(est, draws, "WN+RW+DR", {"weights": "ci-eta3"}, 2**16, 14, 250.0)
    by = {r["parameter"]: r for r in rows}
    assert by["DR[1].omega"]["p_le0"] == 0.5 and by["DR[1].omega"]["observed_at_zero"] == 2
    assert by["RW[1].gamma2"]["observed_at_zero"] == 1 and by["RW[1].gamma2"]["n"] == 3
    assert by["DR[1].omega"]["highlight"] and by["RW[1].gamma2"]["highlight"]
    paths = [tmp_path / n for n in ("a.csv", "a.md", "counts.json", "counts.md")]
    write_design(rows, *map(str, paths))
    c = json.loads(paths[2].read_text())["counts"]
    assert c["navchip.gyroscope_X.DR1.omega.p_le0"]["value"] == 0.5
    assert c["navchip.gyroscope_X.RW1.gamma2.observed_at_zero_share"]["value"] == pytest.approx(1 / 3)
    assert c["navchip.gyroscope_X.RW1.gamma2.rse"]["source"] == "a.csv"
    assert "| navchip | gyroscope_X |" in paths[1].read_text()


def test_counts_label_T_only_with_several_lengths():
    df, rec = toy_table()
    rows = study_design("toy", df, rec, ESTIMATORS)
    names = {c.name for c in design_counts(rows, "x.csv")}
    assert "toy.gmwm.RW1.gamma2.p_le0" in names and "toy.gmwm_eff.RW1.gamma2.rse" in names
    rows2 = rows + [dict(r, T=2 * T) for r in rows]
    names2 = {c.name for c in design_counts(rows2, "x.csv")}
    assert f"toy.T{T}.gmwm.RW1.gamma2.p_le0" in names2 and f"toy.T{2 * T}.gmwm.n" not in names2
    assert f"toy.T{2 * T}.gmwm.RW1.gamma2.n" in names2


@pytest.mark.pipeline
def test_quick_run_writes_the_design(quick_run):
    """The quick run's design table covers Simulations 2 and 3, both STIM-300 sensors and the
    Navchip axis it bootstraps, and its observed counts are the counts of counts.json."""
    rep = quick_run.out / "reports"
    df = pd.read_csv(rep / "design" / "asymptotic.csv")
    assert {"sim2", "sim3", "stim300_gyro", "stim300_accel"} <= set(df.study)
    assert set(df[df.study == "navchip"].fit) == {"gyroscope_X"}
    counts = json.loads((rep / "counts.json").read_text())["counts"]
    design = json.loads((rep / "design" / "counts.json").read_text())["counts"]
    for est in ("gmwm", "gmwm_eff"):
        assert (design[f"sim3.{est}.RW1.gamma2.observed_at_zero"]["value"]
                == counts[f"sim3.{est}.at_boundary.RW1.gamma2"]["value"])
        assert (design[f"sim2.{est}.SIN2.observed_factor2"]["value"]
                == counts[f"sim2.{est}.SIN2.factor2_miss"]["value"])
    assert df.rse.dropna().gt(0).all() and df.p_le0.dropna().between(0, 1).all()


def test_audit_counts_match_fits_by_objective():
    """A miss is audited only when the audit searched the same fit (same objective); at its best
    within 1e-6, else local; a non-miss audit row is ignored."""
    truth = {"SIN[2].alpha": 1.0, "SIN[2].beta": 0.01}
    df = pd.DataFrame({
        "replicate": [0, 1, 2, 3, 4, 5], "estimator": ["gmwm"] * 6,
        "SIN[2].alpha": [1.1, 3.0, 0.2, 1.0, 1.0, 1.0],
        "SIN[2].beta": [0.01, 0.01, 0.01, 0.001, 0.05, 0.01],
        "objective": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0], "converged": [1, 1, 1, 1, 1, 0]})
    audit = pd.DataFrame({
        "replicate": [0, 1, 2, 3], "estimator": ["gmwm"] * 4,
        "objective": [1.0, 2.0, 3.0, 4.1],  # replicate 3: another fit than the committed one
        "best_objective": [1.0, 2.0 / (1 + 5e-7), 2.5, 4.1], "best_sin2_within_2x": [0, 0, 1, 0]})
    got = {c.name.split(".audit.")[1]: c.value
           for c in audit_counts("sim2", df, truth, audit, "a.csv")}
    # misses: 1 (alpha 3x), 2 (alpha / 5), 3 (beta / 10), 4 (beta 5x); 5 did not converge
    assert got["misses"] == 4 and got["audited"] == 2 and got["not_audited"] == 2
    assert got["at_best"] == 1 and got["local"] == 1 and got["local_within_2x"] == 1
    assert got["share_at_best"] == 0.5
    assert math.isclose(got["local_excess_min"], 0.2) and math.isclose(got["local_excess_max"], 0.2)
