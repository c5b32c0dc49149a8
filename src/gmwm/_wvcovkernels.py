"""Numba kernels of :mod:`gmwm.wvcov` (the lag sums of the WV estimator's covariance): the
fallback when the C twin ``gmwm._wvcov`` is not built (the same operations in the same order,
hence the same bits, see ``_wvcov.c``), and the reference the tests compare it with. Imported
lazily, so that a process using the C kernel (``gmwm plan``) never imports Numba."""

from __future__ import annotations

import numpy as np
from numba import njit

_N_DIRECT = 16          # lags summed exactly next to every kink


# --------------------------------------------------------------------------------------------------
# stable elementary functions


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
# cross-covariance of Haar coefficients


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
def all_pairs(T: float, tau: np.ndarray, wn: float, rw: float, qn: float, ar_a, ar_neg, ar_p,
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
