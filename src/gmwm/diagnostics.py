"""Diagnostics of a fit: one set of thresholds, used by the fit's warnings (:func:`gmwm.fit`),
the identifiability checks (:mod:`gmwm.identify`) and the reports.

Every rule about one process (an AR1 at |phi| -> 1, a SIN at Nyquist or too slow, ...) is a method
of that process (:mod:`gmwm.processes`) and reads its threshold here. Why each threshold:

Jacobian and conditioning. Both the fit and ``identify`` judge one matrix,
:func:`free_jacobian`: the whitened WV Jacobian ``L' d f(nu) / d eta`` in the optimiser's free
coordinates ``eta`` (logs of variances and amplitudes, scaled logit of AR1 phi, pi-logistic of SIN
beta), columns scaled to unit norm. A unit step in ``eta`` is a factor ``e`` in a scale parameter,
so its singular values compare parameters on one dimensionless footing.

* ``COND_MAX = 1e6``: above it the fit warns ("ill-conditioned") and ``identify`` names the
  near-null directions. The sandwich inverts ``A' Omega A``, whose condition number is the square,
  1e12: its rounding error ``1e12 * eps ~ 2e-4`` leaves standard errors with about four digits.
* ``RANK_RTOL = 1e-8``: singular values below ``RANK_RTOL * s_1`` do not count towards the
  numerical rank; at a condition number of 1e8 the squared one reaches ``1 / eps`` and
  ``A' Omega A`` is singular in double precision.

Components.

* ``VANISH_SHARE = 1e-6``: a component whose WV is below this share of the estimated WV at every
  scale is "at the boundary 0" (held fixed, no standard error).
* ``WEAK_Z = 1.96`` (the normal 0.975 quantile): a scale parameter below ``WEAK_Z`` standard
  errors is "not distinguishable from zero" (a two-sided 5 % Wald test,
  :func:`is_weak`, the test that makes its 95 % interval reach 0).
* ``UNSUPPORTED_PER_PARAM = 2``: a component whose removal raises the objective, on the
  chi-square scale, by less than 2 per parameter is "not supported by the data" (an AIC-type rule:
  the drop in fit does not pay for the parameters).
* ``SNR_MIN = 1``: a component whose WV is below the noise of the WV estimate over all scales
  together (``sqrt(sum_j (nu_c,j / sd_j)^2) < 1``, ``sd_j`` the Gaussian SD
  ``nu_j sqrt(2 / eta_j)``) vanishes in ``identify``.

AR1 / GM (an AR1 with ``phi = exp(-beta / freq)``):

* ``PHI_EDGE = 1e-6``: ``|phi| > 1 - PHI_EDGE`` is the edge of the stationary domain (the free
  coordinate is bounded where ``phi`` would round to 1: a random walk, not an AR1).
* ``PHI_NEG_EDGE = 0.999``: ``phi < -PHI_NEG_EDGE`` is an alternating process whose WV sits at the
  first scale: variance and phi are not separately identified.
* ``PHI_ZERO = 0.05``: ``-PHI_ZERO < phi <= 0`` next to a WN, or a correlation time below
  ``1 / COLLAPSE_RATE = 1/3`` sample: the AR1 is white noise, its split with the WN is not
  identified.
* ``RW_LIKE = 5``: a correlation time above ``RW_LIKE`` times the longest scale makes the AR1 a
  random walk over the observed scales (phi not identified).
* ``PAIR_REL_AR = 0.1``: two AR1 (or two GM) whose decay rates differ by less than 10 % are
  identified only through their sum.

SIN (``nu_j = 2 alpha^2 sin^4(beta tau / 4) / (tau^2 sin^2(beta / 2))``):

* Nyquist: ``beta > pi (1 - SIN_NYQUIST_EDGE)``, ``SIN_NYQUIST_EDGE = 1e-6``, is the upper bound of
  its domain.
* One slow-SIN rule (:meth:`gmwm.processes.Sinusoid.is_slow`): the WV peaks at
  ``tau = 4 x* / beta`` (``x* = 1.1656``, the root of ``tan x = 2 x``); below the peak it rises
  like a drift's, ``alpha^2 beta^2 tau^2 / 32`` bent by ``(sin x / x)^4``. When the peak lies
  beyond the longest scale (``beta tau_max < 4 x*``, a period above about 1.35 longest scales),
  the observed WV shows no peak: alpha and beta are separated only by that bend, which the few
  degrees of freedom of the longest scales cannot resolve, and a drift (DR) of slope
  ``alpha beta`` fits about as well. The fit warns and ``identify`` reports it with the same text.
* ``PAIR_REL_SIN = 0.05``: two SIN whose beta differ by less than 5 %: only their sum is
  identified.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError

__all__ = ["COND_MAX", "LOADING_MIN", "RANK_RTOL", "SD_FREE_MAX", "VANISH_SHARE",
           "condition_number", "degeneracies", "fit_warnings", "free_jacobian",
           "unsupported_warning"]

COND_MAX = 1e6
RANK_RTOL = 1e-8
#: free-coordinate SD above which a direction is weakly identified (a 1-SD move is a factor e)
SD_FREE_MAX = 1.0
#: loadings of a direction's parameters named in a reason
LOADING_MIN = 0.3
VANISH_SHARE = 1e-6
WEAK_Z = 1.959963984540054
UNSUPPORTED_PER_PARAM = 2.0
SNR_MIN = 1.0
PHI_EDGE = 1e-6
PHI_NEG_EDGE = 0.999
PHI_ZERO = 0.05
COLLAPSE_RATE = 3.0
RW_LIKE = 5.0
PAIR_REL_AR = 0.1
PAIR_REL_SIN = 0.05
SIN_NYQUIST_EDGE = 1e-6


# -- the Jacobian -----------------------------------------------------------------------------------
def free_jacobian(problem: Any, theta: np.ndarray, active: np.ndarray) -> np.ndarray:
    """The whitened WV Jacobian ``L' d f(nu) / d eta`` of ``problem`` (a
    :class:`gmwm.inference.Problem`) at ``theta``, columns ``active`` (boolean), in free
    coordinates (not yet scaled: :func:`condition_number` and ``identify`` scale its columns)."""
    model = problem.model
    with np.errstate(all="ignore"):
        eta = model.to_free(theta)
        d = model.dtheta_deta(np.where(np.isfinite(eta), eta, 0.0))
        return (problem.white @ problem.jac_theta(theta))[:, active] * d[active]



def normal_quantile(alpha: float) -> float:
    """``z_{1-alpha/2}``, the two-sided normal quantile of level ``1 - alpha`` (1.96 at 0.05)."""
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha}")
    from scipy.special import ndtri  # SciPy only when a level is asked for

    return float(ndtri(1 - alpha / 2))


def is_weak(theta: np.ndarray, se: np.ndarray, alpha: float = 0.05) -> np.ndarray:
    """True where an estimate is within ``z_{1-alpha/2}`` standard errors of 0 (finite SE): its
    Wald interval of level ``1 - alpha`` reaches 0."""
    theta = np.asarray(theta, float)
    se = np.asarray(se, float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(se) & (np.abs(theta) < normal_quantile(alpha) * se)

def condition_number(A: np.ndarray) -> float:
    """2-norm condition number of A with unit-norm columns (inf if singular or non-finite)."""
    norms = np.linalg.norm(A, axis=0)
    if A.size == 0 or not np.all(np.isfinite(A)) or np.any(norms == 0):
        return np.inf
    try:
        sv = np.linalg.svd(A / norms, compute_uv=False)
    except np.linalg.LinAlgError:
        return np.inf
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf


# -- the fit's warnings -----------------------------------------------------------------------------
def fit_warnings(model: Any, theta: np.ndarray, se: np.ndarray, cond: float,
                 vanished: list[str], fixed: np.ndarray, tau_max: float,
                 sign_identified: bool) -> list[str]:
    """Human-readable problems of a fit (boundary, process edges, weak identification, missing
    SEs); ``tau_max`` = the longest scale fitted [samples]; ``sign_identified`` False when the fit
    saw only a WV (the sign of a drift is then unknown)."""
    out: list[str] = []
    if vanished:
        out.append("component(s) " + ", ".join(vanished) + " contribute less than "
                   f"{VANISH_SHARE:g} of the WV at every scale: estimate at the boundary 0 "
                   "(no standard error); a smaller model fits as well")
    for c in model.components:
        if c.name not in vanished:
            out += c.process.fit_warnings(c.name, theta[c.slice], tau_max, model.freq)
    if not np.isfinite(cond) or cond > COND_MAX:
        out.append(f"the WV Jacobian is ill-conditioned (condition number {cond:.3g}): more "
                   "parameters than the WV can identify; try a smaller model or the identifiability "
                   "check (`gmwm.identify.check`)")
    bad_se = [n for n, s, f in zip(model.param_names, se, fixed, strict=True)
              if not np.isfinite(s) and not f]
    if bad_se:
        out.append("standard errors could not be computed for " + ", ".join(bad_se)
                   + " (singular sandwich)")
    flags = is_weak(theta, se)  # the rule under which the 95 % interval reaches 0
    weak = [c.name for c in model.components
            if c.name not in vanished and flags[c.start + c.process.scale_index]]
    if weak:
        out.append("component(s) " + ", ".join(weak) + " not distinguishable from zero "
                   f"(estimate below {WEAK_Z:.3g} standard errors)")
    if not sign_identified and any(c.process.signed for c in model.components):
        out.append("drift sign is not identified from a WV; reported positive")
    return out


def unsupported_warning(model: Any, drops: list[tuple[int, float]]) -> str | None:
    """The warning for components whose removal raises the objective by less than
    ``UNSUPPORTED_PER_PARAM`` per parameter on the chi-square scale; ``drops`` are
    (component index, rise of the objective on that scale) of the fitted drop-one submodels."""
    found = []
    for k, delta in drops:
        proc = model.components[k].process
        if np.isfinite(delta) and delta < UNSUPPORTED_PER_PARAM * proc.n_params:
            name = proc.name if model.count(proc.name) == 1 else f"one {proc.name}"
            found.append((name, float(delta)))
    if not found:
        return None
    return ("component(s) " + ", ".join(n for n, _ in found) + " not supported by the data: "
            f"dropping one raises the objective by less than {UNSUPPORTED_PER_PARAM:g} per "
            "parameter on the chi-square scale (" + ", ".join(f"{n}: {d:.2g}" for n, d in found)
            + "); a smaller model fits as well")


# -- degenerate configurations ----------------------------------------------------------------------
def degeneracies(model: Any, theta: np.ndarray, wv: Any) -> list[str]:
    """Known non-identifiable configurations of ``theta`` given the observed scales of ``wv``
    (thresholds in the module docstring). Returns human-readable reasons (empty: none found)."""
    theta = np.asarray(theta, dtype=float)
    tau = wv.scales.astype(float)
    tau_max = float(tau[-1])
    total = model.wv(theta, tau)
    sd = np.sqrt(2.0 / wv.edof) * np.abs(total)
    notes: list[str] = []
    comp_wv = model.component_wv(theta, tau)
    for c in model.components:
        nu_c = np.nan_to_num(comp_wv[c.name])
        with np.errstate(divide="ignore", invalid="ignore"):
            snr = float(np.sqrt(np.sum(np.where(sd > 0, nu_c / sd, np.inf) ** 2)))
        if snr < SNR_MIN:
            share = float(np.max(nu_c / total)) if np.all(total > 0) else 0.0
            notes.append(f"{c.name} vanishes: its WV is below the noise of the WV estimate "
                         f"(signal/noise {snr:.2g} over all scales, max share {share:.2g})")
            continue
        notes += c.process.degeneracies(c.name, theta[c.slice], tau_max, model)
    for comps in _same_type(model):
        proc = comps[0].process
        if proc.pair_rel is None:
            continue
        for i, c1 in enumerate(comps):
            for c2 in comps[i + 1:]:
                s1 = proc.pair_key(theta[c1.slice], model.freq)
                s2 = proc.pair_key(theta[c2.slice], model.freq)
                if np.isfinite(s1) and np.isfinite(s2) and abs(s1 - s2) < proc.pair_rel * max(s1,
                                                                                              s2):
                    notes.append(f"{c1.name} and {c2.name} have nearly equal {proc.pair_what}: "
                                 "only their sum is identified")
    return notes


def _same_type(model: Any) -> list[list[Any]]:
    """Components grouped by process, in canonical order, groups of at least two."""
    groups: dict[str, list[Any]] = {}
    for c in model.components:
        groups.setdefault(c.process.name, []).append(c)
    return [g for g in groups.values() if len(g) > 1]
