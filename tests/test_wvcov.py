"""Tests of gmwm.wvcov: exact covariance of the Haar WV estimator.

Three independent references: (1) dense matrices (Cov(W) = H Cov(X) H^T, fourth moments summed
entry by entry) at small T, (2) direct lag sums with gamma_jk from a numerical convolution of the
filters with the autocovariance at moderate T, (3) Monte Carlo of gmwm.wvar_many (tolerances from
the Monte Carlo standard errors).
"""

from __future__ import annotations

import numpy as np
import pytest

from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.wv import wvar_many
from gmwm.wvcov import wv_correlation, wv_covariance


def _haar_rows(T: int, tau: int) -> np.ndarray:
    """Rows t = tau..T (1-based) of the boundary-free Haar MODWT filter matrix."""
    H = np.zeros((T - tau + 1, T))
    h = np.r_[np.full(tau // 2, 1.0), np.full(tau // 2, -1.0)] / tau
    for r, t in enumerate(range(tau, T + 1)):
        H[r, t - tau:t] = h[::-1]
    return H


def _dense_cov(model: Model, theta: np.ndarray, scales: np.ndarray, T: int) -> np.ndarray:
    """Cov(nu_hat) from dense matrices: Gaussian part, QN fourth cumulant and DR mean term."""
    t = np.arange(1, T + 1)
    lag = np.abs(np.subtract.outer(t, t))
    C = np.zeros((T, T))
    omega = q2 = 0.0
    for c in model.components:
        p = theta[c.slice]
        name = c.process.name
        if name == "WN":
            C += p[0] * np.eye(T)
        elif name == "RW":
            C += p[0] * np.minimum.outer(t, t)
        elif name == "AR1":
            C += p[1] / (1 - p[0] ** 2) * p[0] ** lag
        elif name == "GM":
            C += p[1] * np.exp(-p[0] / model.freq) ** lag
        elif name == "QN":
            q2 += p[0]
            C += p[0] * (2 * np.eye(T) - np.eye(T, k=1) - np.eye(T, k=-1))
        elif name == "DR":
            omega += p[0]
    D = np.eye(T, T + 1, k=1) - np.eye(T, T + 1)      # x_t = v_{t+1} - v_t (QN)
    H = [_haar_rows(T, int(s)) for s in scales]
    J = len(scales)
    V = np.zeros((J, J))
    for j in range(J):
        for k in range(J):
            G = H[j] @ C @ H[k].T
            mm = G.size
            V[j, k] = 2 * (G**2).sum() / mm
            V[j, k] += omega**2 * scales[j] * scales[k] / 4 * G.sum() / mm
            a2j = ((H[j] @ D) ** 2).sum(0)
            a2k = ((H[k] @ D) ** 2).sum(0)
            V[j, k] += -1.2 * q2**2 * (a2j * a2k).sum() / mm
    return V


DENSE_CASES = [
    ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 0.01}, 1.0),
    ("WN+AR1", {"WN[1].sigma2": 0.5, "AR1[1].phi": 0.9, "AR1[1].sigma2": 1.0}, 1.0),
    ("WN+AR1", {"WN[1].sigma2": 0.5, "AR1[1].phi": -0.5, "AR1[1].sigma2": 1.0}, 1.0),
    ("AR1", {"AR1[1].phi": -0.95, "AR1[1].sigma2": 1.0}, 1.0),
    ("AR1", {"AR1[1].phi": 0.999995, "AR1[1].sigma2": 3e-11}, 1.0),
    ("QN+WN+RW+DR", {"QN[1].Q2": 2.0, "WN[1].sigma2": 1.0, "RW[1].gamma2": 0.01,
                     "DR[1].omega": 0.02}, 1.0),
    ("WN+2*GM", {"WN[1].sigma2": 0.1, "GM[1].beta": 5.0, "GM[1].sigma2": 1.0,
                 "GM[2].beta": 0.05, "GM[2].sigma2": 2.0}, 10.0),
]


@pytest.mark.parametrize(("spec", "values", "freq"), DENSE_CASES)
def test_matches_dense_matrices(spec: str, values: dict, freq: float) -> None:
    model = Model(spec, freq=freq)
    theta = model.theta(values)
    T = 100
    scales = 2.0 ** np.arange(1, 7)
    V = wv_covariance(model, theta, scales, T)
    ref = _dense_cov(model, theta, scales, T)
    np.testing.assert_allclose(V, ref, rtol=1e-9, atol=1e-10 * np.abs(ref).max())


def _filter(tau: int) -> np.ndarray:
    return np.r_[np.full(tau // 2, 1.0), np.full(tau // 2, -1.0)] / tau


@pytest.mark.parametrize("phi", [0.95, -0.8, 0.9995])
def test_matches_direct_lag_sum(phi: float) -> None:
    """Long lag ranges (summed by quadrature in the module) against an explicit sum over every lag,
    gamma_jk(h) = sum_u c_jk(u) r(h - u), c_jk the filters' cross-correlation, r the
    autocovariance."""
    model = Model("WN+AR1")
    theta = model.theta({"WN[1].sigma2": 0.3, "AR1[1].phi": phi, "AR1[1].sigma2": 1.0})
    T = 5000
    scales = 2 ** np.arange(1, 12)
    V = wv_covariance(model, theta, scales, T)
    L = 2 * T
    r = phi ** np.abs(np.arange(-L, L + 1)) / (1 - phi**2)
    r[L] += 0.3
    for j, k in [(0, 0), (2, 3), (5, 5), (4, 9), (10, 10), (0, 10)]:
        tj, tk = int(scales[j]), int(scales[k])
        c = np.correlate(_filter(tj), _filter(tk), mode="full")     # u = -(tk-1)..tj-1
        g = np.convolve(r, c)                                        # lag of index i below
        lag = np.arange(g.size) - L - (tk - 1)
        h = np.arange(tj - T, T - tk + 1)
        gam = g[h - lag[0]]
        n = np.minimum(T, T + h) - np.maximum(tj, tk + h) + 1
        ref = 2 * np.sum(n * gam**2) / ((T - tj + 1) * (T - tk + 1))
        assert V[j, k] == pytest.approx(ref, rel=1e-8)


def test_white_noise_diagonal_closed_form() -> None:
    """Var(nu_hat_j) for WN: 2 sigma^4 / M^2 sum_h (M - |h|) c(h)^2 with the Haar autocorrelation
    c(h) tau^2 = 2m - 3|h| (|h| <= m), -(2m - |h|) (m <= |h| < 2m)."""
    sigma2 = 2.5
    T = 10**6
    scales = 2.0 ** np.arange(1, 19)
    V = wv_covariance(Model("WN"), np.array([sigma2]), scales, T)
    for j, tau in enumerate(scales.astype(int)):
        m = tau // 2
        h = np.arange(-tau + 1, tau)
        c = np.where(np.abs(h) <= m, 2 * m - 3 * np.abs(h), -(2 * m - np.abs(h))) / tau**2
        M = T - tau + 1
        exact = 2 * sigma2**2 * np.sum((M - np.abs(h)) * c**2) / M**2
        assert V[j, j] == pytest.approx(exact, rel=1e-10)
    # and the chi-square approximation 2 nu^2 / eta_3 is conservative (docs/METHODS.md §2.5)
    eta = (T - scales + 1) / scales
    assert np.all(np.diag(V) < 2 * (sigma2 / scales) ** 2 / eta)


def _mc_check(model: Model, theta: np.ndarray, T: int, J: int, R: int, seed: int,
              **kw: object) -> tuple[np.ndarray, np.ndarray]:
    """Assert MC variances and adjacent-scale correlations agree with wv_covariance within 4 MC
    standard errors; return (MC/analytic variance ratios, analytic V)."""
    rng = np.random.default_rng(np.random.SeedSequence(seed))
    X = np.array([model.simulate(theta, T, rng) for _ in range(R)])
    nu = wvar_many(X, J)
    V = wv_covariance(model, theta, 2.0 ** np.arange(1, J + 1), T, **kw)
    d = nu - nu.mean(0)
    var = (d**2).sum(0) / (R - 1)
    se_var = np.sqrt(np.maximum((d**4).mean(0) - var**2, 0) / R)
    z = (var - np.diag(V)) / se_var
    assert np.all(np.abs(z) < 4), f"variance z-scores {np.round(z, 2)}"
    rho_mc = np.diag(np.corrcoef(nu.T), 1)
    rho = np.diag(wv_correlation(V), 1)
    se_rho = (1 - rho**2) / np.sqrt(R) * 1.5      # 1.5: non-normal nu_hat at large scales
    zr = (rho_mc - rho) / se_rho
    assert np.all(np.abs(zr) < 4), f"correlation z-scores {np.round(zr, 2)}"
    return var / np.diag(V), V


MC_CASES = [
    ("WN", {"WN[1].sigma2": 1.0}),
    ("WN+RW", {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-3}),
    ("WN+AR1", {"WN[1].sigma2": 0.2, "AR1[1].phi": 0.9, "AR1[1].sigma2": 1.0}),
    ("WN+AR1", {"WN[1].sigma2": 0.2, "AR1[1].phi": -0.5, "AR1[1].sigma2": 1.0}),
    ("QN+WN+RW+DR", {"QN[1].Q2": 1.0, "WN[1].sigma2": 0.2, "RW[1].gamma2": 1e-3,
                     "DR[1].omega": 2e-3}),
]


@pytest.mark.parametrize(("spec", "values"), MC_CASES)
def test_monte_carlo(spec: str, values: dict) -> None:
    model = Model(spec)
    _mc_check(model, model.theta(values), T=2**12, J=8, R=800, seed=20261122)


def test_monte_carlo_sinusoid_interaction() -> None:
    """WN + AR1 + SIN (Simulation 1 values, T = 2^12): with the SIN x noise term the MC agrees;
    without it (docs/METHODS.md §5.9's V) the variance at the SIN-dominated scales is far too small."""
    model = Model("WN+AR1+SIN")
    theta = model.theta({"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03,
                         "SIN[1].alpha": 0.85, "SIN[1].beta": 0.35})
    _, V = _mc_check(model, theta, T=2**12, J=8, R=800, seed=7)
    V0 = wv_covariance(model, theta, 2.0 ** np.arange(1, 9), 2**12, sin_interaction=False)
    assert np.max(np.diag(V) / np.diag(V0)) > 2.0


def test_fast_for_large_T() -> None:
    """Simulation 2 at T = 1e7, J = 22: finite, symmetric, positive definite."""
    model = Model("2*AR1+2*SIN")
    theta = model.theta({"AR1[1].phi": 0.1107083, "AR1[1].sigma2": 5.278666e-4,
                         "AR1[2].phi": 0.999995, "AR1[2].sigma2": 3e-11,
                         "SIN[1].alpha": 0.025, "SIN[1].beta": 0.056,
                         "SIN[2].alpha": 0.0015, "SIN[2].beta": 8e-6})
    V = wv_covariance(model, theta, 2.0 ** np.arange(1, 23), 10**7)
    assert np.all(np.isfinite(V)) and np.allclose(V, V.T)
    assert np.linalg.eigvalsh(wv_correlation(V)).min() > 0


def test_bad_scales() -> None:
    with pytest.raises(InputError):
        wv_covariance("WN", np.array([1.0]), [3.0, 4.0], 100)
    with pytest.raises(InputError):
        wv_covariance("WN", np.array([1.0]), [2.0, 256.0], 100)


def test_repeated_covariance_is_the_memo_copy():
    """A repeated request returns the first result's values as a fresh array (a caller adding to
    it cannot change the next answer)."""
    from gmwm import wvcov

    model = Model("WN+GM+RW", freq=100.0)
    theta = model.theta({"WN[1].sigma2": 1e-4, "GM[1].beta": 0.5, "GM[1].sigma2": 1e-5,
                         "RW[1].gamma2": 1e-10})
    scales = 2.0 ** np.arange(1, 13)
    wvcov._MEMO.clear()
    first = wvcov.wv_covariance(model, theta, scales, 50_000)
    kept = first.copy()
    first += 1.0
    again = wvcov.wv_covariance(model, theta, scales, 50_000)
    assert np.array_equal(again, kept) and again is not first
    wvcov._MEMO.clear()
    assert np.array_equal(wvcov.wv_covariance(model, theta, scales, 50_000), kept)
    other = wvcov.wv_covariance(model, theta, scales, 60_000)
    assert not np.array_equal(other, kept)


def test_an_ar1_with_phi_near_zero_is_white_noise() -> None:
    """An AR1 fitted at phi ~ 1e-310 (its -log(phi) > 710, where sinh overflows a double) is white
    noise of variance sigma2: its covariance is that of WN, not an OverflowError (a model ranking
    once stopped on such a candidate's goodness-of-fit test)."""
    scales = 2.0 ** np.arange(1, 12)
    T = 2**14
    ar = wv_covariance(Model("WN+AR1"), np.array([1.0, 1e-310, 0.5]), scales, T)
    wn = wv_covariance(Model("WN"), np.array([1.5]), scales, T)
    assert np.all(np.isfinite(ar))
    np.testing.assert_allclose(ar, wn, rtol=1e-9)
