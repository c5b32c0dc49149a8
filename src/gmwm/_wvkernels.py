"""Numba kernels of :mod:`gmwm.wv`: the classical WV sums (the fallback when the C twin
``gmwm._haar`` is not built; same operations in the same order, see ``_haar.c``) and the robust
WV's per-level passes. Imported lazily, so that ``gmwm wv`` never loads Numba's runtime
(~0.6 s) when the C kernel is there. Algorithm and conventions: the docstring of :mod:`gmwm.wv`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# --------------------------------------------------------------------------------------------------
# classical WV


@njit(cache=True, fastmath={"reassoc"})
def _level_step(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> float:
    """One pyramid level on ``t in [lo, hi)``: ``dst[t] = (src[t] + src[t-lag]) / 2`` and return
    ``sum (src[t] - src[t-lag])**2`` (= 4 * sum W**2).

    ``reassoc`` only lets LLVM split the sum of squares into vector lanes (4x faster); the
    element-wise values are unaffected (the only other operations are one add and an exact halving).
    """
    cur = src[lo:hi]
    prev = src[lo - lag:hi - lag]
    out = dst[lo:hi]
    acc = 0.0
    for i in range(hi - lo):
        a = cur[i]
        b = prev[i]
        d = a - b
        acc += d * d
        out[i] = 0.5 * (a + b)
    return acc


@njit(cache=True)
def _level_avg(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> None:
    """Averages only (halo positions whose coefficients belong to the previous block)."""
    cur = src[lo:hi]
    prev = src[lo - lag:hi - lag]
    out = dst[lo:hi]
    for i in range(hi - lo):
        out[i] = 0.5 * (cur[i] + prev[i])


@njit(cache=True)
def _pyramid(a: np.ndarray, b: np.ndarray, n: int, n_levels: int, unit: int, acc_from: int,
             sums: np.ndarray, first: int) -> int:
    """Pyramid levels ``1..n_levels`` on ``a[:n]`` with lags in multiples of ``unit`` elements,
    ping-ponging between ``a`` and ``b``. Squared differences at positions ``>= acc_from`` are added
    to ``sums[first + j - 1]``. Returns 0 if the last level's averages are in ``a``, 1 if in ``b``."""
    src, dst = a, b
    which = 0
    for j in range(1, n_levels + 1):
        lag = unit << (j - 1)
        lo = (2 * lag) - unit          # first position where level j is defined
        if lo >= n:
            break
        acc_lo = max(lo, acc_from)
        if acc_lo > lo:
            _level_avg(src, dst, lo, min(acc_lo, n), lag)
        if acc_lo < n:
            sums[first + j - 1] += _level_step(src, dst, acc_lo, n, lag)
        src, dst = dst, src
        which = 1 - which
    return which


@njit(cache=True)
def wv_sums(x: np.ndarray, n_levels: int, n_block: int, sums: np.ndarray, buf_a: np.ndarray,
             buf_b: np.ndarray, v_l: np.ndarray, pan_a: np.ndarray, pan_b: np.ndarray) -> None:
    """Add ``sum_t (2 W_{j,t})**2`` over the boundary-free coefficients of ``x`` to ``sums[j-1]``.

    Work arrays (see ``_Workspace``): ``buf_a/buf_b`` hold ``block + 2**L - 1`` values,
    ``v_l`` holds ``T - 2**L + 1`` and ``pan_a/pan_b`` a panel of sub-series.
    """
    T = x.shape[0]
    L = n_block
    halo = (1 << L) - 1
    block = buf_a.shape[0] - halo
    x0 = x[0]
    b0 = 0
    while b0 < T:
        b1 = min(T, b0 + block)
        s0 = max(0, b0 - halo)
        n = b1 - s0
        for i in range(n):
            buf_a[i] = x[s0 + i] - x0
        which = _pyramid(buf_a, buf_b, n, L, 1, b0 - s0, sums, 0)
        if n_levels > L:
            src = buf_a if which == 0 else buf_b
            for t in range(max(b0, halo), b1):
                v_l[t - halo] = src[t - s0]
        b0 = b1
    if n_levels <= L:
        return
    # phase 2: interleaved sub-series of V_L (index s = t - halo, residue s % P, row s // P)
    P = halo + 1
    n_out = T - halo
    rows = (n_out + P - 1) // P
    width = min(pan_a.shape[0] // rows, P)
    r0 = 0
    while r0 < P:
        c = min(width, P - r0)
        last = min(max(n_out - (rows - 1) * P - r0, 0), c)  # valid entries of the last row
        for k in range(rows - 1):
            base = k * P + r0
            for ci in range(c):
                pan_a[k * c + ci] = v_l[base + ci]
        base = (rows - 1) * P + r0
        for ci in range(last):
            pan_a[(rows - 1) * c + ci] = v_l[base + ci]
        _pyramid(pan_a, pan_b, (rows - 1) * c + last, n_levels - L, c, 0, sums, L)
        r0 += c


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
