"""Numba kernels of :mod:`gmwm.wccv` and :mod:`gmwm.virtual`: the Haar pyramid of
:mod:`gmwm.wv` for p interleaved signals (rows = times, columns = signals), giving the wavelet
cross-covariance sums (:func:`wccv_sums`) and the moving-block bootstrap sums of SVO
(:func:`mbb_pass`). Imported lazily, so that importing the library never loads Numba.
Conventions: the docstrings of :mod:`gmwm.wccv` and :mod:`gmwm.virtual`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# --------------------------------------------------------------------------------------------------
# wavelet cross-covariance sums


@njit(cache=True, fastmath={"reassoc", "contract"})
def _step_p(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int, sums: np.ndarray,
            row: int, dbuf: np.ndarray) -> None:
    """One level on rows ``[lo, hi)``: ``dst[t] = (src[t] + src[t-lag]) / 2`` and add the packed
    upper triangle of ``sum_t d_t d_t'`` (``d = src[t] - src[t-lag] = 2 W_t``) to ``sums[row]``.

    The differences go to ``dbuf`` (one contiguous row per signal) first so that every pair's sum
    is a contiguous dot product; ``reassoc`` lets LLVM split it into vector lanes (values of
    ``dst`` are unaffected)."""
    p = src.shape[1]
    n = hi - lo
    for t in range(lo, hi):
        for i in range(p):
            a = src[t, i]
            b = src[t - lag, i]
            dbuf[i, t - lo] = a - b
            dst[t, i] = 0.5 * (a + b)
    q = 0
    for i in range(p):
        di = dbuf[i]
        for k in range(i, p):
            dk = dbuf[k]
            acc = 0.0
            for t in range(n):
                acc += di[t] * dk[t]
            sums[row, q] += acc
            q += 1


@njit(cache=True)
def _avg_p(src: np.ndarray, dst: np.ndarray, lo: int, hi: int, lag: int) -> None:
    p = src.shape[1]
    for t in range(lo, hi):
        for i in range(p):
            dst[t, i] = 0.5 * (src[t, i] + src[t - lag, i])


@njit(cache=True)
def _pyramid_p(a: np.ndarray, b: np.ndarray, n: int, n_levels: int, unit: int, acc_from: int,
               sums: np.ndarray, first: int, dbuf: np.ndarray) -> int:
    """``gmwm._wvkernels._pyramid`` for p signals: levels ``1..n_levels`` on rows ``[0, n)`` with lags in
    multiples of ``unit`` rows; products at rows ``>= acc_from`` go to ``sums[first + j - 1]``."""
    src, dst = a, b
    which = 0
    for j in range(1, n_levels + 1):
        lag = unit << (j - 1)
        lo = (2 * lag) - unit
        if lo >= n:
            break
        acc_lo = max(lo, acc_from)
        if acc_lo > lo:
            _avg_p(src, dst, lo, min(acc_lo, n), lag)
        if acc_lo < n:
            _step_p(src, dst, acc_lo, n, lag, sums, first + j - 1, dbuf)
        src, dst = dst, src
        which = 1 - which
    return which


@njit(cache=True)
def wccv_sums(x: np.ndarray, n_levels: int, n_block: int, sums: np.ndarray, buf_a: np.ndarray,
               buf_b: np.ndarray, v_l: np.ndarray, pan_a: np.ndarray, pan_b: np.ndarray,
               dbuf: np.ndarray) -> None:
    """Add ``sum_t (2 W_{i,j,t})(2 W_{k,j,t})`` (packed ``i <= k``) to ``sums[j-1]``: the two-phase
    layout of the WV kernel (``gmwm._wvkernels.phase1/phase2``: time blocks with a recomputed halo
    for levels ``1..L``, then interleaved sub-series of ``V_L`` for the levels above), every row
    holding the p signals."""
    T = x.shape[0]
    p = x.shape[1]
    L = n_block
    halo = (1 << L) - 1
    block = buf_a.shape[0] - halo
    x0 = x[0].copy()
    b0 = 0
    while b0 < T:
        b1 = min(T, b0 + block)
        s0 = max(0, b0 - halo)
        n = b1 - s0
        for r in range(n):
            for i in range(p):
                buf_a[r, i] = x[s0 + r, i] - x0[i]
        which = _pyramid_p(buf_a, buf_b, n, L, 1, b0 - s0, sums, 0, dbuf)
        if n_levels > L:
            src = buf_a if which == 0 else buf_b
            for t in range(max(b0, halo), b1):
                for i in range(p):
                    v_l[t - halo, i] = src[t - s0, i]
        b0 = b1
    if n_levels <= L:
        return
    P = halo + 1
    n_out = T - halo
    rows = (n_out + P - 1) // P
    width = min(pan_a.shape[0] // rows, P)
    r0 = 0
    while r0 < P:
        c = min(width, P - r0)
        last = min(max(n_out - (rows - 1) * P - r0, 0), c)
        for k in range(rows - 1):
            base = k * P + r0
            for ci in range(c):
                for i in range(p):
                    pan_a[k * c + ci, i] = v_l[base + ci, i]
        base = (rows - 1) * P + r0
        for ci in range(last):
            for i in range(p):
                pan_a[(rows - 1) * c + ci, i] = v_l[base + ci, i]
        _pyramid_p(pan_a, pan_b, (rows - 1) * c + last, n_levels - L, c, 0, sums, L, dbuf)
        r0 += c


# --------------------------------------------------------------------------------------------------
# moving-block bootstrap of SVO

#: time-scheme blocks whose prefix-sum rows are read ahead together (see mbb_pass)
_TOUCH = 512


@njit(cache=True, inline="always")
def _haar_step(cur: np.ndarray, nxt: np.ndarray, t: int, lag: int, y: np.ndarray,
               w: np.ndarray, keep: bool) -> float:
    """One Haar step at time ``t``: wavelet coefficients into ``w``, the next level's scaling
    coefficients into ``nxt[t]`` if ``keep`` (not at the last level); returns the projection
    ``w'y``."""
    s = 0.0
    for i in range(w.shape[0]):
        a = cur[t, i]
        b = cur[t - lag, i]
        w[i] = 0.5 * (a - b)
        if keep:
            nxt[t, i] = 0.5 * (a + b)
        s += w[i] * y[i]
    return s


@njit(cache=True)
def mbb_pass(x: np.ndarray, J: int, full: bool, y: np.ndarray, wf: np.ndarray,
              p_starts: np.ndarray, p_block: int, p_last: int, p_refill: np.ndarray,
              p_out: np.ndarray, t_starts: np.ndarray, t_block: int, t_last: int,
              t_sums: np.ndarray, t_counts: np.ndarray, cur: np.ndarray, nxt: np.ndarray,
              cum: np.ndarray) -> None:
    """Both MBB schemes in one pass over the Haar pyramid (a scheme with an empty output array
    is skipped): :func:`gmwm.virtual._mbb_kernel` (``p_*``) and
    :func:`gmwm.virtual._mbb_time_kernel` (``t_*``) share the
    pyramid, which is most of the work (memory bound: two ``(T, p)`` arrays per level).

    The paper scheme keeps its per-level prefix sum ``cum[m]`` as a running sum and captures the
    ``2 H`` refill rows as the pass reaches them (refill starts visited in sorted order); the time
    scheme stores ``cum`` (``(T+1, q)``, passed in with the pyramid's two level arrays, see
    :func:`gmwm.virtual._pass_buffers`) as its blocks start anywhere, and reads each draw's
    random rows ahead in chunks of ``_TOUCH`` blocks before summing them. Every floating-point
    operation and its order are those of running the two schemes one by one with separate
    kernels (``cum[m+1] = cum[m] + f_m``; a draw adds ``cum[hi] - cum[lo]`` per block in block
    order), so the output is bit-identical to that (tests/test_svo.py checks it)."""
    T, p = x.shape
    npair = p * (p + 1) // 2
    qj = npair if full else p
    do_p = p_out.shape[0] > 0
    do_t = t_sums.shape[0] > 0
    MJ = T - (1 << J) + 1
    Hp = p_out.shape[0]
    ncol = p_out.shape[1]
    trimmed = np.zeros((MJ + 1 if do_p else 1, ncol))
    rlo = np.empty((Hp, qj))
    Ht, nbt = t_starts.shape
    for t in range(T):
        for i in range(p):
            cur[t, i] = x[t, i] - x[0, i]
    w = np.empty(p)
    f = np.empty(qj)
    cp = np.empty(qj)
    rs = np.empty(Hp, dtype=np.int64)
    touch = 0.0
    for j in range(1, J + 1):
        lag = 1 << (j - 1)
        tau = 2 * lag
        sh = tau - 1
        Mj = T - tau + 1
        Dj = Mj - MJ
        off = (j - 1) * npair if full else 0
        for q in range(qj):
            cp[q] = 0.0
            cum[0, q] = 0.0
        refill = do_p and Dj > 0
        if refill:
            for h in range(Hp):
                rs[h] = p_refill[h, j - 1]
            ordr = np.argsort(rs)
        else:
            ordr = np.empty(0, dtype=np.int64)
        ia = 0
        ib = 0
        for m in range(Mj + 1):
            # cp = the paper scheme's cum[m]
            if refill:
                while ia < Hp and rs[ordr[ia]] == m:
                    h = ordr[ia]
                    for q in range(qj):
                        rlo[h, q] = cp[q]
                    ia += 1
                while ib < Hp and rs[ordr[ib]] + Dj == m:
                    h = ordr[ib]
                    for q in range(qj):
                        p_out[h, off + q] += cp[q] - rlo[h, q]
                    ib += 1
            if m == Mj:
                break
            s = _haar_step(cur, nxt, m + tau - 1, lag, y, w, j < J)
            if do_p:
                if full:
                    q = 0
                    for i in range(p):
                        for k in range(i, p):
                            f[q] = wf[j - 1] * w[i] * w[k]
                            q += 1
                else:
                    for i in range(p):
                        f[i] = wf[j - 1] * s * w[i]
                for q in range(qj):
                    cp[q] = cp[q] + f[q]
                if m >= Dj:
                    r = m - Dj + 1
                    for q in range(qj):
                        trimmed[r, off + q] += f[q]
            if do_t:
                if full:
                    q = 0
                    for i in range(p):
                        for k in range(i, p):
                            cum[m + 1, q] = cum[m, q] + w[i] * w[k]
                            q += 1
                else:
                    for i in range(p):
                        cum[m + 1, i] = cum[m, i] + s * w[i]
        for h in range(Ht if do_t else 0):
            cnt = 0
            for c0 in range(0, nbt, _TOUCH):
                c1 = min(nbt, c0 + _TOUCH)
                # read the chunk's random rows once with nothing waiting on them, so that many
                # cache misses are in flight at once (a prefetch); the sums below then hit cache
                for bi in range(c0, c1):
                    length = t_last if bi == nbt - 1 else t_block
                    lo = max(t_starts[h, bi] - sh, 0)
                    hi = max(t_starts[h, bi] + length - sh, lo)
                    touch += cum[hi, 0] + cum[hi, qj - 1] + cum[lo, 0] + cum[lo, qj - 1]
                for bi in range(c0, c1):
                    length = t_last if bi == nbt - 1 else t_block
                    lo = max(t_starts[h, bi] - sh, 0)
                    hi = t_starts[h, bi] + length - sh
                    if hi <= lo:
                        continue
                    cnt += hi - lo
                    for q in range(qj):
                        t_sums[h, j - 1, q] += cum[hi, q] - cum[lo, q]
            t_counts[h, j - 1] = cnt
        cur, nxt = nxt, cur
    if do_t:
        cum[0, 0] = touch  # (keeps the prefetch reads; cum is a work array)
    if not do_p:
        return
    for r in range(1, MJ + 1):
        for q in range(ncol):
            trimmed[r, q] += trimmed[r - 1, q]
    nb = p_starts.shape[1]
    for h in range(Hp):
        for bi in range(nb):
            u = p_starts[h, bi]
            length = p_last if bi == nb - 1 else p_block
            for q in range(ncol):
                p_out[h, q] += trimmed[u + length, q] - trimmed[u, q]
