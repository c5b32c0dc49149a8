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
independent of T: Simulation 1-3 models at T = 1e7, J = 22 take 20-45 ms CPU on a 2-core machine
at load ~20 (benchmarks/bench_wvcov.py).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from functools import lru_cache
from math import comb

import numpy as np
from numba import njit

from ._once import OnceMemo
from .errors import InputError, ModelError
from .model import Model, as_model
from .processes import Process, Sinusoid

__all__ = ["wv_correlation", "wv_covariance"]

_N_DIRECT = 16          # lags summed exactly next to every kink
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
# numba kernels: stable elementary functions


@njit(cache=True)
def _exp_tail(x: float, n: int) -> float:
    """exp(-x) minus its Taylor polynomial of degree n - 1, for x >= 0 (series below 0.5)."""
    if x < 0.5:
        term = 1.0
        for k in range(1, n + 1):
            term *= -x / k
        s = term
        for k in range(n + 1, 30):
            term *= -x / k
            s += term
            if abs(term) <= 1e-17 * abs(s):
                break
        return s
    s = np.expm1(-x)
    term = 1.0
    for k in range(1, n):
        term *= -x / k
        s -= term
    return s


@njit(cache=True)
def _e3(x: float) -> float:
    """exp(-x) - 1 + x - x^2/2 for x >= 0."""
    return _exp_tail(x, 3)


@njit(cache=True)
def _e2(x: float) -> float:
    """exp(-x) - 1 + x for x >= 0."""
    return _exp_tail(x, 2)


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
    return math.sinh(a) - a


@njit(cache=True)
def _pw(a: float, neg: bool, n: float, par: int) -> float:
    """phi^n for n >= 0 with |phi| = exp(-a); the sign for phi < 0 comes from the parity of n."""
    x = a * n
    if x > 745.0:
        return 0.0
    v = np.exp(-x)
    if neg and (par & 1):
        return -v
    return v


# --------------------------------------------------------------------------------------------------
# numba kernels: cross-covariance of Haar coefficients


@njit(cache=True)
def _g_ar(n0: float, par: int, m: float, tau: float, c: int, e3: bool, ar_a, ar_neg, ar_p,
          ar_pl, ar_sm, u: float) -> float:
    """sum_b beta_b K_AR(n0 + b), b in (0, m, tau), beta = (1, -2, 1); ``par`` = parity of n0."""
    a = ar_a[c]
    neg = ar_neg[c]
    p = ar_p[c]
    if n0 >= 0.0 or n0 + tau <= 0.0:
        if n0 >= 0.0:
            x = n0
            px = par
        else:
            x = -(n0 + tau)
            px = par + int(tau)
        if e3:
            return -p * (np.expm1(-a * x) * u * u - _e2(a * m) * (u + a * m))
        return -p * _pw(a, neg, x, px) * u * u
    # the three arguments straddle 0: evaluate K directly, in the form free of cancellation
    s = 0.0
    if (not neg) and a * tau <= 2.0:
        sm = ar_sm[c]
        for ib in range(3):
            b = 0.0 if ib == 0 else (m if ib == 1 else tau)
            w = 1.0 if ib != 1 else -2.0
            n = abs(n0 + b)
            s += w * -p * (_e3(a * n) + n * sm)
        if not e3:
            s -= p * a * a * m * m
        return s
    pl = ar_pl[c]
    for ib in range(3):
        b = 0.0 if ib == 0 else (m if ib == 1 else tau)
        w = 1.0 if ib != 1 else -2.0
        n = abs(n0 + b)
        pe = 0.0 if p == 0.0 else p * _pw(a, neg, n, par + int(b))
        s += w * (-pe - pl * n)
    return s


@njit(cache=True)
def _gamma(h: float, par: int, tj: float, mj: float, tk: float, mk: float, wn: float, rw: float,
           qn: float, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3) -> float:
    """gamma_jk(h) = Cov(W_{j,t}, W_{k,t-h}); ``par`` = parity of h (used only if some phi < 0)."""
    nar = ar_a.shape[0]
    norm = 1.0 / (tj * tk)
    if h > tj or h < -tk:
        # outside the filters' overlap only the AR1 terms survive, in product form
        s = 0.0
        for c in range(nar):
            if ar_p[c] == 0.0:
                continue
            if h >= tj:
                e = _pw(ar_a[c], ar_neg[c], h - tj, par + int(tj))
            else:
                e = _pw(ar_a[c], ar_neg[c], -h - tk, par + int(tk))
            s -= ar_p[c] * e * uj[c] * uj[c] * uk[c] * uk[c]
        return s * norm
    s = 0.0
    for ia in range(3):
        a = 0.0 if ia == 0 else (mj if ia == 1 else tj)
        alpha = 1.0 if ia != 1 else -2.0
        n0 = h - a
        p0 = par + int(a)
        g = 0.0
        pos = n0 >= 0.0
        negs = n0 + tk <= 0.0
        if pos or negs:
            x = n0 if pos else -(n0 + tk)
            g += rw * mk * mk * (x + mk) / 2.0
        else:
            for ib in range(3):
                b = 0.0 if ib == 0 else (mk if ib == 1 else tk)
                w = 1.0 if ib != 1 else -2.0
                n = abs(n0 + b)
                g += w * (-0.5 * wn * n + rw * (n * n * n - n) / 12.0)
        if qn != 0.0:
            for ib in range(3):
                b = 0.0 if ib == 0 else (mk if ib == 1 else tk)
                w = 1.0 if ib != 1 else -2.0
                if n0 + b == 0.0:
                    g += w * qn
        for c in range(nar):
            g += _g_ar(n0, p0, mk, tk, c, e3[c], ar_a, ar_neg, ar_p, ar_pl, ar_sm, uk[c])
        s += alpha * g
    return s * norm


@njit(cache=True)
def _point(h: float, par: int, T: float, tj: float, mj: float, tk: float, mk: float, wn: float,
           rw: float, qn: float, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3):
    """(N(h) gamma(h), N(h) gamma(h)^2)."""
    nn = min(T, T + h) - max(tj, tk + h) + 1.0
    if nn <= 0.0:
        return 0.0, 0.0
    g = _gamma(h, par, tj, mj, tk, mk, wn, rw, qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
    return nn * g, nn * g * g


@njit(cache=True)
def _lattice_sum(h0: float, step: float, n: int, kd: int, left: bool, right: bool, T: float,
                 tj: float, mj: float, tk: float, mk: float, wn: float, rw: float, qn: float,
                 ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3, gl_x, gl_w, grades, greg_l, greg_r):
    """sum over h = h0 + step * i, i = 0..n-1, of (N gamma, N gamma^2). The summand is smooth
    in i (no kink inside): next to an end that is a kink of gamma (``left``/``right``), ``kd``
    terms are summed exactly (they hold the fast AR1 transients) and the quadrature panels are
    graded; the rest is summed by Gregory's rule with a Gauss-Legendre integral."""
    kl = kd if left else 0
    kr = kd if right else 0
    # on the unit lattice the parity alternates (AR1 transients with phi < 0 are summed exactly
    # there, so the parity passed at the non-integer quadrature nodes does not matter)
    par = int(h0) & 1
    alt = 1 if step == 1.0 else 0
    s1 = 0.0
    s2 = 0.0
    if n <= kl + kr + 40:
        for i in range(n):
            v1, v2 = _point(h0 + step * i, par + alt * i, T, tj, mj, tk, mk, wn, rw, qn, ar_a,
                            ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
            s1 += v1
            s2 += v2
        return s1, s2
    for ii in range(kl):
        v1, v2 = _point(h0 + step * ii, par + alt * ii, T, tj, mj, tk, mk, wn, rw, qn, ar_a,
                        ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
        s1 += v1
        s2 += v2
    for ii in range(n - kr, n):
        v1, v2 = _point(h0 + step * ii, par + alt * ii, T, tj, mj, tk, mk, wn, rw, qn, ar_a,
                        ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
        s1 += v1
        s2 += v2
    A = float(kl)
    B = float(n - 1 - kr)
    for i in range(greg_l.shape[0]):
        v1, v2 = _point(h0 + step * (A + i), par + alt * (kl + i), T, tj, mj, tk, mk, wn, rw, qn,
                        ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
        s1 += greg_l[i] * v1
        s2 += greg_l[i] * v2
        v1, v2 = _point(h0 + step * (B - i), par + alt * (n - 1 - kr - i), T, tj, mj, tk, mk, wn,
                        rw, qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
        s1 += greg_r[i] * v1
        s2 += greg_r[i] * v2
    # integral over [A, B], panels graded at s / a from each kink end, for each AR1 decay rate
    # (12-node Gauss-Legendre: a panel over which exp(-2 a x) changes by e^c has relative error
    # ~1e-38 c^24, and the panels beyond 40 / a hold less than e^-40 of the transient)
    mid = 0.5 * (A + B)
    nar = ar_a.shape[0]
    edges = np.empty(3 + 2 * nar * grades.shape[0])
    ne = 0
    edges[ne] = A
    edges[ne + 1] = B
    ne += 2
    if nar > 0:
        edges[ne] = mid
        ne += 1
    last = float(n - 1)
    for c in range(nar):
        if ar_a[c] <= 0.0 or ar_p[c] == 0.0:
            continue
        for s in grades:
            d = s / (ar_a[c] * step)
            if left and A < d < mid:
                edges[ne] = d
                ne += 1
            if right and mid < last - d < B:
                edges[ne] = last - d
                ne += 1
    e = np.sort(edges[:ne])
    for q in range(ne - 1):
        lo = e[q]
        hi = e[q + 1]
        if hi <= lo:
            continue
        half = 0.5 * (hi - lo)
        cen = 0.5 * (hi + lo)
        for r in range(gl_x.shape[0]):
            v1, v2 = _point(h0 + step * (cen + half * gl_x[r]), par, T, tj, mj, tk, mk, wn, rw,
                            qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3)
            s1 += half * gl_w[r] * v1
            s2 += half * gl_w[r] * v2
    return s1, s2


@njit(cache=True)
def _direct_ends(ar_a, ar_neg, ar_p) -> tuple[int, int, bool]:
    """(terms summed exactly at each end of a piece on the unit lattice, same on the even/odd
    sub-lattices, whether to split by parity). Gregory's rule is accurate once every AR1 transient
    ``phi^i`` is smooth on the lattice (a < 0.05) or has decayed below e^-40; a negative phi whose
    transient outlives 64 lags alternates in sign, so its pieces are summed per parity."""
    kd = 0
    kd2 = 0
    split = False
    for c in range(ar_a.shape[0]):
        if ar_p[c] == 0.0:
            continue
        a = ar_a[c]
        if ar_neg[c]:
            need = int(np.ceil(40.0 / a))
            if need > 64:
                split = True
            else:
                kd = max(kd, need)
        if a >= 0.05:
            kd = max(kd, _N_DIRECT)
        if 2.0 * a >= 0.05:
            kd2 = max(kd2, _N_DIRECT)
    if split:
        kd = kd2
    return kd, kd2, split


@njit(cache=True)
def _pair_sums(T: float, tj: float, tk: float, wn: float, rw: float, qn: float, ar_a, ar_neg,
               ar_p, ar_pl, ar_sm, gl_x, gl_w, grades, greg_l, greg_r):
    """(sum_h N gamma, sum_h N gamma^2) for one pair of scales, exact up to quadrature rounding."""
    mj = tj / 2.0
    mk = tk / 2.0
    nar = ar_a.shape[0]
    kd, kd2, split_parity = _direct_ends(ar_a, ar_neg, ar_p)
    uj = np.empty(nar)
    uk = np.empty(nar)
    e3 = np.empty(nar, dtype=np.bool_)
    for c in range(nar):
        a = ar_a[c]
        if ar_neg[c]:
            phi = -np.exp(-a)
            uj[c] = 1.0 - phi ** int(mj)
            uk[c] = 1.0 - phi ** int(mk)
            e3[c] = False
        else:
            uj[c] = -np.expm1(-a * mj)
            uk[c] = -np.expm1(-a * mk)
            e3[c] = a * (tj + tk) <= 2.0
    h_lo = tj - T
    h_hi = T - tk
    cand = np.empty(11)
    nc = 0
    for a in (0.0, mj, tj):
        for b in (0.0, mk, tk):
            cand[nc] = a - b
            nc += 1
    cand[nc] = h_lo
    cand[nc + 1] = h_hi
    nc += 2
    kinks = np.minimum(np.maximum(cand[:9], h_lo), h_hi)
    bp = np.unique(np.minimum(np.maximum(cand[:nc], h_lo), h_hi))
    s1 = 0.0
    s2 = 0.0
    for i in range(bp.shape[0]):
        h = bp[i]
        v1, v2 = _point(h, int(h) & 1, T, tj, mj, tk, mk, wn, rw, qn, ar_a, ar_neg, ar_p, ar_pl,
                        ar_sm, uj, uk, e3)
        s1 += v1
        s2 += v2
        if i + 1 == bp.shape[0]:
            break
        lo = h + 1.0
        n = int(bp[i + 1] - h) - 1
        if n <= 0:
            continue
        left = np.any(kinks == h)
        right = np.any(kinks == bp[i + 1])
        if split_parity:
            for r in range(2):
                nr = (n - r + 1) // 2
                if nr > 0:
                    v1, v2 = _lattice_sum(lo + r, 2.0, nr, kd2, left, right, T, tj, mj, tk, mk,
                                          wn, rw, qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk,
                                          e3, gl_x, gl_w, grades, greg_l, greg_r)
                    s1 += v1
                    s2 += v2
        else:
            v1, v2 = _lattice_sum(lo, 1.0, n, kd, left, right, T, tj, mj, tk, mk, wn, rw, qn,
                                  ar_a, ar_neg, ar_p, ar_pl, ar_sm, uj, uk, e3, gl_x, gl_w,
                                  grades, greg_l, greg_r)
            s1 += v1
            s2 += v2
    return s1, s2


@njit(cache=True, nogil=True)  # nogil: gmwm.plan computes several lengths side by side
def _all_pairs(T: float, tau: np.ndarray, wn: float, rw: float, qn: float, ar_a, ar_neg, ar_p,
               ar_pl, ar_sm, gl_x, gl_w, grades, greg_l, greg_r):
    J = tau.shape[0]
    S1 = np.zeros((J, J))
    S2 = np.zeros((J, J))
    for j in range(J):
        for k in range(j, J):
            # the larger scale goes first: the outer (step m_j) difference is then the long one,
            # which keeps the rounding of gamma ~ eps tau_k / tau_j instead of eps (tau_k/tau_j)^2
            v1, v2 = _pair_sums(T, max(tau[j], tau[k]), min(tau[j], tau[k]), wn, rw, qn, ar_a, ar_neg, ar_p, ar_pl, ar_sm,
                                gl_x, gl_w, grades, greg_l, greg_r)
            S1[j, k] = S1[k, j] = v1
            S2[j, k] = S2[k, j] = v2
    return S1, S2


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
