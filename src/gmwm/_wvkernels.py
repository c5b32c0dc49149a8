"""Numba kernels of :mod:`gmwm.wv`: the classical WV sums (the fallback when the C twin
``gmwm._haar`` is not built; the same operations in the same order, hence the same bits, see
``_haar.c``) and the robust WV's per-level passes. Imported lazily, so that ``gmwm wv`` never
loads Numba's runtime when the C kernel is there. Algorithm and conventions: the docstring of
:mod:`gmwm.wv`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# --------------------------------------------------------------------------------------------------
# classical WV (the same operations in the same order as gmwm/_haar.c, which documents them)


@njit(cache=True, inline="always")
def _lane(cur: np.ndarray, prev: np.ndarray, out: np.ndarray, k: int) -> float:
    """``out[k] = (cur[k] + prev[k]) / 2``; returns ``(cur[k] - prev[k])**2``."""
    x = cur[k]
    y = prev[k]
    out[k] = 0.5 * (x + y)
    d = x - y
    return d * d


@njit(cache=True, inline="always")
def _sq(cur: np.ndarray, prev: np.ndarray, k: int) -> float:
    d = cur[k] - prev[k]
    return d * d


@njit(cache=True, inline="always")
def _pair_lane(p0: np.ndarray, p1: np.ndarray, p2: np.ndarray, p3: np.ndarray, out: np.ndarray,
               k: int) -> tuple[float, float]:
    """Two levels at one position (see ``_pair_step``): the two squared differences."""
    x = p0[k]
    y = p1[k]
    u = p2[k]
    z = p3[k]
    v = 0.5 * (x + y)
    w = 0.5 * (u + z)
    d = x - y
    e = v - w
    out[k] = 0.5 * (v + w)
    return d * d, e * e


@njit(cache=True, inline="always")
def _reduce16(a0: float, a1: float, a2: float, a3: float, a4: float, a5: float, a6: float,
              a7: float, a8: float, a9: float, a10: float, a11: float, a12: float, a13: float,
              a14: float, a15: float) -> float:
    """The 16 lanes reduced pairwise ``(l, l + 8)``, ``(l, l + 4)``, ``(l, l + 2)``, ``(0, 1)``."""
    b0, b1, b2, b3 = a0 + a8, a1 + a9, a2 + a10, a3 + a11
    b4, b5, b6, b7 = a4 + a12, a5 + a13, a6 + a14, a7 + a15
    c0, c1, c2, c3 = b0 + b4, b1 + b5, b2 + b6, b3 + b7
    d0, d1 = c0 + c2, c1 + c3
    return d0 + d1


@njit(cache=True, nogil=True)
def _level_step(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> float:
    """One pyramid level on ``t in [lo, hi)``: ``dst[t] = (src[t] + src[t-lag]) / 2``; returns
    ``sum (src[t] - src[t-lag])**2`` (= 4 * sum W**2) accumulated in 16 lanes (lane ``l`` takes the
    terms ``i = l mod 16`` of the first ``16 * floor(n / 16)``), reduced by ``_reduce16``, then
    the remaining terms in order."""
    cur = src[lo:hi]
    prev = src[lo - lag:hi - lag]
    out = dst[lo:hi]
    n = hi - lo
    n16 = n - n % 16
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    a8 = a9 = a10 = a11 = a12 = a13 = a14 = a15 = 0.0
    for i in range(0, n16, 16):
        a0 += _lane(cur, prev, out, i)
        a1 += _lane(cur, prev, out, i + 1)
        a2 += _lane(cur, prev, out, i + 2)
        a3 += _lane(cur, prev, out, i + 3)
        a4 += _lane(cur, prev, out, i + 4)
        a5 += _lane(cur, prev, out, i + 5)
        a6 += _lane(cur, prev, out, i + 6)
        a7 += _lane(cur, prev, out, i + 7)
        a8 += _lane(cur, prev, out, i + 8)
        a9 += _lane(cur, prev, out, i + 9)
        a10 += _lane(cur, prev, out, i + 10)
        a11 += _lane(cur, prev, out, i + 11)
        a12 += _lane(cur, prev, out, i + 12)
        a13 += _lane(cur, prev, out, i + 13)
        a14 += _lane(cur, prev, out, i + 14)
        a15 += _lane(cur, prev, out, i + 15)
    acc = _reduce16(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15)
    for i in range(n16, n):
        acc += _lane(cur, prev, out, i)
    return acc


@njit(cache=True, nogil=True)
def _diff_sq(src: np.ndarray, lo: int, hi: int, lag: int) -> float:
    """``sum (src[t] - src[t-lag])**2`` over ``[lo, hi)``, lanes as ``_level_step``."""
    cur = src[lo:hi]
    prev = src[lo - lag:hi - lag]
    n = hi - lo
    n16 = n - n % 16
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    a8 = a9 = a10 = a11 = a12 = a13 = a14 = a15 = 0.0
    for i in range(0, n16, 16):
        a0 += _sq(cur, prev, i)
        a1 += _sq(cur, prev, i + 1)
        a2 += _sq(cur, prev, i + 2)
        a3 += _sq(cur, prev, i + 3)
        a4 += _sq(cur, prev, i + 4)
        a5 += _sq(cur, prev, i + 5)
        a6 += _sq(cur, prev, i + 6)
        a7 += _sq(cur, prev, i + 7)
        a8 += _sq(cur, prev, i + 8)
        a9 += _sq(cur, prev, i + 9)
        a10 += _sq(cur, prev, i + 10)
        a11 += _sq(cur, prev, i + 11)
        a12 += _sq(cur, prev, i + 12)
        a13 += _sq(cur, prev, i + 13)
        a14 += _sq(cur, prev, i + 14)
        a15 += _sq(cur, prev, i + 15)
    acc = _reduce16(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15)
    for i in range(n16, n):
        acc += _sq(cur, prev, i)
    return acc


@njit(cache=True, nogil=True)
def _pair_step(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, m: int) -> tuple[float, float]:
    """Two levels in one pass (lags ``m`` and ``2m``) on ``[lo, hi)``: from ``V`` at ``t, t-m,
    t-2m, t-3m``, ``v = (V_t + V_(t-m))/2``, ``w = (V_(t-2m) + V_(t-3m))/2`` and
    ``dst[t] = (v + w)/2``; returns the sums of squares of ``V_t - V_(t-m)`` and ``v - w``, lanes
    as ``_level_step``."""
    p0 = src[lo:hi]
    p1 = src[lo - m:hi - m]
    p2 = src[lo - 2 * m:hi - 2 * m]
    p3 = src[lo - 3 * m:hi - 3 * m]
    out = dst[lo:hi]
    n = hi - lo
    n16 = n - n % 16
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    a8 = a9 = a10 = a11 = a12 = a13 = a14 = a15 = 0.0
    b0 = b1 = b2 = b3 = b4 = b5 = b6 = b7 = 0.0
    b8 = b9 = b10 = b11 = b12 = b13 = b14 = b15 = 0.0
    for i in range(0, n16, 16):
        d, e = _pair_lane(p0, p1, p2, p3, out, i)
        a0 += d
        b0 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 1)
        a1 += d
        b1 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 2)
        a2 += d
        b2 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 3)
        a3 += d
        b3 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 4)
        a4 += d
        b4 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 5)
        a5 += d
        b5 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 6)
        a6 += d
        b6 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 7)
        a7 += d
        b7 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 8)
        a8 += d
        b8 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 9)
        a9 += d
        b9 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 10)
        a10 += d
        b10 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 11)
        a11 += d
        b11 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 12)
        a12 += d
        b12 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 13)
        a13 += d
        b13 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 14)
        a14 += d
        b14 += e
        d, e = _pair_lane(p0, p1, p2, p3, out, i + 15)
        a15 += d
        b15 += e
    s0 = _reduce16(a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11, a12, a13, a14, a15)
    s1 = _reduce16(b0, b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11, b12, b13, b14, b15)
    for i in range(n16, n):
        d, e = _pair_lane(p0, p1, p2, p3, out, i)
        s0 += d
        s1 += e
    return s0, s1


@njit(cache=True, nogil=True)
def _pair_avg(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, m: int) -> None:
    """Averages only of ``_pair_step``."""
    for t in range(lo, hi):
        dst[t] = 0.5 * (0.5 * (src[t] + src[t - m]) + 0.5 * (src[t - 2 * m] + src[t - 3 * m]))


@njit(cache=True, nogil=True)
def _level_avg(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> None:
    """Averages only (halo positions whose coefficients belong to the previous block)."""
    cur = src[lo:hi]
    prev = src[lo - lag:hi - lag]
    out = dst[lo:hi]
    for i in range(hi - lo):
        out[i] = 0.5 * (cur[i] + prev[i])


@njit(cache=True, nogil=True)
def _pyramid(a: np.ndarray, b: np.ndarray, n: int, n_levels: int, unit: int, acc_from: int,
             out: np.ndarray) -> int:
    """Pyramid levels ``1..n_levels`` on ``a[:n]`` with lags in multiples of ``unit`` elements,
    ping-ponging between ``a`` and ``b``, two levels per pass (a last odd level alone). Level ``j``
    is defined from ``lo_j = 2 lag_j - unit``; its sum of squared differences at positions
    ``>= acc_from`` goes to ``out[j - 1]`` (0 if none): for the first level of a pair the positions
    below the second level's ``lo`` are summed apart and added first. Returns 0 if the last
    computed level's averages are in ``a``, 1 if in ``b``."""
    src, dst = a, b
    which = 0
    j = 1
    while j <= n_levels:
        m = unit << (j - 1)
        lo1 = 2 * m - unit
        out[j - 1] = 0.0
        if j < n_levels:
            lo2 = 4 * m - unit
            out[j] = 0.0
            if lo1 < n:
                p_lo = max(lo1, acc_from)
                p_hi = min(lo2, n)
                head = _diff_sq(src, p_lo, p_hi, m) if p_lo < p_hi else 0.0
                out[j - 1] = head
                if lo2 < n:
                    acc_lo = max(lo2, acc_from)
                    s0 = 0.0
                    s1 = 0.0
                    if acc_lo > lo2:
                        _pair_avg(src, dst, lo2, min(acc_lo, n), m)
                    if acc_lo < n:
                        s0, s1 = _pair_step(src, dst, acc_lo, n, m)
                    out[j - 1] = head + s0
                    out[j] = s1
                    src, dst = dst, src
                    which = 1 - which
            j += 2
        else:
            if lo1 < n:
                acc_lo = max(lo1, acc_from)
                if acc_lo > lo1:
                    _level_avg(src, dst, lo1, min(acc_lo, n), m)
                if acc_lo < n:
                    out[j - 1] = _level_step(src, dst, acc_lo, n, m)
                src, dst = dst, src
                which = 1 - which
            j += 1
    return which


@njit(cache=True, nogil=True)
def phase1(x: np.ndarray, t_lo: int, t_begin: int, t_end: int, x0: float, L: int, block: int,
           sums: np.ndarray, store: np.ndarray, k_first: int, nrows: int, panel: int) -> None:
    """Levels ``1..L`` of the positions ``[t_begin, t_end)`` (``x[t - t_lo]`` is sample ``t``, its
    block's halo included; ``x0`` is sample 0), added to ``sums[:L]`` block by block in order;
    ``V_L`` is stored panel-major in ``store`` unless it is empty (layout: ``gmwm/_haar.c``)."""
    halo = (1 << L) - 1
    P = halo + 1
    buf_a = np.empty(block + halo)
    buf_b = np.empty(block + halo)
    out = np.empty(L)
    keep = store.shape[0] > 0
    b0 = t_begin
    while b0 < t_end:
        b1 = min(t_end, b0 + block)
        s0 = max(0, b0 - halo)
        n = b1 - s0
        for i in range(n):
            buf_a[i] = x[s0 - t_lo + i] - x0
        which = _pyramid(buf_a, buf_b, n, L, 1, b0 - s0, out)
        for j in range(L):
            sums[j] += out[j]
        if keep:
            src = buf_a if which == 0 else buf_b
            for t in range(max(b0, halo), b1):
                s = t - halo
                k = s >> L
                r = s & (P - 1)
                p = r // panel
                cp = min(panel, P - p * panel)
                store[nrows * p * panel + (k - k_first) * cp + (r - p * panel)] = src[t - s0]
        b0 = b1


@njit(cache=True, nogil=True)
def phase2(store: np.ndarray, rows: int, n_out: int, L: int, panel: int, p_begin: int, p_end: int,
           n_levels2: int, sums: np.ndarray) -> None:
    """Levels ``L+1..L+n_levels2`` of the panels ``[p_begin, p_end)`` (contiguous in ``store``,
    overwritten), added to ``sums[L:]`` panel by panel in order."""
    P = 1 << L
    pan_b = np.empty(rows * min(panel, P))
    out = np.empty(n_levels2)
    for p in range(p_begin, p_end):
        r0 = p * panel
        cp = min(panel, P - r0)
        last = min(max(n_out - (rows - 1) * P - r0, 0), cp)
        base = rows * (p - p_begin) * panel
        _pyramid(store[base:base + rows * cp], pan_b, (rows - 1) * cp + last, n_levels2, cp, 0,
                 out)
        for j in range(n_levels2):
            sums[L + j] += out[j]


# --------------------------------------------------------------------------------------------------
# robust WV (see the estimator notes above gmwm.wv.wvar_robust)


@njit(cache=True)
def haar_step(v: np.ndarray, w: np.ndarray, n: int, m: int) -> int:
    """One MODWT Haar level in place: from the ``n`` local averages ``v[:n]`` of the previous level
    (lag ``m``), write the ``n - m`` wavelet coefficients to ``w`` and the new averages to ``v``.
    In place is safe: ``v[i]`` is overwritten only after ``v[i]`` and ``v[i + m]`` were read."""
    k = n - m
    for i in range(k):
        a = v[i + m]
        b = v[i]
        w[i] = 0.5 * (a - b)
        v[i] = 0.5 * (a + b)
    return k


@njit(cache=True)
def _rho_terms(v: np.ndarray, n: int, m: int, inv: float) -> tuple[float, float]:
    """``mean rho(u)`` and ``mean 3 u (1 - u)**2`` over ``u = W_i**2 * inv`` (``inv = 1 / (c**2 nu)``),
    ``W_i = (v[i + m] - v[i]) / 2``, ``i < n``, formed on the fly from the previous level's local
    averages ``v`` (no coefficient array); the second is ``-d mean rho / d log nu``."""
    s0 = 0.0
    s1 = 0.0
    for i in range(n):
        wi = 0.5 * (v[i + m] - v[i])
        u = wi * wi * inv
        if u < 1.0:
            q = 1.0 - u
            s0 += 1.0 - q * q * q
            s1 += 3.0 * u * q * q
        else:
            s0 += 1.0
    return s0 / n, s1 / n


@njit(cache=True)
def m_scale(v: np.ndarray, n: int, m: int, c: float, b: float, nu0: float) -> float:
    """Solve ``mean rho_c(w / sqrt(nu)) = b`` for nu: Newton in log nu from ``nu0`` (the left side
    decreases in nu), steps capped at a factor 4, bisection once a bracket is known and a step
    leaves it. Converges in ~4-6 passes from the MAD start."""
    c2 = c * c
    x = np.log(nu0)
    lo = -np.inf
    hi = np.inf
    cap = np.log(4.0)
    for _ in range(300):
        g, d = _rho_terms(v, n, m, 1.0 / (c2 * np.exp(x)))
        g -= b
        if g > 0.0:
            lo = x
        else:
            hi = x
        if hi - lo < 1e-11:
            break
        if d > 0.0:
            step = min(max(g / d, -cap), cap)
        else:
            step = cap if g > 0.0 else -cap
        if abs(step) < 1e-11:
            x += step
            break
        x_new = x + step
        if not (lo < x_new < hi):  # only possible once both ends are finite
            x_new = 0.5 * (lo + hi)
        x = x_new
    return np.exp(x)


@njit(cache=True)
def haar_average(v: np.ndarray, n: int, m: int) -> int:
    """Next level's local averages in place, ``v[i] = (v[i] + v[i + m]) / 2`` for ``i < n - m``
    (``v[i + m]`` is still the previous level's value when read)."""
    k = n - m
    for i in range(k):
        v[i] = 0.5 * (v[i] + v[i + m])
    return k
