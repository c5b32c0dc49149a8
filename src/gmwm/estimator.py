"""GMWM (and ARMAV, AVSM) estimation of composite error models from a signal or its wavelet
variance: :func:`fit` and its result, :class:`GMWMResult`.

:func:`fit` is the one boundary of estimation: it validates the settings once
(:class:`gmwm.settings.FitSettings`), computes the WV of a signal (:func:`gmwm.settings.prepare_wv`)
and dispatches on the method: GMWM and ARMAV minimise the objective of :mod:`gmwm.inference` by
the global search of :mod:`gmwm.search`; AVSM reads the Allan-variance slopes
(:mod:`gmwm.avsm`). Warnings use the thresholds of :mod:`gmwm.diagnostics`.

Standard errors use the sandwich of [Vibration] (``(A'WA)^-1 A'W V W A (A'WA)^-1``) with ``V`` the
covariance of the WV estimate under the fitted model (between-scale correlation included, SIN only
through its cross term with the noise; :func:`gmwm.inference.model_wv_cov`), or the caller's
covariance. ``weights="efficient"`` is the two-step efficient GMWM: a first fit with CI weights,
then ``Omega = V(theta_1)^-1``.

Every fit with that ``V`` carries the goodness-of-fit test of :mod:`gmwm.gof` (``result.gof``; a
rejected model is a warning) and its intervals stay inside the parameter space
(:func:`gmwm.intervals.fit_intervals`). Fits with ``se_cov="gaussian"`` (the model ranking's
candidates) skip the test, which would cost about as much as the fit; call
:func:`gmwm.gof.gof_test` on them when needed. ``estimate_only=True`` (the bootstrap's refits)
also skips the sandwich and the diagnostics: the same search and estimate, nothing else.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from . import diagnostics as dg
from .errors import IdentifiabilityError, InputError
from .inference import Problem, check_cov, omega_from_cov, weight_matrix, wv_cov
from .model import Model, as_model
from .results import check_alpha, freeze_arrays, json_safe
from .settings import N_STARTS, FitSettings, prepare_wv
from .wv import WaveletVariance

if TYPE_CHECKING:
    from .avsm import AVSMResult
    from .gof import GOFResult
    from .search import Search

__all__ = ["N_STARTS", "GMWMResult", "fit", "weight_matrix"]


# -- result ---------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class GMWMResult:
    """Outcome of a GMWM or ARMAV :func:`fit` (the result protocol of :mod:`gmwm.results`).
    ``params``/``se`` follow ``param_names`` (canonical order).

    ``weights`` is the weight matrix Omega the objective used, ``wv_cov`` the covariance V of
    the WV estimate behind ``cov``/``se``, and ``settings`` every option needed to repeat the
    fit (:class:`gmwm.settings.FitSettings`, the user covariance included). ``gof`` is the
    goodness-of-fit test (:class:`gmwm.gof.GOFResult`: ``statistic``, ``df``, ``p_value``,
    per-scale ``residuals``), None for a fit with ``se_cov="gaussian"``."""

    model: Model
    params: np.ndarray
    se: np.ndarray
    cov: np.ndarray
    objective: float
    weights: np.ndarray
    converged: bool
    message: str
    wv: WaveletVariance
    diagnostics: dict[str, Any] = field(default_factory=dict)
    seconds_wv: float = 0.0
    seconds_fit: float = 0.0
    wv_cov: np.ndarray | None = None
    settings: FitSettings = field(default_factory=FitSettings)
    gof: GOFResult | None = None

    def __post_init__(self) -> None:
        freeze_arrays(self, ("params", "se", "cov", "weights", "wv_cov"))
        if isinstance(self.settings, dict):  # a stored result (gmwm.codec)
            object.__setattr__(self, "settings", FitSettings.from_tree(self.settings))
        if isinstance(self.gof, dict):
            from .gof import GOFResult

            object.__setattr__(self, "gof", GOFResult.from_tree(self.gof))

    @property
    def method(self) -> str:
        return self.settings.method

    @property
    def param_names(self) -> list[str]:
        return self.model.param_names

    @property
    def warnings(self) -> list[str]:
        return list(self.diagnostics.get("warnings", []))

    def as_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.params)

    def se_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.se)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) intervals at level ``1 - alpha`` inside the parameter space
        (:func:`gmwm.intervals.fit_intervals`: Wald lower end, log-scale upper end for a scale
        parameter, reaching 0 when it is within ``z`` SE of 0; ``[0, z se_0]`` for a component at
        the boundary 0; shapes cut to their domain). See :mod:`gmwm.bootstrap` for others."""
        from .intervals import fit_intervals

        check_alpha(alpha)
        return fit_intervals(self, alpha)

    def datasheet(self, units: str | None = None, alpha: float = 0.05) -> dict[str, Any]:
        """Continuous datasheet coefficients (ARW/VRW, RRW, QN, RR, GM, SIN) in ``units``
        (see :func:`gmwm.datasheet.datasheet`)."""
        from .datasheet import datasheet

        return datasheet(self, units, alpha)

    def problem(self) -> Problem:
        """The objective this result minimised (:class:`gmwm.inference.Problem`)."""
        return Problem.of(self)

    def fit_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`fit` that repeat this fit on another WV (bootstrap)."""
        return self.settings.fit_kwargs()

    def with_drift_sign(self, sign: float | None) -> GMWMResult:
        """This fit with the sign of every drift (DR) set to ``sign`` (+1/-1, from the signal:
        its last sample against its first, as :func:`fit` takes it). A WV does not see the sign,
        so a fit of a WV has |omega| and a warning saying so; ``sign`` None: unchanged."""
        signed = [c for c in self.model.components if c.process.signed]
        if sign is None or not signed:
            return self
        params = np.array(self.params, dtype=float)
        for c in signed:
            params[c.slice] = sign * np.abs(params[c.slice])
        warnings = [w for w in self.diagnostics.get("warnings", []) if "drift sign" not in w]
        return dataclasses.replace(self, params=params,
                                   diagnostics=dict(self.diagnostics, warnings=warnings))

    def model_wv(self, scales: np.ndarray | None = None) -> np.ndarray:
        return self.model.wv(self.params, self.wv.scales if scales is None else scales)

    def component_wv(self, scales: np.ndarray | None = None) -> dict[str, np.ndarray]:
        return self.model.component_wv(self.params, self.wv.scales if scales is None else scales)

    def gof_line(self) -> str:
        """The goodness-of-fit line of the text outputs (:meth:`gmwm.gof.GOFResult.line`)."""
        if self.gof is None:
            return ("goodness of fit: not computed (se_cov='gaussian'); "
                    "gmwm.gof.gof_test(result) computes it")
        return self.gof.line()

    def summary(self) -> str:
        """Plain-text table of estimates, standard errors, 95 % intervals (:meth:`conf_int`),
        the goodness-of-fit line and the warnings."""
        ci = self.conf_int()
        lines = [(f"GMWM fit ({self.method}, {self.settings.weights_kind} weights) of "
                  f"{self.model.spec}  |  T = {self.wv.n_samples}, J = {self.wv.n_levels}, "
                  f"freq = {self.wv.freq:g} Hz"),
                 f"objective = {self.objective:.6g}   converged = {self.converged}"
                 + ("" if self.converged else f"   ({self.message})"),
                 self.gof_line(),
                 (f"{'parameter':<16}{'estimate':>14}{'std. error':>14}{'95% CI low':>14}"
                  f"{'95% CI high':>14}"),
                 "-" * 72]
        for name, est, se, (lo, hi) in zip(self.param_names, self.params, self.se, ci,
                                           strict=True):
            lines.append(f"{name:<16}{est:>14.6g}{se:>14.4g}{lo:>14.4g}{hi:>14.4g}")
        for w in self.warnings:
            lines.append(f"warning: {w}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-able summary (model, n, params, se, ci95 (name -> [low, high], :meth:`conf_int`),
        objective, gof (:meth:`gmwm.gof.GOFResult.to_json_dict`: statistic, df, p_value,
        rejected, per-scale residuals; None when not computed), converged, warnings, weights
        (their kind), settings, WV, timings); non-finite numbers are None."""
        ci = self.conf_int()
        return json_safe({
            "model": self.model.spec,
            "method": self.method,
            "n": int(self.wv.n_samples),
            "freq": self.wv.freq,
            "params": self.as_dict(),
            "se": self.se_dict(),
            "ci95": {n: [float(lo), float(hi)] for n, (lo, hi) in zip(self.param_names, ci,
                                                                       strict=True)},
            "objective": float(self.objective),
            "gof": None if self.gof is None else self.gof.to_json_dict(),
            "converged": bool(self.converged),
            "message": self.message,
            "warnings": self.warnings,
            "weights": self.settings.weights_kind,
            "settings": self.settings.to_json_dict(),
            "condition_number": self.diagnostics.get("condition_number"),
            "wv": self.wv.to_dict(),
            "seconds_wv": self.seconds_wv,
            "seconds_fit": self.seconds_fit,
        })

    def plot(self, ax=None, **kwargs):
        """Log-log WV with CI band, fitted model and its components (see gmwm.plots.plot_wv)."""
        from .plots import plot_wv

        return plot_wv(self.wv, result=self, ax=ax, **kwargs)


# -- main entry -----------------------------------------------------------------------------------
def fit(data: np.ndarray | WaveletVariance, model: str | Model, *,
        settings: FitSettings | None = None, freq: float | None = None,
        estimate_only: bool = False, gof: bool = True,
        **options: Any) -> GMWMResult | AVSMResult:
    """Estimate ``model`` from a signal or a precomputed wavelet variance.

    Parameters
    ----------
    data : 1-D signal (per-sample units) or a :class:`~gmwm.wv.WaveletVariance`.
    model : model string such as ``"WN+RW+AR1+SIN"`` or a :class:`~gmwm.model.Model`.
    settings : a :class:`~gmwm.settings.FitSettings` (default: the defaults).
    freq : sampling frequency [Hz] of a raw signal (GM parameters and scales in seconds use it).
    estimate_only : GMWM/ARMAV only: compute what the estimate needs and nothing else (the
        bootstrap's refits, :func:`gmwm.bootstrap.parametric_bootstrap`). ``params``,
        ``objective``, ``weights``, ``converged`` and ``message`` are those of the full fit
        (same search, same starts); ``se``/``cov`` are NaN and ``wv_cov`` None (no sandwich), no
        goodness-of-fit test, ``diagnostics`` holds only ``estimate_only``, ``at_boundary`` and
        the non-convergence warning, and a signal's WV carries the eta_3 interval unless the
        weights are ``"ci-mixture"`` (the WV values and the weights are unchanged).
    gof : run the goodness-of-fit test (:func:`gmwm.gof.gof_test`) on a fit with model-based
        standard errors (the default). ``False`` leaves ``result.gof`` None and everything else
        as it is: for callers that read no p-value, such as the Monte Carlo studies (a test on a
        weak sinusoid refits the model at its competing frequencies, several times a fit's cost).
    **options : fit options replacing those of ``settings``: ``method`` (``"gmwm"``: f(x) = x,
        ``"armav"``: f = log10 of the Allan variance, ``"avsm"``: the Allan-variance slope
        method), ``weights``, ``n_starts``, ``seed``, ``reweight``, ``nested``, ``se_cov``,
        ``max_nfev``, ``alpha``, ``levels``, ``robust``, ``eff``, ``min_edof``, ``slope_tol``
        (meaning and defaults: :class:`~gmwm.settings.FitSettings`).

    Returns
    -------
    :class:`GMWMResult` (GMWM, ARMAV) or :class:`gmwm.avsm.AVSMResult`, estimates in canonical
    component order, ``result.settings`` the settings used; ``diagnostics["warnings"]`` lists
    boundary estimates, weak identification and non-convergence.
    """
    settings = FitSettings.of(settings, **options)
    if estimate_only and settings.method == "avsm":
        raise InputError("estimate_only applies to GMWM and ARMAV fits, not to method 'avsm'")
    if freq is None and isinstance(model, Model):
        freq = model.freq
    if freq is None and isinstance(data, WaveletVariance):
        freq = data.freq
    # the mixture interval of a signal's WV is read only by "ci-mixture" weights; an
    # estimate-only fit skips it (the WV values, edof and eta_3 bounds are the same either way)
    ci = "eta3" if estimate_only and settings.weights_kind != "ci-mixture" else "mixture"
    wv, drift_sign, seconds_wv = prepare_wv(data, settings, freq=freq, ci=ci)
    model = as_model(model, wv.freq)
    settings = settings.replace(levels=wv.n_levels)
    if settings.method == "avsm":
        from .avsm import avsm_fit

        return avsm_fit(wv, model, settings, seconds_wv)
    return _fit_gmwm(wv, model, settings, drift_sign, seconds_wv, estimate_only, gof)


def _fit_gmwm(wv: WaveletVariance, model: Model, settings: FitSettings,
              drift_sign: float | None, seconds_wv: float,
              estimate_only: bool = False, gof: bool = True) -> GMWMResult:
    """GMWM or ARMAV: the search, the boundary components, the sandwich and the warnings
    (``estimate_only``: the search and the boundary components only; ``gof``: the test, see
    :func:`fit`)."""
    method = settings.method
    if model.n_params > wv.n_levels:
        raise IdentifiabilityError(
            f"model {model.spec} has {model.n_params} parameters but only {wv.n_levels} wavelet "
            "scales are available; use a longer signal, more levels or a smaller model")
    if np.any(wv.variance <= 0) or not np.all(np.isfinite(wv.variance)):
        raise InputError("wavelet variance must be positive and finite at every level "
                         "(constant signal?)")
    user_cov = settings.user_cov
    if user_cov is not None:
        user_cov = check_cov(user_cov, wv.n_levels)
    efficient = settings.weights_kind == "efficient"
    for c in model.components:
        # compiled kernels load before the clock starts, so that seconds_fit is the search's
        # time, as on every later fit
        c.process.load_kernels()
    # here, not at the top: a process that only unpickles a result (the report's calling
    # process) then does not import the search and scipy.optimize (~0.25 s)
    from .search import Search

    search = Search(settings.n_starts, settings.seed, 1.0 if drift_sign is None else drift_sign,
                    settings.max_nfev, settings.nested)
    t0 = time.perf_counter()
    with np.errstate(all="ignore"):
        omega = weight_matrix(wv, "ci" if efficient else settings.weights, method)
        prob = Problem(model, wv, omega, method)
        node = search.run(prob)
        for _ in range(0 if user_cov is not None or efficient else settings.reweight):
            omega = weight_matrix(wv, "gaussian", method, model_wv=model.wv(node.theta, prob.tau))
            prob = Problem(model, wv, omega, method)
            node = search.run(prob, extra_starts=[node.theta])
        if efficient:
            V1 = wv_cov("model", model, node.theta, wv)
            omega = omega_from_cov(V1, wv.variance, method)
            prob = Problem(model, wv, omega, method)
            node = search.run(prob, extra_starts=[node.theta])
    seconds_fit = time.perf_counter() - t0
    theta = np.array(node.theta, dtype=float)
    gone = prob.vanished(theta)
    vanished = [c.name for c in model.components if c.name in gone]
    fixed = np.zeros(model.n_params, bool)
    for c in model.components:
        if c.name in vanished:
            fixed[c.slice] = True
            theta[c.start + c.process.scale_index] = 0.0
    converged = node.converged and not node.edge
    message = node.message if not node.edge else (
        "parameter(s) at the edge of the search region: " + ", ".join(node.edge))
    if estimate_only:
        nan = np.full(model.n_params, np.nan)
        diagnostics = {"estimate_only": True, "at_boundary": vanished,
                       "warnings": [] if converged else
                       [f"the optimiser did not converge ({message})"]}
        return GMWMResult(model=model, params=theta, se=nan, cov=np.full((nan.size,) * 2, np.nan),
                          objective=node.objective, weights=omega, converged=converged,
                          message=message, wv=wv, diagnostics=diagnostics,
                          seconds_wv=seconds_wv, seconds_fit=seconds_fit, settings=settings)
    V = user_cov if user_cov is not None else wv_cov(settings.se_cov, model, theta, wv)
    cov, se, cond = prob.sandwich(theta, V, fixed)
    warnings = dg.fit_warnings(model, theta, se, cond, vanished, fixed, float(wv.scales[-1]),
                               sign_identified=drift_sign is not None)
    if settings.nested:
        note = _unsupported(prob, model, node.objective, V, vanished, search)
        if note:
            warnings.append(note)
    diagnostics = {"warnings": warnings, "condition_number": cond, "at_boundary": vanished,
                   "closed_form": bool(model.is_linear and method == "gmwm"),
                   "n_refined": node.n_refined, "from_submodel": node.from_submodel,
                   "n_models_searched": search.n_models_searched}
    if not converged:
        warnings.insert(0, f"the optimiser did not converge ({message})")
    res = GMWMResult(model=model, params=theta, se=se, cov=cov, objective=node.objective,
                     weights=omega, converged=converged, message=message, wv=wv,
                     diagnostics=diagnostics, seconds_wv=seconds_wv, seconds_fit=seconds_fit,
                     wv_cov=V, settings=settings)
    if not gof or (user_cov is None and settings.se_cov_kind == "gaussian"):
        return res  # the fast path (bootstrap refits, ranking): no test (module docstring)
    from .gof import gof_test

    g = gof_test(res)
    note = g.warning()
    if note is not None:
        diagnostics = dict(diagnostics, warnings=[*warnings, note])
    return dataclasses.replace(res, gof=g, diagnostics=diagnostics)


def _unsupported(prob: Problem, model: Model, objective: float, V: np.ndarray,
                 vanished: list[str], search: Search) -> str | None:
    """The warning for components whose removal raises the objective by less than
    :data:`gmwm.diagnostics.UNSUPPORTED_PER_PARAM` per parameter on the chi-square scale (the
    objective divided by ``c = tr(Omega V_f) / J``). The drop-one submodels were fitted by the
    nested search."""
    c = prob.chi2_scale(V)
    if not np.isfinite(c) or c <= 0:
        return None
    drops = [(k, (sub.objective - objective) / c) for k, sub in search.drop_one(model)
             if not any(v.startswith(model.components[k].process.name) for v in vanished)]
    return dg.unsupported_warning(model, drops)
