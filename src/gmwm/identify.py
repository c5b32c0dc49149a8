"""Identifiability checks of a GMWM fit: local (Jacobian), global (multi-start), posterior (emcee).

Everything is evaluated in the optimiser's free coordinates ``eta`` (logs of variances and
amplitudes, scaled logit of AR1 phi, pi-logistic of SIN beta; ``Model.to_free``), where a unit
step is a factor ``e`` in a scale parameter, so thresholds are dimensionless:

Local (:func:`local_check`), at the estimate, parameters at the boundary 0 left out:

* ``A = L' d f(nu)/d eta`` (``Omega = L L'``; :func:`gmwm.diagnostics.free_jacobian`, the matrix
  the fit's own condition number is computed from) with unit-norm columns; its singular values
  give the numerical ``rank`` (``s_i > RANK_RTOL * s_1``) and ``condition_number`` (warn above
  ``COND_MAX``); right singular vectors of the small singular values name the parameter
  combinations the WV cannot tell apart (loadings ``>= LOADING_MIN``). Thresholds and why:
  :mod:`gmwm.diagnostics`.
* Statistical size of the flat directions: eigenvectors of the sandwich covariance in free
  coordinates whose SD exceeds ``SD_FREE_MAX = 1`` (a 1-SD move changes a scale parameter by a
  factor e) are reported as weakly identified.
* Known degenerate configurations at the estimate (:func:`gmwm.diagnostics.degeneracies`): a
  component whose WV is below the noise of the WV estimate (it vanishes), an AR1/GM with
  ``phi ~ 0`` next to a WN, an AR1/GM whose correlation time exceeds 5 times the longest scale (a
  random walk over the observed scales), a SIN whose WV peaks beyond the longest scale
  (confounded with a drift), two AR1/GM or two SIN with nearly equal shape (only their sum is
  identified).

Global (:func:`global_check`): least-squares refinements of the same objective from dispersed
starts; two optima are distinct if some free coordinate differs by more than
``min(max(3 SD, 0.05), 1)`` and near-equal if their objectives differ by less than 1 on the
chi-square scale (Gaussian inverse-variance weights of the WV) or by less than 1 %.

Posterior (:func:`posterior_check`): emcee on the quasi-posterior ``exp(-Q/2)`` with
``Q = (f(nu_hat) - f(nu))' V^-1 (f(nu_hat) - f(nu))`` and flat priors on a box around the
estimate in free coordinates; chains are extended until ``n_steps > 50 tau_int``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .diagnostics import COND_MAX, LOADING_MIN, RANK_RTOL, SD_FREE_MAX, degeneracies, free_jacobian
from .errors import GMWMError, InputError
from .estimator import GMWMResult
from .inference import Problem, f_jacobian, omega_from_cov, whitener, wv_cov
from .model import Model
from .wv import WaveletVariance

__all__ = ["COND_MAX", "LOADING_MIN", "RANK_RTOL", "SD_FREE_MAX", "GlobalCheck",
           "IdentifiabilityReport", "LocalCheck", "PosteriorCheck", "batch_wv", "check",
           "corner_plot", "degeneracies", "global_check", "local_check", "posterior_check"]

TAU_FACTOR = 50  # chains must be longer than TAU_FACTOR integrated autocorrelation times
_LOG10E = np.log10(np.e)


# -- the problem ----------------------------------------------------------------------------------
@dataclass
class _Setup:
    """The fitted quantities every check needs, around the fit's own :class:`Problem`."""

    problem: Problem
    theta: np.ndarray
    V: np.ndarray              # covariance of nu_hat behind the SEs
    cov: np.ndarray            # sandwich covariance of theta_hat
    objective: float

    @property
    def model(self) -> Model:
        return self.problem.model

    @property
    def wv(self) -> WaveletVariance:
        return self.problem.wv

    @property
    def omega(self) -> np.ndarray:
        return self.problem.omega

    @property
    def tau(self) -> np.ndarray:
        return self.problem.tau

    @property
    def omega_chi(self) -> np.ndarray:
        """Inverse covariance of f(nu_hat): the chi-square scale."""
        return omega_from_cov(self.V, self.wv.variance, self.problem.method)

    def quad(self, theta: np.ndarray, omega: np.ndarray | None = None) -> float:
        if omega is None:
            return self.problem.objective(theta)
        with np.errstate(all="ignore"):
            r = self.problem.target - self.problem.f(self.model.wv(theta, self.tau))
        return float(r @ omega @ r)

    def posterior_scale(self) -> float:
        """c such that ``Q_fit / c`` is on the chi-square scale: ``tr(Omega V_f) / J`` (1 for
        the efficient weights Omega = V_f^-1)."""
        return self.problem.chi2_scale(self.V)


def _setup(obj: Any, cov: np.ndarray | None = None) -> _Setup:
    """From a GMWMResult or a tuple ``(model, theta, wv, Omega[, V])``; ``cov`` (J, J) is a
    covariance of nu_hat (e.g. from a bootstrap) that replaces the fit's."""
    if isinstance(obj, GMWMResult):
        prob, theta = Problem.of(obj), np.asarray(obj.params, dtype=float)
        V = obj.wv_cov if cov is None else np.asarray(cov, dtype=float)
        if V is None:
            V = wv_cov("model", obj.model, theta, obj.wv)
    elif isinstance(obj, tuple) and len(obj) in (4, 5):
        model, theta, wv, omega = obj[:4]
        if not isinstance(model, Model) or not isinstance(wv, WaveletVariance):
            raise InputError("expected (Model, theta, WaveletVariance, Omega[, V])")
        theta = np.asarray(theta, dtype=float)
        omega = np.asarray(omega, dtype=float)
        J = wv.n_levels
        if theta.shape != (model.n_params,) or omega.shape != (J, J):
            raise InputError(f"theta must have {model.n_params} entries and Omega be {J}x{J}")
        prob = Problem(model, wv, omega)
        V = cov if cov is not None else (obj[4] if len(obj) == 5 else None)
        V = wv_cov("model", model, theta, wv) if V is None else np.asarray(V, dtype=float)
    else:
        raise InputError("identifiability checks need a GMWM/ARMAV fit result "
                         "or a tuple (model, theta, wv, Omega[, V])")
    if isinstance(obj, GMWMResult) and cov is None:
        C = np.asarray(obj.cov, dtype=float)
    else:
        with np.errstate(all="ignore"):
            C = prob.sandwich(theta, V)[0]
    return _Setup(prob, theta, V, C, prob.objective(theta))


def batch_wv(model: Model, theta: np.ndarray, scales: np.ndarray) -> np.ndarray:
    """Theoretical Haar WV for many parameter vectors at once: theta (N, p) -> (N, J)."""
    return model.wv_many(theta, scales)


# -- local ------------------------------------------------------------------------------------------
def _loadings(v: np.ndarray, names: list[str]) -> dict[str, float]:
    v = v / np.max(np.abs(v)) * np.sign(v[np.argmax(np.abs(v))]) * np.linalg.norm(v)
    big = np.argsort(-np.abs(v))
    return {names[i]: float(round(v[i], 3)) for i in big if abs(v[i]) >= LOADING_MIN}


def _fmt_direction(load: dict[str, float]) -> str:
    return " ".join(f"{c:+.2f} {n}" for n, c in load.items())


@dataclass
class LocalCheck:
    """Outcome of :func:`local_check`. Directions are unit vectors in free coordinates over
    ``active`` parameters; ``free_sd`` is the sandwich SD of each free coordinate."""

    param_names: list[str]
    active: list[str]
    singular_values: np.ndarray
    condition_number: float
    rank: int
    free_sd: np.ndarray
    null_directions: list[dict[str, Any]] = field(default_factory=list)
    weak_directions: list[dict[str, Any]] = field(default_factory=list)
    degeneracies: list[str] = field(default_factory=list)
    boundary: list[str] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.reasons

    def to_json_dict(self) -> dict[str, Any]:
        return {"ok": self.ok, "rank": self.rank, "n_active": len(self.active),
                "condition_number": _num(self.condition_number),
                "singular_values": [_num(s) for s in self.singular_values],
                "free_sd": dict(zip(self.param_names, [_num(s) for s in self.free_sd],
                                    strict=True)),
                "null_directions": self.null_directions, "weak_directions": self.weak_directions,
                "degeneracies": self.degeneracies, "boundary": self.boundary,
                "reasons": self.reasons}


def _num(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def local_check(result: GMWMResult | tuple, *, cov: np.ndarray | None = None) -> LocalCheck:
    """Rank, condition number and weak directions of the whitened WV Jacobian at the estimate.

    ``result`` is a :class:`GMWMResult` or ``(model, theta, wv, Omega[, V])``; ``cov`` optionally
    replaces the WV covariance behind the SEs (e.g. a bootstrap covariance). Thresholds:
    ``RANK_RTOL``, ``COND_MAX``, ``SD_FREE_MAX``, ``LOADING_MIN`` (module docstring).
    """
    s = _setup(result, cov)
    model, theta = s.model, s.theta
    names = model.param_names
    with np.errstate(all="ignore"):
        eta = model.to_free(theta)
        d = model.dtheta_deta(np.where(np.isfinite(eta), eta, 0.0))
    degen = degeneracies(model, theta, s.wv)
    boundary = [n for n, e, dd in zip(names, eta, d, strict=True)
                if not np.isfinite(e) or dd == 0]
    act = np.array([n not in boundary for n in names])
    reasons: list[str] = []
    if boundary:
        reasons.append("at the boundary of the parameter space (not locally identified): "
                       + ", ".join(boundary))
    free_sd = np.full(len(names), np.nan)
    with np.errstate(all="ignore"):
        C = s.cov / np.outer(d, d)
    free_sd[act] = np.sqrt(np.clip(np.diag(C)[act], 0, None))
    anames = [n for n, a in zip(names, act, strict=True) if a]
    sv = np.zeros(0)
    cond, rank = np.inf, 0
    null_dirs: list[dict[str, Any]] = []
    weak_dirs: list[dict[str, Any]] = []
    if act.any():
        A = free_jacobian(s.problem, theta, act)
        norms = np.linalg.norm(A, axis=0)
        if np.all(np.isfinite(A)) and np.all(norms > 0):
            _, sv, Vt = np.linalg.svd(A / norms, full_matrices=False)
            rank = int(np.sum(sv > RANK_RTOL * sv[0]))
            cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
            for k in range(sv.size):
                if sv[k] * COND_MAX < sv[0]:
                    load = _loadings(Vt[k], anames)
                    null_dirs.append({"singular_value": float(sv[k] / sv[0]), "loadings": load})
        else:
            bad = [n for n, ok in zip(anames, np.isfinite(norms) & (norms > 0), strict=True)
                   if not ok]
            null_dirs.append({"singular_value": 0.0, "loadings": dict.fromkeys(bad, 1.0)})
            reasons.append("the WV does not respond to " + ", ".join(bad))
        Ca = C[np.ix_(act, act)]
        if np.all(np.isfinite(Ca)):
            w, U = np.linalg.eigh((Ca + Ca.T) / 2)
            for k in np.argsort(-w):
                sdk = float(np.sqrt(max(w[k], 0.0)))
                if sdk > SD_FREE_MAX:
                    weak_dirs.append({"sd": sdk, "loadings": _loadings(U[:, k], anames)})
    if rank < len(anames):
        reasons.append(f"Jacobian of the WV is rank deficient (rank {rank} < {len(anames)})")
    elif cond > COND_MAX:
        reasons.append(f"Jacobian of the WV is ill-conditioned (condition number {cond:.3g} "
                       f"> {COND_MAX:g})")
    for nd in null_dirs:
        if nd["loadings"] and nd["singular_value"] > 0:
            reasons.append(", ".join(nd["loadings"]) + " cannot be told apart (near-null "
                           f"direction {_fmt_direction(nd['loadings'])})")
    for wd in weak_dirs:
        reasons.append(", ".join(wd["loadings"]) + f" weakly identified: SD {wd['sd']:.3g} in "
                       f"free coordinates along {_fmt_direction(wd['loadings'])}")
    reasons.extend(degen)
    return LocalCheck(names, anames, sv, cond, rank, free_sd, null_dirs, weak_dirs, degen,
                      boundary, reasons)


# -- global -----------------------------------------------------------------------------------------
@dataclass
class GlobalCheck:
    """Outcome of :func:`global_check`: ``optima`` are the distinct local optima found (best
    first), each with parameters, objective, ``delta`` (objective - best) and ``delta_chi2``
    (the same on the chi-square scale), and ``alternatives`` those near-equal to the best."""

    n_starts: int
    n_failed: int
    estimate_objective: float
    optima: list[dict[str, Any]]
    alternatives: list[dict[str, Any]]
    better_found: bool
    reasons: list[str] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def ok(self) -> bool:
        return not self.reasons

    def to_json_dict(self) -> dict[str, Any]:
        return {"ok": self.ok, "n_starts": self.n_starts, "n_failed": self.n_failed,
                "estimate_objective": self.estimate_objective, "optima": self.optima,
                "alternatives": self.alternatives, "better_found": self.better_found,
                "reasons": self.reasons, "seconds": self.seconds}


def _finite_free(model: Model, theta: np.ndarray, wv: WaveletVariance) -> np.ndarray:
    """Free coordinates of theta with boundary values moved just inside the domain."""
    th = theta.copy()
    for c in model.components:
        p = th[c.slice]
        if c.process.linear and p[0] == 0:
            col = c.process.wv(np.ones(1), wv.scales.astype(float), model.freq)
            p = np.asarray(c.process.from_vp(0.0, 1e-4 * np.min(wv.variance / col), model.freq))
        th[c.slice] = p
    with np.errstate(all="ignore"):
        eta = model.to_free(th)
    return np.clip(np.nan_to_num(eta, nan=0.0, posinf=30.0, neginf=-30.0), -30, 30)


def _random_start(model: Model, eta_hat: np.ndarray, wv: WaveletVariance,
                  rng: np.random.Generator, dispersed: bool) -> np.ndarray:
    """Perturbation of the estimate (dispersed=False) or a random draw of every shape parameter
    over the observed scales with perturbed scale parameters (dispersed=True)."""
    eta = eta_hat + rng.normal(0.0, 2.0, eta_hat.size)
    if not dispersed:
        return eta
    tau_max = float(wv.scales[-1])
    th = model.from_free(eta)
    for c in model.components:
        th[c.slice] = c.process.random_shape(th[c.slice], rng, tau_max, model.freq)
    return model.to_free(th)


def _optimise(s: _Setup, eta0: np.ndarray, center: np.ndarray) -> tuple[np.ndarray, float, bool]:
    sol = s.problem.solve(s.model.from_free(eta0), max_nfev=400, center=center)
    return s.model.canonical(sol.theta), sol.objective, sol.ok


def _describe(model: Model, best: np.ndarray, alt: np.ndarray, far: np.ndarray,
              wv: WaveletVariance) -> list[str]:
    """Name what differs between two near-equal optima."""
    comps = [c.name for c in model.components if np.any(far[c.slice])]
    kinds: list[str] = []
    groups: dict[str, list[Any]] = {}
    for c in model.components:
        if c.name in comps:
            groups.setdefault(c.process.name, []).append(c)
    for moved in groups.values():
        if len(moved) >= 2 and moved[0].process.swap_verb:
            kinds.append(f"{' and '.join(c.name for c in moved)} {moved[0].process.swap_verb}")
    before = set(degeneracies(model, best, wv))
    kinds += [d for d in degeneracies(model, alt, wv) if d not in before]
    if not kinds and comps:
        kinds.append("components that differ: " + ", ".join(comps))
    return kinds


def global_check(result: GMWMResult | tuple, *, n_starts: int = 16, seed: int = 0,
                 cov: np.ndarray | None = None) -> GlobalCheck:
    """Refine the fit's objective from ``n_starts`` dispersed starts (half large free-coordinate
    perturbations of the estimate, sd 2; half random shape parameters over the observed scales)
    and report distinct optima whose objective is near-equal to the best (criteria in the
    module docstring), naming the kind when recognisable."""
    t0 = time.perf_counter()
    s = _setup(result, cov)
    model, wv = s.model, s.wv
    rng = np.random.default_rng(seed)
    eta_hat = _finite_free(model, s.theta, wv)
    with np.errstate(all="ignore"):
        d = model.dtheta_deta(eta_hat)
        sd = np.sqrt(np.clip(np.diag(s.cov), 0, None)) / np.abs(d)
    thr = np.minimum(np.maximum(3 * np.nan_to_num(sd, nan=np.inf), 0.05), 1.0)
    runs: list[tuple[np.ndarray, float]] = []
    n_failed = 0
    for k in range(int(n_starts)):
        eta0 = _random_start(model, eta_hat, wv, rng, dispersed=bool(k % 2))
        try:
            th, obj, ok = _optimise(s, eta0, eta_hat)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError):
            ok = False
        if ok:
            runs.append((th, obj))
        else:
            n_failed += 1
    est_obj = s.quad(s.theta, s.omega)
    runs.append((s.theta.copy(), est_obj))
    runs.sort(key=lambda r: r[1])

    def free(th: np.ndarray) -> np.ndarray:
        return _finite_free(model, th, wv)

    optima: list[dict[str, Any]] = []
    kept: list[np.ndarray] = []
    best_th, best_obj = runs[0]
    best_chi = s.quad(best_th, s.omega_chi)
    for th, obj in runs:
        e = free(th)
        if any(np.all(np.abs(e - k) <= thr) for k in kept):
            continue
        kept.append(e)
        chi = s.quad(th, s.omega_chi)
        optima.append({"params": model.as_dict(th), "objective": obj,
                       "delta": obj - best_obj, "delta_chi2": chi - best_chi,
                       "is_estimate": bool(np.all(np.abs(e - free(s.theta)) <= thr))})
    alternatives = []
    for opt in optima[1:]:
        near = opt["delta_chi2"] < 1.0 or opt["delta"] < 0.01 * max(best_obj, 1e-300)
        if near:
            th = np.array([opt["params"][n] for n in model.param_names])
            far = np.abs(free(th) - free(best_th)) > thr
            opt["kind"] = _describe(model, best_th, th, far, wv)
            alternatives.append(opt)
    # judged on the objective alone: a lower objective is a better optimum wherever it lies
    better = bool(best_obj < est_obj - max(1e-6 * abs(est_obj), 1e-12))
    reasons = []
    if better:
        reasons.append(f"a better optimum exists (objective {best_obj:.6g} < {est_obj:.6g}): "
                       + ", ".join(f"{k}={v:.4g}" for k, v in optima[0]["params"].items()))
    groups: dict[str, list[dict[str, Any]]] = {}
    for alt in alternatives:
        groups.setdefault("; ".join(alt["kind"]) or "parameters far apart", []).append(alt)
    for kind, alts in groups.items():
        dmax = max(a["delta"] for a in alts)
        cmax = max(a["delta_chi2"] for a in alts)
        reasons.append(f"{len(alts)} distinct optim{'um' if len(alts) == 1 else 'a'} with "
                       f"near-equal objective (differences up to {dmax:.3g}, chi-square scale "
                       f"{cmax:.3g}): {kind}")
    return GlobalCheck(int(n_starts), n_failed, est_obj, optima, alternatives, better, reasons,
                       time.perf_counter() - t0)


# -- posterior --------------------------------------------------------------------------------------
@dataclass
class PosteriorCheck:
    """Outcome of :func:`posterior_check`. ``samples`` (n, p) are canonical parameter draws after
    burn-in and thinning; ``tau`` the integrated autocorrelation times (steps) per free coordinate."""

    param_names: list[str]
    samples: np.ndarray
    estimate: np.ndarray
    sandwich_se: np.ndarray
    laplace_se: np.ndarray
    tau: np.ndarray
    n_walkers: int
    n_steps: int
    burn: int
    thin: int
    tau_ok: bool
    acceptance: float
    map_params: np.ndarray
    unimodal: bool
    multimodal: list[str]
    seconds: float
    reasons: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.reasons

    @property
    def median(self) -> np.ndarray:
        return np.median(self.samples, axis=0)

    @property
    def sd(self) -> np.ndarray:
        return np.std(self.samples, axis=0, ddof=1)

    @property
    def centred(self) -> np.ndarray:
        """Per parameter: ``|median - estimate| < 1 posterior SD``."""
        return np.abs(self.median - self.estimate) < self.sd

    @property
    def sd_ratio(self) -> np.ndarray:
        """Posterior SD / its Laplace (Gaussian) approximation ``c (A' Omega A)^-1`` per
        parameter: about 1 when the objective is locally quadratic over the posterior's
        extent. With efficient weights the Laplace SE is the sandwich SE."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return self.sd / self.laplace_se

    def plot(self, truths: np.ndarray | None = None, fig=None):
        return corner_plot(self.samples, self.param_names, truths=truths, fig=fig)

    def to_json_dict(self) -> dict[str, Any]:
        names = self.param_names
        as_d = lambda v: dict(zip(names, [_num(x) for x in v], strict=True))
        return {"ok": self.ok, "n_walkers": self.n_walkers, "n_steps": self.n_steps,
                "burn": self.burn, "thin": self.thin, "n_samples": int(self.samples.shape[0]),
                "tau": as_d(self.tau), "tau_ok": self.tau_ok, "tau_factor": TAU_FACTOR,
                "acceptance": self.acceptance, "unimodal": self.unimodal,
                "multimodal": self.multimodal, "median": as_d(self.median), "sd": as_d(self.sd),
                "centred": dict(zip(names, self.centred.tolist(), strict=True)),
                "sd_ratio": as_d(self.sd_ratio), "map": as_d(self.map_params),
                "reasons": self.reasons, "seconds": self.seconds}


def _n_modes(x: np.ndarray, n_grid: int = 200) -> int:
    """Number of separated modes of a 1-D sample: KDE maxima above 10 % of the highest peak,
    separated from their neighbour by a valley below 70 % of the lower peak."""
    from scipy.stats import gaussian_kde

    lo, hi = np.quantile(x, [0.002, 0.998])
    if not hi > lo:
        return 1
    grid = np.linspace(lo, hi, n_grid)
    y = gaussian_kde(x)(grid)
    peaks = [i for i in range(1, n_grid - 1) if y[i] >= y[i - 1] and y[i] > y[i + 1]
             and y[i] > 0.1 * y.max()]
    modes = 1
    last = peaks[0] if peaks else None
    for i in peaks[1:]:
        valley = y[last:i + 1].min()
        if valley < 0.7 * min(y[last], y[i]):
            modes += 1
            last = i
        elif y[i] > y[last]:
            last = i
    return modes


def posterior_check(result: GMWMResult | tuple, *, n_walkers: int | None = None,
                    n_steps: int = 1000, max_steps: int = 10000, seed: int = 0,
                    cov: np.ndarray | None = None, box: float = 20.0,
                    progress: bool = False) -> PosteriorCheck:
    """emcee sample of the quasi-posterior ``exp(-Q(eta) / (2 c))`` of the estimator being
    checked: ``Q`` is the fit's own objective (its weight matrix Omega and method), so the
    posterior mode is the estimate, and ``c = tr(Omega V_f) / J`` puts it on the chi-square
    scale (c = 1 for the efficient weights; V the fit's covariance of nu_hat, or ``cov``).
    Flat prior on a box of half-width ``clip(box * SD_i, 2, box)`` around the estimate in free
    coordinates (``SD_i`` the sandwich SD of free coordinate i); a marginal with more than 1 %
    of its draws in the outer 2 % of the box is reported (the box then truncates it).

    Runs ``n_steps`` and extends by ``n_steps`` until the chain is longer than ``TAU_FACTOR = 50``
    integrated autocorrelation times (or ``max_steps``); burn-in ``2 tau_max``, thinning
    ``tau_max / 2``. Verdicts: unimodal (one KDE mode per parameter and along the two leading
    principal axes), centred (|median - estimate| < 1 posterior SD), spread (posterior SD /
    Laplace SE in [0.5, 2]), MAP within one posterior SD of the estimate.
    Parameters at the boundary 0 are held fixed.
    """
    import emcee

    t0 = time.perf_counter()
    s = _setup(result, cov)
    model, tau = s.model, s.tau
    names = model.param_names
    with np.errstate(all="ignore"):
        eta_raw = model.to_free(s.theta)
    act = np.isfinite(eta_raw)
    # components with a parameter at the boundary are held fixed (their WV is a constant)
    fixed_comps = [c for c in model.components if not np.all(act[c.slice])]
    for c in fixed_comps:
        act[c.slice] = False
    if not act.any():
        raise InputError("no interior parameter to sample")
    offset = np.zeros(tau.size)
    for c in fixed_comps:
        offset += np.nan_to_num(c.process.wv(s.theta[c.slice], tau, model.freq))
    eta_hat = eta_raw[act]
    ndim = int(act.sum())
    with np.errstate(all="ignore"):
        d = model.dtheta_deta(np.where(act, eta_raw, 0.0))
        sd = (np.sqrt(np.clip(np.diag(s.cov), 0, None)) / np.abs(d))[act]
    half = np.clip(box * np.nan_to_num(sd, nan=box, posinf=box), 2.0, box)
    lo, hi = eta_hat - half, eta_hat + half
    L = whitener(s.omega / s.posterior_scale())
    target = s.problem.target
    base = s.theta.copy()
    wv_of = lambda TH: model.wv_many(TH, tau)

    pos = np.cumsum(act) - 1  # column of each active parameter in the sampled vector
    blocks = [(c, np.arange(c.start, c.start + c.process.n_params))
              for c in model.components if c not in fixed_comps]

    def to_theta(E: np.ndarray) -> np.ndarray:
        TH = np.tile(base, (E.shape[0], 1))
        for c, cols in blocks:
            TH[:, cols] = c.process.from_free(E[:, pos[cols]].T).T
        return TH

    def log_prob(E: np.ndarray) -> np.ndarray:
        E = np.atleast_2d(E)
        inside = np.all((E > lo) & (E < hi), axis=1)
        out = np.full(E.shape[0], -np.inf)
        if inside.any():
            TH = to_theta(E[inside])
            with np.errstate(all="ignore"):
                nu = wv_of(_zero_fixed(TH, fixed_comps, model.freq)) + offset
                R = (target - s.problem.f(nu)) @ L
                q = np.einsum("ij,ij->i", R, R)
            out[inside] = np.where(np.isfinite(q), -0.5 * q, -np.inf)
        return out

    nw = int(n_walkers) if n_walkers else max(32, 4 * ndim)
    nw += nw % 2
    rng = np.random.default_rng(seed)
    spread = 0.1 * np.clip(np.nan_to_num(sd, nan=1.0, posinf=1.0), 1e-3, 1.0)
    p0 = eta_hat + spread * rng.standard_normal((nw, ndim))
    p0 = np.clip(p0, lo + 1e-9 * half, hi - 1e-9 * half)
    # differential-evolution moves mix faster than the default stretch move on these
    # near-Gaussian targets (shorter tau for the same number of evaluations)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)]
    sampler = emcee.EnsembleSampler(nw, ndim, log_prob, vectorize=True, moves=moves)
    # emcee draws from its own RandomState (numpy's global one by default): seed it
    sampler.random_state = np.random.RandomState(int(rng.integers(2**31))).get_state()
    state = sampler.run_mcmc(p0, min(n_steps, max_steps), progress=progress)
    while True:
        tau_int = sampler.get_autocorr_time(tol=0)
        needed = TAU_FACTOR * np.nanmax(tau_int)
        done = sampler.iteration > needed
        # stop when even the current (short-chain, optimistic) tau says max_steps will not do
        if done or needed >= max_steps or not np.isfinite(needed):
            break
        extra = int(min(max(1.2 * needed - sampler.iteration, n_steps / 2), max_steps
                        - sampler.iteration))
        state = sampler.run_mcmc(state, extra, progress=progress)
    tmax = float(np.nanmax(tau_int))
    burn = min(int(np.ceil(2 * tmax)), sampler.iteration // 2)
    thin = max(1, int(tmax / 2))
    chain = sampler.get_chain(discard=burn, thin=thin, flat=True)
    lp = sampler.get_log_prob(flat=True)
    best_eta = sampler.get_chain(flat=True)[int(np.argmax(lp))]
    at_edge = []
    for i, n in enumerate(np.array(names)[act]):
        w = 0.02 * (hi[i] - lo[i])
        frac = float(np.mean((chain[:, i] < lo[i] + w) | (chain[:, i] > hi[i] - w)))
        if frac > 0.01:
            at_edge.append(f"{n} ({frac:.0%} of draws)")
    samples = model.canonical_many(to_theta(chain))
    map_params = model.canonical(to_theta(best_eta[None, :])[0])
    # modes, in free coordinates of the canonical draws
    with np.errstate(all="ignore"):
        free = np.array([model.to_free(t) for t in samples[:: max(1, len(samples) // 4000)]])
    free = free[:, act]
    multimodal = [n for n, x in zip(np.array(names)[act], free.T, strict=True)
                  if np.ptp(x) > 0 and _n_modes(x) > 1]
    z = (free - free.mean(axis=0)) / np.where(free.std(axis=0) > 0, free.std(axis=0), 1.0)
    if ndim > 1:
        _, _, Vt = np.linalg.svd(z, full_matrices=False)
        for k in range(min(2, ndim)):
            if _n_modes(z @ Vt[k]) > 1:
                multimodal.append(f"principal axis {k + 1}")
    tau_full = np.full(len(names), np.nan)
    tau_full[act] = tau_int
    c_post = s.posterior_scale()
    F = f_jacobian(s.wv.variance, s.problem.method)
    with np.errstate(all="ignore"):
        lap = s.problem.sandwich(s.theta, c_post * np.linalg.pinv(s.omega, hermitian=True)
                                 / np.outer(F, F), ~act)[1]
    pc = PosteriorCheck(names, samples, s.theta.copy(), np.sqrt(np.clip(np.diag(s.cov), 0, None)),
                        lap, tau_full, nw, int(sampler.iteration), burn, thin, bool(done),
                        float(np.mean(sampler.acceptance_fraction)), map_params,
                        not multimodal, multimodal, 0.0)
    reasons = []
    if not pc.tau_ok:
        reasons.append(f"posterior chain too short: {pc.n_steps} steps <= {TAU_FACTOR} x tau "
                       f"({tmax:.3g}); increase max_steps")
    if multimodal:
        reasons.append("posterior is not unimodal along " + ", ".join(multimodal))
    fa = np.asarray(act)
    off = [n for n, c, a in zip(names, pc.centred, fa, strict=True) if a and not c]
    if off:
        reasons.append("posterior median more than 1 SD from the estimate for " + ", ".join(off))
    ratio = pc.sd_ratio
    bad = [f"{n} ({r:.2g})" for n, r, a in zip(names, ratio, fa, strict=True)
           if a and not 0.5 <= r <= 2]
    if bad:
        reasons.append("posterior SD / its Laplace approximation outside [0.5, 2] for "
                       + ", ".join(bad))
    far_map = [n for n, m, e, sdv, a in zip(names, map_params, s.theta, pc.sd, fa, strict=True)
               if a and abs(m - e) > sdv]
    if far_map:
        reasons.append("posterior mode more than 1 SD from the estimate for " + ", ".join(far_map))
    if at_edge:
        reasons.append("posterior piles up at the prior box edge (the box truncates it) for "
                       + ", ".join(at_edge))
    pc.reasons = reasons
    pc.seconds = time.perf_counter() - t0
    return pc


def _zero_fixed(TH: np.ndarray, fixed_comps: list, freq: float) -> np.ndarray:
    """Set the scale parameter of held-fixed components to zero (their WV is in the offset)."""
    if not fixed_comps:
        return TH
    TH = TH.copy()
    for c in fixed_comps:
        TH[:, c.slice] = c.process.off_params(freq)
    return TH


# -- corner plot ------------------------------------------------------------------------------------
def corner_plot(samples: np.ndarray, names: list[str], truths: np.ndarray | None = None,
                fig=None, bins: int = 30, log: Sequence[bool] | None = None):
    """Pairwise marginals of ``samples`` (n, p): histograms on the diagonal, 2-D histograms
    below it, optional ``truths`` (p,) as lines. ``log``: which parameters to show in log10
    coordinates (default: every parameter with positive draws except an AR1 phi, i.e. variances,
    amplitudes and frequencies, whose posteriors span decades). Labels use the papers' notation.
    Returns the matplotlib Figure."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    from gmwm.plots import param_label

    X = np.asarray(samples, dtype=float)
    if X.ndim != 2 or X.shape[1] != len(names):
        raise InputError(f"samples must be (n, {len(names)}), got {X.shape}")
    p = X.shape[1]
    if log is None:
        log = [not n.endswith(".phi") and bool(np.all(X[:, k] > 0)) for k, n in enumerate(names)]
    log = [bool(v) for v in log]
    X = X.copy()
    t = None if truths is None else np.asarray(truths, dtype=float).copy()
    for k in range(p):
        if log[k]:
            X[:, k] = np.log10(X[:, k])
            if t is not None:
                t[k] = np.log10(t[k]) if t[k] > 0 else np.nan
    labels = [f"log10 {param_label(n, names)}" if lg else param_label(n, names)
              for n, lg in zip(names, log, strict=True)]
    if fig is None:
        fig = plt.figure(figsize=(1.9 * p + 1, 1.9 * p + 1))
    axes = fig.subplots(p, p, squeeze=False)
    for i in range(p):
        for j in range(p):
            ax = axes[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            if i == j:
                ax.hist(X[:, i], bins=bins, color="0.35", histtype="stepfilled", alpha=0.8)
                ax.set_yticks([])
                if t is not None and np.isfinite(t[i]):
                    ax.axvline(t[i], color="C3", lw=1)
            else:
                ax.hist2d(X[:, j], X[:, i], bins=bins, cmap="Greys")
                if t is not None:
                    if np.isfinite(t[j]):
                        ax.axvline(t[j], color="C3", lw=0.8)
                    if np.isfinite(t[i]):
                        ax.axhline(t[i], color="C3", lw=0.8)
                ax.yaxis.set_major_locator(MaxNLocator(3))
            ax.xaxis.set_major_locator(MaxNLocator(3))
            if i == p - 1:
                ax.set_xlabel(labels[j], fontsize=8)
            else:
                ax.set_xticklabels([])
            if j == 0 and i > 0:
                ax.set_ylabel(labels[i], fontsize=8)
            elif j > 0:
                ax.set_yticklabels([])
            ax.tick_params(labelsize=6)
            for lab in ax.get_xticklabels():
                lab.set_rotation(45)
    fig.subplots_adjust(hspace=0.08, wspace=0.08)
    return fig


# -- combined ---------------------------------------------------------------------------------------
@dataclass
class IdentifiabilityReport:
    """Local + global (+ posterior) checks; ``status`` is 'pass' or 'warn' (with ``reasons``)."""

    model: str
    local: LocalCheck
    global_: GlobalCheck | None
    posterior: PosteriorCheck | None = None
    seconds: float = 0.0

    @property
    def reasons(self) -> list[str]:
        out = [f"local: {r}" for r in self.local.reasons]
        if self.global_ is not None:
            out += [f"global: {r}" for r in self.global_.reasons]
        if self.posterior is not None:
            out += [f"posterior: {r}" for r in self.posterior.reasons]
        return out

    @property
    def status(self) -> str:
        return "warn" if self.reasons else "pass"

    def summary(self) -> str:
        """Text for the CLI: status, the checks run, each reason on its own line."""
        loc = self.local
        parts = [f"identifiability ({self.model}): {self.status.upper()}",
                 (f"  local: rank {loc.rank}/{len(loc.active)}, condition number "
                 f"{loc.condition_number:.3g}")]
        if self.global_ is not None:
            g = self.global_
            parts.append(f"  global: {g.n_starts} starts, {len(g.optima)} distinct optima, "
                         f"{len(g.alternatives)} near-equal to the best")
        if self.posterior is not None:
            pc = self.posterior
            parts.append(f"  posterior: {pc.n_walkers} walkers x {pc.n_steps} steps, tau max "
                         f"{np.nanmax(pc.tau):.3g} ({'ok' if pc.tau_ok else 'too short'}), "
                         f"{'unimodal' if pc.unimodal else 'multimodal'}, SD/SE "
                         + ", ".join(f"{r:.2g}" for r in pc.sd_ratio))
        parts += [f"  - {r}" for r in self.reasons]
        return "\n".join(parts)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        return {"model": self.model, "status": self.status, "reasons": self.reasons,
                "local": self.local.to_json_dict(),
                "global": None if self.global_ is None else self.global_.to_json_dict(),
                "posterior": None if self.posterior is None else self.posterior.to_json_dict(),
                "seconds": self.seconds}


def check(result: GMWMResult, *, posterior: bool = False, seed: int = 0, n_starts: int = 12,
          cov: np.ndarray | None = None, **posterior_kwargs: Any) -> IdentifiabilityReport:
    """Local and global identifiability checks (plus the emcee posterior check when
    ``posterior``) of a GMWM/ARMAV fit; ``cov`` is an optional covariance of nu_hat (bootstrap)."""
    if not isinstance(result, GMWMResult):
        raise InputError("identifiability checks apply to GMWM/ARMAV fits "
                         f"(got {type(result).__name__})")
    t0 = time.perf_counter()
    loc = local_check(result, cov=cov)
    try:
        glob = global_check(result, n_starts=n_starts, seed=seed, cov=cov)
    except GMWMError:
        glob = None
    post = posterior_check(result, seed=seed, cov=cov, **posterior_kwargs) if posterior else None
    return IdentifiabilityReport(result.model.spec, loc, glob, post, time.perf_counter() - t0)
