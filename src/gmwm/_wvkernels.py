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


@njit(cache=True, nogil=True)
def _level_step(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> float:
    """One pyramid level on ``t in [lo, hi)``: ``dst[t] = (src[t] + src[t-lag]) / 2``; returns
    ``sum (src[t] - src[t-lag])**2`` (= 4 * sum W**2) accumulated in 16 lanes (lane ``l`` takes the
    terms ``i = l mod 16`` of the first ``16 * floor(n / 16)``), reduced pairwise ``(l, l + 8)``,
    ``(l, l + 4)``, ``(l, l + 2)``, ``(0, 1)``, then the remaining terms in order."""
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
    b0, b1, b2, b3 = a0 + a8, a1 + a9, a2 + a10, a3 + a11
    b4, b5, b6, b7 = a4 + a12, a5 + a13, a6 + a14, a7 + a15
    c0, c1, c2, c3 = b0 + b4, b1 + b5, b2 + b6, b3 + b7
    d0, d1 = c0 + c2, c1 + c3
    acc = d0 + d1
    for i in range(n16, n):
        acc += _lane(cur, prev, out, i)
    return acc


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
    ping-ponging between ``a`` and ``b``. The sum of squared differences of level ``j`` at
    positions ``>= acc_from`` goes to ``out[j - 1]`` (0 if none). Returns 0 if the last level's
    averages are in ``a``, 1 if in ``b``."""
    src, dst = a, b
    which = 0
    for j in range(1, n_levels + 1):
        out[j - 1] = 0.0
        lag = unit << (j - 1)
        lo = (2 * lag) - unit          # first position where level j is defined
        if lo >= n:
            continue
        acc_lo = max(lo, acc_from)
        if acc_lo > lo:
            _level_avg(src, dst, lo, min(acc_lo, n), lag)
        if acc_lo < n:
            out[j - 1] = _level_step(src, dst, acc_lo, n, lag)
        src, dst = dst, src
        which = 1 - which
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
def _haar_step(v: np.ndarray, w: np.ndarray, n: int, m: int) -> int:
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
def _m_scale(v: np.ndarray, n: int, m: int, c: float, b: float, nu0: float) -> float:
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
def _haar_average(v: np.ndarray, n: int, m: int) -> int:
    """Next level's local averages in place, ``v[i] = (v[i] + v[i + m]) / 2`` for ``i < n - m``
    (``v[i + m]`` is still the previous level's value when read)."""
    k = n - m
    for i in range(k):
        v[i] = 0.5 * (v[i] + v[i + m])
    return k
