"""Haar (MODWT) wavelet variance and maximal-overlap Allan variance.

Conventions (docs/API.md, SPEC 1.1-1.3): level ``j = 1..J``, scale = Haar filter length
``tau_j = 2**j`` samples, ``M_j = T - tau_j + 1`` boundary-free coefficients, WV = mean square of the
coefficients (never demeaned). The Allan variance at cluster length ``m_j = 2**(j-1)`` samples is
exactly ``2 * nu_j``.

Algorithm: the local-average pyramid ``W_{j,t} = (V_{j-1,t} - V_{j-1,t-m})/2``,
``V_{j,t} = (V_{j-1,t} + V_{j-1,t-m})/2`` (``m = 2**(j-1)``, ``V_0 = X - X_0``), which keeps every value
at the size of a local average (a global cumulative sum loses ~6 digits on random-walk signals).
It is evaluated cache-friendly in two phases:

1. levels ``1..L`` on time blocks of ``B`` samples plus a halo of ``2**L - 1`` samples (the halo is
   recomputed, so the values equal those of one global pass), storing ``V_L``;
2. for ``j > L`` the lags are multiples of ``P = 2**L``, so ``V_L`` splits into ``P`` interleaved
   sub-series on which levels ``j > L`` are the ordinary pyramid (levels ``j - L``). Sub-series are
   gathered a few at a time into a short buffer that stays in cache.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from scipy.stats import chi2

from gmwm.errors import InputError

__all__ = ["AllanVariance", "WaveletVariance", "avar", "chi2_ci", "wvar", "wvar_many"]

def _layout(T: int, n_levels: int) -> tuple[int, int, int]:
    """Default (L, block length, panel width). Phase 1 does up to 11 levels (blocks of
    ``8 * 2**L`` samples, ~300 KiB of work arrays, sit in L2) and more only when needed to keep the
    phase-2 sub-series (``~T / 2**L`` samples) short. Chosen from ``bench_wv.py --tune`` on a
    2-core AMD EPYC (512 KiB L2, 32 MiB L3); timings are flat within 10 % around this choice."""
    n_block = min(n_levels, max((n_levels + 1) // 2, 11))
    return n_block, 8 << n_block, 8


# --------------------------------------------------------------------------------------------------
# numba kernels


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
def _wv_sums(x: np.ndarray, n_levels: int, n_block: int, sums: np.ndarray, buf_a: np.ndarray,
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


class _Workspace:
    """Work arrays for one signal length, reused across replicates by ``wvar_many``.

    ``n_block`` = L (levels done on time blocks, halo ``2**L - 1``), ``block`` = samples per time
    block, ``panel`` = sub-series gathered together in phase 2. Defaults: see ``_layout``.
    """

    def __init__(self, T: int, n_levels: int, n_block: int | None = None,
                 block: int | None = None, panel: int | None = None) -> None:
        d_block, d_len, d_panel = _layout(T, n_levels)
        self.n_block = d_block if n_block is None else min(n_block, n_levels)
        halo = (1 << self.n_block) - 1
        blen = min(T, d_len if block is None else block)
        self.buf_a = np.empty(blen + halo)
        self.buf_b = np.empty(blen + halo)
        if n_levels > self.n_block:
            n_out = T - halo
            rows = -(-n_out // (halo + 1))
            width = d_panel if panel is None else panel
            self.v_l = np.empty(n_out)
            self.pan_a = np.empty(rows * width)
            self.pan_b = np.empty(rows * width)
        else:
            self.v_l = self.pan_a = self.pan_b = np.empty(0)

    def sums(self, x: np.ndarray, n_levels: int) -> np.ndarray:
        out = np.zeros(n_levels)
        _wv_sums(x, n_levels, self.n_block, out, self.buf_a, self.buf_b, self.v_l, self.pan_a,
                 self.pan_b)
        return out


# --------------------------------------------------------------------------------------------------
# validation helpers


def _as_signal(x: Any, name: str = "signal", ndim: int = 1) -> np.ndarray:
    """``x`` as a C-contiguous float64 array of ``ndim`` dimensions (copied only if needed)."""
    if np.iscomplexobj(x):
        raise InputError(f"{name} is complex; a real-valued signal is required")
    try:
        arr = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} is not numeric: {exc}") from None
    if arr.ndim != ndim:
        shape = "1-D (T,)" if ndim == 1 else "2-D (R, T)"
        raise InputError(f"{name} must be {shape}, got shape {arr.shape}")
    return arr


def _check_finite(arr: np.ndarray, name: str = "signal") -> None:
    n_nan = int(np.count_nonzero(np.isnan(arr)))
    n_inf = int(np.count_nonzero(np.isinf(arr)))
    if n_nan or n_inf:
        parts = [f"{n_nan} NaN values"] if n_nan else []
        parts += [f"{n_inf} infinite values"] if n_inf else []
        raise InputError(f"{name} contains {' and '.join(parts)}")


def _n_levels(T: int, levels: Any) -> int:
    """Number of levels J: default floor(log2 T) - 1, at most floor(log2 T) (M_J >= 1)."""
    if T < 4:
        raise InputError(f"signal has T={T} samples; at least 4 are needed")
    j_max = T.bit_length() - 1
    if levels is None:
        return j_max - 1
    if isinstance(levels, (bool, np.bool_)) or not isinstance(levels, (int, np.integer)):
        raise InputError(f"levels must be an integer number of levels, got {levels!r}")
    if levels < 1:
        raise InputError(f"levels must be >= 1, got {levels}")
    if levels > j_max:
        raise InputError(f"T={T} samples allow at most J={j_max} levels (2**J <= T); "
                         f"J={levels} requested")
    return int(levels)


def _check_alpha_freq(alpha: float, freq: float) -> None:
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be in (0, 1), got {alpha}")
    if not (np.isfinite(freq) and freq > 0.0):
        raise InputError(f"freq must be a positive number of Hz, got {freq}")


def _sums_checked(x: np.ndarray, J: int, ws: _Workspace, name: str) -> np.ndarray:
    sums = ws.sums(x, J)
    if not np.all(np.isfinite(sums)):
        # NaN/inf always propagate into the level-1 sum, so the finiteness check is done only here
        _check_finite(x, name)
        raise InputError(f"{name} is too large in magnitude: squared differences overflow float64")
    return sums


# --------------------------------------------------------------------------------------------------
# public API


def chi2_ci(variance: np.ndarray, edof: np.ndarray, alpha: float = 0.05
            ) -> tuple[np.ndarray, np.ndarray]:
    """Chi-square CI ``[eta nu / q(1-alpha/2), eta nu / q(alpha/2)]``, ``q`` the quantiles of a
    chi-square with ``eta`` (non-integer) degrees of freedom (Percival's eta_3, SPEC 1.2)."""
    variance = np.asarray(variance, dtype=np.float64)
    edof = np.asarray(edof, dtype=np.float64)
    low = edof * variance / chi2.ppf(1.0 - alpha / 2.0, edof)
    high = edof * variance / chi2.ppf(alpha / 2.0, edof)
    return low, high


def _freeze_fields(obj: Any, arrays: tuple[tuple[str, type], ...]) -> None:
    """Coerce a frozen dataclass's per-level fields to read-only 1-D copies of one length, and its
    scalars to plain Python numbers."""
    for name, dtype in arrays:
        arr = np.array(getattr(obj, name), dtype=dtype, copy=True).reshape(-1)
        arr.setflags(write=False)
        object.__setattr__(obj, name, arr)
    if len({getattr(obj, name).size for name, _ in arrays}) != 1:
        raise InputError(f"{type(obj).__name__} arrays must all have one entry per level")
    object.__setattr__(obj, "n_samples", int(obj.n_samples))
    object.__setattr__(obj, "freq", float(obj.freq))
    object.__setattr__(obj, "alpha", float(obj.alpha))


@dataclass(frozen=True, eq=False)
class WaveletVariance:
    """Haar WV per level with its chi-square CI. ``scales`` are filter lengths in samples,
    ``n`` the number of coefficients ``M_j``; variances are in (signal unit)**2."""

    levels: np.ndarray
    scales: np.ndarray
    variance: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    n: np.ndarray
    n_samples: int
    freq: float = 1.0
    alpha: float = 0.05

    def __post_init__(self) -> None:
        _freeze_fields(self, (("levels", np.int64), ("scales", np.float64),
                              ("variance", np.float64), ("ci_low", np.float64),
                              ("ci_high", np.float64), ("n", np.int64)))

    @property
    def n_levels(self) -> int:
        return int(self.levels.size)

    @property
    def scales_s(self) -> np.ndarray:
        """Scales in seconds (``tau_j / freq``)."""
        return self.scales / self.freq

    @property
    def edof(self) -> np.ndarray:
        """Equivalent degrees of freedom ``eta_j = max(M_j / 2**j, 1)``."""
        return np.maximum(self.n / self.scales, 1.0)

    def subset(self, levels: int | Iterable[int]) -> WaveletVariance:
        """Keep levels ``1..levels`` (an int) or the listed level numbers ``j``."""
        if isinstance(levels, (int, np.integer)) and not isinstance(levels, bool):
            if not 1 <= levels <= self.n_levels:
                raise InputError(f"subset needs 1 <= levels <= {self.n_levels}, got {levels}")
            idx = np.arange(int(levels))
        else:
            wanted = np.asarray(list(levels))
            if wanted.size == 0 or wanted.dtype.kind not in "iu":
                raise InputError(f"subset needs a non-empty list of integer levels, got {levels!r}")
            missing = np.setdiff1d(wanted, self.levels)
            if missing.size:
                raise InputError(f"levels {missing.tolist()} are not in this wavelet variance "
                                 f"(levels {self.levels.tolist()})")
            idx = np.searchsorted(self.levels, np.unique(wanted))
        return WaveletVariance(self.levels[idx], self.scales[idx], self.variance[idx],
                               self.ci_low[idx], self.ci_high[idx], self.n[idx], self.n_samples,
                               self.freq, self.alpha)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (plain lists and numbers)."""
        return {
            "levels": self.levels.tolist(),
            "scales": self.scales.tolist(),
            "scales_s": self.scales_s.tolist(),
            "variance": self.variance.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "n": self.n.tolist(),
            "edof": self.edof.tolist(),
            "n_samples": self.n_samples,
            "freq": self.freq,
            "alpha": self.alpha,
        }

    @classmethod
    def from_table(cls, scales: Any, variance: Any, ci_low: Any = None, ci_high: Any = None, *,
                   n_samples: int, freq: float = 1.0, alpha: float = 0.05) -> WaveletVariance:
        """WV shared as a table: ``scales`` in samples (increasing powers of 2, not necessarily
        consecutive), ``variance > 0``, optional CI bounds (computed from the eta_3 edof when both
        are None), ``n_samples`` = T of the signal it came from."""
        _check_alpha_freq(alpha, freq)
        sc = np.asarray(scales, dtype=np.float64).reshape(-1)
        var = np.asarray(variance, dtype=np.float64).reshape(-1)
        if sc.size == 0 or sc.size != var.size:
            raise InputError(f"table needs as many scales as variances, got {sc.size} and "
                             f"{var.size}")
        if not np.all(np.isfinite(sc)) or np.any(sc < 2):
            raise InputError("table scales must be finite filter lengths >= 2 samples")
        lev = np.log2(sc)
        if not np.all(lev == np.round(lev)):
            raise InputError(f"table scales must be powers of 2 (in samples), got {sc.tolist()}")
        if np.any(np.diff(sc) <= 0):
            raise InputError("table scales must be strictly increasing")
        if not np.all(np.isfinite(var)) or np.any(var <= 0):
            raise InputError("table variances must be finite and positive")
        T = int(n_samples)
        if T != n_samples or T < sc[-1]:
            raise InputError(f"n_samples must be an integer >= the largest scale {sc[-1]:g}, "
                             f"got {n_samples}")
        n = T - sc.astype(np.int64) + 1
        if (ci_low is None) != (ci_high is None):
            raise InputError("give both ci_low and ci_high, or neither")
        if ci_low is None:
            low, high = chi2_ci(var, np.maximum(n / sc, 1.0), alpha)
        else:
            low = np.asarray(ci_low, dtype=np.float64).reshape(-1)
            high = np.asarray(ci_high, dtype=np.float64).reshape(-1)
            if low.size != var.size or high.size != var.size:
                raise InputError("table CI bounds need one value per scale")
            ok = np.isfinite(low) & np.isfinite(high) & (low > 0) & (low <= var) & (var <= high)
            if not np.all(ok):
                raise InputError("table CI bounds must satisfy 0 < ci_low <= variance <= ci_high")
        return cls(np.round(lev).astype(np.int64), sc, var, low, high, n, T, freq, alpha)


@dataclass(frozen=True, eq=False)
class AllanVariance:
    """Maximal-overlap Allan variance at cluster lengths ``clusters = 2**(j-1)`` samples
    (``tau`` in seconds); ``avar = 2 * nu_j`` and its CI is twice the WV CI."""

    levels: np.ndarray
    clusters: np.ndarray
    tau: np.ndarray
    avar: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    n: np.ndarray
    n_samples: int
    freq: float = 1.0
    alpha: float = 0.05

    def __post_init__(self) -> None:
        _freeze_fields(self, (("levels", np.int64), ("clusters", np.int64), ("tau", np.float64),
                              ("avar", np.float64), ("ci_low", np.float64),
                              ("ci_high", np.float64), ("n", np.int64)))

    @property
    def adev(self) -> np.ndarray:
        """Allan deviation ``sqrt(avar)``."""
        return np.sqrt(self.avar)

    @classmethod
    def from_wv(cls, wv: WaveletVariance) -> AllanVariance:
        clusters = (wv.scales // 2).astype(np.int64)
        return cls(wv.levels, clusters, clusters / wv.freq, 2.0 * wv.variance, 2.0 * wv.ci_low,
                   2.0 * wv.ci_high, wv.n, wv.n_samples, wv.freq, wv.alpha)

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (plain lists and numbers)."""
        return {
            "levels": self.levels.tolist(),
            "clusters": self.clusters.tolist(),
            "tau": self.tau.tolist(),
            "avar": self.avar.tolist(),
            "adev": self.adev.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "n": self.n.tolist(),
            "n_samples": self.n_samples,
            "freq": self.freq,
            "alpha": self.alpha,
        }


def wvar(x: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0
         ) -> WaveletVariance:
    """Haar wavelet variance of a 1-D signal at levels ``1..J`` (``levels`` = J, default
    ``floor(log2 T) - 1``), with the eta_3 chi-square CI at level ``1 - alpha``; ``freq`` in Hz."""
    arr = _as_signal(x)
    T = arr.shape[0]
    J = _n_levels(T, levels)
    _check_alpha_freq(alpha, freq)
    sums = _sums_checked(arr, J, _Workspace(T, J), "signal")
    lev = np.arange(1, J + 1)
    scales = 2.0 ** lev
    n = T - (1 << lev) + 1
    variance = 0.25 * sums / n
    low, high = chi2_ci(variance, np.maximum(n / scales, 1.0), alpha)
    return WaveletVariance(lev, scales, variance, low, high, n, T, freq, alpha)


def wvar_many(X: Any, levels: int | None = None) -> np.ndarray:
    """Wavelet variances (no CI) of ``R`` replicates ``X`` of shape ``(R, T)``: array ``(R, J)``."""
    arr = _as_signal(X, "X", ndim=2)
    R, T = arr.shape
    J = _n_levels(T, levels)
    ws = _Workspace(T, J)
    n = T - (1 << np.arange(1, J + 1)) + 1
    out = np.empty((R, J))
    for r in range(R):
        out[r] = 0.25 * _sums_checked(arr[r], J, ws, f"X[{r}]") / n
    return out


def avar(x: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0
         ) -> AllanVariance:
    """Maximal-overlap Allan variance at clusters ``m_j = 2**(j-1)``, ``j = 1..J`` (= 2 x WV)."""
    return AllanVariance.from_wv(wvar(x, levels, alpha, freq))
