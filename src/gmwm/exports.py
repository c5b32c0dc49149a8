"""IMU noise configuration files for the filters and estimators people feed (docs/METHODS.md §10.6).

One internal representation, :class:`NoiseExport`, is built from the per-axis GMWM fits
(:func:`noise_export`); one writer per target turns it into the file that tool reads:

==============  ==========================  ===================================================
target          file                        values
==============  ==========================  ===================================================
``kalibr``      ``imu.yaml``                continuous-time densities (Kalibr ``imu.yaml``)
``openvins``    ``kalibr_imu_chain.yaml``   continuous-time densities under ``imu0:`` (OpenCV YAML)
``vins-fusion`` ``vins_fusion_imu.yaml``    per-sample sigmas matched to its preintegration
``orb-slam3``   ``orb_slam3_imu.yaml``      continuous-time densities + ``IMU.Frequency``
``lio-sam``     ``lio_sam_imu.yaml``        continuous-time densities (GTSAM covariances' sigmas)
``fast-lio``    ``fast_lio_imu.yaml``       per-sample variances (``dt^2 Q`` per IMU interval)
``json``        ``imu_noise.json``          continuous and discrete, per axis and combined
==============  ==========================  ===================================================

Per sensor (gyroscope, accelerometer) and axis the representation holds the continuous-time
white-noise density N [SI/sqrt(Hz)] and random-walk density K [SI/s/sqrt(Hz)] with their 95 %
intervals, taken from :func:`gmwm.datasheet.datasheet` so that every file agrees with the
parameter table and the report; a flag when the term is at the boundary 0 or not distinguishable
from 0 (the fit's own diagnostics, :func:`gmwm.diagnostics.is_weak`); the terms no target has a
field for (Gauss-Markov, bias instability from the Allan readings, QN, rate ramp, sinusoids) as
comment text. One value per sensor is chosen by a stated axis rule (default: the worst axis) and
inflated after that (``parse_inflation("noise=2,walk=10")``), and every text file says in
comments its units, continuous or discrete, the axis rule, the interval of each value, the
inflation, and for a flagged term what was written and what to do. A flagged term is written as
its 95 % upper bound (a filter told too little noise is overconfident; one told too much is only
suboptimal); a term the model lacks is never written as 0: its key is left commented out, so the
target tool stops on a missing key instead of running with a made-up number.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable, Collection, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.datasheet import datasheet, fit_readings
from gmwm.errors import InputError
from gmwm.units import parse_unit, unit_system

__all__ = ["AXIS_RULES", "TARGETS", "AxisNoise", "AxisTerm", "Combined", "Inflation", "NoiseExport",
           "Target", "noise_export", "parse_inflation", "parse_targets", "render", "write_exports"]

SENSORS = ("gyroscope", "accelerometer")
TERMS = ("noise_density", "random_walk")
#: SI units of the continuous-time coefficients: sensor -> (signal, noise density, random walk)
SI_UNITS = {"gyroscope": ("rad/s", "rad/s/sqrt(Hz)", "rad/s^2/sqrt(Hz)"),
            "accelerometer": ("m/s^2", "m/s^2/sqrt(Hz)", "m/s^3/sqrt(Hz)")}
#: how one value per sensor is chosen from its axes
AXIS_RULES = {
    "worst": "the largest value over the sensor's axes (the worst axis; conservative for a filter)",
    "rms": ("the root mean square over the sensor's axes (the same total variance as the axes; "
            "its interval from the axes' interval ends, conservative)"),
}
FLAG_TEXT = {"boundary": "at the boundary 0 (the fit puts this term at 0)",
             "weak": "not distinguishable from zero (estimate below 1.96 standard errors)",
             "unidentified": "not identifiable at this length (its predicted 95 % interval at "
                             "the fitted values includes 0: gmwm plan)"}
_ROS_NAME = re.compile(r"^[~/]?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


# --------------------------------------------------------------------------------------------------
# inflation
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Inflation:
    """Factors applied to the combined values after the axis rule: ``noise`` multiplies the
    white-noise densities, ``walk`` the random-walk densities (both >= 1; 1 = none)."""

    noise: float = 1.0
    walk: float = 1.0

    def factor(self, term: str) -> float:
        return self.noise if term == "noise_density" else self.walk

    @property
    def none(self) -> bool:
        return self.noise == 1.0 and self.walk == 1.0

    def describe(self) -> str:
        if self.none:
            return "none"
        return (f"noise densities x{self.noise:g}, random walks x{self.walk:g} (on the densities, "
                f"i.e. x{self.noise ** 2:g} and x{self.walk ** 2:g} on the variances), applied "
                "after the axis rule")


def parse_inflation(text: str | Inflation | None) -> Inflation:
    """``"noise=2,walk=10"`` (either key may be left out: factor 1), or one number for both
    (``"3"``); None/empty/``"none"``: no inflation. Factors multiply the densities and must be
    finite and >= 1. A bad spec is an :class:`InputError` naming it."""
    if isinstance(text, Inflation):
        return text
    if text is None or not str(text).strip() or str(text).strip().lower() == "none":
        return Inflation()
    spec = str(text).strip()
    factors = {"noise": 1.0, "walk": 1.0}
    parts = [p.strip() for p in spec.split(",")]
    if len(parts) == 1 and "=" not in parts[0]:
        factors["noise"] = factors["walk"] = _factor(parts[0], spec)
    else:
        seen = set()
        for part in parts:
            key, sep, value = part.partition("=")
            key = key.strip().lower()
            if not sep or key not in factors:
                raise InputError(f"bad inflation {spec!r}: use noise=F,walk=F (e.g. "
                                 "noise=2,walk=10) or one factor for both")
            if key in seen:
                raise InputError(f"bad inflation {spec!r}: {key} given twice")
            seen.add(key)
            factors[key] = _factor(value, spec)
    return Inflation(**factors)


def _factor(value: str, spec: str) -> float:
    try:
        f = float(value)
    except ValueError:
        raise InputError(f"bad inflation {spec!r}: {value.strip()!r} is not a number") from None
    if not (math.isfinite(f) and f >= 1.0):
        raise InputError(f"bad inflation {spec!r}: factors must be finite and >= 1 (a factor below "
                         "1 would make the filter more confident than the data)")
    return f


# --------------------------------------------------------------------------------------------------
# the internal representation
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AxisTerm:
    """One continuous-time coefficient of one axis, SI units (see :data:`SI_UNITS`).

    ``estimate``: the fitted value (None: the model has no such component); ``ci95``: its 95 %
    interval (None when the fit gives none); ``flag``: None, ``"boundary"`` or ``"weak"``;
    ``value``: what the files carry for this axis (the estimate, or for a flagged term its 95 %
    upper bound; None when there is nothing to write); ``note``: why, for comments."""

    estimate: float | None
    ci95: tuple[float, float] | None
    flag: str | None
    value: float | None
    note: str = ""

    def to_json_dict(self, rate: float, term: str) -> dict[str, Any]:
        return {"value": self.value, "estimate": self.estimate,
                "ci95": None if self.ci95 is None else list(self.ci95), "flag": self.flag,
                "note": self.note or None,
                "discrete": _discrete_dict(self.value, self.ci95, rate, term)}


@dataclass(frozen=True)
class AxisNoise:
    """Noise of one axis: its sensor, signal unit, model, the two coefficients, and comment lines
    for the terms the targets have no field for (``others``) and the fit's warnings."""

    axis: str
    sensor: str
    unit: str
    model: str
    noise_density: AxisTerm
    random_walk: AxisTerm
    others: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)

    def term(self, name: str) -> AxisTerm:
        return self.noise_density if name == "noise_density" else self.random_walk


@dataclass(frozen=True)
class Combined:
    """One value per sensor and term: ``base`` by the axis rule (``axis`` names the axis it came
    from under the ``"worst"`` rule), ``value = inflation * base`` (what the files write);
    ``ci95`` is the interval of ``base`` (before inflation); ``flagged`` lists the axes whose term
    is flagged and ``missing`` those whose model lacks the term."""

    sensor: str
    term: str
    value: float | None
    base: float | None
    ci95: tuple[float, float] | None
    axis: str | None
    axes: tuple[str, ...]
    flag: str | None
    flagged: tuple[str, ...]
    missing: tuple[str, ...]
    inflation: float

    def to_json_dict(self, rate: float) -> dict[str, Any]:
        return {"value": self.value, "value_before_inflation": self.base,
                "ci95_before_inflation": None if self.ci95 is None else list(self.ci95),
                "inflation": self.inflation, "axis": self.axis, "axes": list(self.axes),
                "flag": self.flag, "flagged_axes": list(self.flagged),
                "axes_without_term": list(self.missing),
                "discrete": {"value": _discrete(self.value, rate, self.term),
                             "value_before_inflation": _discrete(self.base, rate, self.term),
                             "ci95_before_inflation": None if self.ci95 is None else
                             [_discrete(c, rate, self.term) for c in self.ci95]}}


@dataclass(frozen=True)
class NoiseExport:
    """Everything the configuration writers need (build it with :func:`noise_export`)."""

    update_rate: float
    topic: str | None
    rule: str
    flagged_policy: str
    inflation: Inflation
    axes: Mapping[str, AxisNoise]
    combined: Mapping[str, Mapping[str, Combined]]
    skipped: tuple[str, ...] = ()
    source: str | None = None
    #: what the tool knows about these numbers (gmwm.verdict): the first comment lines of every
    #: file, and "caveats" in the JSON
    caveats: tuple[str, ...] = ()

    def sensor_axes(self, sensor: str) -> list[AxisNoise]:
        return [a for a in self.axes.values() if a.sensor == sensor]

    def to_json_dict(self) -> dict[str, Any]:
        """The plain-JSON export: conventions, combined values per sensor, values per axis."""
        from gmwm import __version__

        rate = self.update_rate
        return {
            "format": "gmwm IMU noise export", "format_version": 1, "gmwm_version": __version__,
            "caveats": list(self.caveats), "source": self.source, "rostopic": self.topic, "update_rate_hz": rate,
            "conventions": {
                "continuous": {
                    "noise_density": "white-noise density N, rad/s/sqrt(Hz) (gyroscope) or "
                                     "m/s^2/sqrt(Hz) (accelerometer)",
                    "random_walk": "random-walk (bias diffusion) density K, rad/s^2/sqrt(Hz) or "
                                   "m/s^3/sqrt(Hz)"},
                "discrete": {
                    "noise_density": "N * sqrt(update_rate): standard deviation of one sample's "
                                     "white noise, rad/s or m/s^2",
                    "random_walk": "K / sqrt(update_rate): standard deviation of the bias "
                                   "increment over one sample interval, rad/s or m/s^2"},
                "interval": "95 % confidence interval of the GMWM fit (docs/METHODS.md §10.3), "
                            "null when the fit gives none",
                "axis_rule": f"{self.rule}: {AXIS_RULES[self.rule]}",
                "flagged": _flag_policy_text(self.flagged_policy),
                "inflation": self.inflation.describe(),
            },
            "inflation": {"noise": self.inflation.noise, "walk": self.inflation.walk},
            "sensors": {s: {t: c.to_json_dict(rate) for t, c in terms.items()}
                        for s, terms in self.combined.items()},
            "axes": {name: {"sensor": a.sensor, "unit": a.unit, "model": a.model,
                            **{t: a.term(t).to_json_dict(rate, t) for t in TERMS},
                            **a.extra, "warnings": list(a.warnings)}
                     for name, a in self.axes.items()},
            "skipped_axes": list(self.skipped),
        }


def _discrete(value: float | None, rate: float, term: str) -> float | None:
    if value is None:
        return None
    return value * math.sqrt(rate) if term == "noise_density" else value / math.sqrt(rate)


def _discrete_dict(value: float | None, ci: tuple[float, float] | None, rate: float, term: str
                   ) -> dict[str, Any]:
    return {"value": _discrete(value, rate, term),
            "ci95": None if ci is None else [_discrete(c, rate, term) for c in ci]}


def _flag_policy_text(policy: str) -> str:
    if policy == "upper":
        return ("a term at the boundary 0 or not distinguishable from 0 is written as its 95 % "
                "upper bound: the data cannot exclude values up to it, and a filter told too "
                "little noise is overconfident while one told too much is only suboptimal")
    return ("a term at the boundary 0 or not distinguishable from 0 is written as its estimate "
            "(flagged in comments); an estimate of 0 is written as its 95 % upper bound")


# --------------------------------------------------------------------------------------------------
# building it from the fits
# --------------------------------------------------------------------------------------------------


def noise_export(per_axis: Mapping[str, tuple[str | None, Any]],
                 update_rate: float | None = None, *, topic: str | None = None,
                 inflation: str | Inflation | None = None, rule: str = "worst",
                 flagged: str = "upper",
                 readings: Mapping[str, Mapping[str, Any] | None] | None = None,
                 source: str | None = None,
                 datasheets: Mapping[str, Mapping[str, Any] | None] | None = None,
                 caveats: Sequence[str] = (),
                 unidentified: Mapping[str, Collection[str]] | None = None) -> NoiseExport:
    """Build the noise representation from per-axis fits.

    ``per_axis[axis] = (unit, result)``: the signal unit (its sensor role and SI factor from
    :data:`gmwm.units.SIGNAL_UNITS`, e.g. 'deg/s', 'rad/s', 'm/s^2', 'g', '0.00875*deg/s') and
    the GMWM fit of that axis. Axes without a gyroscope/accelerometer unit are skipped (listed in
    the files); none at all is an :class:`InputError`. ``update_rate`` [Hz] defaults to the fits'
    common sampling frequency and must equal it. ``topic``: the IMU's ROS topic if known.
    ``inflation``: see :func:`parse_inflation`. ``rule``: ``"worst"`` or ``"rms"``
    (:data:`AXIS_RULES`). ``flagged``: ``"upper"`` (default; write a flagged term's 95 % upper
    bound) or ``"estimate"``. ``readings[axis]``: the IEEE 952 readings of
    :func:`gmwm.datasheet.allan_readings` (computed from the fit's WV when not given; their bias
    instability goes into the comments). ``datasheets[axis]``: that fit's
    :func:`gmwm.datasheet.datasheet` in ``unit`` (computed when not given). ``caveats``: lines
    every file starts with (:attr:`gmwm.verdict.Verdict.caveats`); ``unidentified[axis]``: the
    components not identifiable at the length used (:attr:`gmwm.verdict.Verdict.unidentified`),
    flagged and written like a term not distinguishable from 0 (its 95 % upper bound).
    """
    if rule not in AXIS_RULES:
        raise InputError(f"unknown axis rule {rule!r}; use one of {', '.join(AXIS_RULES)}")
    if flagged not in ("upper", "estimate"):
        raise InputError(f"unknown policy for flagged terms {flagged!r}; use upper or estimate")
    if not per_axis:
        raise InputError("no axes to export")
    if topic is not None:
        topic = str(topic).strip() or None
    if topic is not None and not _ROS_NAME.match(topic):
        raise InputError(f"topic {topic!r} is not a ROS topic name (e.g. /imu0)")
    infl = parse_inflation(inflation)
    freqs = {name: float(res.wv.freq) for name, (_, res) in per_axis.items()}
    rate = _check_rate(update_rate, freqs)
    axes: dict[str, AxisNoise] = {}
    skipped: list[str] = []
    for name, (unit, res) in per_axis.items():
        parsed = parse_unit(unit) if unit else None
        if parsed is None:
            skipped.append(f"{name}: no unit given, so neither its sensor nor its SI scale is "
                           "known")
            continue
        got = None if readings is None else readings.get(name)
        ds = None if datasheets is None else datasheets.get(name)
        axes[name] = _axis(name, unit, parsed[2], res, got, ds,
                           (unidentified or {}).get(name, ()))
    if not axes:
        raise InputError("no axis has a gyroscope or accelerometer unit (deg/s, rad/s, m/s^2, g, "
                         "...): the noise files need one to know the sensor and SI units")
    if flagged == "estimate":
        axes = {n: _estimate_policy(a) for n, a in axes.items()}
    combined = {s: {t: _combine(s, t, [a for a in axes.values() if a.sensor == s], rule, infl)
                    for t in TERMS} for s in SENSORS}
    return NoiseExport(rate, topic, rule, flagged, infl, axes, combined, tuple(skipped), source,
                       tuple(str(c) for c in caveats))


def _check_rate(update_rate: float | None, freqs: Mapping[str, float]) -> float:
    values = sorted(set(freqs.values()))
    if update_rate is None:
        if len(values) > 1:
            raise InputError("the axes were fitted at different sampling frequencies ("
                             + ", ".join(f"{n}: {f:g} Hz" for n, f in freqs.items())
                             + "): one IMU configuration needs one update rate")
        update_rate = values[0]
    rate = float(update_rate)
    if not (math.isfinite(rate) and rate > 0):
        raise InputError(f"update rate must be a positive number of Hz, got {update_rate!r}")
    for name, f in freqs.items():
        if not math.isclose(f, rate, rel_tol=1e-9):
            raise InputError(f"axis {name} was fitted at {f:g} Hz but the update rate is {rate:g} "
                             "Hz: the densities' discretisation would not match")
    return rate


def filter_process(term: str) -> Any:
    """The process (:mod:`gmwm.processes`) that gives filter term ``term`` (``"noise_density"``,
    ``"random_walk"``; :attr:`gmwm.processes.Process.filter_term`)."""
    from gmwm.processes import PROCESSES  # SciPy: only once a file is written

    return next(p for p in PROCESSES.values() if p.filter_term == term)


def _scale_index(result: Any, proc: Any) -> list[tuple[str, int]]:
    """(component name, index of its scale parameter) of each component of process ``proc``."""
    names = list(result.param_names)
    key = proc.param_names[proc.scale_index]
    return [(n.split(".")[0], i) for i, n in enumerate(names)
            if n.startswith(proc.name + "[") and n.endswith("." + key)]


def _flag(result: Any, comp: str, i: int, unidentified: Collection[str] = ()) -> str | None:
    """The fit's own verdict on a scale parameter: at the boundary (vanished, held at 0), not
    distinguishable from 0 (the rule behind its "not distinguishable from zero" warning), or
    not identifiable at the length used (``unidentified``: components named by
    :func:`gmwm.verdict.identifiability`)."""
    from gmwm.diagnostics import is_weak

    theta = float(np.asarray(result.params, float)[i])
    diag = getattr(result, "diagnostics", None) or {}
    if comp in (diag.get("at_boundary") or []) or theta == 0.0:
        return "boundary"
    se = getattr(result, "se", None)
    if se is not None and bool(is_weak(np.array([theta]), np.array([np.asarray(se, float)[i]]))[0]):
        return "weak"
    return "unidentified" if comp in unidentified else None


def _param_interval(result: Any, i: int) -> tuple[float, float] | None:
    """Domain-respecting interval of parameter ``i`` (:func:`gmwm.intervals.fit_intervals`), for
    terms the datasheet gives no interval for (a component at the boundary); None if unavailable."""
    from gmwm.intervals import fit_intervals

    try:
        ci = fit_intervals(result)[i]
    except (AttributeError, KeyError, TypeError, ValueError, IndexError, np.linalg.LinAlgError):
        return None
    return (float(ci[0]), float(ci[1])) if np.all(np.isfinite(ci)) else None


def _axis(name: str, unit: str, sensor: str, result: Any, readings: Mapping[str, Any] | None,
          ds: Mapping[str, Any] | None = None, unidentified: Collection[str] = ()) -> AxisNoise:
    us = unit_system(unit)
    freq = float(result.wv.freq)
    if ds is None:
        ds = datasheet(result, unit)
    terms = {}
    used_keys: set[str] = set()
    for term in ("noise_density", "random_walk"):
        proc = filter_process(term)
        label, (_, to_si) = us.coefficient(proc.datasheet_kind)
        comps = _scale_index(result, proc)
        keys = [k for k in ds if k.split("[")[0] == label]
        used_keys.update(keys)
        terms[term] = _axis_term(result, comps, [ds[k] for k in keys], us.si / to_si,
                                 lambda p, c=proc.coefficient: us.si * c(p, freq), proc.name,
                                 unidentified)
    terms["noise_density"] = _fold_fast_terms(terms["noise_density"], result, us.si)
    others, extra = _other_terms(ds, used_keys, us, result, unit, readings)
    model = getattr(getattr(result, "model", None), "spec", None) or "+".join(
        dict.fromkeys(n.split("[")[0] for n in result.param_names))
    warns = tuple(str(w) for w in ((getattr(result, "diagnostics", None) or {}).get("warnings")
                                   or []))
    return AxisNoise(name, sensor, unit, model, terms["noise_density"], terms["random_walk"],
                     tuple(others), warns, extra)


def _fold_fast_terms(term: AxisTerm, result: Any, si: float) -> AxisTerm:
    """The noise density with the GM/AR1 terms white at the sampling rate folded in
    (:func:`gmwm.verdict.white_equivalent`); ``term`` unchanged when there are none. The WN
    term alone stays in the note, so the files and the datasheet table show both."""
    from gmwm.verdict import white_equivalent

    if getattr(result, "model", None) is None:
        return term
    we = white_equivalent(result)
    if we is None or not we.changed:
        return term
    lo, hi = we.ci95
    ci = (lo * si, hi * si) if math.isfinite(lo) and math.isfinite(hi) else None
    value = we.density * si
    parts = ", ".join(f"{t.component} (correlation time {t.tau_samples:.2g} sampling intervals, "
                      f"{t.density * si:.4g})" for t in we.folded)
    white = "none" if term.estimate is None else f"{term.estimate:.4g}"
    return AxisTerm(value, ci, None, value,
                    f"white-noise-equivalent density: the WN term ({white}) and {parts} added in "
                    f"quadrature; {we.rule()}")


def _axis_term(result: Any, comps: list[tuple[str, int]], entries: list[dict], to_si: float,
               param_to_si: Callable[[float], float], prefix: str,
               unidentified: Collection[str] = ()) -> AxisTerm:
    if not comps:
        return AxisTerm(None, None, None, None, f"the model has no {prefix} component")
    values, los, his, flags = [], [], [], []
    theta = np.asarray(result.params, float)
    for (comp, i), e in zip(comps, entries, strict=True):
        v = e.get("value")
        v = param_to_si(theta[i]) if v is None else float(v) * to_si
        ci = e.get("ci95")
        if ci is not None and all(c is not None and math.isfinite(c) for c in ci):
            lo, hi = float(ci[0]) * to_si, float(ci[1]) * to_si
        elif (pci := _param_interval(result, i)) is not None:
            lo, hi = param_to_si(pci[0]), param_to_si(pci[1])
        else:
            lo = hi = None
        values.append(v)
        los.append(lo)
        his.append(hi)
        flags.append(_flag(result, comp, i, unidentified))
    # several components of one kind add their variances (independent white noises / walks)
    est = math.sqrt(sum(v * v for v in values))
    ci = None if any(c is None for c in (*los, *his)) else (
        math.sqrt(sum(c * c for c in los)), math.sqrt(sum(c * c for c in his)))
    flag = "boundary" if all(f == "boundary" for f in flags) else (
        "weak" if any(f is not None for f in flags) else None)
    multi = f" (sum of {len(comps)} {prefix} components)" if len(comps) > 1 else ""
    if flag is None:
        note = "" if ci is not None else "the fit gives no interval for it"
        return AxisTerm(est, ci, None, est, note + multi)
    if ci is None:
        if est > 0:
            return AxisTerm(est, None, flag, est, f"{FLAG_TEXT[flag]} and no interval is "
                            f"available: written as its estimate{multi}")
        return AxisTerm(est, None, flag, None, f"{FLAG_TEXT[flag]} and no upper bound is available"
                        f"{multi}")
    return AxisTerm(est, ci, flag, ci[1], f"{FLAG_TEXT[flag]}: written as its 95 % upper bound"
                    f"{multi}")


def _estimate_policy(a: AxisNoise) -> AxisNoise:
    """The ``flagged="estimate"`` variant: flagged terms keep their estimate unless it is 0."""
    def fix(t: AxisTerm) -> AxisTerm:
        if t.flag is None or t.estimate is None or t.estimate == 0.0:
            return t
        return AxisTerm(t.estimate, t.ci95, t.flag, t.estimate,
                        f"{FLAG_TEXT[t.flag]}: written as its estimate")

    return AxisNoise(a.axis, a.sensor, a.unit, a.model, fix(a.noise_density), fix(a.random_walk),
                     a.others, a.warnings, a.extra)


def _fmt_ci(ci: Sequence[float] | None, fmt: str = ".3g") -> str:
    return "none" if not ci else f"[{format(ci[0], fmt)}, {format(ci[1], fmt)}]"


def _other_terms(ds: Mapping[str, dict], used: set[str], us: Any, result: Any, unit: str,
                 readings: Mapping[str, Any] | None) -> tuple[list[str], dict[str, Any]]:
    """Comment lines (and JSON entries) for the datasheet terms no target has a field for, and the
    bias instability of the Allan readings."""
    lines: list[str] = []
    extra: dict[str, Any] = {"other_terms": {k: v for k, v in ds.items() if k not in used}}
    level_label = us.level[0]
    si_label = SI_UNITS[us.sensor][0] if us.sensor in SI_UNITS else None

    def one(what: str, e: Mapping[str, Any]) -> str:
        if e.get("value") is None:
            return f"{what} {e.get('note') or 'not identified'}"
        text = f"{what} {e['value']:.4g} {e['unit']} (95 % CI {_fmt_ci(e.get('ci95'), '.4g')})"
        if e["unit"] == level_label and si_label is not None and e["unit"] != si_label:
            text += f" = {e['value'] / us.level[1] * us.si:.4g} {si_label}"
        return text

    for key, e in ds.items():
        if key in used:
            continue
        if "value" in e:
            lines.append(one(key, e))
        else:
            lines.append(f"{key}: " + "; ".join(one(w.replace("_", " "), v) for w, v in e.items()
                                                if isinstance(v, Mapping)))
    if readings is None:
        readings = fit_readings(result, unit)
    b = (readings or {}).get("B")
    if b and b.get("value") is not None:
        where = f"Allan-deviation floor at tau = {b['tau_s']:.4g} s / 0.6643"
        if b.get("at_end"):
            where += ", at the longest cluster time: an upper bound of a floor not yet reached"
        lines.append(one(f"bias instability B ({where}):", b))
        extra["bias_instability"] = {k: b[k] for k in ("value", "unit", "ci95", "tau_s", "at_end")
                                     if k in b}
    return lines, extra


def _combine(sensor: str, term: str, axes: list[AxisNoise], rule: str, infl: Inflation
             ) -> Combined:
    names = tuple(a.axis for a in axes)
    with_value = [a for a in axes if a.term(term).value is not None]
    missing = tuple(a.axis for a in axes if a.term(term).estimate is None)
    flagged = tuple(a.axis for a in axes if a.term(term).flag is not None)
    factor = infl.factor(term)
    if not with_value:
        return Combined(sensor, term, None, None, None, None, names, None, flagged, missing, factor)
    if rule == "worst":
        best = max(with_value, key=lambda a: a.term(term).value)
        t = best.term(term)
        base, ci, axis, flag = t.value, t.ci95, best.axis, t.flag
    else:  # rms
        vals = [a.term(term).value for a in with_value]
        base = math.sqrt(sum(v * v for v in vals) / len(vals))
        cis = [a.term(term).ci95 for a in with_value]
        ci = None if any(c is None for c in cis) else (
            math.sqrt(sum(c[0] ** 2 for c in cis) / len(cis)),
            math.sqrt(sum(c[1] ** 2 for c in cis) / len(cis)))
        axis, flag = None, ("weak" if flagged else None)
    return Combined(sensor, term, factor * base, base, ci, axis, names, flag, flagged, missing,
                    factor)


# --------------------------------------------------------------------------------------------------
# writers
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Key:
    """One noise key of a target: its name, the sensor and term it carries, the map from the
    continuous-time SI value to the file's value (``convert(value, rate)``, increasing), the file
    value's unit and a phrase saying what it is."""

    name: str
    sensor: str
    term: str
    convert: Callable[[float, float], float]
    unit: str
    meaning: str


def _continuous(v: float, rate: float) -> float:
    return v


def _num(v: float) -> str:
    """A float every target parses as a real (OpenCV's parser needs the '.', YAML 1.1 the signed
    exponent)."""
    return f"{v:.6e}"


def _real(v: float) -> str:
    s = repr(float(v))
    return s if "." in s and "e" not in s.lower() else _num(v)


def _header(exp: NoiseExport, tool: str, what: str, values: str, topic_key: bool = True
            ) -> list[str]:
    from gmwm import __version__

    first = [f"CAUTION ({len(exp.caveats)}): read before using these values:",
             *(f"- {c}" for c in exp.caveats), ""] if exp.caveats else []
    lines = [*first, f"{tool} IMU noise ({what}), written by gmwm {__version__}"
             + (f" from {exp.source}" if exp.source else "") + ".",
             f"Values: {values}",
             f"Axis rule: one value per sensor = {AXIS_RULES[exp.rule]}.",
             f"Inflation: {exp.inflation.describe()}.",
             ("Intervals: 95 % confidence intervals of the fit, before inflation, in the unit of "
             "the key they follow."),
             f"Flagged terms: {_flag_policy_text(exp.flagged_policy)}.",
             f"Update rate: {exp.update_rate:g} Hz" + ("" if not topic_key else "; IMU topic: "
                                                       + (exp.topic or "not known from the input "
                                                          "(placeholder below: set yours or "
                                                          "give the topic when calibrating (rostopic))")) + "."]
    return _wrap_comment(lines)


def _wrap_comment(lines: Iterable[str], indent: str = "", width: int = 98) -> list[str]:
    import textwrap

    out = []
    for line in lines:
        first, rest = f"{indent}# ", f"{indent}#   "
        out += textwrap.wrap(line, width=width, initial_indent=first, subsequent_indent=rest,
                             break_on_hyphens=False, break_long_words=False) or [first.rstrip()]
    return out


def _key_lines(exp: NoiseExport, key: _Key, indent: str = "") -> list[str]:
    """Comment lines and the ``key: value`` line (or the commented-out key) of one noise key."""
    c = exp.combined[key.sensor][key.term]
    rate = exp.update_rate
    conv = key.convert
    kind = "noise density" if key.term == "noise_density" else "random walk"
    lines = [f"{key.name} [{key.unit}]: {key.meaning}."]
    comp = filter_process(key.term).name
    if c.value is None:
        whys = [] if c.axes else [f"no {key.sensor} axis"]
        if c.missing:
            whys.append(f"the model of {', '.join(c.missing)} has no {comp} component")
        if c.flagged:
            whys.append(f"{', '.join(c.flagged)}: {kind} at the boundary 0 with no upper bound "
                        "available")
        why = "; ".join(whys)
        lines.append(f"NOT WRITTEN ({why}): the key is left out so that the tool stops rather "
                     "than run with a made-up value; refit with that term or set it yourself.")
        return [*_wrap_comment(lines, indent), f"{indent}# {key.name}:"]
    src = (f"axis {c.axis} (of {', '.join(c.axes)})" if c.axis is not None
           else f"root mean square of {', '.join(a for a in c.axes if a not in c.missing)}")
    lines.append(f"From {src}: {_num(conv(c.base, rate))}"
                 + (" (the fit gives no interval)" if c.ci95 is None else
                    f", 95 % CI {_fmt_ci([conv(x, rate) for x in c.ci95])}")
                 + ("" if c.inflation == 1.0 else
                    f"; inflated x{c.inflation:g} (on the density) to {_num(conv(c.value, rate))}")
                 + ".")
    axes = {a.axis: a for a in exp.sensor_axes(key.sensor)}
    for name in c.flagged:
        t = axes[name].term(key.term)
        lines.append(f"{name}: {t.note}; estimate "
                     f"{'none' if t.estimate is None else _num(conv(t.estimate, rate))}, 95 % "
                     f"CI {_fmt_ci(None if t.ci95 is None else [conv(x, rate) for x in t.ci95])}.")
    if c.flagged:
        lines.append("A flagged value is not a measurement but what the data cannot exclude: a "
                     "longer recording narrows it (`gmwm plan` estimates how long)"
                     + ("; a random walk shows only at scales near the recording's length"
                        if key.term == "random_walk" else "") + ".")
    for name in c.missing:
        lines.append(f"{name}: the model has no {comp} component, so this axis does not enter "
                     "the value.")
    return [*_wrap_comment(lines, indent), f"{indent}{key.name}: {_num(conv(c.value, rate))}"]


def _axis_block(exp: NoiseExport, keys: Sequence[_Key]) -> list[str]:
    """Per-axis values in the file's convention, the terms without a field, warnings, skips."""
    rate = exp.update_rate
    lines = ["Per axis (before inflation; value written, 95 % CI):"]
    for a in exp.axes.values():
        parts = []
        for key in keys:
            if key.sensor != a.sensor:
                continue
            t = a.term(key.term)
            if t.value is None:
                parts.append(f"{key.name} not estimated ({t.note})")
                continue
            ci = None if t.ci95 is None else [key.convert(x, rate) for x in t.ci95]
            parts.append(f"{key.name} {_num(key.convert(t.value, rate))} "
                         + (_fmt_ci(ci) if ci else "(no interval)")
                         + (f" ({FLAG_TEXT[t.flag].split(' (')[0]})" if t.flag else ""))
        lines.append(f"  {a.axis} ({a.sensor}, {a.unit}, model {a.model}): " + "; ".join(parts))
    others = [(a.axis, o) for a in exp.axes.values() for o in a.others]
    if others:
        lines.append("Terms this file has no field for (per axis, datasheet units; a filter with "
                     "bias states may model them):")
        lines += [f"  {axis} {o}" for axis, o in others]
    warns = [(a.axis, w) for a in exp.axes.values() for w in a.warnings]
    if warns:
        lines.append("Fit warnings:")
        lines += [f"  {axis}: {w}" for axis, w in warns]
    if exp.skipped:
        lines.append("Axes not used:")
        lines += [f"  {s}" for s in exp.skipped]
    return _wrap_comment(lines)


def _topic(exp: NoiseExport) -> str:
    return json.dumps(exp.topic or "/imu0")


_KALIBR_MEANING = {
    "noise_density": "continuous-time white-noise density",
    "random_walk": "continuous-time random-walk (bias diffusion) density"}


def _kalibr_keys(prefix: str = "") -> list[_Key]:
    return [_Key(f"{prefix}{s}_{t}", s, t, _continuous,
                 SI_UNITS[s][1 if t == "noise_density" else 2], _KALIBR_MEANING[t])
            for s in ("accelerometer", "gyroscope") for t in TERMS]


def kalibr_text(exp: NoiseExport) -> str:
    """Kalibr ``imu.yaml``: the four continuous-time densities, ``rostopic``, ``update_rate``."""
    keys = _kalibr_keys()
    lines = _header(exp, "Kalibr", "imu.yaml",
                    "continuous-time densities in SI units, as Kalibr's IMU noise model defines "
                    "them (Kalibr discretises them with update_rate).")
    lines.append("")
    for key in keys:
        lines += [*_key_lines(exp, key), ""]
    if exp.topic is None:
        lines += _wrap_comment([("rostopic: placeholder, the input had no ROS topic: set yours "
                                "or give the topic when calibrating (rostopic).")])
    lines.append(f"rostopic: {_topic(exp)}")
    lines.append(f"update_rate: {_real(exp.update_rate)}  # Hz")
    lines += ["", *_axis_block(exp, keys)]
    return "\n".join(lines) + "\n"


def openvins_text(exp: NoiseExport) -> str:
    """OpenVINS ``kalibr_imu_chain.yaml`` (OpenCV YAML): ``imu0:`` with the Kalibr keys,
    ``rostopic``, ``time_offset``, ``update_rate``, ``model`` and identity frame/intrinsics."""
    keys = _kalibr_keys()
    lines = ["%YAML:1.0", *_header(
        exp, "OpenVINS", "kalibr_imu_chain.yaml",
        "continuous-time densities in SI units (OpenVINS discretises them with the measured "
        "time step). T_i_b, time_offset and the intrinsics Tw, R_IMUtoGYRO, Ta, R_IMUtoACC, Tg "
        "are identity/zero placeholders: a static recording does not calibrate them."), "", "imu0:"]
    lines += ["  T_i_b:", *("    - [" + ", ".join("1.0" if i == j else "0.0" for j in range(4))
                            + "]" for i in range(4))]
    for key in keys:
        lines += _key_lines(exp, key, "  ")
    lines += [*([("  # rostopic: placeholder (the input had no ROS topic): set yours or give "
                 "the topic when calibrating (rostopic).")]
                if exp.topic is None else []),
              f"  rostopic: {_topic(exp)}", "  time_offset: 0.0",
              f"  update_rate: {_real(exp.update_rate)}", '  model: "kalibr"']
    eye = ["[ 1.0, 0.0, 0.0 ]", "[ 0.0, 1.0, 0.0 ]", "[ 0.0, 0.0, 1.0 ]"]
    for name in ("Tw", "R_IMUtoGYRO", "Ta", "R_IMUtoACC"):
        lines += [f"  {name}:", *(f"    - {r}" for r in eye)]
    lines += ["  Tg:", *("    - [ 0.0, 0.0, 0.0 ]" for _ in range(3))]
    lines += ["", *_axis_block(exp, keys)]
    return "\n".join(lines) + "\n"


def _vins_keys(convention: str) -> list[_Key]:
    out = []
    for s, short in (("accelerometer", "acc"), ("gyroscope", "gyr")):
        si = SI_UNITS[s][0]
        for t, suffix in (("noise_density", "n"), ("random_walk", "w")):
            if convention == "continuous":
                out.append(_Key(f"{short}_{suffix}", s, t, _continuous,
                                SI_UNITS[s][1 if t == "noise_density" else 2],
                                _KALIBR_MEANING[t]
                                + " (taken by VINS-Fusion as a per-sample sigma)"))
            elif t == "noise_density":
                out.append(_Key(f"{short}_{suffix}", s, t, lambda v, r: v * math.sqrt(2.0 * r), si,
                                "white-noise sigma per sample as VINS-Fusion's midpoint "
                                "preintegration uses it, N * sqrt(2 * update_rate)"))
            else:
                out.append(_Key(f"{short}_{suffix}", s, t, lambda v, r: v * math.sqrt(r),
                                si + "/s", "bias random-walk sigma of the bias rate per sample as "
                                "VINS-Fusion's preintegration uses it, K * sqrt(update_rate)"))
    return out


def vins_fusion_text(exp: NoiseExport, convention: str = "matched") -> str:
    """VINS-Fusion configuration keys (OpenCV YAML): ``imu``, ``imu_topic``, ``acc_n``, ``gyr_n``,
    ``acc_w``, ``gyr_w``, to merge into its config file.

    VINS-Fusion's preintegration adds ``0.5 acc_n^2 dt^2`` (two half-weighted samples) to the
    velocity covariance and ``acc_w^2 dt^2`` to the bias covariance per IMU interval ``dt``, so its
    covariance equals the continuous model's (``N^2 dt`` and ``K^2 dt``) with
    ``acc_n = N sqrt(2 f_s)`` and ``acc_w = K sqrt(f_s)`` (``convention="matched"``, default).
    ``convention="continuous"`` writes the Kalibr densities unchanged, as many published configs
    do (then the IMU factor is sqrt(2 f_s) and sqrt(f_s) times too confident)."""
    if convention not in ("matched", "continuous"):
        raise InputError(f"unknown VINS-Fusion convention {convention!r}; use matched or "
                         "continuous")
    keys = _vins_keys(convention)
    r = exp.update_rate
    if convention == "matched":
        values = ("discrete-time (per-sample) sigmas matched to VINS-Fusion's preintegration, "
                  "which adds 0.5 * n^2 * dt^2 (white noise, two half-weighted samples) and w^2 * "
                  "dt^2 (bias walk) per IMU interval dt: n = N * sqrt(2 * update_rate) = N * "
                  f"{math.sqrt(2 * r):.4g}, w = K * sqrt(update_rate) = K * {math.sqrt(r):.4g}, "
                  "with N, K the continuous-time densities (Kalibr's; listed below). Configs that "
                  "paste N and K unchanged make the IMU factor that many times too confident. "
                  "VINS-Fusion reads no IMU rate: these values hold for the update rate below.")
    else:
        values = ("continuous-time densities in SI units, unchanged (VINS-Fusion takes them as "
                  f"per-sample sigmas: its IMU factor is then sqrt(2 * update_rate) = "
                  f"{math.sqrt(2 * r):.4g} times too confident in white noise and sqrt(update_rate)"
                  f" = {math.sqrt(r):.4g} times in the bias walk).")
    lines = ["%YAML:1.0", *_header(exp, "VINS-Fusion", "keys to merge into its config file",
                                   values), "", "imu: 1"]
    if exp.topic is None:
        lines.append("# imu_topic: placeholder (the input had no ROS topic): set yours or give "
                     "the topic when calibrating (rostopic).")
    lines += [f"imu_topic: {_topic(exp)}", ""]
    for key in keys:
        lines += [*_key_lines(exp, key), ""]
    cont = [] if convention == "continuous" else _kalibr_keys()
    lines += _wrap_comment([("g_norm, estimate_td, td and body_T_cam0 are not set by this "
                            "calibration: keep yours.")])
    lines += ["", *_axis_block(exp, [*keys, *cont])]
    return "\n".join(lines) + "\n"


def orbslam3_text(exp: NoiseExport) -> str:
    """ORB-SLAM3 settings keys (OpenCV YAML): ``IMU.NoiseGyro``, ``IMU.NoiseAcc``,
    ``IMU.GyroWalk``, ``IMU.AccWalk`` (continuous-time; ORB-SLAM3 multiplies the noises by
    sqrt(IMU.Frequency) and divides the walks by it) and ``IMU.Frequency``."""
    keys = [_Key(f"IMU.{n}", s, t, _continuous, SI_UNITS[s][1 if t == "noise_density" else 2],
                 _KALIBR_MEANING[t])
            for n, s, t in (("NoiseGyro", "gyroscope", "noise_density"),
                            ("NoiseAcc", "accelerometer", "noise_density"),
                            ("GyroWalk", "gyroscope", "random_walk"),
                            ("AccWalk", "accelerometer", "random_walk"))]
    lines = ["%YAML:1.0", *_header(
        exp, "ORB-SLAM3", "IMU keys to merge into its settings file",
        "continuous-time densities in SI units; ORB-SLAM3 discretises them with IMU.Frequency "
        "(noise x sqrt(f), walk / sqrt(f)), so IMU.Frequency must be the true rate. "
        "IMU.T_b_c1 and IMU.InsertKFsWhenLost are not set by this calibration: keep yours.",
        topic_key=False), ""]
    for key in keys:
        lines += [*_key_lines(exp, key), ""]
    lines += [f"IMU.Frequency: {_real(exp.update_rate)}  # Hz", "", *_axis_block(exp, keys)]
    return "\n".join(lines) + "\n"


_LIOSAM_WALK = "continuous-time bias random-walk density (bias factor sigma = sqrt(dt) * value)"


def liosam_text(exp: NoiseExport) -> str:
    """LIO-SAM ``params.yaml`` keys under ``lio_sam:``: ``imuTopic``, ``imuAccNoise``,
    ``imuGyrNoise``, ``imuAccBiasN``, ``imuGyrBiasN``. LIO-SAM squares the noises into GTSAM's
    continuous-time preintegration covariances and uses ``sqrt(dt_ij) * BiasN`` as the sigma of
    the bias between-factor over an interval dt_ij: all four are continuous-time densities."""
    keys = [_Key(n, s, t, _continuous, SI_UNITS[s][1 if t == "noise_density" else 2], m)
            for n, s, t, m in (
                ("imuAccNoise", "accelerometer", "noise_density",
                 ("continuous-time white-noise density (squared into GTSAM's "
                 "accelerometerCovariance)")),
                ("imuGyrNoise", "gyroscope", "noise_density",
                 "continuous-time white-noise density (squared into GTSAM's gyroscopeCovariance)"),
                ("imuAccBiasN", "accelerometer", "random_walk", _LIOSAM_WALK),
                ("imuGyrBiasN", "gyroscope", "random_walk", _LIOSAM_WALK))]
    lines = _header(exp, "LIO-SAM", "keys of params.yaml",
                    "continuous-time densities in SI units. For the ROS 2 branch put the keys "
                    "under '/**: ros__parameters:' instead of 'lio_sam:'. imuGravity, "
                    "imuRPYWeight and the extrinsics are not set by this calibration: keep yours.")
    lines += ["", "lio_sam:"]
    if exp.topic is None:
        lines.append("  # imuTopic: placeholder (the input had no ROS topic): set yours or give "
                     "the topic when calibrating (rostopic).")
    lines.append(f"  imuTopic: {_topic(exp)}")
    for key in keys:
        lines += _key_lines(exp, key, "  ")
    lines += ["", *_axis_block(exp, keys)]
    return "\n".join(lines) + "\n"


def fastlio_text(exp: NoiseExport) -> str:
    """FAST-LIO ``common: imu_topic`` and ``mapping: acc_cov, gyr_cov, b_acc_cov, b_gyr_cov``.
    These are variances: FAST-LIO's predict step adds ``dt^2 * cov`` per IMU interval dt, so
    ``gyr_cov = N^2 f_s`` (the variance of one sample's white noise) and
    ``b_gyr_cov = K^2 f_s`` (the variance of the bias rate per sample)."""
    keys = []
    for n, s, t in (("acc_cov", "accelerometer", "noise_density"),
                    ("gyr_cov", "gyroscope", "noise_density"),
                    ("b_acc_cov", "accelerometer", "random_walk"),
                    ("b_gyr_cov", "gyroscope", "random_walk")):
        si = SI_UNITS[s][0]
        if t == "noise_density":
            keys.append(_Key(n, s, t, lambda v, r: v * v * r, f"({si})^2",
                             "variance of one sample's white noise, N^2 * update_rate"))
        else:
            keys.append(_Key(n, s, t, lambda v, r: v * v * r, f"({si}/s)^2",
                             "variance of the bias rate per sample, K^2 * update_rate"))
    lines = _header(exp, "FAST-LIO", "keys of its config yaml",
                    "discrete-time variances (not sigmas): FAST-LIO's predict step adds dt^2 * "
                    "cov per IMU interval dt, so cov = N^2 * update_rate for the white noise and "
                    "K^2 * update_rate for the bias walk, N and K the continuous-time densities "
                    "(listed below); they hold for the update rate below only.")
    lines += ["", "common:"]
    if exp.topic is None:
        lines.append("  # imu_topic: placeholder (the input had no ROS topic): set yours or "
                     "give the topic when calibrating (rostopic).")
    lines += [f"  imu_topic: {_topic(exp)}", "mapping:"]
    for key in keys:
        lines += _key_lines(exp, key, "  ")
    lines += ["", *_axis_block(exp, [*keys, *_kalibr_keys()])]
    return "\n".join(lines) + "\n"


def json_text(exp: NoiseExport) -> str:
    """The plain JSON export (:meth:`NoiseExport.to_json_dict`)."""
    from gmwm.atomic import to_jsonable

    return json.dumps(to_jsonable(exp.to_json_dict()), indent=2, allow_nan=False) + "\n"


@dataclass(frozen=True)
class Target:
    """A configuration target: its name, default file name, renderer and what it is."""

    name: str
    filename: str
    render: Callable[[NoiseExport], str]
    description: str


TARGETS: Mapping[str, Target] = {t.name: t for t in (
    Target("kalibr", "imu.yaml", kalibr_text, "Kalibr imu.yaml (continuous-time)"),
    Target("openvins", "kalibr_imu_chain.yaml", openvins_text,
           "OpenVINS kalibr_imu_chain.yaml (continuous-time, OpenCV YAML)"),
    Target("vins-fusion", "vins_fusion_imu.yaml", vins_fusion_text,
           "VINS-Fusion acc_n/gyr_n/acc_w/gyr_w (per-sample, matched to its preintegration)"),
    Target("orb-slam3", "orb_slam3_imu.yaml", orbslam3_text,
           "ORB-SLAM3 IMU.* settings (continuous-time + IMU.Frequency)"),
    Target("lio-sam", "lio_sam_imu.yaml", liosam_text, "LIO-SAM params.yaml IMU keys (continuous)"),
    Target("fast-lio", "fast_lio_imu.yaml", fastlio_text,
           "FAST-LIO acc_cov/gyr_cov/b_acc_cov/b_gyr_cov (per-sample variances)"),
    Target("json", "imu_noise.json", json_text, "plain JSON, continuous and discrete, per axis"),
)}
_TARGET_ALIASES = {"vins": "vins-fusion", "vinsfusion": "vins-fusion", "orbslam3": "orb-slam3",
                   "orb_slam3": "orb-slam3", "liosam": "lio-sam", "lio_sam": "lio-sam",
                   "fastlio": "fast-lio", "fast_lio": "fast-lio", "open_vins": "openvins",
                   "ov": "openvins"}


def parse_targets(text: str | Sequence[str] | None) -> list[str]:
    """Target names from ``"kalibr,openvins"`` (or a list; ``"all"``: every target); an unknown
    name is an :class:`InputError` listing the known ones."""
    if text is None:
        return []
    items = text.split(",") if isinstance(text, str) else list(text)
    out: list[str] = []
    for item in items:
        key = str(item).strip().lower()
        if not key:
            continue
        if key == "all":
            names = list(TARGETS)
        else:
            key = _TARGET_ALIASES.get(key, key)
            if key not in TARGETS:
                raise InputError(f"unknown export target {str(item).strip()!r}; known: "
                                 + ", ".join(TARGETS) + " (or all)")
            names = [key]
        out += [n for n in names if n not in out]
    return out


def render(exp: NoiseExport, target: str) -> str:
    """The text of one target's file."""
    names = parse_targets(target)
    if len(names) != 1:
        raise InputError(f"render needs exactly one target, got {target!r}")
    return TARGETS[names[0]].render(exp)


def write_exports(exp: NoiseExport, outdir: str | os.PathLike, targets: str | Sequence[str],
                  ) -> list[Path]:
    """Write the files of ``targets`` (see :func:`parse_targets`) into ``outdir`` under their
    default names (:data:`TARGETS`), each atomically; return the paths."""
    from gmwm.atomic import write_text_atomic

    names = parse_targets(targets)
    if not names:
        raise InputError("no export target given; known: " + ", ".join(TARGETS))
    texts = {n: TARGETS[n].render(exp) for n in names}  # render all before writing any
    return [write_text_atomic(Path(outdir) / TARGETS[n].filename, texts[n]) for n in names]
