"""The quick plan and identifiability searches change no number: predictions pinned to values
computed before the length-free parts were shared across lengths, the continuous margin agrees
with the identifiability rule, and the identifiability search keeps its ~5 % contract."""

from __future__ import annotations

import math
import os
from types import SimpleNamespace

import numpy as np
import pytest

from gmwm.model import as_model
from gmwm.plan import IDENTIFIABLE_RSE, predict
from gmwm.verdict import _ID_RATIO, identifiability

# (model, values, rate [Hz], samples) -> SEs computed by gmwm.plan.predict at 27bb467 (12 digits)
PINNED = [
    ("WN+GM", {"WN[1].sigma2": 4.9e-5, "GM[1].beta": 0.0131, "GM[1].sigma2": 3.6e-7}, 100.0, 60000,
     {"WN[1].sigma2": 2.832180297851e-07, "GM[1].beta": 0.02585986059424,
      "GM[1].sigma2": 5.732175967793e-07}),
    ("QN+WN+AR1+RW", {"QN[1].Q2": 1e-6, "WN[1].sigma2": 1.25e-3, "AR1[1].phi": 0.999,
                      "AR1[1].sigma2": 1e-8, "RW[1].gamma2": 3.9e-11}, 200.0, 1234567,
     {"QN[1].Q2": 1.180147587216e-06, "WN[1].sigma2": 2.853658859222e-06,
      "AR1[1].phi": 9.272187318251e-05, "AR1[1].sigma2": 9.21812504087e-10,
      "RW[1].gamma2": 1.416760866884e-11}),
    ("WN+RW+DR", {"WN[1].sigma2": 1.25e-3, "RW[1].gamma2": 3.9e-11, "DR[1].omega": 1e-9}, 100.0,
     360000, {"WN[1].sigma2": 2.946722219803e-06, "RW[1].gamma2": 2.374278591941e-11,
              "DR[1].omega": 3.839717624631e-07}),
    ("WN+GM+GM+RW", {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-7,
                     "GM[2].beta": 0.01, "GM[2].sigma2": 1e-7, "RW[1].gamma2": 1e-12}, 200.0,
     25920000, {"WN[1].sigma2": 2.787031233761e-08, "GM[1].beta": 0.02569549870869,
                "GM[1].sigma2": 2.707924692587e-09, "GM[2].beta": 0.001226687441149,
                "GM[2].sigma2": 9.459253159595e-09, "RW[1].gamma2": 1.81229432848e-13}),
]


def test_predictions_are_unchanged() -> None:
    # a shorter length of the same model first, so the shared per-level tables are reused
    for spec, theta, freq, n, se in PINNED:
        model = as_model(spec, freq)
        predict(model, theta, n // 3)
        got = predict(model, theta, n).se
        for name, want in se.items():
            assert got[name] == pytest.approx(want, rel=1e-11), (spec, name)


def test_margin_agrees_with_the_identifiability_rule() -> None:
    spec, theta, freq, _, _ = PINNED[1]
    for n in (2 ** 12, 2 ** 16, 2 ** 20):
        p = predict(as_model(spec, freq), theta, n)
        assert set(p.margin) == set(p.identifiable)
        for c, m in p.margin.items():
            assert (m <= 1.0) == p.identifiable[c], (n, c, m)
        # the margin is the worst relative SE over the threshold (RW: one parameter)
        assert p.margin["RW[1]"] == pytest.approx(p.rse["RW[1].gamma2"] / IDENTIFIABLE_RSE)
        assert "margin" not in p.to_dict()


def test_identifiability_keeps_its_contract() -> None:
    """The returned length is identifiable and one search ratio (4.4 %) below it is not."""
    model = as_model("WN+GM+RW", 200.0)
    theta = model.theta({"WN[1].sigma2": 1e-4, "GM[1].beta": 0.02, "GM[1].sigma2": 2e-8,
                         "RW[1].gamma2": 4e-13})
    n = 200 * 600
    result = SimpleNamespace(model=model, params=theta, wv=SimpleNamespace(n_samples=n))
    weak = identifiability(result, n)
    assert weak and all(v is not None and v * 200 > n for v in weak.values())
    for comp, secs in weak.items():
        m = round(secs * 200)
        assert predict(model, theta, m).identifiable[comp]
        assert not predict(model, theta, round(m / _ID_RATIO)).identifiable[comp]
    assert np.isclose(_ID_RATIO, 2 ** (1 / 16)) and math.isfinite(_ID_RATIO)


@pytest.mark.parametrize("weights", ["ci", "ci-eta3", "ci-mixture", "gaussian", "efficient"])
def test_the_expected_wvs_own_interval_changes_no_prediction(monkeypatch, weights):
    """The expected WV carries the eta_3 interval (its mixture one costs ~40 % of a plan): with
    the mixture interval instead, every prediction is bit-identical, whatever the weights."""
    from gmwm import plan
    from gmwm.wv import WaveletVariance

    spec, values, freq, n = PINNED[1][:4]
    model = as_model(spec, freq)
    theta = model.theta(values)
    got = predict(model, theta, n, weights=weights)
    eta3 = plan._expected_wv

    def mixture(*args, **kw):
        wv = eta3(*args, **kw)
        assert wv.ci_kind == "eta3"
        return WaveletVariance.from_table(wv.scales, wv.variance, n_samples=wv.n_samples,
                                          freq=wv.freq, ci="mixture")

    monkeypatch.setattr(plan, "_expected_wv", mixture)
    want = predict(model, theta, n, weights=weights)
    assert np.array_equal(got.cov, want.cov) and got.se == want.se
    assert got.coefficients == want.coefficients


def test_a_negative_coefficient_gets_a_positive_relative_se():
    """An AR1 with phi < 0 (its datasheet phi negative, its interval linear): the plan gives a
    positive relative SE instead of failing on the log of a negative ratio."""
    pred = predict("QN+WN+AR1", [1e-6, 1e-4, -0.5, 1e-5], 100000)
    phi = pred.coefficients["AR1[1].phi"]
    assert phi["value"] == -0.5 and phi["rse"] > 0
    lo, hi = phi["ci95"]
    assert phi["rse"] == pytest.approx((hi - lo) / (2 * 1.959963984540054 * 0.5), rel=1e-9)


def test_prefetched_covariances_change_no_number(monkeypatch) -> None:
    """The plan's covariances computed side by side in threads (into wv_covariance's memo) give
    the plan computed one length after the other, to the bit."""
    from gmwm import plan as plan_mod
    from gmwm import wvcov

    model = as_model("WN+GM+RW", freq=100.0)
    theta = model.theta({"WN[1].sigma2": 4.9e-5, "GM[1].beta": 0.0131, "GM[1].sigma2": 3.6e-7,
                         "RW[1].gamma2": 1e-12})
    args = (model, theta, [600.0, 3600.0])
    kw = {"targets": [("WN[1].sigma2", 0.01)], "max_search_s": 21600.0}
    wvcov._MEMO.clear()
    threaded = plan_mod.make_plan(*args, **kw).to_dict()
    if len(os.sched_getaffinity(0)) > 1:
        assert len(wvcov._MEMO) > 10  # the prefetch filled it
    wvcov._MEMO.clear()
    monkeypatch.setattr(plan_mod, "_prefetch_covariances", lambda *a: None)
    assert plan_mod.make_plan(*args, **kw).to_dict() == threaded
