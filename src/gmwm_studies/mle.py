"""Kalman-filter maximum-likelihood baseline for Simulation 1 of the vibration-noise paper (docs/METHODS.md §12.1).

Model (per-sample, discrete time): ``x_t = mu_t + c_t + e_t + b_1 cos(beta t) + b_2 sin(beta t)`` with
``mu_t`` a random walk (increment variance ``gamma2``, diffuse start), ``c_t`` an AR(1)
(``c_t = phi c_{t-1} + w_t``, ``Var w_t = sigma2_AR`` = innovation variance, stationary start) and
``e_t`` white noise (``sigma2``). The sinusoid is deterministic with known frequency ``beta`` (rad/sample);
its amplitude is ``alpha = hypot(b_1, b_2)``.

Two evaluations of the same exact Gaussian likelihood (exact diffuse initialisation of the level,
statsmodels' convention: the diffuse first observation contributes ``-0.5 log 2 pi``):

* ``backend="kalman"`` (default): a two-state Kalman filter written for this model in Numba. The
  cos/sin regressors are filtered alongside the data (the filter is linear and its gains do not
  depend on the data), so their coefficients are concentrated out by GLS, and so is the common
  scale of the three variances (the likelihood is maximised over the ratios ``gamma2/sigma2``,
  ``sigma2_AR/sigma2`` and ``phi`` only). Once the filter covariance has converged the steady-state
  gain is reused (cost per evaluation: ``benchmarks/bench_mle.py``).
* ``backend="statsmodels"``: statsmodels' ``UnobservedComponents(level="llevel", autoregressive=1)``
  filter on the de-sinusoided data, all six parameters free (the reference the Kalman backend is
  tested against).

The optimiser is scipy's BFGS in a parametrisation whitened by the Whittle (spectral) Fisher
information, so that one unit is about one standard error in every direction; this makes the
convergence tolerance meaningful for parameters as different as ``gamma2 ~ 1e-4`` and ``phi ~ 0.98``.
With ``se=True`` the standard errors come from the observed information: a central-difference
Hessian of the exact log-likelihood (sinusoid coefficients concentrated out) at the estimate.

:func:`fit_statsmodels` is the general-purpose baseline: statsmodels' own estimator
(``UnobservedComponents(...).fit()``, its L-BFGS, its start values and iteration cap) on the same
model, the sinusoid as two known-frequency regressors, standard errors by statsmodels' default
(outer product of gradients).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING, Any

import numpy as np
from numba import njit
from scipy.optimize import minimize, nnls

if TYPE_CHECKING:
    from statsmodels.tsa.statespace.structural import UnobservedComponents

from gmwm.atomic import to_jsonable
from gmwm.errors import InputError, ModelError

__all__ = ["BACKENDS", "PARAM_KEYS", "PARAM_NAMES", "MLEResult", "fit_mle", "fit_statsmodels",
           "kalman_loglike", "mle_covariance"]

PARAM_KEYS = ("WN[1].sigma2", "RW[1].gamma2", "AR1[1].phi", "AR1[1].sigma2")
#: Order of ``MLEResult.params``: the estimated parameters, then the sinusoid amplitude.
PARAM_NAMES = (*PARAM_KEYS, "SIN[1].alpha")
_SM_NAMES = {  # statsmodels name -> our name (sigma2.ar is the AR innovation variance, see tests)
    "sigma2.irregular": "WN[1].sigma2",
    "sigma2.level": "RW[1].gamma2",
    "sigma2.ar": "AR1[1].sigma2",
    "ar.L1": "AR1[1].phi",
}
_MIN_SAMPLES = 64
_PHI_BOUND = 0.9999  # |phi| at or beyond this counts as a boundary solution
_VAR_REL_FLOOR = 1e-12  # variances are kept above this times Var(diff x) ...
_VAR_REL_BOUND = 1e-6  # ... and flagged as on the boundary below this times Var(diff x)
_GTOL = 1e-3  # gradient tolerance in standard-error units (log-likelihood scale)
_FD_STEP = 1e-3  # forward-difference step in standard-error units
_LL_TIE = 1e-3  # log-likelihood differences below this count as the same optimum
_STEADY_TOL = 1e-15  # relative distance of the filter covariance from its limit when the gain is frozen
_RATIO_BOUND = 30.0  # |log variance ratio| cap of the concentrated parametrisation
BACKENDS = ("kalman", "statsmodels")
_LOG2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True, eq=False)
class MLEResult:
    """Outcome of :func:`fit_mle`.

    ``params`` (read-only, in the order of ``param_names`` = :data:`PARAM_NAMES`) holds
    ``WN[1].sigma2``, ``RW[1].gamma2``, ``AR1[1].phi``, ``AR1[1].sigma2`` (innovation variance),
    all per sample, plus ``SIN[1].alpha`` (amplitude, for information); :meth:`as_dict` maps them
    by name. ``loglike`` is the exact Gaussian log-likelihood (statsmodels' exact-diffuse
    convention). ``start`` names the winning start: ``'gmwm'`` (the supplied start),
    ``'variogram'`` (data-driven), ``'grid-k'``, ``'default'`` (statsmodels' own start values).
    ``seconds`` is the wall time of the point estimate [s]; ``cov`` (``(5, 5)``, same order) the
    covariance of the estimates when they were asked for (``se=True``; NaN for the amplitude and
    wherever the Hessian was not negative definite), else all NaN, and ``seconds_se`` the extra
    wall time it took [s] (0 when not computed); ``cpu_seconds`` and ``cpu_seconds_se`` the same
    in process CPU time (robust to other load on the machine). Result protocol of the library: ``params``,
    ``param_names``, ``se``, ``conf_int``, ``summary``, ``to_json_dict``.
    """

    params: np.ndarray
    converged: bool
    loglike: float
    start: str
    n_starts: int
    seconds: float
    message: str
    cov: np.ndarray | None = None
    seconds_se: float = 0.0
    cpu_seconds: float = float("nan")
    cpu_seconds_se: float = 0.0

    def __post_init__(self) -> None:
        params = np.array(self.params, dtype=np.float64, copy=True)
        k = len(PARAM_NAMES)
        if params.shape != (k,):
            raise InputError(f"MLEResult needs {k} parameters "
                             f"({', '.join(PARAM_NAMES)}), got shape {params.shape}")
        cov = np.full((k, k), np.nan) if self.cov is None else np.array(self.cov, dtype=np.float64)
        if cov.shape != (k, k):
            raise InputError(f"MLEResult covariance must be ({k}, {k}), got {cov.shape}")
        for a in (params, cov):
            a.setflags(write=False)
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "cov", cov)

    @property
    def param_names(self) -> list[str]:
        return list(PARAM_NAMES)

    @property
    def se(self) -> np.ndarray:
        """Standard errors (NaN unless computed: ``fit_mle(..., se=True)``)."""
        d = np.diag(self.cov)
        return np.where(d >= 0, np.sqrt(np.abs(d)), np.nan)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """``(p, 2)`` Wald intervals ``estimate -+ z se`` (NaN where there is no SE); ``phi`` is
        clipped to (-1, 1) and the variances at 0, so no interval leaves the parameter space."""
        if not 0.0 < float(alpha) < 1.0:
            raise InputError(f"alpha must be in (0, 1), got {alpha}")
        from scipy.stats import norm

        half = norm.ppf(1.0 - alpha / 2.0) * self.se
        ci = np.column_stack([self.params - half, self.params + half])
        lo = np.array([0.0, 0.0, -1.0, 0.0, 0.0])
        hi = np.array([np.inf, np.inf, 1.0, np.inf, np.inf])
        return np.clip(ci, lo[:, None], hi[:, None])

    def as_dict(self) -> dict[str, float]:
        return dict(zip(PARAM_NAMES, self.params.tolist(), strict=True))

    def summary(self) -> str:
        """Plain-text table of the estimates with the optimiser's verdict."""
        what = ("statsmodels UnobservedComponents MLE" if self.start == "statsmodels"
                else "Kalman-filter MLE")
        lines = [(f"{what} (WN+RW+AR1+SIN, {self.n_starts} start(s)): "
                  f"log-likelihood = {self.loglike:.6f}, converged = {self.converged}"),
                 f"  {self.message}",
                 f"{'parameter':<16}{'estimate':>14}{'SE':>14}",
                 "-" * 44]
        lines += [f"{n:<16}{v:>14.6g}{s:>14.4g}"
                  for n, v, s in zip(PARAM_NAMES, self.params, self.se, strict=True)]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """Strict-JSON-able dict (non-finite numbers as None)."""
        return to_jsonable({
            "params": self.as_dict(), "se": dict(zip(PARAM_NAMES, self.se, strict=True)),
            "converged": self.converged, "loglike": self.loglike, "start": self.start,
            "n_starts": self.n_starts, "seconds": self.seconds, "seconds_se": self.seconds_se,
            "cpu_seconds": self.cpu_seconds, "cpu_seconds_se": self.cpu_seconds_se,
            "message": self.message})


# ----------------------------------------------------------------------------------------------
# input, regressors, parametrisation


def _check_input(x: np.ndarray, beta: float) -> np.ndarray:
    x = np.asarray(x, dtype=float)
    if x.ndim != 1:
        raise InputError(f"signal must be 1-D, got shape {x.shape}")
    if x.size < _MIN_SAMPLES:
        raise InputError(f"signal too short for the MLE: {x.size} samples (need >= {_MIN_SAMPLES})")
    if not np.all(np.isfinite(x)):
        raise InputError("signal contains NaN or inf")
    if not (np.isfinite(beta) and 0.0 < beta <= np.pi):
        raise InputError(f"sinusoid frequency beta must be in (0, pi] rad/sample, got {beta}")
    if np.var(np.diff(x)) <= 0.0:
        raise InputError("signal is constant or linear: no noise to estimate")
    return x


def _regressors(n: int, beta: float) -> np.ndarray:
    """(n, 2) matrix ``[cos(beta t), sin(beta t)]``, ``t = 0..n-1``."""
    t = np.arange(n) * beta
    return np.column_stack([np.cos(t), np.sin(t)])


@lru_cache(maxsize=4)
def _shared_regressors(n: int, beta: float) -> np.ndarray:
    """:func:`_regressors`, read-only and kept for the next fit of the same length and frequency
    (every variant, start and standard error of a study's replicate uses the same matrix)."""
    X = _regressors(n, beta)
    X.setflags(write=False)
    return X


class _Prepared:
    """What every fit of one signal shares: ``Y = [x, cos, sin]`` for the filter and the
    first-difference sinusoid coefficients ``b0``. :func:`_prepared` keeps the last one, so the
    variants and standard errors of one replicate build them once (same values, same bits)."""

    def __init__(self, x: np.ndarray, beta: float):
        self.x = x.copy()
        self.x.setflags(write=False)
        self.beta = beta
        self.X = _shared_regressors(x.size, beta)
        self.Y = np.ascontiguousarray(np.column_stack([x, self.X]))
        self.Y.setflags(write=False)
        self.b0 = _sin_ols(x, self.X)
        self.b0.setflags(write=False)


_LAST_PREPARED: list[_Prepared] = []


def _prepared(x: np.ndarray, beta: float) -> _Prepared:
    """The shared pieces of signal ``x`` (compared by value: a changed array is rebuilt)."""
    cached = _LAST_PREPARED[:1]  # a copy: another thread may replace the entry meanwhile
    if cached:
        last = cached[0]
        if last.beta == beta and last.x.shape == x.shape and np.array_equal(last.x, x):
            return last
    prep = _Prepared(x, beta)
    _LAST_PREPARED[:] = [prep]
    return prep


def _sin_ols(x: np.ndarray, X: np.ndarray) -> np.ndarray:
    """Sinusoid coefficients by least squares on first differences (removes level and RW)."""
    b, *_ = np.linalg.lstsq(np.diff(X, axis=0), np.diff(x), rcond=None)
    return b


def _to_eta(theta: dict[str, float], b: np.ndarray) -> np.ndarray:
    """Free parameters: log variances, atanh(phi), sinusoid coefficients."""
    return np.array([
        np.log(theta["WN[1].sigma2"]),
        np.log(theta["RW[1].gamma2"]),
        np.log(theta["AR1[1].sigma2"]),
        np.arctanh(theta["AR1[1].phi"]),
        b[0],
        b[1],
    ])


def _from_eta(eta: np.ndarray) -> tuple[dict[str, float], np.ndarray]:
    """Inverse of :func:`_to_eta`: (parameter dict, sinusoid coefficients ``[b_cos, b_sin]``)."""
    theta = {
        "WN[1].sigma2": float(np.exp(eta[0])),
        "RW[1].gamma2": float(np.exp(eta[1])),
        "AR1[1].sigma2": float(np.exp(eta[2])),
        "AR1[1].phi": float(np.tanh(eta[3])),
    }
    return theta, np.asarray(eta[4:6], dtype=float)


def _clean_theta(theta: dict[str, float], scale: float) -> dict[str, float]:
    """Move a start strictly inside the domain (a GMWM estimate may sit on a boundary)."""
    floor = 1e-5 * scale
    out = {k: float(theta[k]) for k in PARAM_KEYS}
    for k in ("WN[1].sigma2", "RW[1].gamma2", "AR1[1].sigma2"):
        if not np.isfinite(out[k]) or out[k] < floor:
            out[k] = floor
    phi = out["AR1[1].phi"]
    out["AR1[1].phi"] = float(np.clip(phi if np.isfinite(phi) else 0.5, -0.99, 0.9995))
    return out


# ----------------------------------------------------------------------------------------------
# starting values


def _variogram_fit(lags: np.ndarray, vhat: np.ndarray, phi: float) -> tuple[dict[str, float], float]:
    """Linear part of ``E(y_{t+L}-y_t)^2 = 2 s2 + L g2 + 2 s2_ar (1-phi^L)/(1-phi^2)`` by NNLS, phi fixed.

    Rows are weighted by ``1/vhat`` (relative misfit). Returns the start and the weighted residual norm.
    """
    A = np.column_stack([np.full(lags.size, 2.0), lags, 2.0 * (1.0 - phi**lags) / (1.0 - phi**2)])
    w = 1.0 / vhat
    coef, resid = nnls(A * w[:, None], vhat * w)
    theta = {"WN[1].sigma2": coef[0], "RW[1].gamma2": coef[1], "AR1[1].sigma2": coef[2],
             "AR1[1].phi": phi}
    return theta, float(resid)


def _variogram_starts(y: np.ndarray, n_grid: int = 4) -> list[tuple[str, dict[str, float]]]:
    """Data-driven starts from the empirical variogram of the de-sinusoided signal.

    The best phi on a grid gives ``'variogram'``; the next local minima (or spread grid values)
    give ``'grid-k'``.
    """
    n = y.size
    lags = np.unique(np.round(np.geomspace(1, max(2, n // 10), 30)).astype(int))
    vhat = np.array([np.mean((y[L:] - y[:-L]) ** 2) for L in lags])
    vhat = np.maximum(vhat, 1e-300)
    grid = 1.0 - np.geomspace(1e-4, 0.95, 60)
    fits = [_variogram_fit(lags, vhat, phi) for phi in grid]
    res = np.array([f[1] for f in fits])
    is_min = np.r_[True, res[1:] <= res[:-1]] & np.r_[res[:-1] <= res[1:], True]
    # local minima first, then the rest, keeping only phi values well apart in log(1 - phi)
    order: list[int] = []
    for i in sorted(range(grid.size), key=lambda i: (not is_min[i], res[i])):
        if all(abs(np.log1p(-grid[i]) - np.log1p(-grid[j])) > 1.0 for j in order):
            order.append(i)
    out = [("variogram", fits[order[0]][0])]
    out += [(f"grid-{k}", fits[i][0]) for k, i in enumerate(order[1:n_grid + 1], start=1)]
    return out


# ----------------------------------------------------------------------------------------------
# likelihood and its scaling


class _Likelihood:
    """Exact log-likelihood of ``x`` given ``eta`` (see :func:`_to_eta`), via statsmodels."""

    def __init__(self, x: np.ndarray, X: np.ndarray):
        self.x, self.X = x, X
        self.order = [_SM_NAMES[name] for name in self._model(x).param_names]

    @staticmethod
    def _model(y: np.ndarray) -> UnobservedComponents:
        try:
            from statsmodels.tsa.statespace.structural import UnobservedComponents
        except ImportError:  # an optional dependency (extra "pipeline")
            raise InputError("the MLE's statsmodels backend and its 'default' start need "
                             "statsmodels: pip install 'gmwm[pipeline]'") from None

        # A fresh model per data vector: statsmodels caches its copy of the data, so re-binding new
        # data to an existing model is silently ignored by the filter (construction costs < 1 ms).
        model = UnobservedComponents(y, level="llevel", autoregressive=1, use_exact_diffuse=True)
        # both are exact for a univariate observation; they only skip work
        model.ssm.set_filter_method(filter_univariate=True)
        model.ssm.set_stability_method(0)
        return model

    def __call__(self, eta: np.ndarray) -> float:
        theta, b = _from_eta(eta)
        model = self._model(self.x - self.X @ b)
        return float(model.loglike(np.array([theta[k] for k in self.order])))

    def default_start(self, b0: np.ndarray | None = None) -> dict[str, float]:
        """statsmodels' own start values (known to lead to a wrong optimum, docs/METHODS.md §12.1)
        on the data less the first-difference sinusoid fit ``b0`` (computed when not given)."""
        b0 = _sin_ols(self.x, self.X) if b0 is None else b0
        model = self._model(self.x - self.X @ b0)
        return dict(zip(self.order, (float(v) for v in model.start_params), strict=True))


# ----------------------------------------------------------------------------------------------
# specialised Kalman filter (Numba)


@njit(cache=True, inline="always")
def _riccati_step(p11: float, p12: float, p22: float, prev: float, s2: float, g2: float,
                  s2ar: float, phi: float) -> tuple[float, float, float, float, float, float,
                                                    float, float, bool]:  # pragma: no cover
    """One step of the filter's covariance recursion (shared by every column): innovation
    variance f, gains k1, k2, log f, the next predicted covariance (p11, p12, p22), the step size
    and whether the recursion has reached its steady state."""
    m1, m2 = p11 + p12, p12 + p22
    f = m1 + m2 + s2
    k1, k2 = m1 / f, m2 / f
    log_f = np.log(f)
    n11 = p11 - m1 * k1 + g2
    n12 = phi * (p12 - m1 * k2)
    n22 = phi * phi * (p22 - m2 * k2) + s2ar
    # the Riccati recursion converges geometrically, at a rate close to 1 when the RW is small:
    # the distance from the limit is the step over (1 - rate), not the step
    step = abs(n11 - p11) + abs(n12 - p12) + abs(n22 - p22)
    size = abs(n11) + abs(n22)
    if step == 0.0:
        steady = True
    elif step > _STEADY_TOL * size:
        # then also step > _STEADY_TOL * (1 - rate) * size (0 <= 1 - rate <= 1 and rounding is
        # monotone): the same verdict without the division, which costs while far from the limit
        steady = False
    else:
        rate = step / prev if prev > 0.0 else 0.0
        steady = rate < 1.0 and step <= _STEADY_TOL * (1.0 - rate) * size
    return f, k1, k2, log_f, n11, n12, n22, step, steady


@njit(cache=True)
def _kf_cross(Y: np.ndarray, s2: float, g2: float, s2ar: float, phi: float
              ) -> tuple[np.ndarray, float]:  # pragma: no cover (compiled)
    """Filter every column of ``Y`` (n, k) through the WN + RW + AR1 state space model.

    State ``(mu_t, c_t)``, observation ``mu_t + c_t + e_t``. The diffuse level is conditioned on
    the first observation exactly (its posterior mean is ``Y[0]``), so rows ``1..n-1`` give proper
    innovations ``v_t`` with variance ``F_t``. Returns ``(sum_t v_t v_t^T / F_t, sum_t log F_t)``.
    """
    n, k = Y.shape
    if k == 3:
        return _kf_cross3(Y, s2, g2, s2ar, phi)
    pc = s2ar / (1.0 - phi * phi)  # stationary AR1 variance
    # covariance of (mu_2, c_2) predicted from the first observation
    p11, p12, p22 = pc + s2 + g2, -phi * pc, pc
    amu = Y[0].copy()
    ac = np.zeros(k)
    v = np.zeros(k)
    S = np.zeros((k, k))
    sum_log_f = 0.0
    steady = False
    f = k1 = k2 = log_f = 0.0
    prev = np.inf
    for t in range(1, n):
        if not steady:
            f, k1, k2, log_f, p11, p12, p22, prev, steady = _riccati_step(
                p11, p12, p22, prev, s2, g2, s2ar, phi)
        sum_log_f += log_f
        for i in range(k):
            v[i] = Y[t, i] - amu[i] - ac[i]
        for i in range(k):
            vi = v[i] / f
            for j in range(i, k):
                S[i, j] += vi * v[j]
            amu[i] += k1 * v[i]
            ac[i] = phi * (ac[i] + k2 * v[i])
    for i in range(k):
        for j in range(i):
            S[i, j] = S[j, i]
    return S, sum_log_f


@njit(cache=True)
def _kf_cross3(Y: np.ndarray, s2: float, g2: float, s2ar: float, phi: float
               ) -> tuple[np.ndarray, float]:  # pragma: no cover (compiled)
    """:func:`_kf_cross` for the three columns the MLE filters (data, cos, sin), with the filter
    state in scalars: the same operations in the same order (bit-identical), but LLVM keeps the
    state in registers instead of re-loading arrays it cannot prove unaliased (about 2.5x faster
    per evaluation at T = 8e4, the MLE's whole cost)."""
    n = Y.shape[0]
    pc = s2ar / (1.0 - phi * phi)
    p11, p12, p22 = pc + s2 + g2, -phi * pc, pc
    amu0, amu1, amu2 = Y[0, 0], Y[0, 1], Y[0, 2]
    ac0 = ac1 = ac2 = 0.0
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    sum_log_f = 0.0
    steady = False
    f = k1 = k2 = log_f = 0.0
    prev = np.inf
    for t in range(1, n):
        if not steady:
            f, k1, k2, log_f, p11, p12, p22, prev, steady = _riccati_step(
                p11, p12, p22, prev, s2, g2, s2ar, phi)
        sum_log_f += log_f
        v0 = Y[t, 0] - amu0 - ac0
        v1 = Y[t, 1] - amu1 - ac1
        v2 = Y[t, 2] - amu2 - ac2
        w0 = v0 / f
        s00 += w0 * v0
        s01 += w0 * v1
        s02 += w0 * v2
        amu0 += k1 * v0
        ac0 = phi * (ac0 + k2 * v0)
        w1 = v1 / f
        s11 += w1 * v1
        s12 += w1 * v2
        amu1 += k1 * v1
        ac1 = phi * (ac1 + k2 * v1)
        w2 = v2 / f
        s22 += w2 * v2
        amu2 += k1 * v2
        ac2 = phi * (ac2 + k2 * v2)
    S = np.empty((3, 3))
    S[0, 0], S[1, 1], S[2, 2] = s00, s11, s22
    S[0, 1] = S[1, 0] = s01
    S[0, 2] = S[2, 0] = s02
    S[1, 2] = S[2, 1] = s12
    return S, sum_log_f


def kalman_loglike(x: np.ndarray, beta: float, theta: dict[str, float], b: np.ndarray) -> float:
    """Exact log-likelihood of ``x`` at ``theta`` (keys of ``PARAM_KEYS``) and sinusoid coefficients
    ``b = [b_cos, b_sin]``, by the specialised filter (statsmodels' exact diffuse convention)."""
    x = _check_input(x, beta)
    Y = np.column_stack([x, _regressors(x.size, beta)])
    S, sum_log_f = _kf_cross(Y, theta["WN[1].sigma2"], theta["RW[1].gamma2"],
                             theta["AR1[1].sigma2"], theta["AR1[1].phi"])
    c = np.r_[1.0, -np.asarray(b, dtype=float)]
    n = x.size
    return float(-0.5 * (n * _LOG2PI + sum_log_f + c @ S @ c))


class _Profile:
    """Log-likelihood concentrated over the sinusoid coefficients and the variance scale.

    Coordinates ``r = (log(gamma2/sigma2), log(sigma2_AR/sigma2), atanh(phi))``; filtering with
    ``sigma2 = 1`` gives ``S`` and ``sum log F``, then GLS gives ``b`` and ``sigma2 = RSS/(n-1)``.
    The last few evaluations are remembered by the exact bits of ``r``: the optimiser, its
    convergence check, its polish and the final parameters all ask again for the point reached.
    """

    _MEMO = 8  # evaluations remembered

    def __init__(self, x: np.ndarray, X: np.ndarray, Y: np.ndarray | None = None):
        self.Y = np.ascontiguousarray(np.column_stack([x, X])) if Y is None else Y
        self.n = x.size
        self._memo: dict[bytes, tuple[float, dict[str, float], np.ndarray]] = {}

    def solve(self, r: np.ndarray) -> tuple[float, dict[str, float], np.ndarray]:
        """(concentrated log-likelihood, full parameters, sinusoid coefficients) at ``r``."""
        key = np.asarray(r, dtype=np.float64).tobytes()
        hit = self._memo.get(key)
        if hit is None:
            hit = self._solve(r)
            if len(self._memo) >= self._MEMO:
                del self._memo[next(iter(self._memo))]
            self._memo[key] = hit
        ll, theta, b = hit
        return ll, dict(theta), b.copy()

    def _solve(self, r: np.ndarray) -> tuple[float, dict[str, float], np.ndarray]:
        g, a, phi = float(np.exp(r[0])), float(np.exp(r[1])), float(np.tanh(r[2]))
        S, sum_log_f = _kf_cross(self.Y, 1.0, g, a, phi)
        Sxx, Sxy = S[1:, 1:], S[1:, 0]
        try:
            b = np.linalg.solve(Sxx, Sxy)
        except np.linalg.LinAlgError:
            return -np.inf, {}, np.zeros(2)
        rss = float(S[0, 0] - Sxy @ b)
        m = self.n - 1
        if not (np.isfinite(rss) and rss > 0.0 and np.isfinite(sum_log_f)):
            return -np.inf, {}, b
        s2 = rss / m
        ll = -0.5 * (self.n * _LOG2PI + m * (1.0 + np.log(s2)) + sum_log_f)
        theta = {"WN[1].sigma2": s2, "RW[1].gamma2": g * s2, "AR1[1].sigma2": a * s2,
                 "AR1[1].phi": phi}
        return float(ll), theta, b

    def __call__(self, r: np.ndarray) -> float:
        return self.solve(r)[0]


def _to_r(theta: dict[str, float]) -> np.ndarray:
    s2 = theta["WN[1].sigma2"]
    return np.array([np.log(theta["RW[1].gamma2"] / s2), np.log(theta["AR1[1].sigma2"] / s2),
                     np.arctanh(theta["AR1[1].phi"])])


def _profile_info(r: np.ndarray, n: int, beta: float) -> np.ndarray:
    """Whittle information of ``r`` with the scale profiled out (Schur complement)."""
    eta = np.array([0.0, r[0], r[1], r[2], 0.0, 0.0])
    info4 = _whittle_info(eta, n, beta)[:4, :4]
    M = np.eye(4)
    M[1, 0] = M[2, 0] = 1.0  # eta = (u, u + r0, u + r1, r2)
    iu = M.T @ info4 @ M
    return iu[1:, 1:] - np.outer(iu[1:, 0], iu[0, 1:]) / iu[0, 0]


def _whittle_info(eta: np.ndarray, n: int, beta: float) -> np.ndarray:
    """Whittle Fisher information (total, for n samples) of ``eta`` (see :func:`_to_eta`).

    Uses the spectrum of the first differences,
    ``S(w) = s2 g + g2 + s2_ar g / |1 - phi e^{-iw}|^2``, ``g = 2 - 2 cos w``, summed over the Fourier
    frequencies (each contributes ``grad log S grad log S^T``); the sinusoid coefficients get
    ``(n/2) / S_x(beta)`` with ``S_x = S / g`` and no cross terms (mean and covariance parameters
    are orthogonal in a Gaussian model).
    """
    theta, _ = _from_eta(eta)
    s2, g2 = theta["WN[1].sigma2"], theta["RW[1].gamma2"]
    s2ar, phi = theta["AR1[1].sigma2"], theta["AR1[1].phi"]

    def parts(cw: np.ndarray) -> tuple[np.ndarray, ...]:  # cw = cos(w)
        g = 2.0 - 2.0 * cw
        d = 1.0 - 2.0 * phi * cw + phi**2
        ar = s2ar * g / d
        return g, d, ar, s2 * g + g2 + ar

    cw = _fourier_cos(n)
    g, d, ar, S = parts(cw)
    dphi = ar * (2.0 * cw - 2.0 * phi) / d * (1.0 - phi**2)  # d ar / d atanh(phi)
    grad = np.vstack([s2 * g, np.full_like(cw, g2), ar, dphi]) / S
    info = np.zeros((6, 6))
    info[:4, :4] = grad @ grad.T
    gb, _, _, Sb = parts(np.cos(np.array([beta])))
    info[4, 4] = info[5, 5] = 0.5 * n * gb[0] / Sb[0]
    return info


@lru_cache(maxsize=4)
def _fourier_cos(n: int) -> np.ndarray:
    """``cos(w)`` at the Fourier frequencies ``w = 2 pi j / n``, ``j = 1..(n-1)//2`` (read-only;
    the optimiser asks for the Whittle information of the same ``n`` many times)."""
    cw = np.cos(2.0 * np.pi * np.arange(1, (n - 1) // 2 + 1) / n)
    cw.setflags(write=False)
    return cw


def _whitening(info: np.ndarray) -> np.ndarray:
    """``R`` with ``R^T info R ~ I``; directions with less than unit information are left unscaled."""
    lam, U = np.linalg.eigh(0.5 * (info + info.T))
    return U / np.sqrt(np.maximum(lam, 1.0))


# ----------------------------------------------------------------------------------------------
# optimisation


def _eta_box(scale: float) -> tuple[np.ndarray, np.ndarray]:
    ls = np.log(scale)
    lo = np.array([ls + np.log(_VAR_REL_FLOOR)] * 3 + [-np.arctanh(0.999999), -np.inf, -np.inf])
    hi = np.array([ls + np.log(1e6)] * 3 + [np.arctanh(0.999999), np.inf, np.inf])
    return lo, hi


def _r_box() -> tuple[np.ndarray, np.ndarray]:
    a = np.arctanh(0.999999)
    return np.array([-_RATIO_BOUND, -_RATIO_BOUND, -a]), np.array([_RATIO_BOUND, _RATIO_BOUND, a])


Info = Callable[[np.ndarray], np.ndarray]


def _bfgs(loglike: Callable[[np.ndarray], float], eta0: np.ndarray, info: Info, box: tuple,
          maxiter: int, n: int) -> tuple[np.ndarray, float, bool, int, str, np.ndarray]:
    """Maximise ``loglike`` from ``eta0`` with BFGS in coordinates whitened by ``info(eta0)``.

    Outside ``box`` the parameters are clamped and a quadratic penalty pulls them back, so the
    filter never sees overflowing values. Returns (eta, loglike, success, iterations, message,
    gradient of the negative log-likelihood with respect to eta at the end point).
    """
    lo, hi = box
    R = _whitening(info(np.clip(eta0, lo, hi)))
    ll0 = loglike(np.clip(eta0, lo, hi))
    if not np.isfinite(ll0):
        return eta0, -np.inf, False, 0, "log-likelihood not finite at the start", np.zeros(eta0.size)

    def f(z: np.ndarray) -> float:
        eta = eta0 + R @ z
        clamped = np.clip(eta, lo, hi)
        ll = loglike(clamped)
        if not np.isfinite(ll):
            return 1e10
        return -(ll - ll0) + 0.5 * float(np.sum((eta - clamped) ** 2)) * n

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        opt = minimize(f, np.zeros(eta0.size), method="BFGS",
                       options={"gtol": _GTOL, "eps": _FD_STEP, "maxiter": maxiter})
    eta = np.clip(eta0 + R @ opt.x, lo, hi)
    grad = np.linalg.solve(R.T, opt.jac)
    return eta, ll0 - float(opt.fun), bool(opt.success), int(opt.nit), str(opt.message), grad


def _maximise(loglike: Callable[[np.ndarray], float], eta0: np.ndarray, info: Info, box: tuple,
              maxiter: int, n: int, at_boundary: Callable[[np.ndarray], str]
              ) -> tuple[np.ndarray, float, bool, str]:
    """BFGS from the start; convergence is then re-checked in coordinates whitened at the optimum
    found (the start's whitening may be poor), polishing with a second BFGS run if the gradient
    there exceeds the tolerance. A boundary solution is not polished: it is reported as not
    converged anyway."""
    eta, ll, ok1, nit1, msg1, grad = _bfgs(loglike, eta0, info, box, maxiter, n)
    if not np.isfinite(ll):
        return eta, ll, False, msg1
    if at_boundary(eta):
        return eta, ll, ok1, f"{nit1} BFGS iterations, no polish at the boundary"
    R = _whitening(info(eta))
    if ok1 and np.max(np.abs(R.T @ grad)) < _GTOL:
        return eta, ll, True, f"{nit1} BFGS iterations; gradient < tol"
    eta, ll, ok2, nit2, msg2, _ = _bfgs(loglike, eta, info, box, maxiter, n)
    return eta, ll, ok2, f"{nit1}+{nit2} BFGS iterations; {msg2 if not ok2 else 'gradient < tol'}"


def _boundary_problem(theta: dict[str, float], scale: float) -> str:
    if not theta:
        return "log-likelihood not finite"
    if abs(theta["AR1[1].phi"]) >= _PHI_BOUND:
        return f"AR1[1].phi on the boundary ({theta['AR1[1].phi']:.6f})"
    for k in ("WN[1].sigma2", "RW[1].gamma2", "AR1[1].sigma2"):
        if theta[k] < _VAR_REL_BOUND * scale:
            return f"{k} on the zero boundary ({theta[k]:.3g})"
    return ""


class _Backend:
    """One backend's likelihood in its own optimiser coordinates (see :data:`BACKENDS`)."""

    def __init__(self, name: str, x: np.ndarray, X: np.ndarray, beta: float, scale: float):
        self.name, self.n, self.beta, self.scale = name, x.size, beta, scale
        prep = _prepared(x, beta)
        self.b0 = prep.b0
        if name == "kalman":
            self.loglike: Callable[[np.ndarray], float] = _Profile(x, X, prep.Y)
            self.box = _r_box()
        else:
            self.loglike = _Likelihood(x, X)
            self.box = _eta_box(scale)

    def info(self, eta: np.ndarray) -> np.ndarray:
        if self.name == "kalman":
            return _profile_info(eta, self.n, self.beta)
        return _whittle_info(eta, self.n, self.beta)

    def coords(self, theta: dict[str, float]) -> np.ndarray:
        theta = _clean_theta(theta, self.scale)
        return _to_r(theta) if self.name == "kalman" else _to_eta(theta, self.b0)

    def params(self, eta: np.ndarray) -> tuple[dict[str, float], np.ndarray]:
        if self.name == "kalman":
            _, theta, b = self.loglike.solve(eta)
            return theta, b
        return _from_eta(eta)

    def default_start(self) -> dict[str, float]:
        ref = self.loglike if self.name == "statsmodels" else None
        if ref is None:
            X = _shared_regressors(self.n, self.beta)
            ref = _Likelihood(self.loglike.Y[:, 0], X)
        return ref.default_start(self.b0)


# ----------------------------------------------------------------------------------------------
# standard errors (observed information)

_HESS_STEP = 0.1  # central-difference step of the Hessian, in (Whittle) standard-error units


def _full_loglike(Y: np.ndarray, v: np.ndarray) -> float:
    """Exact log-likelihood at ``v = (log sigma2, log(gamma2/sigma2), log(sigma2_AR/sigma2),
    atanh phi)`` with the sinusoid coefficients concentrated out (GLS). With the scale ``s``
    factored out of the filter, ``sum log F_t = (n-1) log s + sum log F_t(s=1)`` (the diffuse first
    observation contributes only its constant) and the quadratic form is ``RSS / s``."""
    n = Y.shape[0]
    S, sum_log_f = _kf_cross(Y, 1.0, float(np.exp(v[1])), float(np.exp(v[2])),
                             float(np.tanh(v[3])))
    b = np.linalg.solve(S[1:, 1:], S[1:, 0])
    rss = float(S[0, 0] - S[1:, 0] @ b)
    return float(-0.5 * (n * _LOG2PI + (n - 1) * v[0] + rss * np.exp(-v[0]) + sum_log_f))


def mle_covariance(x: np.ndarray, beta: float, theta: dict[str, float]) -> np.ndarray:
    """Covariance ``(4, 4)`` of the MLE of ``PARAM_KEYS`` at ``theta`` from the observed information.

    The Hessian of the exact log-likelihood (sinusoid coefficients concentrated out, which leaves
    the inverse Hessian of the variance parameters unchanged) is taken by central differences in
    coordinates whitened by the Whittle information (steps of 0.1 standard error; 33 filter
    passes) and mapped to the natural parameters by the delta method. NaN if the Hessian is not
    negative definite (e.g. an estimate on a boundary).
    """
    x = _check_input(x, beta)
    n = x.size
    Y = _prepared(x, beta).Y
    s2 = theta["WN[1].sigma2"]
    g2, s2ar, phi = theta["RW[1].gamma2"], theta["AR1[1].sigma2"], theta["AR1[1].phi"]
    if not (min(s2, g2, s2ar) > 0 and abs(phi) < 1):
        return np.full((4, 4), np.nan)
    v0 = np.array([np.log(s2), np.log(g2 / s2), np.log(s2ar / s2), np.arctanh(phi)])
    M = np.eye(4)
    M[1, 0] = M[2, 0] = 1.0  # (log s2, log g2, log s2ar, atanh phi) = M v
    info4 = _whittle_info(np.r_[M @ v0, 0.0, 0.0], n, beta)[:4, :4]
    R = _whitening(M.T @ info4 @ M)
    h = _HESS_STEP

    def f(z: np.ndarray) -> float:
        return _full_loglike(Y, v0 + R @ z)

    f0 = f(np.zeros(4))
    E = np.eye(4) * h
    H = np.empty((4, 4))
    for i in range(4):
        H[i, i] = (f(E[i]) - 2.0 * f0 + f(-E[i])) / h**2
        for k in range(i):
            H[i, k] = H[k, i] = (f(E[i] + E[k]) - f(E[i] - E[k]) - f(E[k] - E[i])
                                 + f(-E[i] - E[k])) / (4.0 * h**2)
    try:
        np.linalg.cholesky(-H)
    except np.linalg.LinAlgError:
        return np.full((4, 4), np.nan)
    cov_v = R @ np.linalg.inv(-H) @ R.T
    # d(sigma2, gamma2, phi, sigma2_AR) / d v, rows in PARAM_KEYS order
    J = np.array([[s2, 0.0, 0.0, 0.0],
                  [g2, g2, 0.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0 - phi**2],
                  [s2ar, 0.0, s2ar, 0.0]])
    return J @ cov_v @ J.T


def _padded(cov4: np.ndarray) -> np.ndarray:
    """``(5, 5)`` covariance in ``PARAM_NAMES`` order, NaN for the amplitude."""
    out = np.full((len(PARAM_NAMES),) * 2, np.nan)
    out[:4, :4] = cov4
    return out


# ----------------------------------------------------------------------------------------------
# public


def fit_mle(x: np.ndarray, beta: float, start: dict[str, float] | None = None, *, n_starts: int = 2,
            maxiter: int = 200, backend: str = "kalman", own_starts: str = "variogram",
            se: bool = False) -> MLEResult:
    """Exact Gaussian MLE of WN + RW + AR1 + deterministic sinusoid of known frequency ``beta``.

    Parameters
    ----------
    x : 1-D signal, per-sample units.
    beta : sinusoid frequency in rad/sample (known; regressors ``cos(beta t)``, ``sin(beta t)``).
    start : optional start ``{'WN[1].sigma2', 'RW[1].gamma2', 'AR1[1].phi', 'AR1[1].sigma2'}``
        (e.g. the GMWM estimate; extra keys are ignored). Tried first, as start ``'gmwm'``.
    n_starts : number of starts optimised; after the supplied one come the MLE's own starts.
    maxiter : BFGS iteration cap per start (and per polish).
    backend : ``"kalman"`` (specialised Numba filter, profile likelihood; default) or
        ``"statsmodels"`` (statsmodels filter, all six parameters free). Same likelihood.
    own_starts : the MLE's own starts (no outside information): ``"variogram"`` gives
        ``'variogram'`` (best AR1 on a grid fitted by NNLS to the empirical variogram, a moment
        method), ``'grid-1'``, ... (other grid values), then ``'default'`` (statsmodels' start
        values); ``"default"`` gives ``'default'`` first. The highest log-likelihood wins.
    se : also compute standard errors (:func:`mle_covariance`, for a converged fit), timed
        separately in ``seconds_se``.

    Never raises for non-convergence: ``converged`` is False (with ``message``) when the optimiser
    did not meet its gradient tolerance, the log-likelihood is not finite, ``|phi| >= 0.9999`` or a
    variance is below ``1e-6 * Var(diff x)``. Raises :class:`InputError` for unusable input and
    :class:`ModelError` for a start missing a parameter.
    """
    t0, c0 = time.perf_counter(), time.process_time()
    x = _check_input(x, beta)
    if n_starts < 1:
        raise InputError(f"n_starts must be >= 1, got {n_starts}")
    if maxiter < 1:
        raise InputError(f"maxiter must be >= 1, got {maxiter}")
    if backend not in BACKENDS:
        raise InputError(f"unknown MLE backend {backend!r}; use one of {', '.join(BACKENDS)}")
    if own_starts not in ("variogram", "default"):
        raise InputError(f"own_starts must be 'variogram' or 'default', got {own_starts!r}")
    if start is not None:
        missing = [k for k in PARAM_KEYS if k not in start]
        if missing:
            raise ModelError(f"start is missing {', '.join(missing)}")

    n = x.size
    scale = float(np.var(np.diff(x)))
    X = _shared_regressors(n, beta)
    be = _Backend(backend, x, X, beta, scale)

    starts: list[tuple[str, dict[str, float] | None]] = []
    if start is not None:
        starts.append(("gmwm", start))
    own: list[tuple[str, dict[str, float] | None]] = []
    if own_starts == "default":
        own.append(("default", None))
    if len(starts) + len(own) < n_starts:  # the variogram scan costs a little: only if needed
        own += _variogram_starts(x - X @ be.b0)
    if own_starts == "variogram":
        own.append(("default", None))  # computed only if reached
    starts = (starts + own)[:n_starts]

    def at_boundary(eta: np.ndarray) -> str:
        return _boundary_problem(be.params(eta)[0], scale)

    best: tuple | None = None
    for name, theta in starts:
        theta = be.default_start() if theta is None else theta
        eta, ll, ok, msg = _maximise(be.loglike, be.coords(theta), be.info, be.box, maxiter, n,
                                     at_boundary)
        # a later start must beat the incumbent materially (or converge where it did not) to win,
        # so that 'start' tells which start was needed rather than rounding noise
        if best is None or (np.isfinite(ll) and (ll > best[1] + _LL_TIE
                                                 or (ok and not best[2] and ll > best[1] - _LL_TIE))):
            best = (eta, ll, ok, msg, name)

    eta, ll, ok, msg, name = best
    theta, b = be.params(eta)
    problem = "" if np.isfinite(ll) else "log-likelihood not finite"
    problem = problem or _boundary_problem(theta, scale)
    converged = ok and not problem
    if problem:
        message = f"not converged: {problem} (start {name}; {msg})"
    elif not ok:
        message = f"not converged: {msg} (start {name})"
    else:
        message = f"converged from start {name} ({msg})"
    params = [theta.get(k, np.nan) for k in PARAM_KEYS] + [float(np.hypot(*b))]
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    cov, seconds_se, cpu_se = None, 0.0, 0.0
    if se:
        t1, c1 = time.perf_counter(), time.process_time()
        if converged:
            with np.errstate(all="ignore"):
                cov = _padded(mle_covariance(x, beta, theta))
        seconds_se, cpu_se = time.perf_counter() - t1, time.process_time() - c1
    return MLEResult(params=np.array(params), converged=converged, loglike=float(ll), start=name,
                     n_starts=len(starts), seconds=seconds, message=message, cov=cov,
                     seconds_se=seconds_se, cpu_seconds=cpu, cpu_seconds_se=cpu_se)


def fit_statsmodels(x: np.ndarray, beta: float, *, maxiter: int = 50, se: bool = False
                    ) -> MLEResult:
    """statsmodels' own MLE of WN + RW + AR1 + deterministic sinusoid of known frequency ``beta``.

    ``UnobservedComponents(x, level="llevel", autoregressive=1, exog=[cos(beta t), sin(beta t)],
    use_exact_diffuse=True).fit(maxiter=maxiter, cov_type="none")``: statsmodels' start values,
    its L-BFGS and (by default) its iteration cap of 50; the sinusoid coefficients are estimated
    with the variances (``mle_regression``), the exact diffuse start matches :func:`fit_mle`'s
    likelihood, so ``loglike`` is comparable. ``converged`` is statsmodels' own verdict (its
    optimiser's flag, a finite log-likelihood, no exception); a solution on the boundary is named
    in ``message`` but not counted as a failure. ``seconds`` times model construction and fit; with
    ``se=True`` the covariance by statsmodels' default for a fit (outer product of gradients, one
    more filter pass) is added, timed in ``seconds_se``. Needs statsmodels (extra "pipeline").
    """
    x = _check_input(x, beta)
    if maxiter < 1:
        raise InputError(f"maxiter must be >= 1, got {maxiter}")
    try:
        from statsmodels.tsa.statespace.structural import UnobservedComponents
    except ImportError:
        raise InputError("the statsmodels baseline needs statsmodels: "
                         "pip install 'gmwm[pipeline]'") from None
    n = x.size
    X = _regressors(n, beta)
    nan = np.full(len(PARAM_NAMES), np.nan)
    t0, c0 = time.perf_counter(), time.process_time()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            model = UnobservedComponents(x, level="llevel", autoregressive=1, exog=X,
                                         use_exact_diffuse=True)
            res = model.fit(disp=False, maxiter=int(maxiter), cov_type="none")
        except (np.linalg.LinAlgError, ValueError, FloatingPointError) as exc:
            return MLEResult(params=nan, converged=False, loglike=np.nan, start="statsmodels",
                             n_starts=1, seconds=time.perf_counter() - t0,
                             message=f"not converged: statsmodels raised {type(exc).__name__}: "
                                     f"{exc}", cpu_seconds=time.process_time() - c0)
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    est = dict(zip(model.param_names, np.asarray(res.params, dtype=float), strict=True))
    theta = {ours: est[sm] for sm, ours in _SM_NAMES.items()}
    b = np.array([est["beta.x1"], est["beta.x2"]])
    ll = float(res.llf)
    info = res.mle_retvals or {}
    ok = bool(info.get("converged", False)) and np.isfinite(ll)
    notes = sorted({str(w.message).splitlines()[0] for w in caught
                    if issubclass(w.category, Warning)})
    detail = f"statsmodels {res.mle_settings.get('optimizer', 'lbfgs')}, " \
             f"{info.get('iterations', '?')} iterations"
    boundary = _boundary_problem(theta, float(np.var(np.diff(x))))
    message = (f"converged ({detail})" if ok else f"not converged ({detail})")
    message += "".join(f"; {m}" for m in [boundary, *notes] if m)
    cov, seconds_se, cpu_se = None, 0.0, 0.0
    if se:
        t1, c1 = time.perf_counter(), time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                full = np.asarray(model.filter(res.params, cov_type="opg").cov_params(),
                                  dtype=float)
                order = [model.param_names.index(sm) for sm in
                         ("sigma2.irregular", "sigma2.level", "ar.L1", "sigma2.ar")]
                cov = _padded(full[np.ix_(order, order)])
            except (np.linalg.LinAlgError, ValueError):
                cov = None
        seconds_se, cpu_se = time.perf_counter() - t1, time.process_time() - c1
    params = [theta[k] for k in PARAM_KEYS] + [float(np.hypot(*b))]
    return MLEResult(params=np.array(params), converged=ok, loglike=ll, start="statsmodels",
                     n_starts=1, seconds=seconds, message=message, cov=cov,
                     seconds_se=seconds_se, cpu_seconds=cpu, cpu_seconds_se=cpu_se)
