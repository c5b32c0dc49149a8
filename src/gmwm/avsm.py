"""Automated Allan-variance slope method (AVSM, docs/METHODS.md §9.2), the classical baseline for GMWM.

Rule (applied to a Haar wavelet variance; no tuning beyond these constants):

1. Allan deviation from the WV: ``AD_j = sqrt(2 nu_j)`` at cluster time ``tau_j = 2^{j-1} / f_s`` [s]
   (AV at cluster m = 2^{j-1} equals 2 nu_j). Keep levels with ``eta_j = max(M_j / 2^j, 1) >= 2``
   (``min_edof``) and ``nu_j > 0``.
2. Local log-log slopes between consecutive kept levels,
   ``d_i = (log10 AD_{i+1} - log10 AD_i) / (log10 tau_{i+1} - log10 tau_i)``.
3. For each model term with its AD slope ``s`` (QN -1, WN -1/2, BI 0, RW +1/2, DR +1): the region is
   every level adjacent to a local slope with ``|d_i - s| <= 0.1`` (``slope_tol``). With at least two
   such levels the intercept is the fixed-slope fit ``b = mean(log10 AD - s log10 tau)`` over the
   region; otherwise the tangent (lower envelope) ``b = min_j (log10 AD_j - s log10 tau_j)`` over all
   kept levels.
4. Read the continuous coefficient off the line ``log10 AD = b + s log10 tau`` at the docs/METHODS.md §10 points:
   Q at tau = sqrt(3) s, N at 1 s, K at 3 s, R at sqrt(2) s; B = 10^b / 0.6643 (flat floor).
5. Convert to discrete per-sample parameters (gmwm.units): Q2 = (Q f_s)^2, sigma2 = N^2 f_s,
   gamma2 = K^2 / f_s, omega = R / f_s (the WV only sees omega^2: the sign is not identified and
   omega >= 0 is returned).

Known bias (docs/METHODS.md §9.2; 40 replicates, T = 2.5e6, STIM-300, relative bias / SD in Table I units):
gyro N +0.4 % / 1.2 %, K +17 % / 28 %; accel N +0.7 %, K +3.7 % / 8 %, R +91 % / 53 %, Q about x16
(no slope -1 region exists, so Q is read from WN-dominated scales). With eta_j >= 4 or 8 the gyro K
bias grows to +71 % because the RW region is cut off. Noise-free theoretical WV (measured here,
J = floor(log2 T) - 1): gyro T = 2.5e6: N +0.5 %, K +22 % (no kept level reaches slope 0.4, so K
comes from the tangent); T = 6.3e6: N +0.5 %, K +3.7 %. Accel T = 2.5e6: Q x16, N +0.6 %, K +4.9 %,
R +88 % (QN and DR by the tangent). AVSM is inconsistent by construction: each term is read where
it is assumed to dominate, ignoring the other terms there.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from math import sqrt
from typing import Any

import numpy as np

from gmwm import units
from gmwm.errors import InputError, ModelError
from gmwm.results import freeze_arrays, json_safe, readonly, wald_ci
from gmwm.settings import FitSettings

#: AD slope of each supported term on log-log axes.
SLOPES = {"QN": -1.0, "WN": -0.5, "BI": 0.0, "RW": 0.5, "DR": 1.0}
#: Cluster time [s] at which the AD line equals the continuous coefficient (BI: flat, any tau).
READ_TAU_S = {"QN": sqrt(3.0), "WN": 1.0, "BI": 1.0, "RW": 3.0, "DR": sqrt(2.0)}


@dataclass(frozen=True)
class SlopeRegion:
    """How one term was read: the levels used, the AD line and the continuous coefficient.

    ``intercept`` b is in log10(AD [u]) at tau = 1 s; ``coefficient`` is Q [u s], N [u sqrt(s)],
    B [u], K [u/sqrt(s)] or R [u/s]; ``method`` is 'fixed-slope' or 'tangent'.
    """

    component: str
    slope: float
    levels: np.ndarray
    intercept: float
    method: str
    read_tau_s: float
    coefficient: float

    def adev(self, tau_s) -> np.ndarray:
        """The fitted AD line [u] at cluster times ``tau_s`` [s]."""
        return 10.0 ** (self.intercept + self.slope * np.log10(np.asarray(tau_s, dtype=float)))


@dataclass(frozen=True, eq=False)
class AVSMResult:
    """AVSM estimate (the result protocol of :mod:`gmwm.results`): discrete parameters in the
    model's order plus the regions used per term. AVSM has no standard errors: ``se`` and
    ``conf_int`` are NaN."""

    params: np.ndarray
    param_names: list[str]
    model: object
    wv: object
    regions: dict[str, SlopeRegion]
    levels: np.ndarray       # WV levels kept (eta_j >= min_edof, nu_j > 0)
    tau_s: np.ndarray        # their cluster times [s]
    adev: np.ndarray         # their empirical AD [u]
    converged: bool
    message: str
    settings: FitSettings = field(default_factory=lambda: FitSettings(method="avsm"))
    seconds_wv: float = 0.0
    seconds_fit: float = 0.0

    def __post_init__(self) -> None:
        freeze_arrays(self, ("params", "tau_s", "adev"))
        freeze_arrays(self, ("levels",), dtype=int)
        object.__setattr__(self, "param_names", list(self.param_names))

    @property
    def method(self) -> str:
        return "avsm"

    @property
    def objective(self) -> float:
        """NaN: the AVSM reads slopes, it minimises no objective (JSON: null)."""
        return float("nan")

    @property
    def se(self) -> np.ndarray:
        """No standard errors: NaN per parameter."""
        return readonly(np.full(len(self.param_names), np.nan))

    @property
    def warnings(self) -> list[str]:
        return []

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """No intervals: (p, 2) NaN."""
        return wald_ci(self.params, self.se, alpha)

    def as_dict(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.param_names, self.params, strict=True)}

    def fit_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`gmwm.fit` that repeat this fit."""
        return self.settings.fit_kwargs()

    def model_wv(self, scales=None) -> np.ndarray:
        """Theoretical WV of the estimated model at ``scales`` (default: the input's scales)."""
        scales = self.wv.scales if scales is None else np.asarray(scales, dtype=float)
        return self.model.wv(self.params, scales)

    def component_wv(self, scales=None) -> dict[str, np.ndarray]:
        scales = self.wv.scales if scales is None else np.asarray(scales, dtype=float)
        return self.model.component_wv(self.params, scales)

    def _spec(self) -> str:
        return str(getattr(self.model, "spec", "+".join(self.regions)))

    def summary(self) -> str:
        """Plain-text table: each parameter with the AD slope, levels and reading of its term."""
        head = (f"AVSM fit of {self._spec()}  |  T = {self.wv.n_samples}, "
                f"J = {len(self.wv.scales)}, freq = {float(getattr(self.wv, 'freq', 1.0)):g} Hz")
        lines = [head, f"converged = {self.converged}   ({self.message})",
                 f"{'parameter':<16}{'estimate':>14}{'slope':>7}  {'read by':<12}levels",
                 "-" * 60]
        for name, est in zip(self.param_names, self.params, strict=True):
            r = self.regions.get(name.split(".", 1)[0])
            how = "" if r is None else (f"{r.slope:>7.2g}  {r.method:<12}"
                                        + ",".join(str(int(v)) for v in r.levels))
            lines.append(f"{name:<16}{est:>14.6g}{how}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-able summary (model, n, params, se (None), objective and weights (None: AVSM
        minimises nothing), converged, regions, settings, WV, timings), with the keys of
        :meth:`gmwm.estimator.GMWMResult.to_json_dict` where they apply."""
        wv = self.wv
        return json_safe({
            "model": self._spec(), "method": "avsm", "n": int(wv.n_samples),
            "freq": float(getattr(wv, "freq", 1.0)), "params": self.as_dict(),
            "se": dict.fromkeys(self.param_names), "objective": None, "weights": None,
            "converged": bool(self.converged),
            "message": self.message, "warnings": self.warnings,
            "settings": self.settings.to_json_dict(),
            "regions": {c: {"slope": r.slope, "levels": r.levels, "intercept": r.intercept,
                            "method": r.method, "read_tau_s": r.read_tau_s,
                            "coefficient": r.coefficient} for c, r in self.regions.items()},
            "wv": wv.to_dict() if hasattr(wv, "to_dict") else None,
            "seconds_wv": self.seconds_wv, "seconds_fit": self.seconds_fit})


def _component_types(model) -> list[tuple[str, str, str]]:
    """(component name, type, parameter name) per parameter; AVSM terms have one parameter each."""
    out = []
    for pname in model.param_names:
        comp = pname.split(".", 1)[0]
        ctype = comp.split("[", 1)[0]
        if ctype not in SLOPES:
            raise ModelError(f"AVSM cannot estimate {comp} (only QN, WN, BI, RW, DR have an AD slope)")
        out.append((comp, ctype, pname))
    return out


def _resolve_model(model, freq: float):
    if isinstance(model, str):
        from gmwm.model import Model  # local import: model.py is optional for stand-in objects

        return Model(model, freq=freq)
    if not hasattr(model, "param_names"):
        raise ModelError(f"expected a model string or Model, got {type(model).__name__}")
    return model


def usable_levels(wv, min_edof: float = 2.0) -> np.ndarray:
    """Boolean mask of levels with eta_j = max(M_j / 2^j, 1) >= ``min_edof`` and nu_j > 0."""
    scales = np.asarray(wv.scales, dtype=float)
    edof = np.maximum(np.asarray(wv.n, dtype=float) / scales, 1.0)
    var = np.asarray(wv.variance, dtype=float)
    return (edof >= min_edof) & np.isfinite(var) & (var > 0)


def slope_region(log_tau: np.ndarray, log_ad: np.ndarray, slope: float,
                 slope_tol: float = 0.1) -> tuple[np.ndarray, float, str]:
    """Indices used, intercept b and method for one term's AD slope (rule steps 2-3)."""
    d = np.diff(log_ad) / np.diff(log_tau)
    seg = np.flatnonzero(np.abs(d - slope) <= slope_tol)
    idx = np.union1d(seg, seg + 1)
    resid = log_ad - slope * log_tau
    if idx.size >= 2:
        return idx, float(np.mean(resid[idx])), "fixed-slope"
    k = int(np.argmin(resid))
    return np.array([k]), float(resid[k]), "tangent"


def _coefficient_to_param(ctype: str, pname: str, coef: float, freq: float) -> float:
    if ctype == "QN":
        return float(units.qn_q2_from_coefficient(coef, freq))
    if ctype == "WN":
        return float(units.wn_from_density(coef, freq))
    if ctype == "RW":
        return float(units.rw_gamma2_from_coefficient(coef, freq))
    if ctype == "DR":
        return float(units.dr_omega_from_coefficient(coef, freq))
    # BI: parameter named like 'BI[1].B2' (variance-type) or 'BI[1].B'
    return float(coef * coef) if pname.endswith("2") else float(coef)


def fit_avsm(wv, model, *, min_edof: float = 2.0, slope_tol: float = 0.1) -> AVSMResult:
    """Estimate a model made of QN, WN, BI, RW, DR terms by the AV slope method (module docstring).

    Parameters
    ----------
    wv : WaveletVariance (needs ``scales`` = 2^j samples, ``variance``, ``n`` = M_j, ``freq`` Hz).
    model : model string (e.g. ``"WN+RW"``) or Model; parameters named as in docs/API.md.
    min_edof : keep levels with eta_j >= min_edof (docs/METHODS.md §9.2: 2).
    slope_tol : half-width of the slope window defining a term's region (docs/METHODS.md §9.2: 0.1).

    Returns
    -------
    AVSMResult with ``params`` in the model's parameter order (discrete, per sample).
    ``converged`` is False when a parameter is not finite; ``message`` names the terms read by the
    tangent fallback. ``gmwm.fit(x, model, method="avsm")`` is the same estimator from a signal
    or a WV.
    """
    settings = FitSettings(method="avsm", min_edof=min_edof, slope_tol=slope_tol)
    return avsm_fit(wv, model, settings)


def avsm_fit(wv, model, settings: FitSettings, seconds_wv: float = 0.0) -> AVSMResult:
    """:func:`fit_avsm` with validated ``settings`` (``min_edof``, ``slope_tol``); what
    :func:`gmwm.fit` calls for ``method="avsm"``."""
    t0 = time.perf_counter()
    min_edof, slope_tol = settings.min_edof, settings.slope_tol
    freq = float(getattr(wv, "freq", 1.0))
    model = _resolve_model(model, freq)
    terms = _component_types(model)
    keep = usable_levels(wv, min_edof)
    if keep.sum() < 2:
        raise InputError(f"AVSM needs at least 2 levels with eta_j >= {min_edof:g} and positive "
                         f"WV, got {int(keep.sum())}")
    levels = np.asarray(getattr(wv, "levels", np.log2(wv.scales).round()), dtype=int)[keep]
    tau_s = np.asarray(wv.scales, dtype=float)[keep] / (2.0 * freq)
    adev = np.sqrt(2.0 * np.asarray(wv.variance, dtype=float)[keep])
    log_tau, log_ad = np.log10(tau_s), np.log10(adev)

    params = np.empty(len(terms))
    regions: dict[str, SlopeRegion] = {}
    fallback = []
    for i, (comp, ctype, pname) in enumerate(terms):
        slope = SLOPES[ctype]
        idx, b, method = slope_region(log_tau, log_ad, slope, slope_tol)
        tau_read = READ_TAU_S[ctype]
        coef = 10.0 ** (b + slope * np.log10(tau_read))
        if ctype == "BI":
            coef /= units.BI_AD_FACTOR
        params[i] = _coefficient_to_param(ctype, pname, coef, freq)
        regions[comp] = SlopeRegion(comp, slope, readonly(levels[idx], int), b, method, tau_read,
                                    float(coef))
        if method == "tangent":
            fallback.append(comp)

    converged = bool(np.all(np.isfinite(params)))
    parts = [] if converged else ["non-finite estimate"]
    if fallback:
        parts.append("tangent fallback (no slope region) for " + ", ".join(fallback))
    return AVSMResult(params=params, param_names=list(model.param_names), model=model, wv=wv,
                      regions=regions, levels=levels, tau_s=tau_s, adev=adev,
                      converged=converged, message="; ".join(parts) or "ok", settings=settings,
                      seconds_wv=seconds_wv, seconds_fit=time.perf_counter() - t0)
