"""Haar (MODWT) wavelet variance and maximal-overlap Allan variance.

Conventions (docs/API.md, docs/METHODS.md §2.1-§2.4): level ``j = 1..J``, scale = Haar filter length
``tau_j = 2**j`` samples, ``M_j = T - tau_j + 1`` boundary-free coefficients, WV = mean square of the
coefficients (never demeaned). The Allan variance at cluster length ``m_j = 2**(j-1)`` samples is
exactly ``2 * nu_j``.

Algorithm: the local-average pyramid ``W_{j,t} = (V_{j-1,t} - V_{j-1,t-m})/2``,
``V_{j,t} = (V_{j-1,t} + V_{j-1,t-m})/2`` (``m = 2**(j-1)``, ``V_0 = X - X_0``), which keeps every value
at the size of a local average (a global cumulative sum loses ~6 digits on random-walk signals).
It is evaluated cache-friendly in two phases:

1. levels ``1..L`` on time blocks of ``B`` samples plus a halo of ``2**L - 1`` samples (the halo is
   recomputed, so the values equal those of one global pass; the C kernel recomputes it only for
   the first block of each run of consecutive blocks a thread takes, and copies the same values
   from the previous block otherwise), storing ``V_L``;
2. for ``j > L`` the lags are multiples of ``P = 2**L``, so ``V_L`` splits into ``P`` interleaved
   sub-series on which levels ``j > L`` are the ordinary pyramid (levels ``j - L``). Phase 1 stores
   ``V_L`` "panel-major": the sub-series a panel of a few at a time, each panel contiguous, so
   phase 2 runs on each panel in cache.

Blocks and panels are independent: the C kernel shares them among threads and adds their sums to
the totals in block (panel) order, so the bits depend neither on the thread count nor on how
:mod:`gmwm.stream` cuts a file into chunks (it runs the same phases on chunks and keeps the panels
in a temporary file).
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cache, lru_cache
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["AllanVariance", "WaveletVariance", "avar", "biweight_tuning", "chi2_ci", "haar_coefficients",
           "kernel_name", "load_kernel", "wvar", "wvar_many", "wvar_robust"]

def default_layout(T: int, n_levels: int) -> tuple[int, int, int]:
    """Default (L, block length, panel width). Phase 1 does up to 11 levels (blocks of
    ``8 * 2**L`` samples, ~300 KiB of work arrays, sit in L2) and more only when needed to keep the
    phase-2 sub-series (``~T / 2**L`` samples) short. Chosen from ``bench_wv.py --tune``; timings
    are flat within 10 % around this choice."""
    n_block = min(n_levels, max((n_levels + 1) // 2, 11))
    return n_block, 8 << n_block, 8


@cache
def classical_kernels() -> Any:
    """The classical WV kernels (a module with ``phase1`` and ``phase2``): the C ones
    (``gmwm._haar``, built at install; no Numba start-up, several threads, releases the GIL) or
    else their Numba twins (``gmwm._wvkernels``, one thread). Both compute the same operations in
    the same order: identical bits on any IEEE-754 machine (tests/test_wv.py)."""
    try:
        from gmwm import _haar
        return _haar
    except ImportError:
        from gmwm import _wvkernels
        return _wvkernels


def kernel_name() -> str:
    """``"c"`` or ``"numba"``: which classical WV kernel this installation uses."""
    return "c" if classical_kernels().__name__ == "gmwm._haar" else "numba"


#: signals shorter than this are done on one thread (starting a thread costs ~50 us)
_THREAD_MIN_SAMPLES = 1 << 17


def n_threads(T: int | None = None) -> int:
    """Threads the C kernel uses for a signal of ``T`` samples: the cores this process may run on
    (``GMWM_NUM_THREADS`` overrides), 1 for short signals. The result does not depend on it."""
    if T is not None and T < _THREAD_MIN_SAMPLES:
        return 1
    env = os.environ.get("GMWM_NUM_THREADS", "").strip()
    if env:
        try:
            return max(1, min(64, int(env)))
        except ValueError:
            raise InputError(f"GMWM_NUM_THREADS must be a positive integer, got {env!r}") from None
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        cores = os.cpu_count() or 1
    return max(1, min(64, cores))


def load_kernel(n: int = 1024) -> str:
    """Load the classical WV kernel by a call on ``n`` (>= 4) samples and return its name (see
    :func:`kernel_name`). The C kernel loads in about a millisecond; the Numba fallback pays its
    runtime's start-up and the cache load once per process."""
    n = max(4, int(n))
    J = n.bit_length() - 2
    Workspace(n, J).sums(np.arange(float(n)), J)
    return kernel_name()


def aligned_empty(n: int) -> np.ndarray:
    """``np.empty(n)`` starting on a 64-byte boundary (whole cache lines for the kernel's
    panel-major stores)."""
    raw = np.empty(n + 8)
    skip = (-raw.ctypes.data % 64) // 8
    return raw[skip:skip + n]


class Workspace:
    """Geometry and the phase-2 store for one signal length, reused across replicates by
    ``wvar_many``.

    ``n_block`` = L (levels done on time blocks, halo ``2**L - 1``), ``block`` = samples per time
    block, ``panel`` = sub-series per phase-2 panel; ``rows`` = length of a sub-series,
    ``n_out = T - 2**L + 1`` values of ``V_L``, ``store`` holds them panel-major
    (``rows * 2**L`` values, only when ``J > L``). Defaults: see ``default_layout``.
    """

    def __init__(self, T: int, n_levels: int, n_block: int | None = None,
                 block: int | None = None, panel: int | None = None) -> None:
        d_block, d_len, d_panel = default_layout(T, n_levels)
        self.T = T
        self.n_block = d_block if n_block is None else min(n_block, n_levels)
        self.block = min(T, d_len if block is None else block)
        self.panel = d_panel if panel is None else panel
        P = 1 << self.n_block
        self.n_out = T - P + 1
        self.rows = -(-self.n_out // P)
        self.n_panels = -(-P // self.panel)
        self.phase2 = n_levels > self.n_block
        self._store = np.empty(0)

    def store(self) -> np.ndarray:
        """The phase-2 store (``rows * 2**L`` values; allocated on first use, then reused)."""
        if self.phase2 and self._store.size == 0:
            self._store = aligned_empty(self.rows << self.n_block)
        return self._store

    def sums(self, x: np.ndarray, n_levels: int, threads: int | None = None,
             kern: Any = None) -> np.ndarray:
        """``sum_t (2 W_{j,t})**2`` over the boundary-free coefficients of ``x``, ``j = 1..J``;
        ``kern``: the kernel module (default the dispatched one; the C kernel, any build of
        ``_haar``, takes ``threads``, default :func:`n_threads`; the Numba twin runs on one)."""
        kern = classical_kernels() if kern is None else kern
        out = np.zeros(n_levels)
        extra = ((n_threads(self.T) if threads is None else threads),) \
            if kern.__name__.rsplit(".", 1)[-1] == "_haar" else ()
        store = self.store()
        kern.phase1(x, 0, 0, self.T, float(x[0]), self.n_block, self.block, out, store, 0,
                    self.rows, self.panel, *extra)
        if self.phase2:
            kern.phase2(store, self.rows, self.n_out, self.n_block, self.panel, 0, self.n_panels,
                        n_levels - self.n_block, out, *extra)
        return out


# --------------------------------------------------------------------------------------------------
# validation helpers


def as_signal(x: Any, name: str = "signal", ndim: int = 1, layout: str | None = None
               ) -> np.ndarray:
    """``x`` as a C-contiguous float64 array of ``ndim`` dimensions (copied only if needed).
    ``layout`` names the expected shape in the error message (default "1-D (T,)" / "2-D (R, T)")."""
    if np.iscomplexobj(x):
        raise InputError(f"{name} is complex; a real-valued signal is required")
    try:
        arr = np.ascontiguousarray(x, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} is not numeric: {exc}") from None
    if arr.ndim != ndim:
        shape = layout or ("1-D (T,)" if ndim == 1 else "2-D (R, T)")
        raise InputError(f"{name} must be {shape}, got shape {arr.shape}")
    return arr


def _check_finite(arr: np.ndarray, name: str = "signal") -> None:
    n_nan = int(np.count_nonzero(np.isnan(arr)))
    n_inf = int(np.count_nonzero(np.isinf(arr)))
    if n_nan or n_inf:
        parts = [f"{n_nan} NaN values"] if n_nan else []
        parts += [f"{n_inf} infinite values"] if n_inf else []
        raise InputError(f"{name} contains {' and '.join(parts)}")


def n_levels_for(T: int, levels: Any) -> int:
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


def check_alpha_freq(alpha: float, freq: float) -> None:
    """InputError unless ``alpha`` lies in (0, 1) and ``freq`` [Hz] is finite and positive."""
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be in (0, 1), got {alpha}")
    if not (np.isfinite(freq) and freq > 0.0):
        raise InputError(f"freq must be a positive number of Hz, got {freq}")


def _check_ci(ci: str) -> None:
    from gmwm.wvci import check_ci_kind

    check_ci_kind(ci)


def _sums_checked(x: np.ndarray, J: int, ws: Workspace, name: str) -> np.ndarray:
    sums = ws.sums(x, J)
    if not np.all(np.isfinite(sums)):
        # NaN/inf always propagate into the level-1 sum, so the finiteness check is done only here
        _check_finite(x, name)
        raise InputError(f"{name} is too large in magnitude: squared differences overflow float64")
    return sums


# --------------------------------------------------------------------------------------------------
# public API


def wv_ci(ci: str, variance: np.ndarray, scales: np.ndarray, n: np.ndarray, n_samples: int,
           alpha: float, efficiency: float = 1.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(edof, ci_low, ci_high)`` of the interval kind ``ci`` (:mod:`gmwm.wvci`); ``"eta3"`` is
    :func:`chi2_ci` with ``efficiency * max(M_j / 2**j, 1)`` edof, as before the kinds existed."""
    from gmwm import wvci

    wvci.check_ci_kind(ci)
    if ci == "eta3":
        edof = np.maximum(n / scales, 1.0)
        if efficiency != 1.0:
            edof = efficiency * edof
    else:
        edof = wvci.edof_for(ci, variance, scales, n, n_samples, efficiency)
    low, high = chi2_ci(variance, edof, alpha)
    return edof, low, high


def chi2_ci(variance: np.ndarray, edof: np.ndarray, alpha: float = 0.05
            ) -> tuple[np.ndarray, np.ndarray]:
    """Chi-square CI ``[eta nu / q(1-alpha/2), eta nu / q(alpha/2)]``, ``q`` the quantiles of a
    chi-square with ``eta`` (non-integer) degrees of freedom (Percival's eta_3, docs/METHODS.md §2.5)."""
    from scipy.special import chdtri  # lazily: the CLI overlaps this import with the kernel load

    variance = np.asarray(variance, dtype=np.float64)
    edof = np.asarray(edof, dtype=np.float64)
    # chdtri(k, p) is the chi-square quantile of upper tail p (scipy.stats.chi2.ppf(1 - p, k)
    # without importing scipy.stats, which costs ~0.5 s of a CLI call)
    low = edof * variance / chdtri(edof, alpha / 2.0)
    high = edof * variance / chdtri(edof, 1.0 - alpha / 2.0)
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


def _recognise_ci(variance: np.ndarray, scales: np.ndarray, n: np.ndarray, n_samples: int,
                  alpha: float, low: np.ndarray, high: np.ndarray) -> tuple[str, Any]:
    """``(kind, edof)`` of the interval kind whose bounds equal ``low``/``high`` to 1e-6 (a table
    written by this package), else ``("table", None)``."""
    from gmwm import wvci

    for kind in wvci.CI_KINDS:
        edof, lo, hi = wv_ci(kind, variance, scales, n, n_samples, alpha)
        if np.allclose(lo, low, rtol=1e-6, atol=0.0) and np.allclose(hi, high, rtol=1e-6, atol=0.0):
            return kind, edof
    return "table", None


def _finite_list(a: np.ndarray) -> list[float | None]:
    """``a`` as a JSON-able list, None for a non-finite value (the edof of a zero-width CI)."""
    return [float(v) if np.isfinite(v) else None for v in a]


def _freeze_ci_edof(obj: Any, wv_variance: np.ndarray, scales: np.ndarray, eff: float) -> None:
    """Check ``ci_kind`` and store ``ci_edof`` as a read-only array (computed when None)."""
    from gmwm import wvci

    kind = obj.ci_kind
    if kind != "table":
        wvci.check_ci_kind(kind)
    if obj.ci_edof is None:
        if kind == "table":
            edof = wvci.implied_edof(obj.ci_low, obj.ci_high, obj.alpha)
        else:
            edof = wvci.edof_for(kind, wv_variance, scales, obj.n, obj.n_samples, eff)
    else:
        edof = obj.ci_edof
    edof = np.array(edof, dtype=np.float64, copy=True).reshape(-1)
    if edof.size != obj.n.size:
        raise InputError(f"{type(obj).__name__} ci_edof needs one value per level")
    edof.setflags(write=False)
    object.__setattr__(obj, "ci_edof", edof)


@dataclass(frozen=True, eq=False)
class WaveletVariance:
    """Haar WV per level with its chi-square CI. ``scales`` are filter lengths in samples,
    ``n`` the number of coefficients ``M_j``; variances are in (signal unit)**2.

    ``ci_kind``: how ``ci_low``/``ci_high`` were made, a kind of :data:`gmwm.wvci.CI_KINDS`
    (``"mixture"``, ``"eta3"``) or ``"table"`` (bounds given with a table); ``ci_edof``: the
    chi-square edof of those bounds (None: computed for the kind; for ``"table"`` the edof
    implied by the bounds' ratio). ``edof`` (a property) stays Percival's eta_3: the estimator's
    ``"gaussian"`` and ``"ci-eta3"`` weights use it (and :meth:`eta3_ci`), whatever the interval
    kind (the default ``"ci"`` weights are ``"ci-eta3"``, :data:`gmwm.inference.CI_WEIGHTS`)."""

    levels: np.ndarray
    scales: np.ndarray
    variance: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    n: np.ndarray
    n_samples: int
    freq: float = 1.0
    alpha: float = 0.05
    efficiency: float = 1.0
    ci_kind: str = "eta3"
    ci_edof: Any = None

    def __post_init__(self) -> None:
        _freeze_fields(self, (("levels", np.int64), ("scales", np.float64),
                              ("variance", np.float64), ("ci_low", np.float64),
                              ("ci_high", np.float64), ("n", np.int64)))
        eff = float(self.efficiency)
        if not 0.0 < eff <= 1.0:
            raise InputError(f"efficiency must be in (0, 1], got {self.efficiency}")
        object.__setattr__(self, "efficiency", eff)
        _freeze_ci_edof(self, self.variance, self.scales, eff)

    @property
    def robust(self) -> bool:
        """True for the bounded-influence estimate of :func:`wvar` with ``robust=True``."""
        return self.efficiency < 1.0

    @property
    def n_levels(self) -> int:
        return int(self.levels.size)

    @property
    def scales_s(self) -> np.ndarray:
        """Scales in seconds (``tau_j / freq``)."""
        return self.scales / self.freq

    @property
    def edof(self) -> np.ndarray:
        """Percival's eta_3 equivalent degrees of freedom ``eta_j = e * max(M_j / 2**j, 1)`` with
        ``e`` the Gaussian efficiency of the estimator (1 for the classical WV, see
        ``robust_edof``). The estimator's weights use it; the CI's own edof is ``ci_edof``."""
        return self.efficiency * np.maximum(self.n / self.scales, 1.0)

    def eta3_ci(self) -> tuple[np.ndarray, np.ndarray]:
        """``(low, high)`` of the eta_3 chi-square CI (``ci="eta3"``; the given bounds when the CI
        came with a table). The GMWM's ``"ci-eta3"`` weights are the inverse squared widths of
        these, whatever ``ci_kind``."""
        if self.ci_kind in ("eta3", "table"):
            return self.ci_low, self.ci_high
        return chi2_ci(self.variance, self.edof, self.alpha)

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
                               self.freq, self.alpha, self.efficiency, self.ci_kind,
                               self.ci_edof[idx])

    def to_dict(self) -> dict[str, Any]:
        """JSON-able dict (plain lists and numbers; ``efficiency`` only for a robust WV)."""
        extra = {"robust": True, "efficiency": self.efficiency} if self.robust else {}
        return {
            "levels": self.levels.tolist(),
            "scales": self.scales.tolist(),
            "scales_s": self.scales_s.tolist(),
            "variance": self.variance.tolist(),
            "ci_low": self.ci_low.tolist(),
            "ci_high": self.ci_high.tolist(),
            "n": self.n.tolist(),
            "edof": self.edof.tolist(),
            "ci": self.ci_kind,
            "ci_edof": _finite_list(self.ci_edof),
            "n_samples": self.n_samples,
            "freq": self.freq,
            "alpha": self.alpha,
            **extra,
        }

    @classmethod
    def from_table(cls, scales: Any, variance: Any, ci_low: Any = None, ci_high: Any = None, *,
                   n_samples: int, freq: float = 1.0, alpha: float = 0.05,
                   ci: str = "mixture") -> WaveletVariance:
        """WV shared as a table: ``scales`` in samples (increasing powers of 2, not necessarily
        consecutive), ``variance > 0``, optional CI bounds, ``n_samples`` = T of the signal it
        came from. Without bounds the CI of kind ``ci`` is computed: both kinds need only the
        WV and T, so a table of the same levels gets exactly its signal's interval. Given bounds
        are kept; they are recognised as ``"mixture"`` or ``"eta3"`` bounds when they equal
        those (to 1e-6, e.g. a table written by ``gmwm wv``), else ``ci_kind="table"``."""
        check_alpha_freq(alpha, freq)
        _check_ci(ci)
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
            edof, low, high = wv_ci(ci, var, sc, n, T, alpha)
            kind = ci
        else:
            low = np.asarray(ci_low, dtype=np.float64).reshape(-1)
            high = np.asarray(ci_high, dtype=np.float64).reshape(-1)
            if low.size != var.size or high.size != var.size:
                raise InputError("table CI bounds need one value per scale")
            ok = np.isfinite(low) & np.isfinite(high) & (low > 0) & (low <= var) & (var <= high)
            if not np.all(ok):
                raise InputError("table CI bounds must satisfy 0 < ci_low <= variance <= ci_high")
            kind, edof = _recognise_ci(var, sc, n, T, alpha, low, high)
        return cls(np.round(lev).astype(np.int64), sc, var, low, high, n, T, freq, alpha,
                   ci_kind=kind, ci_edof=edof)


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
    ci_kind: str = "eta3"
    ci_edof: Any = None

    def __post_init__(self) -> None:
        _freeze_fields(self, (("levels", np.int64), ("clusters", np.int64), ("tau", np.float64),
                              ("avar", np.float64), ("ci_low", np.float64),
                              ("ci_high", np.float64), ("n", np.int64)))
        _freeze_ci_edof(self, self.avar / 2.0, 2.0 * self.clusters, 1.0)

    @property
    def adev(self) -> np.ndarray:
        """Allan deviation ``sqrt(avar)``."""
        return np.sqrt(self.avar)

    @classmethod
    def from_wv(cls, wv: WaveletVariance) -> AllanVariance:
        clusters = (wv.scales // 2).astype(np.int64)
        return cls(wv.levels, clusters, clusters / wv.freq, 2.0 * wv.variance, 2.0 * wv.ci_low,
                   2.0 * wv.ci_high, wv.n, wv.n_samples, wv.freq, wv.alpha, wv.ci_kind,
                   wv.ci_edof)

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
            "ci": self.ci_kind,
            "ci_edof": _finite_list(self.ci_edof),
            "n_samples": self.n_samples,
            "freq": self.freq,
            "alpha": self.alpha,
        }


def wvar(x: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0, *,
         robust: bool = False, eff: float = 0.6, ci: str = "mixture") -> WaveletVariance:
    """Haar wavelet variance of a 1-D signal at levels ``1..J`` (``levels`` = J, default
    ``floor(log2 T) - 1``), with a chi-square CI at level ``1 - alpha``; ``freq`` in Hz.

    ``ci``: ``"mixture"`` (edof of the noise mixture identified around each level, nominal
    coverage) or ``"eta3"`` (Percival's ``max(M_j / 2**j, 1)``, conservative; R ``wv``/``simts``),
    see :mod:`gmwm.wvci`. ``robust=True``: bounded-influence Tukey-biweight M-estimate of each
    level's WV with Gaussian efficiency ``eff`` (see :func:`wvar_robust`); the edof is then
    ``eff`` times that of ``ci``."""
    _check_ci(ci)
    if robust:
        return wvar_robust(x, levels, alpha, freq, eff=eff, ci=ci)
    arr = as_signal(x)
    T = arr.shape[0]
    J = n_levels_for(T, levels)
    check_alpha_freq(alpha, freq)
    return wv_from_sums(_sums_checked(arr, J, Workspace(T, J), "signal"), T, alpha, freq, ci)


def wv_from_sums(sums: np.ndarray, T: int, alpha: float = 0.05, freq: float = 1.0,
                 ci: str = "mixture") -> WaveletVariance:
    """The WV and its CI from the kernel's sums ``sum_t (2 W_{j,t})**2``, ``j = 1..J``, of a
    signal of ``T`` samples (shared by :func:`wvar` and :mod:`gmwm.stream`)."""
    J = len(sums)
    lev = np.arange(1, J + 1)
    scales = 2.0 ** lev
    n = T - (1 << lev) + 1
    variance = 0.25 * np.asarray(sums, dtype=np.float64) / n
    edof, low, high = wv_ci(ci, variance, scales, n, T, alpha)
    return WaveletVariance(lev, scales, variance, low, high, n, T, freq, alpha, ci_kind=ci,
                           ci_edof=edof)


def wvar_many(X: Any, levels: int | None = None) -> np.ndarray:
    """Wavelet variances (no CI) of ``R`` replicates ``X`` of shape ``(R, T)``: array ``(R, J)``."""
    arr = as_signal(X, "X", ndim=2)
    R, T = arr.shape
    J = n_levels_for(T, levels)
    ws = Workspace(T, J)
    n = T - (1 << np.arange(1, J + 1)) + 1
    out = np.empty((R, J))
    for r in range(R):
        out[r] = 0.25 * _sums_checked(arr[r], J, ws, f"X[{r}]") / n
    return out


def avar(x: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0, *,
         ci: str = "mixture") -> AllanVariance:
    """Maximal-overlap Allan variance at clusters ``m_j = 2**(j-1)``, ``j = 1..J`` (= 2 x WV;
    CI kind ``ci`` as in :func:`wvar`)."""
    return AllanVariance.from_wv(wvar(x, levels, alpha, freq, ci=ci))


# --------------------------------------------------------------------------------------------------
# robust wavelet variance (separate path: the classical kernels above are untouched)
#
# Estimator. At level j the boundary-free MODWT Haar coefficients W_t (t = 2**j - 1 .. T - 1, the
# same M_j coefficients as the classical WV) are treated as mean-zero with scale nu_j = E W_t**2.
# The robust nu_j is the M-estimate of scale solving
#     (1/M_j) sum_t rho_c(W_t / sqrt(nu)) = b,    b = E rho_c(Z), Z ~ N(0, 1),
# with Tukey's biweight rho_c(r) = 1 - (1 - (r/c)**2)**3 for |r| <= c, 1 beyond: bounded, so one
# coefficient (or a burst of them) moves nu_j by at most a bounded amount, and Fisher-consistent
# when W_t is Gaussian (any Gaussian latent process: the W_t are linear in X), whatever the
# dependence between coefficients. Breakdown point min(b, 1 - b).
#
# Efficiency. With chi = rho_c - b the influence function of nu_hat at N(0, nu) is
#     IF(w) = 2 nu chi(w / sqrt(nu)) / E[Z chi'(Z)],
# so for independent coefficients Var(nu_hat) = 4 nu**2 E[chi(Z)**2] / (M E[Z chi'(Z)]**2), while the
# mean square has 2 nu**2 / M. The Gaussian efficiency is therefore
#     e(c) = E[Z rho'(Z)]**2 / (2 Var rho(Z)),
# (e = 1 for rho(r) = r**2), increasing in c; c is solved from the user's e.
#
# CI. The classical chi-square CI matches Var(nu_hat) = 2 nu**2 / eta with eta = eta_3. Matching
# 2 nu**2 / eta_rob = Var(robust) = Var(classical) / e gives eta_rob = e * eta_3. For dependent
# coefficients this is conservative: expanding chi in Hermite polynomials, its order-2 term has the
# same variance contribution as the classical estimator's (Stein: E[Z chi'] = E[(Z**2 - 1) chi]), and
# the orders >= 4 carry sum_h rho_W(h)**k <= sum_h rho_W(h)**2, so the true variance ratio lies in
# [1, 1/e]: 1/e for white coefficients, tending to 1 for strongly correlated ones (long scales).


def _rho_moments(c: float) -> tuple[float, float, float]:
    """``(E rho_c(Z), Var rho_c(Z), E[Z rho_c'(Z)])`` for Z ~ N(0, 1) (numerical quadrature)."""
    import math

    from scipy.integrate import quad

    def pdf(r: float) -> float:
        return math.exp(-0.5 * r * r) / math.sqrt(2.0 * math.pi)

    def rho(r: float) -> float:
        u = (r / c) ** 2
        return 1.0 - (1.0 - u) ** 3 if u < 1.0 else 1.0

    def zdrho(r: float) -> float:
        u = (r / c) ** 2
        return 6.0 * u * (1.0 - u) ** 2 if u < 1.0 else 0.0

    tail = math.erfc(c / math.sqrt(2.0))  # P(|Z| > c)
    e1 = 2.0 * quad(lambda r: rho(r) * pdf(r), 0.0, c, epsabs=1e-13, epsrel=1e-12)[0] + tail
    e2 = 2.0 * quad(lambda r: rho(r) ** 2 * pdf(r), 0.0, c, epsabs=1e-13, epsrel=1e-12)[0] + tail
    ez = 2.0 * quad(lambda r: zdrho(r) * pdf(r), 0.0, c, epsabs=1e-13, epsrel=1e-12)[0]
    return e1, e2 - e1**2, ez


def _efficiency(c: float) -> float:
    _, var, ez = _rho_moments(c)
    return ez**2 / (2.0 * var)


@lru_cache(maxsize=64)
def biweight_tuning(eff: float) -> tuple[float, float, float]:
    """Tuning of the biweight M-scale for Gaussian efficiency ``eff`` (relative to the classical
    mean square, independent Gaussian coefficients): ``(c, b, breakdown)`` with ``c`` the cut-off in
    units of sqrt(nu), ``b = E rho_c(Z)`` and ``breakdown = min(b, 1 - b)``."""
    from scipy.optimize import brentq

    eff = float(eff)
    if not 0.05 <= eff <= 0.99:
        raise InputError(f"robust efficiency eff must be in [0.05, 0.99], got {eff}")
    c = brentq(lambda cc: _efficiency(cc) - eff, 0.3, 60.0, xtol=1e-12)
    b = _rho_moments(c)[0]
    return float(c), float(b), float(min(b, 1.0 - b))


def _start_scale(v: np.ndarray, n: int, m: int) -> float:
    """Robust starting value for the M-scale: MAD of a strided subsample (at most ~65k) of the
    coefficients ``W_i = (v[i + m] - v[i]) / 2``, ``i < n``."""
    idx = np.arange(0, n, max(1, n // 65536))
    w = 0.5 * (v[idx + m] - v[idx])
    med = float(np.median(np.abs(w)))
    if med > 0:
        return (med / 0.6744897501960817) ** 2
    ms = float(np.mean(w * w))
    return ms if ms > 0 else 1.0


def haar_levels(x: Any, J: int) -> Iterator[tuple[int, np.ndarray]]:
    """Yield ``(j, W_j)`` for j = 1..J: the boundary-free MODWT Haar coefficients of every level in
    one pass of the pyramid (docs/METHODS.md §2.3), same convention as :func:`haar_coefficients`.
    ``W_j`` is a view into one work array, valid until the next step."""
    from gmwm._wvkernels import haar_step

    v = np.ascontiguousarray(x, dtype=float) - float(x[0])
    w = np.empty_like(v)
    n = v.size
    for j in range(1, int(J) + 1):
        n = haar_step(v, w, n, 1 << (j - 1))
        yield j, w[:n]


def haar_coefficients(x: Any, level: int) -> np.ndarray:
    """Boundary-free MODWT Haar coefficients of level ``level`` (``M_j = T - 2**j + 1`` values,
    ``W_t`` for ``t = 2**j - 1 .. T - 1``, same convention as :func:`wvar`: ``mean(W**2)`` is the
    classical WV). Mainly for checks; :func:`wvar_robust` streams all levels in place."""
    arr = as_signal(x)
    J = n_levels_for(arr.shape[0], level)
    for _, w in haar_levels(arr, J):
        pass
    return w.copy()


def wvar_robust(x: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0, *,
                eff: float = 0.6, ci: str = "mixture") -> WaveletVariance:
    """Robust Haar WV: per level, the Tukey-biweight M-estimate of scale of the boundary-free
    MODWT coefficients with Gaussian efficiency ``eff`` (default 0.6; see the notes above this
    function in the source for the estimator, its efficiency and the CI). CI: chi-square with
    ``eff`` times the edof of kind ``ci`` (conservative for correlated coefficients). Cost: per level 3-5 passes for
    the M-estimate (Newton) and one for the next averages, 11-17x the classical WV's CPU time
    at T = 1e6-1e7; memory: one copy of the signal.
    """
    _check_ci(ci)
    arr = as_signal(x)
    T = arr.shape[0]
    J = n_levels_for(T, levels)
    check_alpha_freq(alpha, freq)
    _check_finite(arr)
    from gmwm._wvkernels import haar_average, m_scale

    c, b, _ = biweight_tuning(eff)
    v = arr - arr[0]  # the only work array: the levels' local averages, updated in place
    variance = np.empty(J)
    n = T
    with np.errstate(over="ignore", invalid="ignore"):
        for j in range(1, J + 1):
            m = 1 << (j - 1)
            nu = m_scale(v, n - m, m, c, b, _start_scale(v, n - m, m))
            n = haar_average(v, n, m)
            if not np.isfinite(nu):
                raise InputError("signal is too large in magnitude: squared coefficients overflow "
                                 "float64")
            variance[j - 1] = nu
    lev = np.arange(1, J + 1)
    scales = 2.0 ** lev
    counts = T - (1 << lev) + 1
    edof, low, high = wv_ci(ci, variance, scales, counts, T, alpha, float(eff))
    return WaveletVariance(lev, scales, variance, low, high, counts, T, freq, alpha, float(eff),
                           ci_kind=ci, ci_edof=edof)
