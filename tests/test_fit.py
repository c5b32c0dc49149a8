"""GMWM estimator: recovery of known truth, closed form, weights, diagnostics, bad input."""

import numpy as np
import pytest

import gmwm
from gmwm.errors import IdentifiabilityError, InputError
from gmwm.model import Model
from gmwm.wv import WaveletVariance, wvar

SIM1 = {"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
        "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35}
SIM3 = {"AR1[1].phi": 0.9997083, "AR1[1].sigma2": 9e-6, "WN[1].sigma2": 8e-4,
        "RW[1].gamma2": 3e-11, "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056}


def _monte_carlo(spec, truth, T, R, seed):
    model = Model(spec)
    theta = model.theta(truth)
    est, conv = [], []
    for r in range(R):
        res = gmwm.fit(model.simulate(theta, T, np.random.default_rng([seed, r])), model)
        est.append(res.params)
        conv.append(res.converged)
    return model, theta, np.array(est), np.array(conv)


def _z(est, theta):
    """Standardised bias: (mean - truth) / (SD / sqrt(R)), ~N(0,1) for an unbiased estimator."""
    return (est.mean(0) - theta) / (est.std(0, ddof=1) / np.sqrt(len(est)))


@pytest.mark.slow
def test_simulation1_recovers_truth_without_bias():
    # T = 1.6e5 is Simulation 1's largest size; 20 replicates; |z| < 3.5 for all 6 parameters
    # fails by chance with probability ~ 6 * 5e-4
    model, theta, est, conv = _monte_carlo("WN+RW+AR1+SIN", SIM1, 160_000, 20, 1)
    assert conv.all()
    z = _z(est, theta)
    assert np.all(np.abs(z) < 3.5), dict(zip(model.param_names, z, strict=True))
    # precision comparable to docs/METHODS.md §5.1's check (relative SD sigma2 0.4 %, phi 0.1 %, alpha 0.5 %)
    rel_sd = est.std(0) / theta
    assert rel_sd[model.param_names.index("AR1[1].phi")] < 0.003
    assert rel_sd[model.param_names.index("SIN[1].alpha")] < 0.01
    assert rel_sd[model.param_names.index("SIN[1].beta")] < 0.01


@pytest.mark.slow
def test_simulation3_sinusoid_identified_and_unbiased():
    # T = 2^21 instead of the paper's 1e7 to stay fast; the RW (gamma2 = 3e-11) is then weak
    # (relative SD > 1) but still unbiased within Monte Carlo error, which the z-test checks
    model, theta, est, conv = _monte_carlo("AR1+RW+WN+SIN", SIM3, 2**21, 12, 3)
    assert conv.all()
    z = _z(est, theta)
    assert np.all(np.abs(z) < 3.5), dict(zip(model.param_names, z, strict=True))
    for name in ("SIN[1].alpha", "SIN[1].beta", "AR1[1].phi", "WN[1].sigma2"):
        i = model.param_names.index(name)
        assert np.max(np.abs(est[:, i] / theta[i] - 1)) < 0.02, name


def test_automatic_starts_recover_ar1_instead_of_collapsing_into_white_noise():
    model = Model("WN+RW+AR1")
    theta = model.theta({k: v for k, v in SIM1.items() if not k.startswith("SIN")})
    x = model.simulate(theta, 100_000, 11)
    res = gmwm.fit(x, model)
    assert res.converged
    est = res.as_dict()
    assert abs(est["AR1[1].phi"] - 0.975) < 0.01
    assert abs(est["AR1[1].sigma2"] / 0.03 - 1) < 0.2
    assert abs(est["WN[1].sigma2"] - 1) < 0.05


def test_two_sinusoids_are_separated_and_ordered():
    model = Model("WN+2*SIN")
    theta = model.theta({"WN[1].sigma2": 1.0, "SIN[1].alpha": 1.0, "SIN[1].beta": 0.5,
                         "SIN[2].alpha": 2.0, "SIN[2].beta": 0.01})
    res = gmwm.fit(model.simulate(theta, 2**18, 5), model)
    est = res.as_dict()
    assert res.converged
    assert abs(est["SIN[1].beta"] / 0.5 - 1) < 0.02 and abs(est["SIN[2].beta"] / 0.01 - 1) < 0.05
    assert abs(est["SIN[1].alpha"] - 1) < 0.05 and abs(est["SIN[2].alpha"] - 2) < 0.2


def test_linear_model_uses_closed_form_equal_to_weighted_least_squares():
    model = Model("QN+WN+RW", freq=250.0)
    theta = model.theta({"QN[1].Q2": 0.5, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6})
    wv = wvar(model.simulate(theta, 2**20, 2), freq=250.0)
    res = gmwm.fit(wv, model)
    assert res.diagnostics["closed_form"] and res.converged
    # unconstrained WLS ([GMWFM] eq. 5) with the same weights
    X = np.column_stack([6 / wv.scales**2, 1 / wv.scales, (wv.scales**2 + 2) / (12 * wv.scales)])
    W = res.weights
    wls = np.linalg.solve(X.T @ W @ X, X.T @ W @ wv.variance)
    assert np.all(wls > 0)  # this seed's WLS solution is interior, so NNLS must equal it
    np.testing.assert_allclose(res.params, wls, rtol=1e-6)


def test_closed_form_reports_a_negative_component_at_the_boundary():
    # data with no random walk at all: the WLS solution for gamma2 is often negative
    model = Model("WN+RW")
    hits = 0
    for seed in range(6):
        x = np.random.default_rng(seed).standard_normal(2**16)
        res = gmwm.fit(x, model)
        assert np.all(res.params >= 0)
        hits += bool(res.diagnostics["at_boundary"])
        if res.diagnostics["at_boundary"]:
            assert any("boundary" in w for w in res.diagnostics["warnings"])
    assert hits >= 1


def test_drift_sign_comes_from_the_signal():
    model = Model("WN+DR")
    x = model.simulate(np.array([1.0, -1e-3]), 2**16, 4)
    res = gmwm.fit(x, model)
    assert res.as_dict()["DR[1].omega"] < 0
    assert abs(res.as_dict()["DR[1].omega"] / -1e-3 - 1) < 0.05


def test_fit_from_precomputed_wv_equals_fit_from_signal():
    model = Model("WN+AR1")
    x = model.simulate(np.array([1.0, 0.9, 0.5]), 2**15, 9)
    wv = wvar(x, ci="eta3")   # a table's given bounds are the "ci" weights: give eta_3 ones
    a, b = gmwm.fit(x, model), gmwm.fit(wv, model)
    np.testing.assert_allclose(a.params, b.params, rtol=1e-10)
    table = WaveletVariance.from_table(wv.scales, wv.variance, wv.ci_low, wv.ci_high,
                                       n_samples=wv.n_samples)
    np.testing.assert_allclose(gmwm.fit(table, model).params, a.params, rtol=1e-8)


@pytest.mark.parametrize("weights", ["ci", "gaussian", "identity"])
def test_every_weighting_recovers_a_simple_model(weights):
    model = Model("WN+AR1")
    theta = np.array([1.0, 0.95, 0.1])
    res = gmwm.fit(model.simulate(theta, 2**17, 21), model, weights=weights)
    assert res.converged
    np.testing.assert_allclose(res.params, theta, rtol=0.15)


def test_user_covariance_weights_and_armav():
    model = Model("WN+RW")
    theta = np.array([1.0, 1e-4])
    x = model.simulate(theta, 2**17, 8)
    wv = wvar(x)
    V = np.diag(2 * wv.variance**2 / wv.edof)
    res = gmwm.fit(wv, model, weights=V)
    np.testing.assert_allclose(res.weights, np.linalg.inv(V), rtol=1e-8)
    arm = gmwm.fit(wv, model, method="armav")
    assert arm.converged and arm.method == "armav"
    np.testing.assert_allclose(arm.params, theta, rtol=0.5)
    with pytest.raises(InputError, match="weight covariance must be"):
        gmwm.fit(wv, model, weights=np.eye(3))


def test_sandwich_se_matches_monte_carlo_spread():
    # SEs use the model covariance of the WV (between-scale correlation included): with 30
    # replicates the SD estimate has ~13 % error, so the ratio must lie within [0.6, 1.6]
    model, theta, est, _ = _monte_carlo("WN+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9,
                                                   "AR1[1].sigma2": 0.2}, 2**15, 30, 7)
    res = gmwm.fit(model.simulate(theta, 2**15, 99), model)
    ratio = res.se / est.std(0, ddof=1)
    assert np.all((ratio > 0.6) & (ratio < 1.6)), ratio


def test_reweighting_runs_and_keeps_the_estimate_close():
    model = Model("WN+RW")
    x = model.simulate(np.array([1.0, 1e-5]), 2**16, 3)
    a = gmwm.fit(x, model)
    b = gmwm.fit(x, model, reweight=2)
    assert b.converged
    np.testing.assert_allclose(a.params[0], b.params[0], rtol=0.02)


def test_more_parameters_than_scales_is_rejected():
    with pytest.raises(IdentifiabilityError, match="parameters but only"):
        gmwm.fit(np.random.default_rng(0).standard_normal(64), "QN+WN+2*AR1+SIN+RW")


def test_constant_signal_and_bad_method_are_clear_errors():
    with pytest.raises(InputError, match="positive"):
        gmwm.fit(np.ones(1000), "WN")
    with pytest.raises(InputError, match="unknown method"):
        gmwm.fit(np.random.default_rng(0).standard_normal(1000), "WN", method="mle")
    with pytest.raises(InputError, match="unknown weights"):
        gmwm.fit(np.random.default_rng(0).standard_normal(1000), "WN", weights="foo")


def test_result_summary_json_and_conf_int():
    model = Model("WN+AR1")
    res = gmwm.fit(model.simulate(np.array([1.0, 0.9, 0.5]), 2**14, 2), model)
    text = res.summary()
    assert "AR1[1].phi" in text and "converged" in text
    d = res.to_json_dict()
    assert set(d["params"]) == set(model.param_names) and d["n"] == 2**14
    ci = res.conf_int()
    assert np.all(ci[:, 0] < res.params) and np.all(res.params < ci[:, 1])


def test_sandwich_se_survives_parameters_on_very_different_scales():
    # STIM-300 gyro-like WN + RW: sigma2 ~ 1e-3 and gamma2 ~ 1e-13 (per sample at 250 Hz).
    # An unscaled pseudo-inverse used to cut the sigma2 direction to a zero standard error.
    model = Model("WN+RW", freq=250.0)
    theta = np.array([1.7118e-3, 1.5394e-11])
    est, se = [], []
    for r in range(12):
        res = gmwm.fit(model.simulate(theta, 2**18, np.random.default_rng([5, r])), model)
        est.append(res.params)
        se.append(res.se)
    se = np.array(se)
    # replicates where the weak RW sits at the boundary have no SE (NaN) by design
    assert np.isfinite(se[:, 0]).all() and np.isfinite(se[:, 1]).sum() >= 6
    ratio = np.nanmedian(se, axis=0) / np.std(est, axis=0, ddof=1)
    assert np.all((ratio > 0.2) & (ratio < 5)), ratio


def _wn_rw_wv(seed: int) -> WaveletVariance:
    model = Model("WN+RW")
    theta = model.theta({"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4})
    return wvar(model.simulate(theta, 2**18, np.random.default_rng(seed)))


def test_solve_keeps_phi_below_one():
    # an AR1 fitted to a random walk runs phi to 1: its free coordinate (2 atanh phi) reaches
    # ~47, where 2 expit(eta) - 1 rounds to exactly 1.0 (a random walk, outside the domain)
    from gmwm.inference import Problem, weight_matrix

    wv = _wn_rw_wv(5)
    model = Model("WN+AR1")
    prob = Problem(model, wv, weight_matrix(wv, "ci"))
    start = model.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.999, "AR1[1].sigma2": 1e-4})
    sol = prob.solve(start)
    assert sol.theta[1] < 1.0 and "AR1[1].phi" in sol.edge
    model.check(sol.theta)


def test_phi_rounding_onto_one_is_reported_not_a_crash():
    # this efficient-weights fit used to stop with "AR1[1]: phi must lie in (-1, 1), got 1"
    res = gmwm.fit(_wn_rw_wv(2), "WN+AR1", weights="efficient")
    phi = res.as_dict()["AR1[1].phi"]
    assert 1 - 1e-12 < phi < 1.0
    res.model.check(res.params)
    assert any("edge of the stationary domain" in w for w in res.warnings)


def test_gof_false_skips_only_the_test():
    """``gof=False`` (the studies' fits) leaves ``result.gof`` None and changes nothing else."""
    model = Model("WN+AR1+SIN")
    theta = model.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                         "SIN[1].alpha": 0.05, "SIN[1].beta": 0.01})
    wv = wvar(model.simulate(theta, 2**14, np.random.default_rng(7)))
    full = gmwm.fit(wv, model, seed=3)
    bare = gmwm.fit(wv, model, seed=3, gof=False)
    assert full.gof is not None and bare.gof is None
    np.testing.assert_array_equal(bare.params, full.params)
    np.testing.assert_array_equal(bare.se, full.se)
    assert bare.objective == full.objective and bare.converged == full.converged
