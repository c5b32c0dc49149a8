"""Theoretical WV, Jacobians and simulation of every process, and model parsing."""

import mpmath as mp
import numpy as np
import pytest

from gmwm.errors import ModelError
from gmwm.model import Model, parse_model
from gmwm.processes import PROCESSES, ar1_unit_wv, ar1_unit_wv_many
from gmwm.wv import wvar_many

TAU = 2.0 ** np.arange(1, 21)


def _ar1_exact(phi: float, tau: int) -> mp.mpf:
    phi = mp.mpf(phi)
    m = tau // 2
    num = (1 - phi**2) * tau - 2 * phi * (3 - 4 * phi**m + phi**tau)
    return num / (tau**2 * (1 - phi) ** 2 * (1 - phi**2))


@pytest.mark.parametrize("phi", [-0.5, 0.3, 0.975, 0.9997083, 0.999995, 1 - 1e-8])
def test_ar1_wv_and_derivative_match_60_digit_arithmetic(phi):
    mp.mp.dps = 60
    tau = TAU[:14] if phi < 0 else TAU
    nu, dnu = ar1_unit_wv(phi, tau)
    exact = np.array([float(_ar1_exact(phi, int(t))) for t in tau])
    dexact = np.array([float(mp.diff(lambda p, t=int(t): _ar1_exact(p, t), mp.mpf(phi)))
                       for t in tau])
    # docs/METHODS.md §3.6: stable recipe <= 2.5e-12 (WV) and <= 1.7e-9 (d/dphi) against mpmath
    np.testing.assert_allclose(nu, exact, rtol=5e-12)
    np.testing.assert_allclose(dnu, dexact, rtol=5e-9)


CASES = {
    "QN": [2e-7], "WN": [1e-4], "RW": [1e-10], "DR": [1e-8], "AR1": [0.9, 3e-5],
    "GM": [0.5, 1e-6], "SIN": [0.0015, 0.05],
}


@pytest.mark.parametrize("name", list(CASES))
def test_jacobian_matches_central_differences(name):
    proc = PROCESSES[name]
    p = np.array(CASES[name])
    # the SIN WV oscillates in beta with frequency tau/4: keep the step small relative to that
    tau = TAU[:14] if name == "SIN" else TAU
    jac = proc.jacobian(p, tau, 250.0)
    for i in range(p.size):
        h = abs(p[i]) * 1e-6
        up, dn = p.copy(), p.copy()
        up[i] += h
        dn[i] -= h
        fd = (proc.wv(up, tau, 250.0) - proc.wv(dn, tau, 250.0)) / (2 * h)
        ok = np.abs(jac[:, i]) > 1e-300
        # float64 central differences lose up to ~6 digits where nu barely depends on the
        # parameter (GM beta at short scales); a wrong formula would be off by O(1). The AR1
        # test above checks the delicate branch against 60-digit arithmetic instead.
        np.testing.assert_allclose(jac[ok, i], fd[ok], rtol=1e-5)


def test_sin_wv_is_stable_for_slow_sinusoids():
    mp.mp.dps = 50
    alpha, beta = 0.0015, 8e-6
    nu = PROCESSES["SIN"].wv(np.array([alpha, beta]), TAU[:13])
    exact = [float(alpha**2 * (1 - mp.cos(mp.mpf(beta) * t / 2)) ** 2
                   / (t**2 * (1 - mp.cos(mp.mpf(beta))))) for t in TAU[:13]]
    np.testing.assert_allclose(nu, exact, rtol=1e-12)


MC_MODELS = [
    ("WN", {"WN[1].sigma2": 1.0}),
    ("QN", {"QN[1].Q2": 2.0}),
    ("RW", {"RW[1].gamma2": 1e-2}),
    ("AR1", {"AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03}),
    ("AR1", {"AR1[1].phi": -0.5, "AR1[1].sigma2": 1.0}),
    ("GM", {"GM[1].beta": 5.0, "GM[1].sigma2": 2.0}),
    ("WN+RW+AR1+SIN", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975,
                       "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35}),
]


@pytest.mark.parametrize(("spec", "truth"), MC_MODELS)
def test_theoretical_wv_matches_simulation(spec, truth):
    """Mean empirical WV over R seeded replicates vs theory, level by level.

    The estimator is unbiased (docs/METHODS.md §2.5), so (mean - theory) / (SD / sqrt(R)) is ~N(0, 1) at each
    level; over 10 levels and 7 models a bound of 4.5 is crossed by chance with probability < 1e-3.
    """
    model = Model(spec, freq=100.0)
    theta = model.theta(truth)
    R, T, J = 60, 2**14, 10
    rng = np.random.default_rng(12345)
    X = np.stack([model.simulate(theta, T, rng) for _ in range(R)])
    nu_hat = wvar_many(X, levels=J)
    theory = model.wv(theta, 2.0 ** np.arange(1, J + 1))
    z = (nu_hat.mean(0) - theory) / (nu_hat.std(0, ddof=1) / np.sqrt(R))
    assert np.max(np.abs(z)) < 4.5, z


def test_drift_wv_is_exact():
    model = Model("DR")
    x = model.simulate(np.array([1e-3]), 5000)
    nu = wvar_many(x[None, :], levels=10)[0]
    np.testing.assert_allclose(nu, model.wv([1e-3], 2.0 ** np.arange(1, 11)), rtol=1e-10)


def test_sin_wv_matches_simulation_exactly_in_expectation():
    # SIN: E nu_hat = nu exactly over U; the error is O(1/T) ([Vibration] Lemma 1), so 200 reps of
    # T = 2^15 pin the mean to ~1e-4 relative at the first levels
    model = Model("SIN")
    theta = np.array([0.85, 0.35])
    rng = np.random.default_rng(3)
    X = np.stack([model.simulate(theta, 2**15, rng) for _ in range(200)])
    nu_hat = wvar_many(X, levels=6).mean(0)
    np.testing.assert_allclose(nu_hat, model.wv(theta, 2.0 ** np.arange(1, 7)), rtol=2e-3)


def test_model_parsing_names_and_canonical_order():
    m = Model("SIN + 2*AR1 + wn + RW")
    assert m.spec == "WN+2*AR1+SIN+RW"
    assert m.param_names == ["WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "AR1[2].phi",
                             "AR1[2].sigma2", "SIN[1].alpha", "SIN[1].beta", "RW[1].gamma2"]
    theta = m.theta({"WN[1].sigma2": 1, "AR1[1].phi": 0.99, "AR1[1].sigma2": 2,
                     "AR1[2].phi": 0.1, "AR1[2].sigma2": 3, "SIN[1].alpha": 1,
                     "SIN[1].beta": 0.1, "RW[1].gamma2": 1e-4})
    # AR1 components are relabelled by increasing phi, carrying their variances along
    assert m.as_dict(theta)["AR1[1].phi"] == 0.1 and m.as_dict(theta)["AR1[1].sigma2"] == 3
    sins = Model("2*SIN")
    th = sins.canonical(np.array([1.0, 0.01, 2.0, 1.0]))
    assert list(th) == [2.0, 1.0, 1.0, 0.01]  # decreasing beta
    gms = Model("2*GM", freq=100)
    th = gms.canonical(np.array([0.1, 1.0, 10.0, 2.0]))
    assert list(th) == [10.0, 2.0, 0.1, 1.0]  # increasing correlation time 1/beta


@pytest.mark.parametrize(("spec", "msg"), [
    ("WN+FOO", "unknown process"), ("", "empty"), ("2*WN", "not identifiable"),
    ("WN++RW", "cannot read"), ("0*AR1", "at least 1"),
])
def test_bad_model_strings(spec, msg):
    with pytest.raises(ModelError, match=msg):
        parse_model(spec)


def test_bad_parameters_are_named():
    m = Model("AR1+SIN")
    with pytest.raises(ModelError, match="AR1\\[1\\]: phi must lie in"):
        m.theta({"AR1[1].phi": 1.2, "AR1[1].sigma2": 1, "SIN[1].alpha": 1, "SIN[1].beta": 1})
    with pytest.raises(ModelError, match="missing value"):
        m.theta({"AR1[1].phi": 0.5})
    with pytest.raises(ModelError, match="unknown parameter"):
        m.theta({"AR1[1].phi": 0.5, "AR1[1].sigma2": 1, "SIN[1].alpha": 1, "SIN[1].beta": 1,
                 "WN[1].sigma2": 1})


def test_free_transform_round_trip_and_derivative():
    m = Model("QN+WN+AR1+GM+SIN+RW+DR", freq=250)
    theta = np.array([1e-7, 1e-4, 0.999995, 3e-11, 0.5, 1e-6, 0.0015, 8e-6, 1e-12, 1e-8])
    eta = m.to_free(theta)
    np.testing.assert_allclose(m.from_free(eta), theta, rtol=1e-9)
    h = 1e-6
    fd = (m.from_free(eta + h) - m.from_free(eta - h)) / (2 * h)
    np.testing.assert_allclose(m.dtheta_deta(eta), fd, rtol=1e-5)


def test_simulation_is_reproducible_from_a_seed():
    m = Model("WN+RW+AR1+SIN")
    theta = m.theta({"WN[1].sigma2": 1, "RW[1].gamma2": 4e-4, "AR1[1].phi": 0.975,
                     "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35})
    np.testing.assert_array_equal(m.simulate(theta, 1000, 7), m.simulate(theta, 1000, 7))
    assert not np.array_equal(m.simulate(theta, 1000, 7), m.simulate(theta, 1000, 8))


def test_ar1_wv_many_rows_equal_the_single_evaluation():
    # one kernel per entry point: the vectorised WV (grid scans, posteriors) must be the same
    # function as the one the optimiser differentiates, on both branches and at the series switch
    tau = TAU
    phi = np.concatenate([[-0.999, -0.5, 0.0, 1e-300, 0.3, 0.975, 0.999995, 1 - 1e-8],
                          np.exp(-1e-2 / (tau / 2))])  # m a exactly at the switch
    many = ar1_unit_wv_many(phi, tau)
    single = np.array([ar1_unit_wv(p, tau)[0] for p in phi])
    np.testing.assert_allclose(many, single, rtol=1e-13, atol=0)
    assert np.all(np.isfinite(many)) and np.all(many > 0)


FAST_MODELS = [
    ("WN+RW", {"WN[1].sigma2": 1.7e-3, "RW[1].gamma2": 1.5e-8}),  # STIM-300 gyro-like ratio
    ("QN+WN+RW+DR", {"QN[1].Q2": 2e-3, "WN[1].sigma2": 1.5e-4, "RW[1].gamma2": 1.6e-7,
                     "DR[1].omega": 1e-6}),
    ("AR1+RW+WN+SIN", {"WN[1].sigma2": 8e-4, "AR1[1].phi": 0.99, "AR1[1].sigma2": 9e-6,
                       "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056, "RW[1].gamma2": 3e-9}),
    ("2*AR1+2*SIN", {"AR1[1].phi": -0.4, "AR1[1].sigma2": 5e-4, "AR1[2].phi": 0.999,
                     "AR1[2].sigma2": 3e-8, "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
                     "SIN[2].alpha": 0.0015, "SIN[2].beta": 1e-3}),
    ("WN+GM+RW", {"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-6,
                  "RW[1].gamma2": 1e-11}),
]


@pytest.mark.parametrize(("spec", "truth"), FAST_MODELS)
def test_simulate_fast_has_the_wv_distribution_of_simulate(spec, truth):
    """simulate_fast's claim: the same distribution as simulate up to a constant, so the same WV
    distribution. Mean: (mean - theory) / MC SE ~ N(0, 1) per level, bound 4.5 as above. Spread:
    the replicate SDs of the two simulators per level; with R = 120 each, log(SD ratio) has SD
    ~ sqrt(1/R) ~ 0.09 (Gaussian-like WV at short scales, heavier at long ones), so 0.45 is ~5 SD
    at short scales; a wrong MA(1) coefficient moves the walk's WV by a factor >= 1.5."""
    model = Model(spec, freq=100.0)
    theta = model.theta(truth)
    R, T, J = 120, 2**13, 9
    rng = np.random.default_rng(2024)
    fast = wvar_many(np.stack([model.simulate_fast(theta, T, rng, block=3000)
                               for _ in range(R)]), levels=J)
    ref = wvar_many(np.stack([model.simulate(theta, T, rng) for _ in range(R)]), levels=J)
    theory = model.wv(theta, 2.0 ** np.arange(1, J + 1))
    z = (fast.mean(0) - theory) / (fast.std(0, ddof=1) / np.sqrt(R))
    assert np.max(np.abs(z)) < 4.5, z
    log_ratio = np.log(fast.std(0, ddof=1) / ref.std(0, ddof=1))
    assert np.max(np.abs(log_ratio)) < 0.45, log_ratio


@pytest.mark.parametrize(("sigma2", "gamma2"), [(1.0, 0.0), (0.0, 2.0), (1.7e-3, 1.5e-13),
                                                (1.0, 1.0)])
def test_simulate_fast_walk_has_the_increment_covariance_of_wn_plus_rw(sigma2, gamma2):
    """Increments of WN + RW: variance 2 sigma2 + gamma2, lag-1 covariance -sigma2, none beyond.
    Sample autocovariances of n = 4e5 increments have SD <= c0 sqrt(2 / n) ~ 2.2e-3 c0."""
    model = Model("WN+RW") if sigma2 and gamma2 else Model("WN" if sigma2 else "RW")
    theta = [v for v in (sigma2, gamma2) if v]
    d = np.diff(model.simulate_fast(theta, 400_001, np.random.default_rng(11)))
    c0 = 2 * sigma2 + gamma2
    acov = [np.mean(d[k:] * d[:d.size - k]) for k in range(3)]
    np.testing.assert_allclose(acov, [c0, -sigma2, 0.0], atol=5 * c0 * np.sqrt(2 / d.size))


def test_simulate_fast_sinusoid_drift_and_reproducibility():
    m = Model("SIN+DR")
    theta = np.array([0.025, 8e-6, 1e-3])
    n = 200_000
    x = m.simulate_fast(theta, n, 3, block=7001)
    phase = np.random.default_rng(3).uniform(0.0, 2 * np.pi)  # the stream's first draw
    t = np.arange(1, n + 1, dtype=float)
    np.testing.assert_allclose(x, 0.025 * np.sin(8e-6 * t + phase) + 1e-3 * t, rtol=0,
                               atol=1e-12)
    np.testing.assert_array_equal(x, m.simulate_fast(theta, n, 3, block=7001))
    with pytest.raises(ModelError, match="positive"):
        m.simulate_fast(theta, 0, 3)
    with pytest.raises(ModelError, match="alpha"):
        m.simulate_fast(np.array([-1.0, 1e-3, 1.0]), 10, 3)


def test_every_process_states_its_domain():
    import math

    from gmwm.processes import PROCESSES

    for name, proc in PROCESSES.items():
        dom = proc.domain
        assert len(dom) == proc.n_params, name
        assert all(lo < hi for lo, hi in dom), name
        i = proc.scale_index
        assert dom[i] == (0.0, math.inf), name    # a scale parameter (|omega| for DR) >= 0
    assert PROCESSES["AR1"].domain[0] == (-1.0, 1.0)
    assert PROCESSES["SIN"].domain[1] == (0.0, math.pi)
    assert PROCESSES["GM"].domain[0] == (0.0, math.inf)


def test_process_lookup_and_roles():
    from gmwm.processes import SINGLETONS, process

    assert process("GM") is PROCESSES["GM"]
    with pytest.raises(ModelError, match="unknown process 'XX'"):
        process("XX")
    assert SINGLETONS == {"QN", "WN", "RW", "DR"}
    assert {n for n, p in PROCESSES.items() if p.filter_term} == {"WN", "RW"}
    assert {n for n, p in PROCESSES.items() if p.slow_term} == {"GM", "AR1"}
    assert {n for n, p in PROCESSES.items() if p.scale_power == 2} == {"SIN", "DR"}
