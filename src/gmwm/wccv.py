"""Haar wavelet cross-covariance (WCCV) of ``p`` signals of one axis ([SVO]).

``X_t`` holds the signals as columns of a ``(T, p)`` array. ``A_j`` is the Haar WCCV matrix at
level ``j`` (``A_j[i, k] = E[W_{i,j,t} W_{k,j,t}]``, lag 0), with the conventions of
:mod:`gmwm.wv`: scale = filter length ``2**j`` samples, ``M_j = T - 2**j + 1`` boundary-free
coefficients, mean squares, never demeaned. :func:`wccv` computes every level in one fused pass
(the Numba kernels of :mod:`gmwm._svokernels`, loaded on first use);
:class:`WaveletCrossCovariance` holds the result, its CIs and the WV of any combination
``c'X`` (:meth:`WaveletCrossCovariance.combine`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ndtri  # the normal quantile (scipy.stats costs ~0.5 s to import)

from gmwm.errors import InputError
from gmwm.wv import (
    WaveletVariance,
    as_signal,
    check_alpha_freq,
    chi2_ci,
    default_layout,
    n_levels_for,
)

__all__ = ["WaveletCrossCovariance", "wccv"]


def _wccv_raw(x: np.ndarray, J: int) -> np.ndarray:
    """Packed sums ``(J, p(p+1)/2)`` of ``4 W_i W_k`` over the boundary-free coefficients."""
    from gmwm._svokernels import wccv_sums  # Numba: loaded on first use

    T, p = x.shape
    n_block, blen, panel = default_layout(T, J)
    n_block = min(n_block, J)
    halo = (1 << n_block) - 1
    blen = min(T, blen)
    buf_a = np.empty((blen + halo, p))
    buf_b = np.empty((blen + halo, p))
    if J > n_block:
        n_out = T - halo
        rows = -(-n_out // (halo + 1))
        v_l = np.empty((n_out, p))
        pan_a = np.empty((rows * panel, p))
        pan_b = np.empty((rows * panel, p))
    else:
        v_l = pan_a = pan_b = np.empty((0, p))
    sums = np.zeros((J, p * (p + 1) // 2))
    dbuf = np.empty((p, max(buf_a.shape[0], pan_a.shape[0])))
    wccv_sums(x, J, n_block, sums, buf_a, buf_b, v_l, pan_a, pan_b, dbuf)
    return sums


# --------------------------------------------------------------------------------------------------
# validation helpers


def as_array(X: Any, name: str = "X") -> np.ndarray:
    """``X`` as a C-contiguous float64 ``(T, p)`` array with ``p >= 2`` finite columns."""
    arr = as_signal(X, name, ndim=2, layout="2-D (T samples, p signals)")
    if arr.shape[1] < 2:
        raise InputError(f"{name} has {arr.shape[1]} signal column(s); at least 2 are needed")
    if arr.shape[1] > arr.shape[0]:
        raise InputError(f"{name} has shape {arr.shape}: more signals than samples "
                         "(pass one signal per column)")
    if np.isfinite(arr.sum()):  # exact: a NaN or an infinity makes the sum non-finite
        return arr
    bad = ~np.isfinite(arr)       # (or the finite values overflowed: look element by element)
    if bad.any():
        t, i = np.argwhere(bad)[0]
        raise InputError(f"{name} contains {int(bad.sum())} NaN/infinite values "
                         f"(first at sample {t}, column {i})")
    return arr


def _names(names: Sequence[str] | None, p: int) -> tuple[str, ...]:
    if names is None:
        return tuple(f"x{i + 1}" for i in range(p))
    out = tuple(str(n) for n in names)
    if len(out) != p:
        raise InputError(f"names has {len(out)} entries for {p} signals")
    return out


def unpack(packed: np.ndarray, p: int) -> np.ndarray:
    """``(..., p(p+1)/2)`` packed upper triangles -> symmetric ``(..., p, p)``."""
    iu = np.triu_indices(p)
    out = np.zeros(packed.shape[:-1] + (p, p))
    out[..., iu[0], iu[1]] = packed
    out[..., iu[1], iu[0]] = packed
    return out


# --------------------------------------------------------------------------------------------------
# wavelet cross-covariance


@dataclass(frozen=True, eq=False)
class WaveletCrossCovariance:
    """Haar WCCV of ``p`` signals per level: ``cov[j-1]`` is the ``p x p`` matrix ``A_j`` in
    (signal unit)**2, ``scales`` filter lengths in samples, ``n`` the ``M_j`` coefficients.

    CIs: the diagonal (each signal's WV) uses the eta_3 chi-square interval of :func:`gmwm.wvar`;
    off-diagonal entries a Gaussian interval with variance ``(A_ii A_kk + A_ik^2) / eta_j`` (the
    analogue of ``2 nu^2 / eta_j``, conservative like eta_3)."""

    levels: np.ndarray
    scales: np.ndarray
    cov: np.ndarray
    n: np.ndarray
    n_samples: int
    names: tuple[str, ...]
    freq: float = 1.0
    alpha: float = 0.05

    def __post_init__(self) -> None:
        for name, dtype in (("levels", np.int64), ("scales", np.float64), ("cov", np.float64),
                            ("n", np.int64)):
            arr = np.array(getattr(self, name), dtype=dtype, copy=True)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "names", tuple(self.names))

    @property
    def n_levels(self) -> int:
        return int(self.levels.size)

    @property
    def n_signals(self) -> int:
        return int(self.cov.shape[1])

    @property
    def edof(self) -> np.ndarray:
        """``eta_j = max(M_j / 2**j, 1)``."""
        return np.maximum(self.n / self.scales, 1.0)

    @property
    def correlation(self) -> np.ndarray:
        """Wavelet correlation ``A_ik / sqrt(A_ii A_kk)`` per level, ``(J, p, p)``."""
        d = np.sqrt(np.einsum("jii->ji", self.cov))
        return self.cov / (d[:, :, None] * d[:, None, :])

    def conf_int(self, alpha: float | None = None) -> np.ndarray:
        """CIs at level ``1 - alpha`` (None: ``self.alpha``), ``(J, p, p, 2)``: ``[..., 0]`` the
        lower, ``[..., 1]`` the upper bounds (the last axis as in every ``conf_int`` of the
        library)."""
        alpha = self.alpha if alpha is None else float(alpha)
        check_alpha_freq(alpha, self.freq)
        eta = self.edof[:, None, None]
        var = np.einsum("jii->ji", self.cov)
        sd = np.sqrt((var[:, :, None] * var[:, None, :] + self.cov**2) / eta)
        z = ndtri(1.0 - alpha / 2.0)
        low, high = self.cov - z * sd, self.cov + z * sd
        dlow, dhigh = chi2_ci(var, np.broadcast_to(self.edof[:, None], var.shape), alpha)
        idx = np.arange(self.n_signals)
        low[:, idx, idx] = dlow
        high[:, idx, idx] = dhigh
        return np.stack([low, high], axis=-1)

    def variance(self, i: int | str) -> WaveletVariance:
        """WV of signal ``i`` (index or name), identical to :func:`gmwm.wvar` of that column."""
        k = self.names.index(i) if isinstance(i, str) else int(i)
        return self.combine(np.eye(self.n_signals)[k])

    def combine(self, c: Any, alpha: float | None = None, ci: str = "mixture") -> WaveletVariance:
        """WV of the virtual signal ``c'X``: ``nu_j = c' A_j c`` (the WV of the combined
        coefficients, so equal to ``wvar(X @ c)`` up to rounding), with the intervals of
        :func:`gmwm.wvar` of that signal (``ci`` as there)."""
        from gmwm.wv import wv_ci

        c = np.asarray(c, dtype=np.float64).reshape(-1)
        if c.size != self.n_signals or not np.all(np.isfinite(c)):
            raise InputError(f"coefficients must be {self.n_signals} finite numbers")
        alpha = self.alpha if alpha is None else float(alpha)
        nu = np.einsum("i,jik,k->j", c, self.cov, c)
        if np.any(nu <= 0):
            raise InputError("the virtual signal has a zero wavelet variance at some level")
        edof, low, high = wv_ci(ci, nu, self.scales, self.n, self.n_samples, alpha)
        return WaveletVariance(self.levels, self.scales, nu, low, high, self.n, self.n_samples,
                               self.freq, alpha, ci_kind=ci, ci_edof=edof)

    def subset(self, levels: int) -> WaveletCrossCovariance:
        """Keep levels ``1..levels``."""
        if not 1 <= int(levels) <= self.n_levels:
            raise InputError(f"subset needs 1 <= levels <= {self.n_levels}, got {levels}")
        k = int(levels)
        return WaveletCrossCovariance(self.levels[:k], self.scales[:k], self.cov[:k], self.n[:k],
                                      self.n_samples, self.names, self.freq, self.alpha)


def wccv(X: Any, levels: int | None = None, alpha: float = 0.05, freq: float = 1.0,
         names: Sequence[str] | None = None) -> WaveletCrossCovariance:
    """Haar wavelet cross-covariance of the columns of ``X`` ``(T, p)`` at levels ``1..J`` (default
    ``J = floor(log2 T) - 1``) in one fused pass; each column's first sample is subtracted first
    (the filter annihilates constants), so large offsets cost no digits. ``freq`` in Hz."""
    arr = as_array(X)
    T, p = arr.shape
    J = n_levels_for(T, levels)
    check_alpha_freq(alpha, freq)
    sums = _wccv_raw(arr, J)
    if not np.all(np.isfinite(sums)):
        raise InputError("X is too large in magnitude: products of differences overflow float64")
    lev = np.arange(1, J + 1)
    n = T - (1 << lev) + 1
    cov = unpack(0.25 * sums / n[:, None], p)
    return WaveletCrossCovariance(lev, 2.0**lev, cov, n, T, _names(names, p), freq, alpha)
