"""Bit-for-bit checks of the SVO pass (:func:`gmwm._svokernels.mbb_pass`) against plain NumPy
references that follow the documented operations one by one (the pyramid, the per-level prefix
sums ``cum[m+1] = cum[m] + f_m``, and per draw the block differences ``cum[hi] - cum[lo]`` added
in block order)."""

from __future__ import annotations

import numpy as np
import pytest

from gmwm.virtual import _mbb_time_kernel, _run_mbb_schemes


def _levels(x: np.ndarray, J: int) -> list[np.ndarray]:
    """Wavelet coefficients ``w`` (``(M_j, p)``, times ``2**j - 1 .. T-1``) of every level, with
    the kernel's operations: ``cur = x - x[0]``, ``w = (a - b) / 2``, next ``(a + b) / 2``."""
    T = x.shape[0]
    cur = x - x[0]
    out = []
    for j in range(1, J + 1):
        lag = 1 << (j - 1)
        t = np.arange(2 * lag - 1, T)
        a, b = cur[t], cur[t - lag]
        out.append(0.5 * (a - b))
        nxt = np.empty_like(cur)
        nxt[t] = 0.5 * (a + b)
        cur = nxt
    return out


def _features(w: np.ndarray, y: np.ndarray, full: bool) -> np.ndarray:
    if full:
        p = w.shape[1]
        return np.column_stack([w[:, i] * w[:, k] for i in range(p) for k in range(i, p)])
    s = np.zeros(w.shape[0])
    for i in range(w.shape[1]):
        s = s + w[:, i] * y[i]
    return s[:, None] * w


def _time_reference(x, J, full, y, starts, block, last):
    H, B = starts.shape
    sums, counts = None, np.zeros((H, J), np.int64)
    for j, w in enumerate(_levels(x, J), start=1):
        f = _features(w, y, full)
        cum = np.vstack([np.zeros((1, f.shape[1])), np.cumsum(f, axis=0)])
        if sums is None:
            sums = np.zeros((H, J, f.shape[1]))
        sh = (1 << j) - 1
        for h in range(H):
            for bi in range(B):
                length = last if bi == B - 1 else block
                lo, hi = max(starts[h, bi] - sh, 0), starts[h, bi] + length - sh
                if hi <= lo:
                    continue
                counts[h, j - 1] += hi - lo
                sums[h, j - 1] += cum[hi] - cum[lo]
    return sums, counts


@pytest.mark.parametrize("full", [False, True])
@pytest.mark.parametrize("T,J,block", [(1500, 9, 37), (1024, 9, 1024), (777, 8, 50)])
def test_time_scheme_equals_numpy_reference_bit_for_bit(full, T, J, block):
    """Random block starts (ties, blocks wholly before a level's first coefficient, a last block
    of another length) give the sums and counts of the stored-prefix-sum reference exactly."""
    rng = np.random.default_rng(T + J)
    p = 3
    x = np.cumsum(rng.standard_normal((T, p)), axis=0) + rng.standard_normal((T, p))
    y = rng.standard_normal(p)
    H, B = 7, -(-T // block)
    last = T - (B - 1) * block
    starts = rng.integers(0, T - block + 1, size=(H, B))
    starts[0, :2] = starts[0, 2 % B]                     # ties
    q = p * (p + 1) // 2 if full else p
    sums, counts = np.zeros((H, J, q)), np.zeros((H, J), np.int64)
    _mbb_time_kernel(x, J, full, y, starts, block, last, sums, counts)
    ref_s, ref_c = _time_reference(x, J, full, y, starts, block, last)
    np.testing.assert_array_equal(counts, ref_c)
    assert np.array_equal(sums, ref_s)


def test_both_schemes_in_one_pass_equal_separate_passes_bit_for_bit():
    rng = np.random.default_rng(4)
    x = np.cumsum(rng.standard_normal((2000, 4)), axis=0)
    y, J = rng.standard_normal(4), 9
    wf = 1.0 / (2000 - (1 << np.arange(1, J + 1)) + 1)
    both = _run_mbb_schemes(x, J, False, y, wf, 20, 40, [("paper", np.random.default_rng(1)),
                                                         ("time", np.random.default_rng(2))])
    paper = _run_mbb_schemes(x, J, False, y, wf, 20, 40, [("paper", np.random.default_rng(1))])
    time_ = _run_mbb_schemes(x, J, False, y, wf, 20, 40, [("time", np.random.default_rng(2))])
    assert np.array_equal(both[0], paper[0]) and np.array_equal(both[1], time_[0])
