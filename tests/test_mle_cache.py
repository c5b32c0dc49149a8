"""The MLE's shortcuts change no result: the per-signal preparation, the remembered likelihood
evaluations and the division-free steady-state test (gmwm_studies.mle)."""

from __future__ import annotations

import numpy as np
import pytest

from gmwm_studies.mle import (
    _STEADY_TOL,
    _fourier_cos,
    _prepared,
    _Profile,
    _regressors,
    _riccati_step,
    _shared_regressors,
    _whittle_info,
    fit_mle,
    mle_covariance,
)

BETA = 0.35


def _signal(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    ar = np.zeros(n)
    w = rng.normal(0.0, np.sqrt(0.03), n)
    for t in range(1, n):
        ar[t] = 0.975 * ar[t - 1] + w[t]
    return (rng.normal(size=n) + np.cumsum(rng.normal(0.0, 0.02, n)) + ar
            + 0.85 * np.sin(BETA * np.arange(n) + 1.0))


def _steady_reference(p11: float, p12: float, p22: float, prev: float, g2: float, s2ar: float,
                      phi: float) -> bool:
    """The steady-state verdict as first written (with the division on every step)."""
    m1, m2 = p11 + p12, p12 + p22
    f = m1 + m2 + 1.0
    k1, k2 = m1 / f, m2 / f
    n11 = p11 - m1 * k1 + g2
    n12 = phi * (p12 - m1 * k2)
    n22 = phi * phi * (p22 - m2 * k2) + s2ar
    step = abs(n11 - p11) + abs(n12 - p12) + abs(n22 - p22)
    rate = step / prev if prev > 0.0 else 0.0
    return step == 0.0 or (rate < 1.0 and step <= _STEADY_TOL * (1.0 - rate)
                           * (abs(n11) + abs(n22)))


def test_steady_verdict_matches_the_division_form_along_real_recursions():
    # every step of recursions that do and do not reach the limit, where the verdict flips
    flips = 0
    for g2, s2ar, phi, steps in [(4e-4, 0.03, 0.975, 6000), (1e-2, 0.5, 0.3, 300),
                                 (1e-9, 1e-9, -0.5, 500), (0.3, 2.0, 0.0, 100)]:
        pc = s2ar / (1.0 - phi * phi)
        p11, p12, p22, prev = pc + 1.0 + g2, -phi * pc, pc, np.inf
        last = False
        for _ in range(steps):
            ref = _steady_reference(p11, p12, p22, prev, g2, s2ar, phi)
            *_, p11, p12, p22, prev, steady = _riccati_step(p11, p12, p22, prev, 1.0, g2, s2ar,
                                                             phi)
            assert steady == ref
            flips += steady != last
            last = steady
            if steady:
                break
    assert flips >= 3  # the comparison reached the steady state in several recursions


def test_steady_verdict_matches_near_the_tolerance():
    # covariances a few ulps away from the limit and previous steps around the step: the verdicts
    # of both forms agree on both sides of the tolerance
    rng = np.random.default_rng(1)
    verdicts = set()
    for g2, s2ar, phi in [(1e-2, 0.5, 0.3), (0.3, 2.0, 0.0), (5e-3, 0.1, 0.9)]:
        pc = s2ar / (1.0 - phi * phi)
        p11, p12, p22, prev = pc + 1.0 + g2, -phi * pc, pc, np.inf
        for _ in range(3000):
            *_, p11, p12, p22, prev, steady = _riccati_step(p11, p12, p22, prev, 1.0, g2, s2ar,
                                                             phi)
            if steady:
                break
        assert steady
        for _ in range(200):
            q11, q12, q22 = np.array([p11, p12, p22]) * (1.0 + rng.integers(-40, 41, 3) * 2e-16)
            step = _riccati_step(q11, q12, q22, np.inf, 1.0, g2, s2ar, phi)[7]
            for prev in step * np.array([0.5, 1.0, 1.5, 3.0, 1e3]):
                got = _riccati_step(q11, q12, q22, prev, 1.0, g2, s2ar, phi)[-1]
                assert got == _steady_reference(q11, q12, q22, prev, g2, s2ar, phi)
                verdicts.add(got)
    assert verdicts == {True, False}


def test_prepared_is_rebuilt_for_a_changed_signal():
    x = _signal(500, 0)
    a = _prepared(x, BETA)
    assert _prepared(x.copy(), BETA) is a  # equal values: the same preparation
    y = x.copy()
    y[250] += 1e-9
    b = _prepared(y, BETA)
    assert b is not a and b.Y[250, 0] == y[250]
    assert _prepared(y, BETA + 1e-3) is not b  # another frequency
    np.testing.assert_array_equal(b.X, _regressors(500, BETA))
    assert not b.Y.flags.writeable and not _shared_regressors(500, BETA).flags.writeable


def test_fourier_cosines_give_the_same_information():
    n = 1001
    w = 2.0 * np.pi * np.arange(1, (n - 1) // 2 + 1) / n
    np.testing.assert_array_equal(_fourier_cos(n), np.cos(w))
    eta = np.array([0.0, np.log(4e-4), np.log(0.03), np.arctanh(0.975), 0.5, 0.1])
    info = _whittle_info(eta, n, BETA)
    assert np.all(np.isfinite(info)) and info[4, 4] > 0


def test_profile_memo_returns_fresh_copies_of_the_same_values():
    x = _signal(800, 2)
    X = _regressors(x.size, BETA)
    memo, fresh = _Profile(x, X), _Profile(x, X)
    r = np.array([np.log(4e-4), np.log(0.03), np.arctanh(0.975)])
    ll, theta, b = memo.solve(r)
    theta["WN[1].sigma2"] = -1.0  # a caller changing its copy must not change the memory
    b[:] = 0.0
    ll2, theta2, b2 = memo.solve(r.copy())
    ll3, theta3, b3 = fresh.solve(r)
    assert ll2 == ll3 == ll and theta2 == theta3 and np.array_equal(b2, b3)
    for k in range(2 * _Profile._MEMO):  # more points than it keeps: still the same answers
        rk = r + 1e-3 * k
        assert memo(rk) == fresh(rk)


@pytest.mark.parametrize("own_starts", ["variogram", "default"])
def test_fit_is_the_same_with_and_without_the_caches(own_starts):
    x = _signal(1500, 3)
    first = fit_mle(x, BETA, n_starts=1, maxiter=20, own_starts=own_starts, se=True)
    _prepared(np.zeros(3), BETA)  # evict the preparation
    again = fit_mle(x.copy(), BETA, n_starts=1, maxiter=20, own_starts=own_starts, se=True)
    np.testing.assert_array_equal(first.params, again.params)
    np.testing.assert_array_equal(first.cov, again.cov)
    assert (first.loglike, first.converged, first.message) == (again.loglike, again.converged,
                                                               again.message)
    theta = dict(zip(("WN[1].sigma2", "RW[1].gamma2", "AR1[1].phi", "AR1[1].sigma2"),
                     first.params[:4].tolist(), strict=True))
    if first.converged:
        np.testing.assert_array_equal(mle_covariance(x, BETA, theta), first.cov[:4, :4])
