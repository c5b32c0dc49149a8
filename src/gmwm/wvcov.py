"""Model-based covariance of the Haar wavelet-variance estimator (finite sample, analytic).

``wv_covariance(model, theta, scales, n_samples)`` returns ``V[j, k] = Cov(nu_hat_j, nu_hat_k)`` of
the boundary-free Haar MODWT WV estimator of ``gmwm.wv`` (docs/METHODS.md §2.1-§2.5: ``tau_j`` = filter length,
``M_j = T - tau_j + 1`` coefficients ``t = tau_j..T``, ``nu_hat_j = mean W_{j,t}^2``, not demeaned)
for a signal of ``T = n_samples`` samples drawn from ``model`` at ``theta``. Units: (signal unit)^4.

Formula (components independent; SIN excluded by default, docs/METHODS.md §5.9 / [Vibration] Thm 1):

* Gaussian part ``G`` (WN, RW, AR1, GM, and QN's second moments):
  ``Cov = 2/(M_j M_k) * sum_h N_jk(h) gamma_jk(h)^2`` with ``gamma_jk(h) = Cov(W_{j,t}, W_{k,t-h})``
  and ``N_jk(h) = #{(t, s): t - s = h}`` over the two boundary-free index ranges (exact count).
* QN is not Gaussian (uniform innovations, fourth cumulant ``-1.2 Q2^2``): its exact fourth-cumulant
  term is added.
* DR adds the constant ``c_j = omega tau_j / 4`` to every coefficient: ``+ 4 c_j c_k Cov(mean W_j,
  mean W_k)``, with ``Cov(mean W_j, mean W_k) = sum_h N_jk(h) gamma_jk(h) / (M_j M_k)``.
* SIN (``W = G + S``, ``S`` deterministic given the phase): its own term is O(T^-2) and omitted, but
  the cross term ``Var(2 mean(G S))`` is O(T^-1) and is added by default (``sin_interaction``):
  ``8/alpha^2 S_G(beta) nu_j^SIN nu_k^SIN min(M_j, M_k) / (M_j M_k)``, ``S_G`` the spectral density
  of the random part. This contradicts docs/METHODS.md §5.9 ("SIN does not enter V"): by Monte Carlo, without
  it Var(nu_hat_j) is underestimated up to 8.7x at SIN-dominated scales (tests).

``gamma_jk`` is evaluated through the generalised covariance ``K`` of the partial-sum process
(``W_{j,t} = (S_t - 2 S_{t-m_j} + S_{t-tau_j}) / tau_j``): ``gamma_jk(h) = sum_{a,b} alpha_a beta_b
K(h - a + b) / (tau_j tau_k)``, ``K`` = -WN|n|/2, RW(|n|^3-|n|)/12, QN delta(n), AR1
``-P phi^|n| - P sinh(a)|n|`` (``a = -ln phi``), written in cancellation-free forms for
``phi -> 1``.
Between the kinks ``h = a - b`` the summand is smooth, so ``sum_h`` is done exactly near each kink
(16 lags) and by Gregory's end-corrected rule with a graded Gauss-Legendre integral elsewhere.
Accuracy: exact for finite ``M_j`` (no asymptotic approximation) except the SIN cross term
(relative error O(tau_j / M_j)). Measured: dense-matrix reference at T = 64..200 agrees to 1e-15
(5e-13 for phi = 0.999995); explicit sums over every lag at T = 5000 and 40000 to <= 9e-9
(phi in {-0.95, -0.5, 0.3, 0.9, 0.99, 0.999995}, WN+RW, two AR1) and at T = 1e7 (Simulation 2
AR1 pair and WN+AR1+RW; scale pairs (1,1), (1,22), (10,13), (22,22)) to <= 7e-12. Cost O(J^2),
independent of T (timings: benchmarks/bench_wvcov.py).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import cache, lru_cache
from math import comb
from typing import Any

import numpy as np

from ._once import OnceMemo
from .errors import InputError, ModelError
from .model import Model, as_model
from .processes import Process, Sinusoid

__all__ = ["wv_correlation", "wv_covariance"]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(12)
_GRADES = np.array([6.0, 16.0, 40.0])   # panel edges at s / a (12-node GL: see _lattice_sum)
_QN_KAPPA4 = -1.2       # fourth cumulant / variance^2 of a uniform variable


def _gregory_weights(order: int = 7) -> tuple[np.ndarray, np.ndarray]:
    """Weights ``wl, wr`` with ``sum_{i=A}^{B} f_i = int_A^B f + sum_i wl[i] f_{A+i}
    + sum_i wr[i] f_{B-i}`` (Gregory's formula; exact for polynomials of degree <= order)."""
    coef = [1 / 12, 1 / 24, 19 / 720, 3 / 160, 863 / 60480, 275 / 24192, 33953 / 3628800]
    wl = np.zeros(order + 1)
    wr = np.zeros(order + 1)
    wl[0] = wr[0] = 0.5
    for k in range(1, order + 1):
        for i in range(k + 1):
            d = (-1) ** (k - i) * comb(k, i)      # Delta^k f_0 = sum d f_i
            wl[i] += coef[k - 1] * (-1) ** k * d
            wr[i] += coef[k - 1] * (-1) ** i * comb(k, i)   # nabla^k f_n
    return wl, wr


_GREG_L, _GREG_R = _gregory_weights()


# --------------------------------------------------------------------------------------------------
# the kernels: C (_wvcov.c) or Numba (_wvcovkernels.py)


@cache
def kernels() -> Any:
    """The lag-sum kernel (a module with ``all_pairs``): the C one (``gmwm._wvcov``, built at
    install; no Numba start-up, releases the GIL) or else its Numba twin (``gmwm._wvcovkernels``,
    ``nogil`` too). The same operations in the same order: identical bits on any IEEE-754 machine
    (tests/test_wvcov_c.py)."""
    try:
        from gmwm import _wvcov
        return _wvcov
    except ImportError:
        from gmwm import _wvcovkernels
        return _wvcovkernels


def _all_pairs(T: float, tau: np.ndarray, *args: Any) -> tuple[np.ndarray, np.ndarray]:
    """(sum_h N gamma, sum_h N gamma^2) for every pair of scales (J x J each), by :func:`kernels`;
    ``args``: the arguments of ``_wvcovkernels.all_pairs`` after ``tau``."""
    kern = kernels()
    if kern.__name__ != "gmwm._wvcov":
        return kern.all_pairs(T, tau, *args)
    J = tau.shape[0]
    S1 = np.empty((J, J))
    S2 = np.empty((J, J))
    arrays = [np.ascontiguousarray(x, dtype=bool if i == 4 else np.float64)
              for i, x in enumerate(args)]   # args[4] is ar_neg
    kern.all_pairs(T, np.ascontiguousarray(tau, dtype=np.float64), *args[:3], *arrays[3:], S1, S2)
    return S1, S2


def _sinh_minus(a: float) -> float:
    """sinh(a) - a, for a >= 0. Plain Python: only :func:`_wv_covariance` calls it, once per AR1
    component, and a kernel of its own would cost every process its load from Numba's cache;
    same operations as compiled (libm's sinh), same bits (tests/test_plan_threads.py)."""
    a = float(a)
    if a < 0.5:
        term = a * a * a / 6.0
        s = term
        for k in range(5, 40, 2):
            term *= a * a / ((k - 1) * k)
            s += term
            if term <= 1e-17 * s:
                break
        return s
    if a > 700.0:
        # sinh overflows a double past ~710 (phi < 1e-304: an AR1 that is white noise); the
        # kernels read this term only where a * tau <= 2, so the value is never used, and inf
        # is what the compiled sinh returns (the Python one raises OverflowError)
        return math.inf
    return math.sinh(a) - a


# --------------------------------------------------------------------------------------------------
# python API


def _lag_count(T: int, tj: np.ndarray, tk: np.ndarray, h: np.ndarray) -> np.ndarray:
    """N_jk(h): pairs t in [tau_j, T], s in [tau_k, T] with t - s = h."""
    return np.maximum(0, np.minimum(T, T + h) - np.maximum(tj, tk + h) + 1)


def _qn_cumulant_term(q2: float, T: int, tau: np.ndarray) -> np.ndarray:
    """Fourth-cumulant part of Cov(nu_hat) for QN: W_{j,t} = (v_{t+1} - 2 v_{t+1-m} + v_{t+1-2m})
    / tau_j with iid v of variance Q2 and fourth cumulant -1.2 Q2^2."""
    M = T - tau + 1
    return _QN_KAPPA4 * q2 * q2 * _qn_lag_weights(int(T), tuple(int(t) for t in tau)) \
        / np.outer(M, M)


@lru_cache(maxsize=64)
def _qn_lag_weights(T: int, scales: tuple[int, ...]) -> np.ndarray:
    """The Q2-free sum of :func:`_qn_cumulant_term` (read-only J x J), cached: it depends on the
    length and scales only, and a Monte Carlo chunk fits one (T, scales) hundreds of times."""
    tau = np.array(scales, dtype=np.int64)
    J = tau.size
    out = np.zeros((J, J))
    w = np.array([1.0, 4.0, 1.0])
    for j in range(J):
        oj = np.array([0, tau[j] // 2, tau[j]])
        for k in range(J):
            ok = np.array([0, tau[k] // 2, tau[k]])
            h = oj[:, None] - ok[None, :]
            cnt = _lag_count(T, tau[j], tau[k], h)
            out[j, k] = (w[:, None] * w[None, :] * cnt).sum() / (float(tau[j]) ** 2
                                                                  * float(tau[k]) ** 2)
    out.flags.writeable = False
    return out


def _check_scales(scales: Iterable[float], n_samples: int) -> tuple[np.ndarray, int]:
    tau = np.asarray(scales, dtype=np.float64).reshape(-1)
    if tau.size == 0 or not np.all(np.isfinite(tau)):
        raise InputError("scales must be a non-empty list of finite filter lengths (samples)")
    lev = np.log2(np.maximum(tau, 1.0))
    if np.any(tau < 2) or not np.all(lev == np.round(lev)):
        raise InputError(f"scales must be Haar filter lengths 2**j >= 2 samples, "
                         f"got {tau.tolist()}")
    T = int(n_samples)
    if T != n_samples or T < tau.max():
        raise InputError(f"n_samples must be an integer >= the largest scale {tau.max():g}, "
                         f"got {n_samples}")
    return tau.astype(np.int64), T


def _spectrum(wn: float, rw: float, qn: float, phi: np.ndarray, s2: np.ndarray,
              beta: float) -> float:
    """Spectral density sum_h r(h) e^{-i beta h} of the random part at ``beta`` rad/sample (RW in
    the generalised sense, exact for the Haar coefficients, which difference it away)."""
    s = 4.0 * np.sin(beta / 2.0) ** 2
    out = wn + qn * s + (rw / s if rw else 0.0)
    return float(out + np.sum(s2 / (1.0 - 2.0 * phi * np.cos(beta) + phi**2)))


def wv_covariance(model: str | Model, theta: np.ndarray, scales: Iterable[float], n_samples: int,
                  *, exclude: Iterable[str] = (Sinusoid.name,), sin_interaction: bool = True
                  ) -> np.ndarray:
    """Finite-sample ``Cov(nu_hat_j, nu_hat_k)`` (J x J, signal unit^4) of the boundary-free Haar
    WV estimator for ``n_samples`` samples of ``model`` at ``theta``; ``scales`` are filter lengths
    ``tau_j = 2**j`` in samples (e.g. ``WaveletVariance.scales``).

    Components named in ``exclude`` have no own term (default SIN: given its phase a sinusoid's WV
    varies only at O(T^-2), docs/METHODS.md §5.9). ``sin_interaction`` adds, for every SIN component, the
    cross term between the sinusoid and the random components, ``8/alpha^2 S(beta) nu_j^SIN
    nu_k^SIN min(M_j, M_k) / (M_j M_k)`` (``S`` = spectral density of the random part). It is
    O(T^-1), like the rest, and measured to raise Var(nu_hat_j) up to 8.7x at SIN-dominated scales
    (WN + SIN of Simulation 1); set False for docs/METHODS.md §5.9's V. That term is asymptotic in the lag
    count (relative error O(tau_j / M_j)); everything else is exact for finite M_j."""
    model = as_model(model)
    theta = np.asarray(theta, dtype=float)
    model.check(theta)
    tau, T = _check_scales(scales, n_samples)
    excl = {str(e).upper() for e in exclude}
    key = (model.spec, model.freq, theta.tobytes(), tau.tobytes(), T, tuple(sorted(excl)),
           bool(sin_interaction))
    # threads may fill it (gmwm.plan); the memo keeps its own copy, callers get theirs
    return _MEMO.get(key, lambda: _wv_covariance(model, theta, tau, T, excl, sin_interaction)
                     ).copy()


#: covariances already computed in this process, by model, parameters, scales, length and
#: options (first in, first out): an automatic model choice asks for the same one up to four
#: times (the goodness-of-fit test of a candidate ranked in two stages, the chosen model's
#: standard errors, the verdict's identifiability search at the fit's own length)
MEMO_SIZE = 64
_MEMO = OnceMemo(MEMO_SIZE)


def _wv_covariance(model: Model, theta: np.ndarray, tau: np.ndarray, T: int, excl: set[str],
                   sin_interaction: bool) -> np.ndarray:
    """:func:`wv_covariance` after its checks."""
    sins: list[tuple[Process, float, float]] = []
    wn = rw = qn = omega = 0.0
    ar_phi: list[float] = []
    ar_a: list[float] = []
    ar_s2: list[float] = []
    for c in model.components:
        # the primitive form of each process (GM: an AR1)
        kind, *v = c.process.primitive(theta[c.slice], model.freq)
        if kind == "sin":
            sins.append((c.process, v[0], v[1]))
        if c.process.name in excl:
            continue
        if kind == "wn":
            wn += v[0]
        elif kind == "rw":
            rw += v[0]
        elif kind == "qn":
            qn += v[0]
        elif kind == "dr":
            omega += v[0]
        elif kind == "ar1":
            phi, a, s2 = v
            if phi == 0.0:
                wn += s2
                continue
            ar_phi.append(phi)
            ar_a.append(a)
            ar_s2.append(s2)
        elif kind == "sin":
            raise ModelError(f"the own term of a {c.process.name} component is not implemented "
                             f"(it is O(T^-2)); keep {c.process.name} in exclude")
        else:
            raise ModelError(f"wv_covariance does not support process {c.process.name}")
    phi = np.array(ar_phi)
    a = np.array(ar_a)
    s2 = np.array(ar_s2)
    neg = phi < 0
    one_m = np.where(neg, 1.0 - phi, -np.expm1(-a))          # 1 - phi, stable for phi -> 1
    p_coef = s2 * phi / (one_m**3 * (1.0 + phi))             # P = s2 phi / ((1-phi)^3 (1+phi))
    pl_coef = s2 / (2.0 * one_m**2)                          # P (1 - phi^2) / (2 phi)
    sm = np.array([_sinh_minus(x) if not n else 0.0 for x, n in zip(a, neg, strict=True)])
    S1, S2 = _all_pairs(float(T), tau.astype(np.float64), wn, rw, qn, a, neg, p_coef, pl_coef, sm,
                        _GL_X, _GL_W, _GRADES, _GREG_L, _GREG_R)
    M = (T - tau + 1).astype(np.float64)
    MM = np.outer(M, M)
    V = 2.0 * S2 / MM
    if qn > 0:
        V += _qn_cumulant_term(qn, T, tau)
    if omega != 0.0:
        c = omega * tau / 4.0
        V += 4.0 * np.outer(c, c) * S1 / MM
    if sin_interaction and sins:
        ftau = tau.astype(np.float64)
        for proc, alpha, beta in sins:
            nu = proc.wv(np.array([alpha, beta]), ftau)
            spec = _spectrum(wn, rw, qn, phi, s2, beta)
            V += 8.0 / alpha**2 * spec * np.outer(nu, nu) * np.minimum.outer(M, M) / MM
    return V


def wv_correlation(V: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance matrix ``V``."""
    V = np.asarray(V, dtype=float)
    d = np.sqrt(np.diag(V))
    return V / np.outer(d, d)
