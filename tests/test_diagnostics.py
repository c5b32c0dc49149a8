"""Boundary, degenerate and over-parameterised fits carry warnings a user sees."""

import json
import warnings as pywarnings

import numpy as np

import gmwm
from gmwm import identify
from gmwm.model import Model


def test_vanishing_component_is_warned_in_summary_and_json():
    x = np.random.default_rng(3).standard_normal(2**14)  # NNLS puts RW at 0 for this seed
    res = gmwm.fit(x, "WN+RW")
    assert res.converged
    assert "RW[1]" in res.diagnostics["at_boundary"]
    assert np.isnan(res.se[1]) and res.params[1] == 0.0
    assert any("RW[1]" in w and "boundary 0" in w for w in res.warnings)
    assert "warning: " in res.summary()
    js = json.loads(json.dumps(res.to_json_dict()))
    assert any("RW[1]" in w for w in js["warnings"])


def test_overparameterised_sinusoids_on_white_noise_are_flagged():
    x = np.random.default_rng(2).standard_normal(4096)
    res = gmwm.fit(x, "3*SIN+WN")
    text = " ".join(res.warnings)
    assert res.warnings, "a 7-parameter SIN model on pure white noise must not pass silently"
    assert "SIN not supported by the data" in text


def test_the_generating_model_carries_no_warning():
    m = Model("WN+AR1+SIN")
    x = m.simulate(m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.95, "AR1[1].sigma2": 0.1,
                            "SIN[1].alpha": 0.5, "SIN[1].beta": 0.3}), 2**16, 6)
    res = gmwm.fit(x, m)
    assert res.converged and not res.warnings, res.warnings


def test_phi_at_minus_one_is_not_called_white_noise():
    m = Model("WN+AR1")
    wv = gmwm.wvar(m.simulate(m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.5,
                                       "AR1[1].sigma2": 0.5}), 2**14, 3))
    theta = m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": -0.9999999, "AR1[1].sigma2": 1e-3})
    notes = identify.degeneracies(m, theta, wv)
    assert any("phi -> -1" in n for n in notes)
    assert not any("collapses into white noise" in n for n in notes)


def test_no_numpy_warnings_escape_a_fit():
    x = np.random.default_rng(4).standard_normal(4096)
    with pywarnings.catch_warnings():
        pywarnings.simplefilter("error")
        gmwm.fit(x, "QN+WN+AR1+RW")
        gmwm.fit(x, "2*SIN+WN")


def test_global_check_reports_a_better_optimum_honestly():
    # a deliberately poor estimate: the global check must say a better optimum exists
    m = Model("WN+AR1+RW")
    x = m.simulate(m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                            "RW[1].gamma2": 1e-6}), 2**15, 5)
    res = gmwm.fit(x, m)
    bad = res.params.copy()
    bad[m.param_names.index("AR1[1].phi")] = 0.5
    poor = identify.global_check((m, bad, res.wv, res.weights), n_starts=8)
    assert poor.better_found and any("better optimum" in r for r in poor.reasons)
    good = identify.global_check(res, n_starts=8)
    assert not good.better_found


def test_sinusoid_slower_than_the_longest_scale_is_called_a_drift():
    # Simulation 2's efficient-weights replicate 42 ended at SIN beta = 5.4e-13, alpha = 1375:
    # a period of 1e13 samples, whose WV is a drift's. The exact WV of WN + DR, fitted with
    # WN + SIN, lands on that ridge; the fit must say so, and a sinusoid inside the scales must not.
    sc = 2.0 ** np.arange(1, 21)
    drift = gmwm.WaveletVariance.from_table(sc, Model("WN+DR").wv(np.array([1.0, 1e-7]), sc),
                                            n_samples=2**21)
    res = gmwm.fit(drift, "WN+SIN")
    slow = [w for w in res.warnings if "drift" in w and w.startswith("SIN[1]")]
    assert res.params[2] < 2 * np.pi / (10 * 2**20) and len(slow) == 1
    inside = Model("WN+SIN").wv(np.array([1.0, 0.3, 2 * np.pi / 5e4]), sc)
    res = gmwm.fit(gmwm.WaveletVariance.from_table(sc, inside, n_samples=2**21), "WN+SIN")
    assert not [w for w in res.warnings if "drift" in w]
