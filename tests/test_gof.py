"""Goodness-of-fit test (gmwm.gof): the weighted chi-square tail, p-value calibration under two
true models (KS over seeded replicates), power against clear misspecifications, the ramp fitted
as white noise, boundary components and the degenerate cases."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import gmwm
from conftest import load_benchmark
from gmwm.gof import gof_test, objective_test, weighted_chi2_sf
from gmwm.model import Model

calibrate = load_benchmark("bench_selection").calibrate

AR1_RW = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 1e-3, "RW[1].gamma2": 1e-6}


def test_weighted_chi2_tail():
    # equal weights: the chi-square itself
    assert weighted_chi2_sf(18.3, np.full(10, 2.0))[0] == pytest.approx(stats.chi2.sf(9.15, 10))
    # unequal weights: Imhof against a large Monte Carlo sample
    lam = np.array([5.0, 2.0, 1.0, 0.5, 0.3, 0.1, 0.05, 0.01])
    draws = (np.random.default_rng(0).standard_normal((400_000, lam.size)) ** 2) @ lam
    for q in (0.5, 0.9, 0.99):
        x = np.quantile(draws, q)
        p, method = weighted_chi2_sf(x, lam)
        assert method == "imhof"
        assert p == pytest.approx(1 - q, abs=4 * np.sqrt(q * (1 - q) / draws.size) + 1e-4)
    # df = 1 (slowest decay of the inversion integrand) against the exact value
    assert weighted_chi2_sf(3.0, np.array([1.0, 1e-9]))[0] == pytest.approx(
        stats.chi2.sf(3.0, 1), rel=1e-5)
    # far tail: the saddlepoint, within a few % of the chi-square it nearly is
    p, method = weighted_chi2_sf(80.0, np.array([1.0, 1.0, 1.0, 0.999]))
    assert method == "saddlepoint"
    assert p == pytest.approx(stats.chi2.sf(80.0, 4), rel=0.05)


def _pvalues(spec: str, truth: dict, T: int, R: int, seed: int) -> np.ndarray:
    m = Model(spec)
    theta = m.theta(truth)
    out = []
    for r in range(R):
        x = m.simulate_fast(theta, T, np.random.default_rng([seed, r]))
        out.append(gmwm.fit(x, m).gof.p_value)
    return np.array(out)


@pytest.mark.slow
@pytest.mark.parametrize("spec,truth,R", [
    ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-5}, 160),
    ("WN+AR1+RW", AR1_RW, 100),
], ids=["WN+RW", "WN+AR1+RW"])
def test_pvalues_uniform_under_the_model(spec, truth, R):
    """Default fits of the true model at T = 2^14: p-values uniform (KS) and the 5 % test's
    rejection share within 3 Monte Carlo SE of 5 %."""
    p = _pvalues(spec, truth, 2**14, R, seed=41)
    assert np.all(np.isfinite(p))
    assert stats.kstest(p, "uniform").pvalue > 0.01
    assert abs(np.mean(p < 0.05) - 0.05) < 3 * np.sqrt(0.05 * 0.95 / R)


def test_power_against_clear_misspecification():
    # a strong AR1 fitted as WN+RW, and a drift at 3 SE left out of QN+WN+RW
    m = Model("WN+AR1+RW")
    theta = m.theta(AR1_RW)
    rejected = 0
    for r in range(10):
        x = m.simulate_fast(theta, 2**14, np.random.default_rng([43, r]))
        rejected += gmwm.fit(x, "WN+RW").gof.rejected()
    assert rejected == 10
    m = Model("QN+WN+RW+DR")
    theta = calibrate(m, m.theta({"QN[1].Q2": 1.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-4,
                                  "DR[1].omega": 2e-4}), "DR[1]", 3.0, 2**14)
    p_test, p_obj = [], []
    for r in range(10):
        x = m.simulate_fast(theta, 2**14, np.random.default_rng([44, r]))
        res = gmwm.fit(x, "QN+WN+RW")
        p_test.append(res.gof.p_value)
        p_obj.append(objective_test(res)[2])
    # the long scales the CI weights ignore: the test sees the drift, the objective does not
    assert np.mean(np.array(p_test) < 0.05) >= 0.7
    assert np.mean(np.array(p_test) < 0.05) > np.mean(np.array(p_obj) < 0.05)


def test_ramp_fitted_as_white_noise_is_rejected():
    rng = np.random.default_rng(0)
    x = rng.standard_normal(2**15) + 1e-3 * np.arange(2**15)
    res = gmwm.fit(x, "WN")
    assert res.converged   # the optimiser reports nothing wrong
    g = res.gof
    assert g.rejected() and g.p_value < 1e-10
    w = g.warning()
    assert w is not None and "rejected" in w
    # the misfit sits at the long scales, the short ones fit
    u = np.abs(g.residuals)
    assert np.all(u[-5:] > 30) and np.all(u[:6] < 3)
    d = g.to_json_dict()
    assert {"statistic", "df", "p_value", "residuals", "scales_s", "rejected"} <= set(d)
    assert d["df"] == res.wv.n_levels - 1 and d["rejected"] is True


def test_boundary_component_keeps_its_direction_and_no_df():
    m = Model("WN+AR1+RW")
    x = m.simulate(m.theta(AR1_RW), 2**15, np.random.default_rng(3))
    res = gmwm.fit(x, m)
    assert res.diagnostics["at_boundary"] == ["RW[1]"]   # this seed puts the RW at 0
    g = res.gof
    # the RW's direction is projected out (df as for the free model); held, it would count
    assert g.df == res.wv.n_levels - 4 and 0 < g.p_value <= 1
    old = gof_test(res, hold_boundary=True)
    assert old.df == res.wv.n_levels - 3 and old.p_value != g.p_value
    # as many parameters as scales: not testable, said so
    wv = gmwm.wvar(x, levels=2)
    g0 = gmwm.fit(wv, "WN+RW").gof
    assert g0.df == 0 and np.isnan(g0.p_value) and not g0.rejected()
    assert "not testable" in g0.line()


def test_boundary_correction_by_hand_on_a_linear_model():
    """WN+RW is linear in (sigma2, gamma2): nu = A theta with A_j = (1 / tau_j, (tau_j^2 + 2) /
    (12 tau_j)). White noise fitted as WN+RW puts the RW at 0; the corrected residual is then the
    residual of the sign-free weighted least-squares fit (a negative gamma2), and each score is
    the gamma law's at the constrained fit's WV plus that residual, with the variance of the
    projected residual. An interior fit is left as it was."""
    from gmwm.inference import Problem

    rng = np.random.default_rng(11)
    res = gmwm.fit(rng.standard_normal(2**12), "WN+RW")
    assert res.diagnostics["at_boundary"] == ["RW[1]"]    # this seed puts the RW at 0
    tau = res.wv.scales.astype(float)
    A = np.column_stack([1.0 / tau, (tau**2 + 2.0) / (12.0 * tau)])
    omega = Problem.of(res).omega
    nu_hat = res.wv.variance
    theta_free = np.linalg.solve(A.T @ omega @ A, A.T @ omega @ nu_hat)
    assert theta_free[1] < 0                              # the data want a negative RW
    nu_c = A @ np.asarray(res.params)
    r_free = nu_hat - A @ theta_free
    M = np.eye(tau.size) - A @ np.linalg.solve(A.T @ omega @ A, A.T @ omega)
    var = np.diag(M @ res.wv_cov @ M.T)
    shape, scale = nu_c**2 / var, var / nu_c
    u = stats.norm.ppf(stats.gamma.cdf(nu_c + r_free, shape, scale=scale))
    g = res.gof
    assert g.df == tau.size - 2
    np.testing.assert_allclose(g.residuals, u, rtol=1e-6, atol=1e-6)
    assert any(n.startswith("RW[1] at the boundary 0") for n in g.notes)   # the caveat, carried
    # the held test scores the constrained residual itself
    held = gof_test(res, hold_boundary=True)
    assert held.df == tau.size - 1 and not any("boundary" in n for n in held.notes)
    assert np.max(np.abs(held.residuals - g.residuals)) > 0.1
    # interior fit (a real RW): both tests are the same test
    x = Model("WN+RW").simulate(np.array([1.0, 1e-4]), 2**12, np.random.default_rng(12))
    inner = gmwm.fit(x, "WN+RW")
    assert not inner.diagnostics["at_boundary"]
    held = gof_test(inner, hold_boundary=True)
    assert held.df == inner.gof.df
    np.testing.assert_allclose(held.residuals, inner.gof.residuals, rtol=1e-8, atol=1e-10)
    assert held.p_value == pytest.approx(inner.gof.p_value, rel=1e-8)


@pytest.mark.slow
def test_size_with_a_weak_component_fitted_at_zero():
    """Issue 40's case (WN + AR1 + RW with the RW at 1-2 SE, T = 2^15; the RW at 0 in about a
    third of the fits), 60 seeded default fits: the test rejects at most 6 (10 %) at 5 %; held at
    0, the RW made the test of WN + AR1 and it rejected 10 of the same fits (3-6 against 5-10
    over eight blocks of 60 seeds; 5.0 % against 11.3 % at R = 400, benchmarks/README.md)."""
    m = Model("WN+AR1+RW")
    theta = m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.99, "AR1[1].sigma2": 0.01,
                     "RW[1].gamma2": 2e-5})
    new, old, at0 = [], [], 0
    for r in range(60):
        x = m.simulate_fast(theta, 2**15, np.random.default_rng([41, r]))
        res = gmwm.fit(x, m)
        new.append(res.gof.p_value)
        old.append(gof_test(res, hold_boundary=True).p_value)
        at0 += bool(res.diagnostics["at_boundary"])
    new, old = np.array(new), np.array(old)
    assert at0 >= 10 and np.all(np.isfinite(new))
    assert np.sum(new < 0.05) <= 6 < np.sum(old < 0.05)


def test_efficient_weights_and_armav():
    m = Model("WN+AR1+RW")
    x = m.simulate(m.theta(AR1_RW), 2**15, np.random.default_rng(5))
    for kw in ({"weights": "efficient"}, {"method": "armav"}):
        g = gmwm.fit(x, m, **kw).gof
        assert 0.01 < g.p_value <= 1 and g.df >= res_df(m, x)


def res_df(m: Model, x: np.ndarray) -> int:
    return gmwm.wvar(x).n_levels - m.n_params


def test_fit_carries_the_test_on_every_surface():
    """gmwm.fit computes the test (the same as gof_test on the result); a rejected model is a
    warning in res.warnings, summary() and to_json_dict(), with the per-scale residuals."""
    import json

    rng = np.random.default_rng(0)
    x = rng.standard_normal(2**14) + 1e-3 * np.arange(2**14)
    res = gmwm.fit(x, "WN")
    g = gof_test(res)
    assert (res.gof.statistic, res.gof.df, res.gof.p_value) == (g.statistic, g.df, g.p_value)
    w = res.gof.warning()
    assert w in res.warnings and w in res.diagnostics["warnings"]
    text = res.summary()
    assert res.gof.line() in text and f"warning: {w}" in text
    d = json.loads(json.dumps(res.to_json_dict(), allow_nan=False))
    assert d["gof"]["rejected"] is True and d["gof"]["df"] == res.wv.n_levels - 1
    assert len(d["gof"]["residuals"]) == res.wv.n_levels and w in d["warnings"]
    # an accepted model: no warning, the line says p
    ok = gmwm.fit(rng.standard_normal(2**14), "WN")
    assert not ok.gof.rejected() and not any("goodness" in v for v in ok.warnings)
    assert "goodness of fit: statistic" in ok.summary()


def test_which_covariance_the_fit_s_test_uses():
    m = Model("WN+AR1+RW")
    x = m.simulate(m.theta(AR1_RW), 2**13, np.random.default_rng(9))
    fast = gmwm.fit(x, m, se_cov="gaussian", n_starts=1)
    assert fast.gof is None                      # the bootstrap's path: not computed
    model_based = gmwm.fit(x, m, n_starts=1)
    assert gof_test(fast).statistic == pytest.approx(model_based.gof.statistic, rel=1e-6)
    V = 1.5 * model_based.wv_cov                 # a user covariance: taken as given
    for kw in ({"weights": V}, {"se_cov": V}):
        res = gmwm.fit(x, m, n_starts=1, **kw)
        assert res.gof.statistic == gof_test(res, V).statistic
    rob = gmwm.fit(x, m, robust=True, n_starts=1)   # the classical covariance / efficiency, once
    assert rob.gof.statistic == gof_test(rob, rob.wv_cov / rob.wv.efficiency).statistic


def test_far_tail_skips_imhof_with_the_same_answer():
    # far in the tail the saddlepoint is returned without the Imhof integral; Imhof's own p is
    # below the switch there, so the longer path would have returned the same number
    from gmwm.gof import SADDLE_BELOW, _imhof_sf, _saddle_sf, weighted_chi2_sf

    rng = np.random.default_rng(3)
    for _ in range(20):
        lam = rng.gamma(1.0, 1.0, int(rng.integers(3, 15)))
        lam /= lam.max()
        x = float(lam.sum() * rng.uniform(8.0, 40.0))
        p, how = weighted_chi2_sf(x, lam)
        q = _saddle_sf(x, lam)
        if q < SADDLE_BELOW * 1e-3:
            assert how == "saddlepoint" and p == q
            assert _imhof_sf(x, lam) < SADDLE_BELOW


@pytest.mark.slow
def test_weak_sinusoid_fitted_elsewhere_leaves_its_wv_in_the_residual():
    """Issue 40, gyro WN+SIN+RW of benchmarks/selection_penalty.py at T = 2^17 (the SIN at an
    expected z of 4): the test's excess size there comes from fits whose sinusoid sits at another
    frequency at the global optimum of the fit's criterion (not a search failure), leaving the
    true sinusoid's WV in the residual at the scales it occupies (bench_gof.py --calibration,
    "SIN frequency off" column). This pins that mechanism on one seeded replicate; a change
    to the test that removes the excess should turn its p-value up while keeping the fit."""
    from gmwm.inference import Problem
    from gmwm.search import Search

    model = Model("WN+SIN+RW")
    theta = model.theta({"WN[1].sigma2": 1.0, "SIN[1].alpha": 0.02889725603511109,
                         "SIN[1].beta": 2 * np.pi / 2000, "RW[1].gamma2": 1.328259463558017e-06})
    T = 2**17
    x = model.simulate_fast(theta, T, np.random.default_rng([2050, T, 576]))
    res = gmwm.fit(x, model)
    beta_hat = float(res.params[2])
    assert beta_hat > 100 * theta[2]            # the fitted sinusoid is elsewhere
    # a search with the truth as an extra start ends at the same optimum: the fit's criterion
    # prefers that frequency (a weak SIN's frequency is not identified), the search is not at fault
    s = res.settings
    prob = Problem(model, res.wv, res.weights, "gmwm")
    node = Search(s.n_starts, s.seed, 1.0, s.max_nfev, s.nested).run(prob, extra_starts=[theta])
    assert node.objective == pytest.approx(res.objective, rel=1e-8)
    r_true = prob.residual(theta)
    assert float(r_true @ r_true) > res.objective
    # the test at the fit's own frequency rejects the true model, and its largest normal score
    # sits at the scale where the true sinusoid's share of the WV is largest
    own = gof_test(res, sin_frequency=False)
    assert own.p_value < 0.005
    share = model.component_wv(theta, res.wv.scales)["SIN[1]"] / model.wv(theta, res.wv.scales)
    u = np.asarray(own.residuals)
    j = int(np.nanargmax(np.abs(u)))
    assert j == int(np.argmax(share)) and u[j] > 3
    # the default test takes the largest p over the competing frequencies: it rises ~20x (0.014)
    # but stays below 5 %: this record is rejected even with the frequency held at the truth
    # (p 0.0012 there), one of the true model's 5 %, not a failure of the correction
    g = res.gof
    assert g.residuals is not None and np.array_equal(g.residuals, own.residuals, equal_nan=True)
    assert 10 * own.p_value < g.p_value < 0.05
    assert any("frequency not identified" in n for n in g.notes)
    held = _held_at(res, 1, float(theta[2]))
    assert held.p_value < 0.005 and held.p_value < g.p_value


def _held_at(res, k: int, beta: float):
    """The test of ``res``'s model with SIN component k's frequency held at ``beta``."""
    import math

    from gmwm import gof
    from gmwm.inference import Problem
    from gmwm.search import VP, shapes_of

    model, prob = res.model, Problem.of(res)
    vp = VP(model, prob.tau, prob.nu_hat, prob.white, 1.0, np.random.default_rng(0))
    shapes = shapes_of(model, np.asarray(res.params), prob.tau)
    shapes[k] = math.log(beta)
    q, theta = gof._held_fit(res, vp, shapes, k, 1.0)
    return gof._held_test(res, None, model.components[k].name, q, theta)


# the gyro WN+SIN+RW of benchmarks/selection_penalty.py at T = 2^17 (SIN at an expected z of 4)
GYRO_SIN = {"WN[1].sigma2": 1.0, "SIN[1].alpha": 0.02889725603511109,
            "SIN[1].beta": 2 * np.pi / 2000, "RW[1].gamma2": 1.328259463558017e-06}


def test_weak_sinusoid_p_value_is_the_largest_over_its_frequency():
    """A record whose fit seats the weak SIN ~600x from its true frequency: the test at that
    seating rejects the true model at 5 %; the default test, the largest p over the seatings
    the objective cannot tell apart, does not, and says so in its notes."""
    model = Model("WN+SIN+RW")
    theta = model.theta(GYRO_SIN)
    T = 2**17
    x = model.simulate_fast(theta, T, np.random.default_rng([2031, T, 10]))
    res = gmwm.fit(x, model)
    assert res.params[2] > 100 * theta[2]         # the fit's SIN is elsewhere
    own = gof_test(res, sin_frequency=False)
    g = res.gof
    assert own.p_value < 0.05 <= g.p_value
    note = next(n for n in g.notes if "frequency not identified" in n)
    assert note.startswith("SIN[1]") and "largest" in note and "conservative" in note
    assert "held at beta" in note and f"{own.p_value:.3g}" in note
    assert g.df == own.df + 1                      # the frequency held: one more df
    # the fit's own statistic and residuals stay the fit's
    np.testing.assert_array_equal(g.residuals, own.residuals)
    assert g.objective == own.objective
    # held near the truth, the test agrees with the true model too
    assert _held_at(res, 1, float(theta[2])).p_value > 0.05
    # ARMAV (log scale: the variable projection is not its objective) keeps the fit's own test
    arm = gmwm.fit(res.wv, model, method="armav")
    assert arm.gof.p_value == gof_test(arm, sin_frequency=False).p_value


def test_identified_or_no_sinusoid_leaves_the_test_unchanged():
    """Models without a SIN, and a strong fast SIN whose frequency the data identify: the
    default test is exactly the test at the fit's own frequency, with no note."""
    m = Model("WN+AR1+RW")
    res = gmwm.fit(m.simulate_fast(m.theta(AR1_RW), 2**13, np.random.default_rng(7)), m)
    own = gof_test(res, sin_frequency=False)
    assert res.gof.p_value == own.p_value and res.gof.notes == own.notes
    m = Model("WN+AR1+SIN")
    theta = m.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                     "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35})
    res = gmwm.fit(m.simulate_fast(theta, 2**14, np.random.default_rng(8)), m)
    own = gof_test(res, sin_frequency=False)
    g = res.gof
    assert (g.p_value, g.statistic, g.df) == (own.p_value, own.statistic, own.df)
    assert g.notes == own.notes and not any("not identified" in n for n in g.notes)
    from gmwm.gof import _sin_seatings

    assert _sin_seatings(res, None) == []          # the scan ran and found no competitor
