"""The statistics of a fleet: from each unit's estimate of a coefficient (value and 95 % interval)
to the fleet's typical value, the spread between units, out-of-family units and drift over time.

Conventions. Every coefficient here is a scale parameter (a noise density, a random-walk density,
a bias instability): positive, with intervals that are roughly symmetric on the log scale. So the
fleet is modelled on the natural log of the value: unit ``i`` reports ``y_i = log(value_i)`` with
standard error ``s_i = (log hi_i - log lo_i) / (2 z)`` (``z`` = 1.96 for a 95 % interval) and

    y_i = mu + u_i + e_i,    u_i ~ N(0, tau^2)  (between units),    e_i ~ N(0, s_i^2)  (within)

(a random-effects meta-analysis). ``exp(mu)`` is the fleet's typical (geometric-mean) value and
``tau`` the between-unit spread on the log scale: units typically differ by a factor
``exp(tau)``, separated from each unit's own estimation error, so short noisy recordings do not
inflate it. ``mu`` and ``tau^2`` come from :func:`statsmodels.stats.meta_analysis.combine_effects`
(Paule-Mandel by default, or DerSimonian-Laird); mu's interval is the modified Hartung-Knapp one
(:class:`RandomEffects`); tau's interval is the Q-profile interval
(:func:`q_profile_tau2`, written here: statsmodels has none); the 95 % prediction interval for a
new unit is ``mu +- t_{k-2} sqrt(tau^2 + se(mu)^2)`` (Higgins, Thompson & Spiegelhalter 2009).

A unit whose term is at the boundary 0, not distinguishable from 0, not identifiable at the length
used, or without a positive interval, has no log-scale standard error: it is left out of the fit
and listed with its reason (:attr:`Estimate.excluded`).

Out of family: a unit whose own 95 % interval lies entirely outside the fleet's 95 % prediction
interval. For fleets of at most :data:`LOO_MAX_UNITS` units the prediction interval a unit is
judged against is computed without that unit (leave-one-out), so one far unit cannot widen the
band that should catch it; larger fleets use the whole fleet's band (one unit barely moves it).

Drift: per unit with recordings on at least two dates, the weighted least-squares line of
``log(value)`` on the date (weights ``1 / s_i^2``), slope per year with a 95 % interval; with
three or more dates the slope's variance is inflated by the residual scatter when it exceeds the
stated errors (``max(1, chi2 / (n - 2))``). A drift whose interval excludes 0 is flagged.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from statistics import NormalDist
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = [
    "LOO_MAX_UNITS",
    "MIN_UNITS",
    "CoefficientSummary",
    "Drift",
    "Estimate",
    "Fleet",
    "RandomEffects",
    "UnitVerdict",
    "compare_units",
    "fit_drift",
    "fleet_table",
    "log_se",
    "prediction_interval",
    "q_profile_tau2",
    "random_effects",
]

#: fewest units with a usable estimate for a fleet estimate of a coefficient (the prediction
#: interval needs k - 2 >= 1 degrees of freedom)
MIN_UNITS = 3
#: largest fleet for which out-of-family is judged against a leave-one-out prediction interval
LOO_MAX_UNITS = 500
_DAYS_PER_YEAR = 365.25


def _z(alpha: float) -> float:
    return NormalDist().inv_cdf(1.0 - alpha / 2.0)


def log_se(ci: Sequence[float] | None, alpha: float = 0.05) -> float | None:
    """Standard error of ``log(value)`` from a ``1 - alpha`` interval ``(lo, hi)``:
    ``(log hi - log lo) / (2 z)``; None unless ``0 < lo < hi`` (finite)."""
    if ci is None or len(ci) != 2:
        return None
    lo, hi = float(ci[0]), float(ci[1])
    if not (math.isfinite(lo) and math.isfinite(hi) and 0.0 < lo < hi):
        return None
    return (math.log(hi) - math.log(lo)) / (2.0 * _z(alpha))


# --------------------------------------------------------------------------------------------------
# one unit's estimate
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Estimate:
    """One recording's estimate of one coefficient of one unit (IMU).

    ``coefficient``: the fleet's key, ``"<axis>.<quantity>"`` (e.g. ``"gx.noise_density"``);
    ``value`` and ``ci95`` in ``value_unit``; ``excluded``: why the value does not enter the fleet
    fit (None: it does); ``datasheet``: this recording's datasheet verdict for the term
    (:data:`gmwm.sensor_datasheet.VERDICT_RULE`), ``datasheet_value`` the datasheet's number in
    ``value_unit``."""

    unit: str
    recording: str
    coefficient: str
    value: float | None
    ci95: tuple[float, float] | None
    value_unit: str = ""
    sensor: str = ""
    date: _dt.date | None = None
    excluded: str | None = None
    datasheet: str | None = None
    datasheet_value: float | None = None

    @property
    def log_value(self) -> float | None:
        return None if self.value is None or not self.value > 0 else math.log(self.value)

    @property
    def usable(self) -> bool:
        """Enters the fleet fit: a positive value with a positive interval, not excluded."""
        return self.excluded is None and self.log_value is not None and log_se(self.ci95) is not None

    def why_not(self) -> str:
        """Why the estimate is left out of the fleet fit ('' if it is not)."""
        if self.excluded:
            return self.excluded
        if self.value is None:
            return "no estimate"
        if not self.value > 0:
            return "estimate at 0"
        if log_se(self.ci95) is None:
            return "no positive 95 % interval"
        return ""


# --------------------------------------------------------------------------------------------------
# the random-effects model
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RandomEffects:
    """A random-effects fit on the log scale (module docstring): ``mu`` with its standard error
    and ``1 - alpha`` interval (modified Hartung-Knapp: ``t_{k-1}`` times the larger of the
    Hartung-Knapp and the plain random-effects standard errors), ``tau2`` (between-unit variance) with its Q-profile interval,
    Cochran's ``q`` and ``i2``, the ``k`` units used, the estimator ``method`` ("pm" or "dl")."""

    mu: float
    se_mu: float
    ci_mu: tuple[float, float]
    tau2: float
    ci_tau2: tuple[float, float]
    q: float
    i2: float
    k: int
    method: str
    alpha: float = 0.05

    @property
    def tau(self) -> float:
        return math.sqrt(self.tau2)

    @property
    def ci_tau(self) -> tuple[float, float]:
        return (math.sqrt(self.ci_tau2[0]), math.sqrt(self.ci_tau2[1]))

    @property
    def pi(self) -> tuple[float, float] | None:
        """The ``1 - alpha`` prediction interval of a new unit's log value (None for k < 3)."""
        return prediction_interval(self)


def _generalised_q(y: np.ndarray, v: np.ndarray, tau2: float) -> float:
    w = 1.0 / (v + tau2)
    mu = float(np.sum(w * y) / np.sum(w))
    return float(np.sum(w * (y - mu) ** 2))


def q_profile_tau2(y: Sequence[float], v: Sequence[float], alpha: float = 0.05
                   ) -> tuple[float, float]:
    """The Q-profile ``1 - alpha`` interval of the between-unit variance tau^2 (Viechtbauer 2007):
    the tau^2 at which the generalised Q statistic ``sum (y_i - mu(tau^2))^2 / (v_i + tau^2)``
    equals the upper and lower ``alpha/2`` quantiles of chi^2 with ``k - 1`` degrees of freedom
    (an end is 0 where Q(0) is already below its quantile). ``v``: within-unit variances."""
    from scipy.optimize import brentq
    from scipy.stats import chi2

    y, v = np.asarray(y, float), np.asarray(v, float)
    k = y.size
    if k < 2:
        raise InputError("the spread between units needs at least two units")
    q0 = _generalised_q(y, v, 0.0)

    def solve(target: float) -> float:
        if q0 <= target:
            return 0.0
        hi = max(float(np.var(y)), float(np.max(v)), 1e-12)
        while _generalised_q(y, v, hi) > target:  # Q decreases to 0 as tau^2 grows
            hi *= 4.0
            if hi > 1e12:
                return math.inf
        return float(brentq(lambda t: _generalised_q(y, v, t) - target, 0.0, hi, xtol=1e-14,
                            rtol=1e-10))

    return (solve(float(chi2.ppf(1.0 - alpha / 2.0, k - 1))),
            solve(float(chi2.ppf(alpha / 2.0, k - 1))))


def random_effects(y: Sequence[float], v: Sequence[float], method: str = "pm",
                   alpha: float = 0.05) -> RandomEffects:
    """Random-effects fit of log values ``y`` with within-unit variances ``v`` (module
    docstring). ``method``: "pm" (Paule-Mandel) or "dl" (DerSimonian-Laird)."""
    from statsmodels.stats.meta_analysis import combine_effects

    if method not in ("pm", "dl"):
        raise InputError(f"random-effects method {method!r}: use 'pm' or 'dl'")
    y, v = np.asarray(y, float), np.asarray(v, float)
    if y.size < 2:
        raise InputError("a random-effects fit needs at least two units")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(v)) and np.all(v > 0)):
        raise InputError("a random-effects fit needs finite log values and positive variances")
    from scipy.stats import t

    res = combine_effects(y, v, method_re=method, alpha=alpha, use_t=False)
    mu, se = float(res.mean_effect_re), float(res.sd_eff_w_re)
    q = float(res.q)
    k = int(y.size)
    i2 = max(0.0, (q - (k - 1)) / q) if q > 0 else 0.0
    # mu's interval: Hartung-Knapp-Sidik-Jonkman with t_{k-1}, never narrower than the plain
    # random-effects SE (the normal interval undercovers badly for few units; benchmarks)
    half = float(t.ppf(1.0 - alpha / 2.0, k - 1)) * max(se, float(res.sd_eff_w_re_hksj))
    return RandomEffects(mu, se, (mu - half, mu + half), float(res.tau2),
                         q_profile_tau2(y, v, alpha), q, i2, k, method, alpha)


def prediction_interval(re: RandomEffects) -> tuple[float, float] | None:
    """``mu +- t_{k-2, 1-alpha/2} sqrt(tau^2 + se(mu)^2)``: where a new unit's log value is
    expected; None for fewer than 3 units."""
    from scipy.stats import t

    if re.k < 3:
        return None
    half = float(t.ppf(1.0 - re.alpha / 2.0, re.k - 2)) * math.sqrt(re.tau2 + re.se_mu ** 2)
    return (re.mu - half, re.mu + half)


# --------------------------------------------------------------------------------------------------
# drift
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Drift:
    """The drift of one unit's coefficient: slope of ``log(value)`` per year with its ``1 -
    alpha`` interval, from ``n`` dated recordings between ``first`` and ``last``; ``intercept``
    the fitted log value at ``first``. ``percent_per_year``: ``100 (exp(slope) - 1)``."""

    unit: str
    coefficient: str
    slope: float
    ci: tuple[float, float]
    n: int
    first: _dt.date
    last: _dt.date
    intercept: float
    points: tuple[tuple[str, float, float, float], ...] = ()  # (date, value, lo, hi)

    @property
    def flagged(self) -> bool:
        return self.ci[0] > 0.0 or self.ci[1] < 0.0

    @property
    def percent_per_year(self) -> tuple[float, float, float]:
        f = [100.0 * math.expm1(s) for s in (self.slope, *self.ci)]
        return (f[0], f[1], f[2])


def fit_drift(dates: Sequence[_dt.date], y: Sequence[float], se: Sequence[float],
              alpha: float = 0.05) -> tuple[float, tuple[float, float], float]:
    """Weighted least squares of log values ``y`` (standard errors ``se``) on ``dates``:
    ``(slope per year, its 1 - alpha interval, intercept at the first date)``. Needs two distinct
    dates; with three or more points the slope's variance is inflated by the residual scatter
    beyond the stated errors."""
    t = np.array([(d - min(dates)).days / _DAYS_PER_YEAR for d in dates], float)
    y, se = np.asarray(y, float), np.asarray(se, float)
    if np.ptp(t) <= 0:
        raise InputError("a drift needs recordings on at least two dates")
    w = 1.0 / se ** 2
    tbar = float(np.sum(w * t) / np.sum(w))
    ybar = float(np.sum(w * y) / np.sum(w))
    sxx = float(np.sum(w * (t - tbar) ** 2))
    slope = float(np.sum(w * (t - tbar) * (y - ybar)) / sxx)
    var = 1.0 / sxx
    n = t.size
    if n >= 3:
        chi2 = float(np.sum(w * (y - ybar - slope * (t - tbar)) ** 2))
        var *= max(1.0, chi2 / (n - 2))
    half = _z(alpha) * math.sqrt(var)
    return slope, (slope - half, slope + half), ybar - slope * tbar


# --------------------------------------------------------------------------------------------------
# the fleet
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class UnitVerdict:
    """One cell of the fleet table: a unit's coefficient with its verdict. ``status``: "in
    family", "out of family", "excluded" (not in the fleet fit; ``reason`` says why) or "no fleet
    estimate" (too few units); ``reason`` for out of family: which side and how far."""

    estimate: Estimate
    status: str
    reason: str = ""


@dataclass(frozen=True)
class CoefficientSummary:
    """The fleet's estimate of one coefficient (values on the coefficient's own scale): typical
    value ``exp(mu)`` with its interval, the spread ``tau`` (log scale) with its interval, the
    prediction interval of a new unit; ``fit`` None when fewer than :data:`MIN_UNITS` units have
    a usable estimate; ``excluded``: (unit, reason) of the units left out."""

    coefficient: str
    value_unit: str
    sensor: str
    n_units: int
    fit: RandomEffects | None
    excluded: tuple[tuple[str, str], ...] = ()
    datasheet_value: float | None = None

    @property
    def typical(self) -> float | None:
        return None if self.fit is None else math.exp(self.fit.mu)

    @property
    def typical_ci(self) -> tuple[float, float] | None:
        return None if self.fit is None else (math.exp(self.fit.ci_mu[0]),
                                              math.exp(self.fit.ci_mu[1]))

    @property
    def prediction(self) -> tuple[float, float] | None:
        pi = None if self.fit is None else self.fit.pi
        return None if pi is None else (math.exp(pi[0]), math.exp(pi[1]))

    @property
    def datasheet_verdict(self) -> str | None:
        """Where the datasheet value lies against the fleet's prediction interval."""
        pi = self.prediction
        if self.datasheet_value is None or pi is None:
            return None
        if pi[0] <= self.datasheet_value <= pi[1]:
            return "within the fleet's prediction interval"
        return ("units better than the datasheet" if pi[1] < self.datasheet_value
                else "units worse than the datasheet")


@dataclass
class Fleet:
    """The fleet table (:func:`fleet_table`): per coefficient a :class:`CoefficientSummary`, per
    unit and coefficient a :class:`UnitVerdict` (the unit's latest recording), the drifts, and the
    recordings that failed with their one-line reason."""

    coefficients: dict[str, CoefficientSummary]
    verdicts: list[UnitVerdict]
    drifts: list[Drift]
    failed: list[tuple[str, str, str]] = field(default_factory=list)  # (unit, recording, reason)
    method: str = "pm"
    alpha: float = 0.05
    notes: list[str] = field(default_factory=list)

    @property
    def units(self) -> list[str]:
        return sorted({v.estimate.unit for v in self.verdicts} | {f[0] for f in self.failed})

    @property
    def out_of_family(self) -> list[UnitVerdict]:
        return [v for v in self.verdicts if v.status == "out of family"]

    def to_json_dict(self) -> dict[str, Any]:
        """Everything in plain JSON types (dates as ISO strings)."""
        def est(e: Estimate) -> dict[str, Any]:
            return {"unit": e.unit, "recording": e.recording, "coefficient": e.coefficient,
                    "sensor": e.sensor, "value": e.value if e.usable else None,
                    "ci95": list(e.ci95) if e.usable and e.ci95 else None,
                    "value_unit": e.value_unit,
                    "date": e.date.isoformat() if e.date else None,
                    "datasheet": e.datasheet}

        def summ(c: CoefficientSummary) -> dict[str, Any]:
            f = c.fit
            return {"coefficient": c.coefficient, "sensor": c.sensor, "value_unit": c.value_unit,
                    "n_units": c.n_units, "typical": c.typical,
                    "typical_ci95": list(c.typical_ci) if c.typical_ci else None,
                    "tau_log": None if f is None else f.tau,
                    "tau_log_ci95": None if f is None else list(f.ci_tau),
                    "spread_factor": None if f is None else math.exp(f.tau),
                    "prediction95": list(c.prediction) if c.prediction else None,
                    "q": None if f is None else f.q, "i2": None if f is None else f.i2,
                    "excluded": [{"unit": u, "reason": r} for u, r in c.excluded],
                    "datasheet_value": c.datasheet_value,
                    "datasheet_verdict": c.datasheet_verdict}

        return {"method_re": self.method, "alpha": self.alpha,
                "conventions": __doc__.split("\n\n")[1].replace("\n", " ") if __doc__ else "",
                "coefficients": {k: summ(c) for k, c in self.coefficients.items()},
                "units": [est(v.estimate) | {"status": v.status, "reason": v.reason}
                          for v in self.verdicts],
                "drift": [{"unit": d.unit, "coefficient": d.coefficient,
                           "slope_log_per_year": d.slope, "ci95": list(d.ci),
                           "percent_per_year": list(d.percent_per_year), "n": d.n,
                           "first": d.first.isoformat(), "last": d.last.isoformat(),
                           "flagged": d.flagged} for d in self.drifts],
                "failed": [{"unit": u, "recording": r, "reason": why}
                           for u, r, why in self.failed],
                "notes": list(self.notes)}


def _latest(ests: Iterable[Estimate]) -> Estimate:
    """A unit's representative recording: the latest dated one, else the last by name."""
    return max(ests, key=lambda e: (e.date or _dt.date.min, e.recording))


def _outside(e: Estimate, pi: tuple[float, float], coef: str, unit_label: str) -> str:
    """'' when the unit's interval meets the prediction interval ``pi`` (values), else why not."""
    lo, hi = e.ci95  # type: ignore[misc]
    where = (f"{coef} {e.value:.3g} [{lo:.3g}, {hi:.3g}] {unit_label}").rstrip()
    band = f"the fleet's 95 % prediction interval [{pi[0]:.3g}, {pi[1]:.3g}]"
    if lo > pi[1]:
        return f"{where}: {lo / pi[1]:.3g}x above {band}"
    if hi < pi[0]:
        return f"{where}: {pi[0] / hi:.3g}x below {band}"
    return ""


def fleet_table(estimates: Sequence[Estimate], *, method: str = "pm", alpha: float = 0.05,
                failed: Sequence[tuple[str, str, str]] = ()) -> Fleet:
    """The fleet table from every recording's estimates (module docstring). Each unit enters a
    coefficient's fleet fit once, with its latest recording; all dated recordings of a unit feed
    its drift."""
    by_coef: dict[str, dict[str, list[Estimate]]] = {}
    for e in estimates:
        by_coef.setdefault(e.coefficient, {}).setdefault(e.unit, []).append(e)
    coefficients: dict[str, CoefficientSummary] = {}
    verdicts: list[UnitVerdict] = []
    drifts: list[Drift] = []
    for coef in sorted(by_coef):
        units = by_coef[coef]
        latest = {u: _latest(es) for u, es in sorted(units.items())}
        use = [e for e in latest.values() if e.usable]
        excluded = tuple((u, e.why_not()) for u, e in latest.items() if not e.usable)
        first = next(iter(latest.values()))
        ds = [e.datasheet_value for e in latest.values() if e.datasheet_value is not None]
        fit = None
        if len(use) >= MIN_UNITS:
            y = np.array([e.log_value for e in use], float)
            v = np.array([log_se(e.ci95, alpha) for e in use], float) ** 2
            fit = random_effects(y, v, method, alpha)
        coefficients[coef] = CoefficientSummary(coef, first.value_unit, first.sensor, len(use),
                                                fit, excluded, ds[0] if ds else None)
        loo = fit is not None and len(use) - 1 >= MIN_UNITS and len(use) <= LOO_MAX_UNITS
        for u, e in latest.items():
            if not e.usable:
                verdicts.append(UnitVerdict(e, "excluded", e.why_not()))
                continue
            if fit is None:
                verdicts.append(UnitVerdict(e, "no fleet estimate",
                                            f"fewer than {MIN_UNITS} units with an estimate"))
                continue
            pi_log = fit.pi
            if loo:
                rest = [o for o in use if o is not e]
                pi_log = random_effects([o.log_value for o in rest],
                                        [log_se(o.ci95, alpha) ** 2 for o in rest],
                                        method, alpha).pi
            assert pi_log is not None
            why = _outside(e, (math.exp(pi_log[0]), math.exp(pi_log[1])), coef, e.value_unit)
            if why and loo:
                why += " (without this unit)"
            verdicts.append(UnitVerdict(e, "out of family" if why else "in family", why))
        for u, es in sorted(units.items()):
            dated = [e for e in es if e.date is not None and e.usable]
            if len({e.date for e in dated}) < 2:
                continue
            dated.sort(key=lambda e: (e.date, e.recording))
            slope, ci, icpt = fit_drift([e.date for e in dated], [e.log_value for e in dated],
                                        [log_se(e.ci95, alpha) for e in dated], alpha)
            drifts.append(Drift(u, coef, slope, ci, len(dated), dated[0].date, dated[-1].date,
                                icpt, tuple((e.date.isoformat(), e.value, *e.ci95)
                                            for e in dated)))
    return Fleet(coefficients, verdicts, drifts, list(failed), method, alpha)


# --------------------------------------------------------------------------------------------------
# comparison with an earlier fleet run
# --------------------------------------------------------------------------------------------------


def compare_units(old: Mapping[str, Any], new: Mapping[str, Any], alpha: float = 0.05
                  ) -> list[dict[str, Any]]:
    """Units whose coefficient moved between two fleet runs (their ``fleet.json`` dicts): per
    unit and coefficient with a usable estimate in both, the log ratio new/old against its
    standard error ``sqrt(s_old^2 + s_new^2)`` (each from the run's own 95 % interval); a row
    per pair with ``moved`` True where ``|z|`` exceeds the normal ``1 - alpha/2`` quantile. A
    recording shared by both runs (same unit, recording and value) is skipped: it cannot have
    moved."""
    def cells(obj: Mapping[str, Any]) -> dict[tuple[str, str], Mapping[str, Any]]:
        return {(u["unit"], u["coefficient"]): u for u in obj.get("units", [])
                if u.get("value") is not None and u.get("ci95")}

    a, b = cells(old), cells(new)
    z_crit = _z(alpha)
    rows = []
    for key in sorted(a.keys() & b.keys()):
        o, n = a[key], b[key]
        if o.get("recording") == n.get("recording") and o["value"] == n["value"]:
            continue
        so, sn = log_se(o["ci95"], alpha), log_se(n["ci95"], alpha)
        if so is None or sn is None or not (o["value"] > 0 and n["value"] > 0):
            continue
        d = math.log(n["value"]) - math.log(o["value"])
        z = d / math.hypot(so, sn)
        rows.append({"unit": key[0], "coefficient": key[1], "old_recording": o.get("recording"),
                     "old_value": o["value"], "old_ci95": list(o["ci95"]),
                     "new_recording": n.get("recording"), "new_value": n["value"],
                     "new_ci95": list(n["ci95"]), "ratio": math.exp(d), "z": z,
                     "moved": abs(z) > z_crit, "value_unit": n.get("value_unit", "")})
    return rows
