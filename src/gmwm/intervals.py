"""Confidence intervals that stay inside the parameter space, for parameters, datasheet
coefficients and bootstrap intervals (one rule everywhere).

The rule, per parameter (``z = z_{1-alpha/2}``; which parameter is a component's scale from
``Process.scale_index``, the domains from ``Process.domain``):

* **Scale parameters** (the one that is 0 when a component vanishes: WN sigma2, QN Q2, RW
  gamma2, AR1/GM variance, SIN alpha, DR |omega|), with ``a = |theta|`` and ``x = z se / a``:

  - distinguishable from 0 (``x <= 1``): ``[a - z se, a exp(x)]``, the Wald lower end and the
    log-scale upper end;
  - near 0 (``x > 1``: the fit's warning "not distinguishable from zero"):
    ``[0, a + (e - 1) z se]``: the Wald lower end cut at 0; the upper end continues the
    log-scale one linearly from ``x = 1`` (where both are ``e a``), so the ends move
    continuously with the estimate and with ``alpha`` (a 95 % interval contains the 90 % one);
  - component at the boundary 0 (no sandwich SE): ``[0, z se_0]``, ``se_0`` the SE of its
    linear scale freed at 0 (:func:`boundary_upper`);
  - a signed scale (DR omega) carries the estimate's sign (the WV sees only |omega|).

* **Shape parameters** (AR1 phi in [-1, 1], GM beta in [0, inf), SIN beta in [0, pi]): Wald
  on the natural scale cut to the closed domain; an end on the domain's edge says the data
  cannot exclude it (phi -> 1: a random walk over the observed scales). For a component at
  the boundary 0 its shape is not identified: the whole domain.

So an interval reaches 0 exactly when the estimate is within ``z`` standard errors of 0, which
is what the fit's "not distinguishable from zero" warning says (at alpha = 0.05, the same test:
:func:`gmwm.diagnostics.is_weak`), and every interval contains the Wald interval cut to the domain, so it never
covers less. Why (``benchmarks/bench_intervals.py``, coverage on 300 fits per model; the
log-scale-only figures from an earlier run of it with that rule): a variance estimated from a
few long scales is right-skewed with an SE that grows with the estimate, and Wald's upper end
misses it (a random walk at 3 SE: Wald 0.88, log scale 0.95); where the SE is set by the other
components the estimate is close to normal and the log scale's lower end is too high (a
Gauss-Markov variance at 3 SE: Wald 0.98, log scale 0.93). The union of the two keeps the
better side of each. Near 0 the skew is strongest: random walks at 1.5-2.5 SE were covered by
Wald in 0.87-0.90 of the fits, by the rule in 0.96-0.97. The shape estimates are not
log-normal: in the earlier run a log-scale interval for GM beta and an atanh-scale interval for
an AR1 phi near 1 both lost coverage (0.93 and 0.88 against Wald's 0.97 and 0.98).

Datasheet coefficients that are monotone functions of one parameter (ARW, RRW, QN, RR, GM
correlation time and sigma, SIN frequency and amplitude) take the image of that parameter's
interval (:func:`image_interval`), so the parameter table and the datasheet agree by
construction; the AR1 stationary sigma (two parameters) uses the same rule on its variance
scale (:func:`function_interval`). Bootstrap basic intervals follow the same rule
(:func:`bootstrap_basic`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .diagnostics import normal_quantile

__all__ = ["bootstrap_basic", "boundary_upper", "fit_intervals", "function_interval",
           "image_interval", "param_domains", "param_intervals", "param_kinds",
           "scale_interval"]



def param_kinds(model: Any) -> list[str]:
    """Per parameter: ``"log"`` (positive; DR omega: positive in |omega|), ``"phi"`` (AR1 phi)
    or ``"pi"`` (SIN beta), from the processes' free coordinates."""
    return [k for c in model.components for k in c.process.free_map_kinds]


def param_domains(model: Any, theta: np.ndarray | None = None) -> np.ndarray:
    """(p, 2) closed domain of each parameter (:attr:`gmwm.processes.Process.domain`); with
    ``theta``, a signed scale parameter estimated negative gets the mirrored domain."""
    dom = np.array([d for c in model.components for d in c.process.domain], dtype=float)
    if theta is not None:
        for c in model.components:
            i = c.start + c.process.scale_index
            if c.process.signed and float(theta[i]) < 0:
                dom[i] = (-dom[i, 1], -dom[i, 0])
    return dom


def scale_interval(a: float, s: float, z: float) -> tuple[float, float]:
    """The interval of a scale parameter (or a positive function of the parameters) with value
    ``a >= 0`` and standard error ``s``: ``[a - z s, a exp(z s / a)]`` when ``a >= z s``, else
    ``[0, a + (e - 1) z s]`` (module docstring); NaN ends without a finite ``a`` and ``s``."""
    if not (np.isfinite(a) and np.isfinite(s) and a >= 0 and s >= 0):
        return (math.nan, math.nan)
    if a > 0 and a >= z * s:
        return (a - z * s, a * math.exp(z * s / a) if s > 0 else a)
    return (0.0, a + (math.e - 1.0) * z * s)


def _scale_mask(model: Any) -> np.ndarray:
    out = np.zeros(model.n_params, bool)
    for c in model.components:
        out[c.start + c.process.scale_index] = True
    return out


def param_intervals(model: Any, theta: np.ndarray, cov: np.ndarray | None, alpha: float = 0.05,
                    *, fixed: np.ndarray | None = None,
                    boundary_upper: np.ndarray | None = None,
                    se: np.ndarray | None = None) -> np.ndarray:
    """(p, 2) intervals at level ``1 - alpha`` inside each parameter's domain (the rule of the
    module docstring).

    ``cov``: covariance of the estimate (NaN rows for parameters held at the boundary);
    ``fixed``: parameters of components at the boundary 0; ``boundary_upper``: the upper ends
    of those components' scale parameters (:func:`boundary_upper`; NaN if not given);
    ``se``: standard errors (default ``sqrt(diag(cov))``). A parameter with no finite SE that is
    not held at the boundary gets NaN ends (no interval)."""
    theta = np.asarray(theta, dtype=float)
    p = theta.size
    z = normal_quantile(alpha)
    if se is None:
        se = np.full(p, np.nan) if cov is None else np.sqrt(np.clip(np.diag(np.asarray(
            cov, float)), 0, None))
    se = np.asarray(se, dtype=float)
    fixed = np.zeros(p, bool) if fixed is None else np.asarray(fixed, bool)
    upper = np.full(p, np.nan) if boundary_upper is None else np.asarray(boundary_upper, float)
    domain = param_domains(model)
    scale = _scale_mask(model)
    out = np.full((p, 2), np.nan)
    for i, (th, s) in enumerate(zip(theta, se, strict=True)):
        if fixed[i]:
            if scale[i]:
                out[i] = (0.0, upper[i])
            else:  # the shape of a component at 0 is not identified: the whole domain
                out[i] = domain[i]
            continue
        if not (np.isfinite(s) and np.isfinite(th)):
            continue
        if scale[i]:  # variance, amplitude, |drift| (module docstring)
            lo, hi = scale_interval(abs(th), s, z)
            out[i] = (lo, hi) if th >= 0 else (-hi, -lo)
        else:  # shape (AR1 phi, GM beta, SIN beta): natural scale, cut to the closed domain
            d_lo, d_hi = domain[i]
            out[i] = (max(th - z * s, d_lo), min(th + z * s, d_hi))
    return out


def boundary_upper(result: Any, alpha: float = 0.05) -> np.ndarray:
    """Per parameter: for the scale parameter of each component at the boundary 0, the upper end
    ``z se_0`` of its interval, ``se_0`` the sandwich SE of its linear scale (sigma2, gamma2,
    Q2, the AR1/GM variance, alpha^2 for SIN, omega^2 for DR) freed at 0 with every other
    parameter at its estimate and the component's shape as reported; for SIN alpha and DR omega
    the square root of that end. NaN elsewhere (and where it cannot be computed)."""
    model = result.model
    theta = np.asarray(result.params, dtype=float)
    out = np.full(model.n_params, np.nan)
    comps = [c for c in model.components if _at_boundary(result, c)]
    V = getattr(result, "wv_cov", None)
    if not comps or V is None:
        return out
    from .inference import Problem, f_jacobian

    z = normal_quantile(alpha)
    prob = Problem.of(result)
    Vf = np.asarray(V, float) * np.outer(*(2 * [f_jacobian(prob.nu_hat, prob.method)]))
    held = np.zeros(model.n_params, bool)
    for c in comps:
        held[c.slice] = True
    with np.errstate(all="ignore"):
        A_free = prob.jac_theta(theta)[:, ~held]
        # d f / d nu at the fitted WV (the component adds nothing there)
        fprime = f_jacobian(model.wv(theta, prob.tau), prob.method)
        for c in comps:
            i = c.start + c.process.scale_index
            p = theta[c.slice].copy()
            p[c.process.scale_index] = 1.0   # the WV is linear in the linear scale
            col = c.process.wv(p, prob.tau, model.freq)
            A = np.column_stack([A_free, fprime * col])
            d = np.linalg.norm(prob.white @ A, axis=0)
            d[~np.isfinite(d) | (d == 0)] = 1.0
            As = A / d
            W = prob.omega
            G = np.linalg.pinv(As.T @ W @ As, hermitian=True) @ As.T @ W
            var = float(G[-1] @ Vf @ G[-1]) / d[-1] ** 2
            if np.isfinite(var) and var >= 0:
                end = z * math.sqrt(var)
                out[i] = math.sqrt(end) if c.process.scale_power == 2 else end
    return out


def _at_boundary(result: Any, c: Any) -> bool:
    vanished = result.diagnostics.get("at_boundary", []) or []
    return c.name in vanished or float(np.asarray(result.params)[c.start
                                                              + c.process.scale_index]) == 0


def fit_intervals(result: Any, alpha: float = 0.05) -> np.ndarray:
    """(p, 2) domain-respecting intervals of a :class:`~gmwm.estimator.GMWMResult` (the rule of
    :func:`param_intervals`; components at the boundary from the fit's diagnostics)."""
    model = result.model
    fixed = np.zeros(model.n_params, bool)
    for c in model.components:
        if _at_boundary(result, c):
            fixed[c.slice] = True
    upper = boundary_upper(result, alpha) if fixed.any() else None
    return param_intervals(model, result.params, result.cov, alpha, fixed=fixed,
                           boundary_upper=upper, se=result.se)


def image_interval(fn: Callable[[float], float], interval: Sequence[float]) -> tuple[float, float]:
    """The image of ``[lo, hi]`` under a monotone ``fn`` (ends sorted; NaN stays NaN)."""
    lo, hi = float(interval[0]), float(interval[1])
    if not (np.isfinite(lo) or np.isinf(lo)) or np.isnan(hi):
        return (float("nan"), float("nan"))
    with np.errstate(all="ignore"):
        a, b = fn(lo), fn(hi)
    return (min(a, b), max(a, b))


def function_interval(fn: Callable[[np.ndarray], float], theta: np.ndarray, cov: np.ndarray,
                      alpha: float = 0.05, weak: bool = False) -> tuple[float, float]:
    """Interval of a positive function ``fn(theta)`` of several parameters by the delta method,
    with the rule of a scale parameter (:func:`scale_interval`); ``weak`` (a component whose
    scale is not distinguishable from 0) makes it reach 0 whatever the delta-method SE says."""
    theta = np.asarray(theta, float)
    value = float(fn(theta))
    cov = np.asarray(cov, float)
    if not (np.isfinite(value) and value >= 0 and np.all(np.isfinite(cov))):
        return (float("nan"), float("nan"))
    grad = np.empty(theta.size)
    for i in range(theta.size):
        h = 1e-6 * max(abs(theta[i]), 1e-300)
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        grad[i] = (fn(up) - fn(dn)) / (2 * h)
    var = float(grad @ cov @ grad)
    if not (np.isfinite(var) and var >= 0):
        return (float("nan"), float("nan"))
    z, s = normal_quantile(alpha), math.sqrt(var)
    lo, hi = scale_interval(value, s, z)
    return (0.0, hi) if weak else (lo, hi)


def bootstrap_basic(model: Any, estimate: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(p, 2) basic bootstrap intervals inside the domain, by the rule of
    :func:`param_intervals`. ``q`` (p, 2): the refits' quantiles ``q(alpha/2), q(1 - alpha/2)``.
    Scale parameters: the basic interval on the log scale, ``[theta^2 / q_hi, theta^2 / q_lo]``
    (sign kept for DR omega); where it does not exist (estimate or lower quantile at 0: at least
    ``alpha/2`` of the refits put the component at 0) the percentile interval ``[0, q_hi]``.
    Shape parameters: ``[2 theta - q_hi, 2 theta - q_lo]`` cut to the closed domain."""
    est = np.asarray(estimate, float)
    q = np.asarray(q, float)
    out = np.full_like(q, np.nan)
    scale = _scale_mask(model)
    domain = param_domains(model)
    for i in range(est.size):
        th, lo, hi = est[i], q[i, 0], q[i, 1]
        if not np.all(np.isfinite([th, lo, hi])):
            continue
        if scale[i]:
            sign = -1.0 if th < 0 else 1.0
            a, (qa_lo, qa_hi) = abs(th), sorted((abs(lo), abs(hi)))
            b = (a * a / qa_hi, a * a / qa_lo) if a > 0 and qa_lo > 0 else (0.0, qa_hi)
            out[i] = b if sign > 0 else (-b[1], -b[0])
        else:
            d_lo, d_hi = domain[i]
            out[i] = (max(2 * th - hi, d_lo), min(2 * th - lo, d_hi))
    return out
