"""Virtual gyroscope by Scale-wise Variance Optimisation (SVO, [SVO]; docs/METHODS.md §11).

(The module is ``gmwm.virtual``; its main function is exported lazily as ``gmwm.svo``. The WCCV
is :mod:`gmwm.wccv`; the Numba kernels are :mod:`gmwm._svokernels`, loaded on first use.)

``p`` signals of one axis ``X_t`` (columns of a ``(T, p)`` array) are combined into a virtual
signal ``S_t = c'X_t`` with ``c'1 = 1``. With ``A_j`` the Haar wavelet cross-covariance (WCCV)
matrix at level ``j`` (``A_j[i, k] = E[W_{i,j,t} W_{k,j,t}]``, lag 0, same conventions as
:mod:`gmwm.wv`: scale = filter length ``2**j`` samples, ``M_j = T - 2**j + 1`` boundary-free
coefficients, mean squares, never demeaned) and scale weights ``omega >= 0`` (renormalised to sum
to 1), SVO chooses ``c = A^-1 1 / (1' A^-1 1)``, ``A = sum_j omega_j A_j`` (solved, not inverted):
the ``c`` minimising the omega-weighted wavelet variance ``c' A c`` of the virtual signal.

Uncertainty (docs/METHODS.md §11.2-§11.4): ``Cov(c_hat) = Sigma / T`` with ``Sigma = G V G'`` (delta method,
plug-in ``G``) and ``V`` from the moving-block bootstrap of the wavelet coefficients (Algorithm 1:
trim every level to the last ``M_J`` times, resample blocks of ``l = a T^(1/3)`` consecutive times
with starts shared by all signals and levels, refill level ``j`` with one random original stretch
of ``D_j = M_j - M_J`` coefficients, centre at the original estimate, scale by ``T``). Because
``G`` is linear, ``G (gamma*_h - gamma_hat)`` is computed per draw directly from the coefficients
(``O(p)`` numbers per time instead of ``J p^2``); ``mbb_wccv`` returns the full draws
``gamma*_h`` for small problems (and tests).

RDVG (docs/METHODS.md §11.5, Vaccaro & Zaki 2017 as described in [SVO]): ``c = Q^-1 1 / (1'Q^-1 1)`` with
the random-walk innovation covariance ``Q`` estimated, per pair ``(i, k)``, by closed-form
weighted least squares of ``A_j[i, k]`` on the Haar WN and RW columns ``1/tau_j`` and
``(tau_j^2 + 2) / (12 tau_j)`` (weights ``eta_j / (A_j[i,i] A_j[k,k] + A_j[i,k]^2)``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.special import ndtri  # the normal quantile (scipy.stats costs ~0.5 s to import)

from gmwm.atomic import to_jsonable
from gmwm.errors import InputError, ModelError
from gmwm.wccv import WaveletCrossCovariance, as_array, unpack, wccv
from gmwm.wv import WaveletVariance, n_levels_for

__all__ = ["PAPER_OMEGA_LONG", "PAPER_OMEGA_SHORT", "SVOResult", "block_length", "equal",
           "mbb_svo_draws", "mbb_svo_draws_schemes", "mbb_wccv", "rdvg", "svo", "svo_coef",
           "svo_jacobian", "svo_schemes", "svo_weights"]

#: [SVO] App. C1 scale weights for J = 19 (printed, sums 0.998 and 1.002; renormalised on use).
#: omega_1 ("long": random-walk scales) and omega_2 ("short": white-noise scales).
PAPER_OMEGA_LONG = (0.0,) * 7 + (0.001, 0.003, 0.007, 0.018, 0.041, 0.077, 0.112, 0.135, 0.147,
                                 0.151, 0.153, 0.153)
PAPER_OMEGA_SHORT = (0.118, 0.118, 0.117, 0.117, 0.116, 0.112, 0.104, 0.086, 0.059, 0.032, 0.014,
                     0.006, 0.002, 0.001) + (0.0,) * 5


# --------------------------------------------------------------------------------------------------
# moving-block bootstrap passes (Numba kernels in gmwm._svokernels, loaded on first use)


@cache
def _kernels() -> Any:
    from gmwm import _svokernels

    return _svokernels


def _pass_buffers(T: int, p: int, q: int, time_scheme: bool) -> tuple[np.ndarray, ...]:
    """Work arrays of :func:`gmwm._svokernels.mbb_pass` (two pyramid levels, the time scheme's
    prefix sums), allocated by NumPy, which asks Linux for transparent huge pages on large arrays (Numba's
    allocator does not): the time scheme reads its prefix sums at ~1e6 random rows per level,
    and 2 MB pages spare most of the TLB misses. Contents are irrelevant (overwritten)."""
    return (np.empty((T, p)), np.empty((T, p)), np.empty((T + 1 if time_scheme else 1, q)))


def _mbb_kernel(x: np.ndarray, J: int, full: bool, y: np.ndarray, wf: np.ndarray,
                starts: np.ndarray, block: int, last: int, refill: np.ndarray,
                out: np.ndarray) -> None:
    """Moving-block bootstrap sums (docs/METHODS.md §11.4) for every draw ``h``, level by level on whole arrays.

    Feature of a time ``t`` at level ``j``: ``wf[j] * w (w'y)`` (``full=False``, p numbers) or
    ``wf[j] * w_i w_k`` packed (``full=True``, stored at columns ``j * npair``). ``out[h]`` gets the
    sum of the features over the resampled coefficients: the blocks ``starts[h, b] .. + block``
    (the last one ``last`` long) of the trimmed times (the last ``M_J`` of every level) plus the
    refill stretch ``refill[h, j] .. + D_j`` of level ``j``'s own coefficients.
    """
    p = x.shape[1]
    q = p * (p + 1) // 2 if full else p
    _kernels().mbb_pass(x, J, full, y, wf, starts, block, last, refill, out,
                        np.zeros((0, 1), dtype=np.int64), 1, 1, np.zeros((0, J, q)),
                        np.zeros((0, J), dtype=np.int64), *_pass_buffers(*x.shape, q, False))


def _mbb_time_kernel(x: np.ndarray, J: int, full: bool, y: np.ndarray, starts: np.ndarray,
                     block: int, last: int, sums: np.ndarray, counts: np.ndarray) -> None:
    """Time-axis variant: the blocks ``starts[h, b] .. + block`` (last one ``last`` long) are taken
    on the common time axis ``0..T-1``; level ``j`` uses the resampled times where it has a
    coefficient (``t >= 2**j - 1``). ``sums[h, j-1]`` gets the feature sums (``w (w'y)`` or packed
    ``w_i w_k``), ``counts[h, j-1]`` the number of coefficients used."""
    _kernels().mbb_pass(x, J, full, y, np.zeros(J), np.zeros((0, 1), dtype=np.int64), 1, 1,
                        np.zeros((0, J), dtype=np.int64), np.zeros((0, sums.shape[2])), starts,
                        block, last, sums, counts, *_pass_buffers(*x.shape, sums.shape[2], True))


# --------------------------------------------------------------------------------------------------
# estimators


def svo_weights(weights: Any, n_levels: int) -> np.ndarray:
    """Scale weights for ``n_levels`` levels, renormalised to sum to 1.

    ``weights``: a sequence of ``n_levels`` non-negative numbers, ``"equal"``, or one of the paper's
    vectors (App. C1, defined for J = 19): ``"short"`` = omega_2 anchored at level 1 (levels above
    19 get 0, levels beyond ``n_levels`` are dropped), ``"long"`` = omega_1 anchored at level
    ``n_levels`` (its last entry on the last level)."""
    J = int(n_levels)
    if isinstance(weights, str):
        key = weights.strip().lower()
        if key == "equal":
            w = np.ones(J)
        elif key == "short":
            base = np.asarray(PAPER_OMEGA_SHORT)
            w = np.zeros(J)
            k = min(J, base.size)
            w[:k] = base[:k]
        elif key == "long":
            base = np.asarray(PAPER_OMEGA_LONG)
            w = np.zeros(J)
            k = min(J, base.size)
            w[J - k:] = base[base.size - k:]
        else:
            raise InputError(f"unknown weights {weights!r}: use 'short', 'long', 'equal' or "
                             f"{J} numbers")
    else:
        try:
            w = np.asarray(weights, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise InputError(f"weights must be numbers, got {weights!r}") from None
        if w.size != J:
            raise InputError(f"weights has {w.size} entries but there are {J} levels")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise InputError("weights must be finite and non-negative")
    total = float(w.sum())
    if total <= 0:
        raise InputError(f"weights put no mass on the {J} levels (all zero)")
    return w / total


def _weighted(cov: np.ndarray, omega: np.ndarray) -> np.ndarray:
    return np.einsum("j,jik->ik", omega, cov)


def _cho(A: np.ndarray) -> tuple[Any, float]:
    """Cholesky factor of ``A / s`` (``s`` = mean diagonal, for conditioning) and ``s``."""
    s = float(np.mean(np.diag(A)))
    if not np.isfinite(s) or s <= 0:
        raise ModelError("weighted WCCV matrix has a non-positive diagonal")
    msg = ("weighted WCCV matrix is singular: signals are collinear (e.g. a duplicated column) "
           "on the weighted levels")
    try:
        fac = cho_factor(A / s)
    except LinAlgError:
        raise ModelError(msg) from None
    pivots = np.diag(fac[0]) ** 2
    if pivots.min() < 1e-12 * pivots.max():
        raise ModelError(msg)
    return fac, s


def svo_coef(cov: Any, omega: Any) -> np.ndarray:
    """SVO coefficients ``c = A^-1 1 / (1'A^-1 1)``, ``A = sum_j omega_j A_j``, for a WCCV array
    ``cov`` ``(J, p, p)`` and scale weights ``omega`` (``J`` numbers or a preset name)."""
    cov = np.asarray(cov, dtype=np.float64)
    w = svo_weights(omega, cov.shape[0])
    fac, _ = _cho(_weighted(cov, w))
    y = cho_solve(fac, np.ones(cov.shape[1]))
    return y / y.sum()


def svo_jacobian(cov: Any, omega: Any) -> np.ndarray:
    """``G`` (docs/METHODS.md §11.2): ``d c / d gamma``, shape ``(p, J, p, p)`` (element ``[:, j, i, k]`` is the
    column of ``gamma_{ik,j}``; ``gamma_{ik}`` and ``gamma_{ki}`` are separate elements)."""
    cov = np.asarray(cov, dtype=np.float64)
    J, p, _ = cov.shape
    w = svo_weights(omega, J)
    A = _weighted(cov, w)
    fac, s = _cho(A)
    y = cho_solve(fac, np.ones(p)) / s
    sy = y.sum()
    K = np.eye(p) / sy - np.outer(y, np.ones(p)) / sy**2
    Ainv = cho_solve(fac, np.eye(p)) / s
    # column (j, i, k) = K (-A^-1 w_j e_i e_k' y) = -w_j y_k (K A^-1)[:, i]
    KA = K @ Ainv
    return -np.einsum("j,ai,k->ajik", w, KA, y)


def block_length(T: int, const: float = 1.0) -> int:
    """MBB block length ``l = max(1, round(const * T^(1/3)))`` (docs/METHODS.md §11.4)."""
    if not (np.isfinite(const) and const > 0):
        raise InputError(f"block constant must be positive, got {const}")
    return max(1, round(const * T ** (1.0 / 3.0)))


def _mbb_draws(T: int, J: int, H: int, block: int, rng: np.random.Generator
               ) -> tuple[np.ndarray, int, np.ndarray]:
    """Block starts ``(H, B)`` (0-based, uniform on ``0..M_J - l``), the last block's length and
    the refill starts ``(H, J)`` (uniform on ``0..M_J``; unused at level J)."""
    MJ = T - (1 << J) + 1
    if block > MJ:
        raise InputError(f"block length {block} exceeds the {MJ} coefficients of level {J}")
    B = -(-MJ // block)
    last = MJ - (B - 1) * block
    starts = rng.integers(0, MJ - block + 1, size=(H, B))
    refill = rng.integers(0, MJ + 1, size=(H, J))
    return starts, last, refill


def _run_mbb(arr: np.ndarray, J: int, full: bool, y: np.ndarray, wf: np.ndarray, H: int,
             block: int, rng: np.random.Generator, scheme: str = "paper") -> np.ndarray:
    """Bootstrap feature sums per draw: ``(H, q)`` with the per-level weights ``wf`` applied
    (``scheme="paper"``: sums over the M_j resampled coefficients; ``"time"``: per-level means of
    the resampled coefficients times ``wf * M_j``, so both estimate the same quantity)."""
    return _run_mbb_schemes(arr, J, full, y, wf, H, block, [(scheme, rng)])[0]


def _run_mbb_schemes(arr: np.ndarray, J: int, full: bool, y: np.ndarray, wf: np.ndarray, H: int,
                     block: int, runs: Sequence[tuple[str, np.random.Generator]]
                     ) -> list[np.ndarray]:
    """:func:`_run_mbb` for each ``(scheme, rng)`` of ``runs`` (distinct schemes), all in one
    pass over the pyramid; each scheme draws from its own generator, so every result equals
    that of its own :func:`_run_mbb` call."""
    T, p = arr.shape
    y = np.ascontiguousarray(y, dtype=np.float64)
    wf = np.ascontiguousarray(wf, dtype=np.float64)
    npair = p * (p + 1) // 2
    q = npair if full else p
    p_args = (np.zeros((0, 1), dtype=np.int64), 1, 1, np.zeros((0, J), dtype=np.int64),
              np.zeros((0, J * q if full else p)))
    t_args = (np.zeros((0, 1), dtype=np.int64), 1, 1, np.zeros((0, J, q)),
              np.zeros((0, J), dtype=np.int64))
    for scheme, rng in runs:
        if scheme == "paper":
            starts, last, refill = _mbb_draws(T, J, H, block, rng)
            p_args = (starts, block, last, refill, np.zeros((H, J * npair if full else p)))
        elif scheme == "time":
            if block > T:
                raise InputError(f"block length {block} exceeds the {T} samples")
            B = -(-T // block)
            starts = rng.integers(0, T - block + 1, size=(H, B))
            t_args = (starts, block, T - (B - 1) * block, np.zeros((H, J, q)),
                      np.zeros((H, J), dtype=np.int64))
        else:
            raise InputError(f"unknown MBB scheme {scheme!r}: use 'paper' or 'time'")
    if len({scheme for scheme, _ in runs}) != len(runs):
        raise InputError("each MBB scheme may appear once per pass")
    _kernels().mbb_pass(arr, J, full, y, wf, *p_args, *t_args,
                        *_pass_buffers(T, p, q, t_args[3].shape[0] > 0))
    outs = []
    for scheme, _ in runs:
        if scheme == "paper":
            outs.append(p_args[4])
            continue
        sums, counts = t_args[3], t_args[4]
        if np.any(counts == 0):
            raise InputError("a bootstrap draw has no coefficient at some level: use longer "
                             "signals or fewer levels")
        n = T - (1 << np.arange(1, J + 1)) + 1
        means = sums / counts[:, :, None] * (wf * n)[None, :, None]
        outs.append(means.reshape(H, -1) if full else means.sum(axis=1))
    return outs


def mbb_wccv(X: Any, levels: int | None = None, n_boot: int = 200, block: int | None = None,
             block_const: float = 1.0, rng: Any = 0, scheme: str = "paper") -> np.ndarray:
    """Moving-block bootstrap draws ``gamma*_h`` of the WCCV (docs/METHODS.md §11.4), ``(n_boot, J, p, p)``.
    Memory ``~ 8 J p^2 T / 2`` bytes: meant for small problems; :func:`svo` uses the projected
    draws (:func:`mbb_svo_draws`)."""
    arr = as_array(X)
    T, p = arr.shape
    J = n_levels_for(T, levels)
    block = block_length(T, block_const) if block is None else int(block)
    n = T - (1 << np.arange(1, J + 1)) + 1
    out = _run_mbb(arr, J, True, np.zeros(p), 1.0 / n, _n_boot(n_boot), block,
                   np.random.default_rng(rng), scheme)
    return unpack(out.reshape(out.shape[0], J, -1), p)


def _n_boot(n_boot: Any) -> int:
    if isinstance(n_boot, bool) or int(n_boot) != n_boot or n_boot < 2:
        raise InputError(f"n_boot must be an integer >= 2, got {n_boot!r}")
    return int(n_boot)


def mbb_svo_draws(X: Any, cov: np.ndarray, omega: np.ndarray, n_boot: int, block: int,
                  rng: np.random.Generator, scheme: str = "paper") -> np.ndarray:
    """Linearised bootstrap coefficient deviations ``G (gamma*_h - gamma_hat)``, ``(n_boot, p)``,
    for the data ``X``, its WCCV ``cov`` and renormalised weights ``omega``. ``scheme``:
    ``"paper"`` (Algorithm 1, docs/METHODS.md §11.4) or ``"time"`` (blocks on the common time axis, every level
    resampled over its whole range; see :func:`svo`)."""
    return mbb_svo_draws_schemes(X, cov, omega, n_boot, block, [(scheme, rng)])[0]


def mbb_svo_draws_schemes(X: Any, cov: np.ndarray, omega: np.ndarray, n_boot: int, block: int,
                          runs: Sequence[tuple[str, np.random.Generator]]) -> list[np.ndarray]:
    """:func:`mbb_svo_draws` for each ``(scheme, rng)`` of ``runs``, equal to separate calls
    (each scheme draws from its own generator); distinct schemes share one pass over the data."""
    return _draws_schemes(as_array(X), cov, omega, n_boot, block, runs)


def _draws_schemes(arr: np.ndarray, cov: np.ndarray, omega: np.ndarray, n_boot: int, block: int,
                   runs: Sequence[tuple[str, np.random.Generator]]) -> list[np.ndarray]:
    """:func:`mbb_svo_draws_schemes` of an array already checked by :func:`as_array`."""
    T, p = arr.shape
    J = cov.shape[0]
    A = _weighted(cov, omega)
    fac, s = _cho(A)
    y = cho_solve(fac, np.ones(p)) / s
    n = T - (1 << np.arange(1, J + 1)) + 1
    H = _n_boot(n_boot)
    us: list[np.ndarray] = []
    batch: list[tuple[str, np.random.Generator]] = []
    for run in [*runs, ("", None)]:  # one pass per stretch of distinct schemes, draws in order
        if batch and (run[1] is None or run[0] in {sch for sch, _ in batch}):
            us += _run_mbb_schemes(arr, J, False, y, omega / n, H, block, batch)
            batch = []
        batch.append(run)
    out = []
    for u in us:
        # A*_w y - A_w y per draw; dc = -K A^-1 (that)
        du = u - A @ y
        sy = y.sum()
        z = cho_solve(fac, du.T) / s                       # (p, H)
        dc = -(z / sy - np.outer(y, z.sum(axis=0)) / sy**2)
        out.append(dc.T)
    return out


def _rdvg_q(cov: np.ndarray, scales: np.ndarray, edof: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-pair WLS of ``A_j[i,k]`` on ``[1/tau, (tau^2+2)/(12 tau)]``: (R, Q) estimates."""
    tau = scales
    Xd = np.column_stack([1.0 / tau, (tau**2 + 2.0) / (12.0 * tau)])
    p = cov.shape[1]
    R = np.empty((p, p))
    Q = np.empty((p, p))
    var = np.einsum("jii->ji", cov)
    for i in range(p):
        for k in range(i, p):
            w = edof / (var[:, i] * var[:, k] + cov[:, i, k] ** 2)
            sw = np.sqrt(w)
            coef, *_ = np.linalg.lstsq(Xd * sw[:, None], cov[:, i, k] * sw, rcond=None)
            R[i, k] = R[k, i] = coef[0]
            Q[i, k] = Q[k, i] = coef[1]
    return R, Q


# --------------------------------------------------------------------------------------------------
# result


@dataclass(frozen=True, eq=False)
class SVOResult:
    """A virtual gyroscope ``S = c'X``. ``coef`` sums to 1; ``cov`` = estimated ``Cov(c_hat)``
    (``Sigma / T``; None without bootstrap), ``weights`` the renormalised scale weights (None for
    RDVG/equal), ``wccv`` the data's WCCV. ``method``: ``"svo"``, ``"rdvg"`` or ``"equal"``.

    Result protocol of the library: ``params`` (= ``coef``), ``param_names`` (the signal names),
    ``se``, ``conf_int``, ``summary``, ``to_json_dict``; immutable (arrays read-only)."""

    coef: np.ndarray
    cov: np.ndarray | None
    weights: np.ndarray | None
    wccv: WaveletCrossCovariance
    method: str = "svo"
    n_boot: int = 0
    block: int = 0
    alpha: float = 0.05
    extra: Mapping[str, Any] | None = None

    def __post_init__(self) -> None:
        for name in ("coef", "cov", "weights"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _read_only(getattr(self, name)))
        if self.extra is not None:
            object.__setattr__(self, "extra", MappingProxyType(
                {k: _read_only(v) if isinstance(v, np.ndarray) else v
                 for k, v in self.extra.items()}))

    @property
    def names(self) -> tuple[str, ...]:
        return self.wccv.names

    @property
    def params(self) -> np.ndarray:
        """The coefficients ``c`` (``(p,)``, read-only), as every result of the library calls
        its estimates."""
        return self.coef

    @property
    def param_names(self) -> list[str]:
        """Names of the combined signals, in the order of ``params``."""
        return list(self.names)

    @property
    def se(self) -> np.ndarray:
        """Standard errors ``sqrt(diag(cov))`` (NaN without bootstrap)."""
        if self.cov is None:
            return np.full(self.coef.size, np.nan)
        return np.sqrt(np.clip(np.diag(self.cov), 0.0, None))

    def conf_int(self, alpha: float | None = None) -> np.ndarray:
        """Wald intervals ``c_i -/+ z_{1-alpha/2} se_i`` ([SVO] eq. 9; docs/METHODS.md §11.3), shape ``(p, 2)``; NaN
        without bootstrap. ``alpha`` None: the level the result was made with (``self.alpha``,
        0.05 unless chosen)."""
        alpha = self.alpha if alpha is None else float(alpha)
        if not 0.0 < alpha < 1.0:
            raise InputError(f"alpha must be in (0, 1), got {alpha}")
        h = ndtri(1.0 - alpha / 2.0) * self.se
        return np.column_stack([self.coef - h, self.coef + h])

    @property
    def objective(self) -> float:
        """``c' A c`` with the weighted WCCV (the minimised weighted WV); NaN without weights."""
        if self.weights is None:
            return float("nan")
        return float(self.coef @ _weighted(self.wccv.cov, self.weights) @ self.coef)

    def wv(self, alpha: float | None = None) -> WaveletVariance:
        """WV of the virtual signal on the same data (in-sample), with its chi-square CI."""
        return self.wccv.combine(self.coef, alpha)

    def as_dict(self) -> dict[str, float]:
        return dict(zip(self.names, self.coef.tolist()))

    def summary(self) -> str:
        ci = self.conf_int()
        lvl = f"{100 * (1 - self.alpha):g}%"
        head = {"svo": "Scale-wise Variance Optimisation", "rdvg": "RDVG (min. RW variance)",
                "equal": "equal weights"}.get(self.method, self.method)
        lines = [(f"Virtual gyroscope: {head}; T = {self.wccv.n_samples}, J = "
                  f"{self.wccv.n_levels}, p = {self.coef.size}")]
        if self.cov is not None:
            scheme = (self.extra or {}).get("mbb", "paper")
            lines.append(f"CIs: moving-block bootstrap ({scheme}), {self.n_boot} draws, block "
                         f"length {self.block} samples")
        width = max(8, *(len(n) for n in self.names))
        lines.append(f"{'signal':<{width}} {'coef':>10} {'se':>10} {lvl + ' CI':>24}")
        for k, name in enumerate(self.names):
            se = "" if self.cov is None else f"{self.se[k]:10.4f}"
            cis = "" if self.cov is None else f"[{ci[k, 0]:9.4f}, {ci[k, 1]:9.4f}]"
            lines.append(f"{name:<{width}} {self.coef[k]:10.4f} {se:>10} {cis:>24}")
        wv = self.wv()
        eq = self.wccv.combine(np.full(self.coef.size, 1.0 / self.coef.size))
        ratio = wv.variance / eq.variance
        picks = sorted({0, (wv.n_levels - 1) // 2, wv.n_levels - 1})
        lines.append("WV ratio to equal weights: " + ", ".join(
            f"j={int(wv.levels[k])}: {ratio[k]:.3g}" for k in picks))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """Strict-JSON-able dict (non-finite numbers as None): the coefficients with their
        standard errors, covariance and ``conf_int`` at the result's level (None without
        bootstrap), the settings, and ``virtual_wv``, the WV of the virtual signal
        (:meth:`wv`)."""
        return to_jsonable({
            "method": self.method,
            "names": list(self.names),
            "coef": self.coef,
            "se": self.se,
            "cov": self.cov,
            "weights": self.weights,
            "n_boot": self.n_boot,
            "block": self.block,
            "alpha": self.alpha,
            "n_samples": self.wccv.n_samples,
            "levels": self.wccv.n_levels,
            "freq": self.wccv.freq,
            "conf_int": None if self.cov is None else self.conf_int(),
            "virtual_wv": self.wv().to_dict(),
        })


def _read_only(a: Any) -> np.ndarray:
    out = np.array(a, dtype=np.float64, copy=True)
    out.setflags(write=False)
    return out


def _wccv_of(X: Any, levels: int | None, alpha: float, freq: float,
             names: Sequence[str] | None) -> tuple[np.ndarray | None, WaveletCrossCovariance]:
    if isinstance(X, WaveletCrossCovariance):
        if levels is not None and levels != X.n_levels:
            X = X.subset(levels)
        return None, X
    arr = as_array(X)
    return arr, wccv(arr, levels, alpha, freq, names)


def svo(X: Any, weights: Any = "short", *, levels: int | None = None, n_boot: int = 500,
        block: int | None = None, block_const: float = 10.0, alpha: float = 0.05,
        freq: float = 1.0, names: Sequence[str] | None = None, seed: Any = 0,
        mbb: str = "paper", wccv_of_x: WaveletCrossCovariance | None = None) -> SVOResult:
    """Optimal virtual gyroscope by SVO from the signals ``X`` ``(T, p)`` (one per column) or
    their :class:`WaveletCrossCovariance` (then no bootstrap: ``se`` is NaN).

    ``weights``: ``J`` non-negative numbers, ``"short"``/``"long"``/``"equal"`` (see
    :func:`svo_weights`); renormalised. ``n_boot`` moving-block bootstrap draws (0 = no CI),
    block length ``block`` or ``block_const * T^(1/3)``, ``seed`` for the draws (int,
    SeedSequence or Generator). ``mbb``: ``"paper"`` = Algorithm 1 of [SVO] (docs/METHODS.md §11.4: blocks
    over the last ``M_J`` times, one random original stretch refills each level); ``"time"`` =
    blocks over the whole time axis, each level averaging the resampled coefficients it has (no
    refill stretch; at the default J the refill is about half of every low level and keeps little
    of its variability, see docs/pipeline.md). ``wccv_of_x``: the WCCV of the array ``X`` at these
    ``levels``, ``alpha``, ``freq`` if already computed (e.g. ``result.wccv`` of another MBB
    scheme on the same array); it is used as given."""
    return svo_schemes(X, weights, levels=levels, n_boot=n_boot, block=block,
                       block_const=block_const, alpha=alpha, freq=freq, names=names,
                       seeds=[seed], mbb=[mbb], wccv_of_x=wccv_of_x)[0]


def svo_schemes(X: Any, weights: Any = "short", *, levels: int | None = None, n_boot: int = 500,
                block: int | None = None, block_const: float = 10.0, alpha: float = 0.05,
                freq: float = 1.0, names: Sequence[str] | None = None,
                seeds: Sequence[Any] = (0, 0), mbb: Sequence[str] = ("paper", "time"),
                wccv_of_x: WaveletCrossCovariance | None = None) -> list[SVOResult]:
    """:func:`svo` once per MBB scheme ``mbb[k]`` with seed ``seeds[k]``: the results equal
    those of separate :func:`svo` calls bit for bit, but the WCCV is computed once and the
    schemes share one pass over the data (about half the bootstrap cost for two schemes)."""
    mbb = [str(m) for m in mbb]
    seeds = list(seeds)
    if len(seeds) != len(mbb) or not mbb:
        raise InputError(f"svo_schemes needs one seed per MBB scheme, got {len(seeds)} seeds "
                         f"for {len(mbb)} schemes")
    if not 0.0 < alpha < 1.0:
        raise InputError(f"alpha must be in (0, 1), got {alpha}")
    if wccv_of_x is not None and not isinstance(X, WaveletCrossCovariance):
        arr, W = as_array(X), wccv_of_x
        if W.n_samples != arr.shape[0] or W.n_signals != arr.shape[1]:
            raise InputError(f"wccv_of_x is of {W.n_samples} x {W.n_signals} samples, X of "
                             f"{arr.shape[0]} x {arr.shape[1]}")
    else:
        arr, W = _wccv_of(X, levels, alpha, freq, names)
    omega = svo_weights(weights, W.n_levels)
    c = svo_coef(W.cov, omega)
    covs: list[np.ndarray | None] = [None] * len(mbb)
    blk = 0
    if arr is not None and n_boot:
        blk = block_length(W.n_samples, block_const) if block is None else int(block)
        if blk < 1:
            raise InputError(f"block length must be >= 1, got {block}")
        runs = [(m, np.random.default_rng(sd)) for m, sd in zip(mbb, seeds, strict=True)]
        dcs = _draws_schemes(arr, W.cov, omega, n_boot, blk, runs)
        covs = [dc.T @ dc / dc.shape[0] for dc in dcs]
    return [SVOResult(c.copy(), cov, omega.copy(), W, "svo", int(n_boot) if cov is not None else 0, blk, alpha,
                      {"mbb": m} if cov is not None else None)
            for m, cov in zip(mbb, covs, strict=True)]


def rdvg(X: Any, *, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0,
         names: Sequence[str] | None = None) -> SVOResult:
    """RDVG virtual gyroscope (docs/METHODS.md §11.5): ``c = Q^-1 1 / (1'Q^-1 1)`` with ``Q`` (random-walk
    innovation covariance) from per-pair WLS fits of the WCCV; ``extra`` holds ``R`` and ``Q``."""
    _, W = _wccv_of(X, levels, alpha, freq, names)
    R, Q = _rdvg_q(W.cov, W.scales, W.edof)
    try:
        y = np.linalg.solve(Q / np.mean(np.abs(np.diag(Q))), np.ones(W.n_signals))
    except np.linalg.LinAlgError:
        raise ModelError("estimated random-walk covariance Q is singular: RDVG undefined") from None
    if not np.all(np.isfinite(y)) or y.sum() == 0:
        raise ModelError("estimated random-walk covariance Q gives no RDVG solution")
    extra = {"R": R, "Q": Q, "q_positive_definite": bool(np.all(np.linalg.eigvalsh(Q) > 0))}
    return SVOResult(y / y.sum(), None, None, W, "rdvg", 0, 0, alpha, extra)


def equal(X: Any, *, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0,
          names: Sequence[str] | None = None) -> SVOResult:
    """Equal-weight virtual gyroscope ``c = 1/p`` (the benchmark)."""
    _, W = _wccv_of(X, levels, alpha, freq, names)
    p = W.n_signals
    return SVOResult(np.full(p, 1.0 / p), None, None, W, "equal", 0, 0, alpha)

