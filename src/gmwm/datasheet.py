"""Datasheet coefficients of a fitted error model and the IEEE 952 Allan-deviation readings.

:func:`datasheet` turns the discrete, per-sample parameters of a GMWM fit into the continuous
coefficients a datasheet prints, in the user's units (SPEC section 3):

==========  ==================  ===========================================================
term        from                value (``u`` = signal unit, ``f_s`` = sampling frequency)
==========  ==================  ===========================================================
ARW / VRW   ``WN[k].sigma2``    N = sqrt(sigma2 / f_s) [u sqrt(s) = u/sqrt(Hz)]
RRW / AccRW ``RW[k].gamma2``    K = sqrt(gamma2 f_s) [u/sqrt(s)]
QN          ``QN[k].Q2``        Q = sqrt(Q2) / f_s [u s]
RR          ``DR[k].omega``     R = omega f_s [u/s] (rate ramp)
GM[k]       ``AR1``/``GM``      correlation time 1/beta = -1/(f_s ln phi) [s], stationary sigma [u]
SIN[k]      ``SIN``             frequency beta f_s / (2 pi) [Hz], amplitude alpha [u]
==========  ==================  ===========================================================

then scaled to the datasheet units of :data:`UNIT_SYSTEMS` (e.g. deg/sqrt(h), deg/h/sqrt(h) for a
gyroscope in deg/s). Confidence intervals are the images of the parameters' intervals
(:mod:`gmwm.intervals`: inside the parameter space, reaching 0 exactly for a component not
distinguishable from zero), so the datasheet and the parameter table agree. The module imports only
NumPy at load (fast CLI start).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["SIGNAL_UNITS", "UNIT_SYSTEMS", "UnitSystem", "allan_readings", "datasheet", "kalibr_yaml",
           "known_units", "noise_densities", "parse_unit", "unit_system"]

G0 = 9.80665  # standard gravity, m/s^2
BI_AD_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # AD floor of flicker noise = 0.6643 B


@dataclass(frozen=True)
class UnitSystem:
    """How a datasheet prints the coefficients of a signal in unit ``unit``.

    Each entry is ``(label, factor)``: the datasheet value is ``factor`` times the SI-second
    coefficient in signal units (white: u sqrt(s); random walk: u/sqrt(s); QN: u s; ramp: u/s;
    level (GM sigma, SIN amplitude, bias instability): u). ``si`` converts one signal unit to SI
    (rad/s or m/s^2) for Kalibr-style noise densities; ``sensor`` is 'gyroscope', 'accelerometer'
    or None.
    """

    unit: str
    sensor: str | None
    white_name: str
    rw_name: str
    white: tuple[str, float]
    rw: tuple[str, float]
    qn: tuple[str, float]
    ramp: tuple[str, float]
    level: tuple[str, float]
    si: float | None


_H, _SQH = 3600.0, 60.0
DEG = math.pi / 180.0

#: Signal units of inertial sensors: name -> (sensor, value of one unit in SI (rad/s or m/s^2)).
#: Gyroscope units print datasheet coefficients in degrees (deg/sqrt(h), deg/h/sqrt(h)) except
#: rad/s, which keeps SI labels (rad/s/sqrt(Hz), as Kalibr-style tools read them); accelerometer
#: units print them in m/s (m/s/sqrt(h), m/s/h/sqrt(h)) with levels in mg.
SIGNAL_UNITS: Mapping[str, tuple[str, float]] = {
    "rad/s": ("gyroscope", 1.0),
    "deg/s": ("gyroscope", DEG),
    "deg/h": ("gyroscope", DEG / _H),
    "mdps": ("gyroscope", 1e-3 * DEG),
    "m/s^2": ("accelerometer", 1.0),
    "g": ("accelerometer", G0),
    "mg": ("accelerometer", 1e-3 * G0),
    "ug": ("accelerometer", 1e-6 * G0),
}
_ALIASES = {"deg/sec": "deg/s", "dps": "deg/s", "°/s": "deg/s", "deg s^-1": "deg/s",
            "rad/sec": "rad/s", "rad s^-1": "rad/s", "rad*s^-1": "rad/s", "rps": "rad/s",
            "deg/hr": "deg/h", "°/h": "deg/h", "dph": "deg/h", "mdeg/s": "mdps",
            "m/s2": "m/s^2", "m/s**2": "m/s^2", "m/s²": "m/s^2", "mps2": "m/s^2",
            "m s^-2": "m/s^2", "m*s^-2": "m/s^2", "m_s2": "m/s^2", "µg": "ug", "μg": "ug",
            "micro-g": "ug", "microg": "ug", "milli-g": "mg", "millig": "mg"}
#: ``"0.00875*deg/s"`` or ``"0.00875 deg/s"``: raw counts (LSB) scaled to a known unit.
_SCALED = re.compile(r"^\s*(?P<k>[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*[* ]\s*(?P<u>\S.*?)\s*$")


def _canonical(text: str) -> str | None:
    """The :data:`SIGNAL_UNITS` key of ``text`` (case-insensitive, with spelling aliases), or None."""
    key = text.strip()
    if key in SIGNAL_UNITS:
        return key
    low = key.lower()
    return _ALIASES.get(key) or _ALIASES.get(low) or (low if low in SIGNAL_UNITS else None)


def known_units() -> str:
    """The known signal units, for messages."""
    return ", ".join(SIGNAL_UNITS) + " (or 'K*UNIT' for raw counts of K UNIT each, e.g. 0.00875*deg/s)"


def parse_unit(text: str | None) -> tuple[str, float, str] | None:
    """Validate a user's signal unit: ``(unit, scale, sensor)`` where the signal value times
    ``scale`` is in ``unit`` (a :data:`SIGNAL_UNITS` key; ``scale`` is 1 except for raw counts
    given as ``"K*UNIT"``); None for None/empty. An unknown unit is an :class:`InputError` listing
    the known ones."""
    if text is None or not str(text).strip():
        return None
    text = str(text)
    key = _canonical(text)
    scale = 1.0
    if key is None and (m := _SCALED.match(text)) is not None:
        try:
            scale = float(m.group("k"))
        except ValueError:
            scale = float("nan")
        key = _canonical(m.group("u"))
        if key is not None and not (math.isfinite(scale) and scale > 0):
            raise InputError(f"unit {text!r}: the count scale must be a positive number")
    if key is None:
        raise InputError(f"unknown unit {text!r}; known units: {known_units()}")
    return key, scale, SIGNAL_UNITS[key][0]


def _system(key: str, scale: float, label: str) -> UnitSystem:
    sensor, si = SIGNAL_UNITS[key]
    si *= scale
    if key == "rad/s":
        return UnitSystem(label, sensor, "ARW", "RRW", ("rad/s/sqrt(Hz)", si),
                          ("rad/s^2/sqrt(Hz)", si), ("rad", si), ("rad/s^2", si), ("rad/s", si), si)
    if sensor == "gyroscope":
        d = si / DEG  # one signal unit in deg/s
        return UnitSystem(label, sensor, "ARW", "RRW", ("deg/sqrt(h)", d * _SQH),
                          ("deg/h/sqrt(h)", d * _H * _SQH), ("deg", d), ("deg/h/h", d * _H * _H),
                          ("deg/h", d * _H), si)
    return UnitSystem(label, sensor, "VRW", "AccRW", ("m/s/sqrt(h)", si * _SQH),
                      ("m/s/h/sqrt(h)", si * _H * _SQH), ("m/s", si), ("m/s/h/h", si * _H * _H),
                      ("mg", si * 1e3 / G0), si)


UNIT_SYSTEMS: Mapping[str, UnitSystem] = {k: _system(k, 1.0, k) for k in SIGNAL_UNITS}


def unit_system(units: str | None) -> UnitSystem:
    """The :class:`UnitSystem` of ``units`` (a :data:`SIGNAL_UNITS` unit, an alias such as 'dps',
    'm/s2', 'µg', or raw counts 'K*UNIT'); any other text (or None: 'u') gives generic SI-second
    labels built from it, e.g. 'V/sqrt(Hz)'. Validate user input with :func:`parse_unit`."""
    text = (units or "").strip()
    try:
        parsed = parse_unit(text)
    except InputError:
        parsed = None
    if parsed is not None:
        key, scale, _ = parsed
        return UNIT_SYSTEMS[key] if scale == 1.0 else _system(key, scale, text)
    u = text or "u"
    wrap = f"({u})" if any(c in u for c in "/*^ ") else u
    return UnitSystem(u, None, "WN", "RW", (f"{wrap}/sqrt(Hz)", 1.0), (f"{wrap}/sqrt(s)", 1.0),
                      (f"{wrap}*s", 1.0), (f"{wrap}/s", 1.0), (u, 1.0), None)


# --------------------------------------------------------------------------------------------------
# datasheet coefficients of a fit
# --------------------------------------------------------------------------------------------------


def _split(name: str) -> tuple[str, int, str]:
    comp, par = name.split(".", 1)
    ctype, k = comp[:-1].split("[")
    return ctype, int(k), par


def _entry(value: float | None, unit: str, ci: tuple[float, float] | None, params: Sequence[str]
           ) -> dict[str, Any]:
    ok = ci is not None and not (math.isnan(ci[0]) or math.isnan(ci[1]))
    return {"value": None if value is None or not np.isfinite(value) else float(value), "unit": unit,
            "ci95": [float(ci[0]), float(ci[1])] if ok else None, "parameters": list(params)}


def _intervals(result: Any, alpha: float) -> np.ndarray:
    """(p, 2) parameter intervals inside the domain: the result's own ``conf_int`` (a GMWM fit:
    :func:`gmwm.intervals.fit_intervals`), else the rule of :func:`gmwm.intervals.param_intervals`
    from ``model``, ``params``, ``cov``/``se`` (NaN where there is no SE)."""
    if callable(getattr(result, "conf_int", None)):
        return np.asarray(result.conf_int(alpha), dtype=float)
    from gmwm.intervals import param_intervals

    cov = getattr(result, "cov", None)
    return param_intervals(result.model, result.params, cov, alpha,
                           se=getattr(result, "se", None))


def _fit_cov(result: Any, idx: list[int]) -> np.ndarray | None:
    cov = getattr(result, "cov", None)
    if cov is not None:
        cov = np.asarray(cov, float)
        if cov.ndim == 2 and cov.shape[0] > max(idx):
            return cov[np.ix_(idx, idx)]
    se = getattr(result, "se", None)
    if se is None:
        return None
    return np.diag(np.asarray(se, float)[idx] ** 2)


def datasheet(result: Any, units: str | None = None, alpha: float = 0.05) -> dict[str, dict]:
    """Continuous datasheet coefficients of a fit (see the module table), keyed by term.

    ``result`` has ``model``, ``params``, ``param_names``, ``se`` (and ``cov``), ``wv.freq`` [Hz]
    and, as every result, ``conf_int(alpha)``; ``units`` is the signal unit ('deg/s', 'rad/s',
    'm/s^2', 'g' or any label). Returns e.g. ``{"ARW": {"value", "unit", "ci95", "parameters"},
    "GM[1]": {"correlation_time": {...}, "sigma": {...}}, "SIN[1]": {"frequency": {...},
    "amplitude": {...}}}``; ``ci95`` (at level ``1 - alpha``) is None when the fit has no
    interval for the parameter (no standard error).

    Intervals: a coefficient that is a monotone function of one parameter takes the image of that
    parameter's interval (:func:`gmwm.intervals.image_interval`), so the datasheet agrees with the
    parameter table by construction and reaches 0 exactly where the parameter's interval does (a
    component not distinguishable from zero, or at the boundary 0). The AR1 stationary sigma
    (phi and the innovation variance) uses the delta method with the same rule on the stationary
    variance (:func:`gmwm.intervals.function_interval`).
    """
    from gmwm.intervals import function_interval, image_interval

    us = unit_system(units)
    freq = float(result.wv.freq)
    names = list(result.param_names)
    theta_all = np.asarray(result.params, float)
    ci_all = _intervals(result, alpha)
    comps: dict[tuple[str, int], dict[str, int]] = {}
    for i, name in enumerate(names):
        ctype, k, par = _split(name)
        comps.setdefault((ctype, k), {})[par] = i
    counts: dict[str, int] = {}
    for ctype, _ in comps:
        counts[ctype] = counts.get(ctype, 0) + 1
    out: dict[str, dict] = {}

    def image(fn, i: int, label_factor: tuple[str, float]) -> dict[str, Any]:
        """The entry of ``factor * fn(theta_i)``, ``fn`` monotone."""
        label, factor = label_factor
        ci = image_interval(lambda t: factor * fn(t), ci_all[i])
        return _entry(factor * fn(theta_all[i]), label, ci, [names[i]])

    def blank_shape(entry: dict[str, Any], size: str, shape: str) -> dict[str, Any]:
        # a component estimated at 0 has no identifiable time scale or frequency
        if entry[size]["value"] == 0.0:
            entry[shape].update(value=None, ci95=None, note=f"not identified: {size} is 0")
        return entry

    def corr_time_of_phi(phi: float) -> float:
        # -1 / (f_s ln phi), increasing on (0, 1); 0 for phi <= 0, infinite for phi >= 1
        if phi <= 0:
            return 0.0
        return math.inf if phi >= 1 else -1.0 / (freq * math.log(phi))

    def ar1_sigma(idx: list[int]) -> dict[str, Any]:
        """The stationary sigma sqrt(sigma2 / (1 - phi^2)) of an AR1 [signal units]."""
        label, factor = us.level
        i_s2 = idx[1]
        theta = theta_all[idx]

        def var(t: np.ndarray) -> float:
            return max(t[1], 0.0) / max(1.0 - t[0] ** 2, 1e-300)

        reaches_zero = ci_all[i_s2, 0] == 0.0
        phi_lo, phi_hi = ci_all[idx[0]]
        cov = _fit_cov(result, idx)
        ci = (float("nan"), float("nan"))
        cov_ok = cov is not None and bool(np.all(np.isfinite(cov)))
        if cov_ok and -1.0 < phi_lo and phi_hi < 1.0:
            ci = function_interval(var, theta, cov, alpha, weak=bool(reaches_zero))
        elif not cov_ok and reaches_zero:
            # at the boundary 0 (no covariance): the variance's interval at the reported phi
            ci = image_interval(lambda s2: var(np.array([theta[0], s2])), ci_all[i_s2])
        if math.isnan(ci[0]) and not np.isnan(ci_all[i_s2]).any():
            # phi's interval reaches +-1 (the linearisation fails there) or the delta method
            # failed: the image of the box of the two intervals (the stationary variance grows
            # with sigma2 and |phi|), unbounded above when phi may be +-1
            if np.isnan([phi_lo, phi_hi]).any():
                phi_lo = phi_hi = theta[0]
            p2_lo = 0.0 if phi_lo <= 0.0 <= phi_hi else min(phi_lo**2, phi_hi**2)
            p2_hi = max(phi_lo**2, phi_hi**2)
            s2_lo, s2_hi = ci_all[i_s2]
            lo = s2_lo / (1.0 - p2_lo) if p2_lo < 1.0 else (0.0 if s2_lo == 0 else math.inf)
            ci = (lo, s2_hi / (1.0 - p2_hi) if p2_hi < 1.0 else math.inf)
        ci = image_interval(lambda v: factor * math.sqrt(v), ci)
        return _entry(factor * math.sqrt(var(theta)), label, ci, [names[i] for i in idx])

    gm_k = 0
    for (ctype, k), pars in comps.items():
        suffix = f"[{k}]" if counts[ctype] > 1 else ""
        if ctype == "WN":
            out[us.white_name + suffix] = image(lambda s: math.sqrt(max(s, 0.0) / freq),
                                                pars["sigma2"], us.white)
        elif ctype == "RW":
            out[us.rw_name + suffix] = image(lambda g: math.sqrt(max(g, 0.0) * freq),
                                             pars["gamma2"], us.rw)
        elif ctype == "QN":
            out["QN" + suffix] = image(lambda q: math.sqrt(max(q, 0.0)) / freq, pars["Q2"], us.qn)
        elif ctype == "DR":
            out["RR" + suffix] = image(lambda w: w * freq, pars["omega"], us.ramp)
        elif ctype == "SIN":
            ia, ib = pars["alpha"], pars["beta"]
            entry = {"frequency": image(lambda b: b * freq / (2 * math.pi), ib, ("Hz", 1.0)),
                     "amplitude": image(abs, ia, us.level)}
            for e in entry.values():
                e["parameters"] = [names[ia], names[ib]]
            out[f"SIN[{k}]"] = blank_shape(entry, "amplitude", "frequency")
        elif ctype == "GM":
            gm_k += 1
            ib, i2 = pars["beta"], pars["sigma2"]
            entry = {"correlation_time": image(lambda b: 1.0 / b if b > 0 else math.inf, ib,
                                               ("s", 1.0)),
                     "sigma": image(lambda s2: math.sqrt(max(s2, 0.0)), i2, us.level)}
            for e in entry.values():
                e["parameters"] = [names[ib], names[i2]]
            out[f"GM[{gm_k}]"] = blank_shape(entry, "sigma", "correlation_time")
        elif ctype == "AR1":
            idx = [pars["phi"], pars["sigma2"]]
            phi = theta_all[idx[0]]
            if 0.0 < phi < 1.0:  # a Gauss-Markov process sampled at f_s
                gm_k += 1
                entry = {"correlation_time": image(corr_time_of_phi, idx[0], ("s", 1.0)),
                         "sigma": ar1_sigma(idx)}
                entry["correlation_time"]["parameters"] = [names[i] for i in idx]
                out[f"GM[{gm_k}]"] = blank_shape(entry, "sigma", "correlation_time")
            else:  # phi <= 0 has no continuous-time counterpart: report the AR1 itself
                out[f"AR1[{k}]"] = {"sigma": ar1_sigma(idx),
                                    "phi": image(lambda p: p, idx[0], ("", 1.0))}
    return out


# --------------------------------------------------------------------------------------------------
# IEEE 952 Allan-deviation readings
# --------------------------------------------------------------------------------------------------


def _line_reading(tau: np.ndarray, adev: np.ndarray, lo: np.ndarray, hi: np.ndarray, w: np.ndarray,
                  slope: float, tau_read: float, tol: float) -> dict[str, Any] | None:
    """Fixed-slope line through the heaviest (by edof) run of at least 2 adjacent points whose local
    log-log slope is within ``tol`` of ``slope``, read at ``tau_read`` [s]. CI: the same line through the points'
    CI bounds (edof-weighted), i.e. about one point's uncertainty (conservative)."""
    lt, ld = np.log10(tau), np.log10(adev)
    if tau.size < 3:
        return None
    local = np.gradient(ld, lt)
    ok = np.abs(local - slope) <= tol
    runs, start = [], None
    for i, flag in enumerate([*ok, False]):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            runs.append((start, i))
            start = None
    runs = [r for r in runs if r[1] - r[0] >= 2]  # one point is no slope region
    if not runs:
        return None
    a, b = max(runs, key=lambda r: float(w[r[0]:r[1]].sum()))
    ww = w[a:b] / w[a:b].sum()

    def at(y: np.ndarray) -> float:
        c = float(ww @ (np.log10(y[a:b]) - slope * lt[a:b]))
        return 10.0 ** (c + slope * math.log10(tau_read))

    return {"value": at(adev), "ci95": [at(lo), at(hi)], "tau_range_s": [float(tau[a]),
                                                                          float(tau[b - 1])],
            "n_points": b - a, "extrapolated": not tau[a] <= tau_read <= tau[b - 1]}


def allan_readings(av: Any, units: str | None = None, tol: float = 0.15) -> dict[str, dict]:
    """IEEE 952 readings of a maximal-overlap Allan variance ``av`` (``tau`` [s], ``avar``,
    ``ci_low``, ``ci_high``, ``clusters``, ``n``):

    * ``N`` (white noise, ARW/VRW): the slope -1/2 line read at tau = 1 s;
    * ``K`` (random walk, RRW/AccRW): the slope +1/2 line read at tau = 3 s;
    * ``B`` (bias instability): the AD minimum / 0.6643 (``at_end`` when the minimum is the longest
      cluster time, so B is then an upper bound of the floor not yet reached).

    Slope lines use the points whose local log-log slope is within ``tol`` of the nominal one.
    Values in the datasheet units of ``units`` (N, K, B labels as in :func:`datasheet`); a reading
    with no region of its slope is ``{"value": None, "note": ...}``.
    """
    us = unit_system(units)
    tau = np.asarray(av.tau, float)
    var = np.asarray(av.avar, float)
    lo, hi = np.asarray(av.ci_low, float), np.asarray(av.ci_high, float)
    m = np.asarray(av.clusters, float)
    n = np.asarray(av.n, float)
    keep = (var > 0) & (lo > 0) & np.isfinite(hi)
    if keep.sum() < 3:
        raise InputError("the Allan variance needs at least 3 positive values for the readings")
    tau, var, lo, hi, m, n = (a[keep] for a in (tau, var, lo, hi, m, n))
    adev, dlo, dhi = np.sqrt(var), np.sqrt(lo), np.sqrt(hi)
    w = np.maximum(n / (2.0 * m), 1.0)  # equivalent degrees of freedom of each point
    out: dict[str, dict] = {}
    for key, slope, tau_read, (label, factor), name in (
            ("N", -0.5, 1.0, us.white, us.white_name), ("K", 0.5, 3.0, us.rw, us.rw_name)):
        r = _line_reading(tau, adev, dlo, dhi, w, slope, tau_read, tol)
        if r is None:
            out[key] = {"value": None, "unit": label, "ci95": None, "name": name,
                        "note": f"no region of slope {slope:+g} in the Allan deviation"}
            continue
        r["value"] *= factor
        r["ci95"] = [c * factor for c in r["ci95"]]
        out[key] = {"name": name, "unit": label, **r, "read_at_tau_s": tau_read}
    i = int(np.argmin(adev))
    label, factor = us.level
    out["B"] = {"name": "bias instability", "value": factor * adev[i] / BI_AD_FACTOR, "unit": label,
                "ci95": [factor * dlo[i] / BI_AD_FACTOR, factor * dhi[i] / BI_AD_FACTOR],
                "tau_s": float(tau[i]), "at_end": bool(i == adev.size - 1)}
    return out


# --------------------------------------------------------------------------------------------------
# Kalibr-style noise densities
# --------------------------------------------------------------------------------------------------


def noise_densities(result: Any, units: str) -> dict[str, float | None]:
    """White-noise density [SI/sqrt(Hz)] and random-walk density [SI/s/sqrt(Hz)] of a fit, in
    rad/s (gyroscope) or m/s^2 (accelerometer), as Kalibr-style tools expect; None for a term
    the model lacks. ``units`` must be one of 'deg/s', 'rad/s', 'm/s^2', 'g'."""
    us = unit_system(units)
    if us.si is None:
        raise InputError(f"noise densities need a known unit (deg/s, rad/s, m/s^2, g), got {units!r}")
    freq = float(result.wv.freq)
    d = dict(zip(result.param_names, np.asarray(result.params, float), strict=True))
    wn = d.get("WN[1].sigma2")
    rw = d.get("RW[1].gamma2")
    return {"noise_density": None if wn is None else us.si * math.sqrt(max(wn, 0.0) / freq),
            "random_walk": None if rw is None else us.si * math.sqrt(max(rw, 0.0) * freq)}


def kalibr_yaml(per_axis: Mapping[str, tuple[str, Any]], update_rate: float) -> str:
    """A Kalibr ``imu.yaml`` block from fits: ``per_axis[column] = (units, result)``.

    Each sensor type gets the largest density over its axes (the conservative choice for a filter);
    the comment lines name the axis each value came from. Keys: gyroscope_noise_density
    [rad/s/sqrt(Hz)], gyroscope_random_walk [rad/s^2/sqrt(Hz)], accelerometer_noise_density
    [m/s^2/sqrt(Hz)], accelerometer_random_walk [m/s^3/sqrt(Hz)], update_rate [Hz].
    """
    best: dict[str, tuple[float, str]] = {}
    for col, (units, res) in per_axis.items():
        sensor = unit_system(units).sensor
        if sensor is None:
            continue
        prefix = "gyroscope" if sensor == "gyroscope" else "accelerometer"
        for key, v in noise_densities(res, units).items():
            name = f"{prefix}_{key}"
            if v is not None and (name not in best or v > best[name][0]):
                best[name] = (v, col)
    lines = ["# noise densities of the largest axis per sensor, SI units (Kalibr imu.yaml)"]
    for name in ("accelerometer_noise_density", "accelerometer_random_walk",
                 "gyroscope_noise_density", "gyroscope_random_walk"):
        if name in best:
            lines.append(f"{name}: {best[name][0]:.6e}  # from {best[name][1]}")
        else:
            lines.append(f"# {name}: not estimated (no such axis or term in the model)")
    lines.append(f"update_rate: {update_rate:g}")
    return "\n".join(lines)
