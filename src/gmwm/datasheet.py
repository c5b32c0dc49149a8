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
gyroscope in deg/s). Confidence intervals come from the fit's covariance by the delta method, formed
on the log scale so they stay positive. The module imports only NumPy (fast CLI start).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from statistics import NormalDist
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["SIGNAL_UNITS", "TERM_KINDS", "UNIT_SYSTEMS", "CoefficientUnit", "UnitSystem",
           "allan_readings", "coefficient_unit", "convert", "datasheet", "from_signal_units",
           "kalibr_yaml", "known_units", "noise_densities", "parse_unit", "to_signal_units",
           "unit_system"]

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
# units of datasheet coefficients (deg/sqrt(h), ug/sqrt(Hz), m/s/h/sqrt(h), ...)
# --------------------------------------------------------------------------------------------------
#
# A small parser rather than a units library: datasheet notation differs from SI conventions in
# ways a general library would have to be taught anyway (g is standard gravity, not the gram; mg
# and ug are milli-/micro-g; sqrt(h), rtHz, deg/hr), and the vocabulary is closed. Dimensions are
# kept as exponents of (angle, length, time), angle counted as its own dimension so that a gyroscope
# coefficient is never converted into an accelerometer one.

_DIMS = ("angle", "length", "time")
#: unit name -> ((angle, length, time) exponents, value in rad / m / s)
_BASE_UNITS: Mapping[str, tuple[tuple[int, int, int], float]] = {
    "rad": ((1, 0, 0), 1.0), "mrad": ((1, 0, 0), 1e-3), "urad": ((1, 0, 0), 1e-6),
    "deg": ((1, 0, 0), DEG), "mdeg": ((1, 0, 0), 1e-3 * DEG),
    "arcmin": ((1, 0, 0), DEG / 60.0), "arcsec": ((1, 0, 0), DEG / 3600.0),
    "m": ((0, 1, 0), 1.0), "cm": ((0, 1, 0), 1e-2), "mm": ((0, 1, 0), 1e-3),
    "ft": ((0, 1, 0), 0.3048),
    "s": ((0, 0, 1), 1.0), "ms": ((0, 0, 1), 1e-3), "us": ((0, 0, 1), 1e-6),
    "min": ((0, 0, 1), 60.0), "h": ((0, 0, 1), _H), "d": ((0, 0, 1), 86400.0),
    "Hz": ((0, 0, -1), 1.0), "kHz": ((0, 0, -1), 1e3),
    "g": ((0, 1, -2), G0), "mg": ((0, 1, -2), 1e-3 * G0), "ug": ((0, 1, -2), 1e-6 * G0),
    "dps": ((1, 0, -1), DEG), "mdps": ((1, 0, -1), 1e-3 * DEG),
}
_UNIT_ALIASES = {"°": "deg", "degree": "deg", "degrees": "deg", "sec": "s", "second": "s",
                 "hr": "h", "hour": "h", "hours": "h", "µg": "ug", "μg": "ug", "µrad": "urad",
                 "μrad": "urad", "µs": "us", "μs": "us", "hz": "Hz", "khz": "kHz", "day": "d",
                 "days": "d", "mins": "min", "minute": "min", "minutes": "min", "″": "arcsec",
                 "′": "arcmin", "gee": "g", "mgee": "mg"}
_TOKEN = re.compile(r"\s*(?:(?P<num>\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)|(?P<name>[A-Za-z°µμ″′_]+)"
                    r"|(?P<op>\*\*|[*/^()·√²³-]))")


@dataclass(frozen=True)
class CoefficientUnit:
    """A parsed coefficient unit: ``factor`` converts one of it to SI (rad, m, s) with the
    dimension ``dims`` = exponents of (angle, length, time)."""

    text: str
    dims: tuple[Fraction, Fraction, Fraction]
    factor: float

    def describe(self) -> str:
        """The dimension in words, e.g. 'angle time^-1/2'."""
        parts = [f"{n}" + ("" if e == 1 else f"^{e}") for n, e in zip(_DIMS, self.dims,
                                                                    strict=True) if e]
        return " ".join(parts) or "dimensionless"


class _UnitParser:
    """Recursive descent over ``expr := factor (('*' | '/' | '·') factor)*``, ``factor := atom
    ('^' number)?``, ``atom := name | number | 'sqrt' '(' expr ')' | 'rt' name | '√' atom |
    '(' expr ')'``; ``a/b/c`` is ``a b^-1 c^-1``."""

    def __init__(self, text: str):
        self.text = text
        self.toks: list[tuple[str, str]] = []
        pos, s = 0, text.strip()
        while pos < len(s):
            m = _TOKEN.match(s, pos)
            if m is None or m.end() == pos:
                raise InputError(f"unit {text!r}: cannot read {s[pos:]!r}")
            kind = m.lastgroup or ""
            self.toks.append((kind, m.group(kind)))
            pos = m.end()
        self.i = 0

    def peek(self) -> tuple[str, str] | None:
        return self.toks[self.i] if self.i < len(self.toks) else None

    def take(self) -> tuple[str, str]:
        tok = self.peek()
        if tok is None:
            raise InputError(f"unit {self.text!r}: unexpected end")
        self.i += 1
        return tok

    def parse(self) -> tuple[list[Fraction], float]:
        if not self.toks:
            raise InputError("empty unit")
        dims, factor = self.expr()
        if self.peek() is not None:
            raise InputError(f"unit {self.text!r}: unexpected {self.peek()[1]!r}")
        return dims, factor

    def expr(self) -> tuple[list[Fraction], float]:
        dims, factor = self.factor()
        while (tok := self.peek()) is not None and tok[1] in ("*", "/", "·"):
            self.take()
            d2, f2 = self.factor()
            sign = -1 if tok[1] == "/" else 1
            dims = [a + sign * b for a, b in zip(dims, d2, strict=True)]
            factor = factor * f2 ** sign
        return dims, factor

    def factor(self) -> tuple[list[Fraction], float]:
        dims, factor = self.atom()
        tok = self.peek()
        if tok is not None and tok[1] in ("^", "**", "²", "³"):
            self.take()
            if tok[1] in ("²", "³"):
                power = Fraction(2 if tok[1] == "²" else 3)
            else:
                neg = False
                if self.peek() is not None and self.peek()[1] == "-":
                    self.take()
                    neg = True
                kind, val = self.take()
                if kind != "num":
                    raise InputError(f"unit {self.text!r}: exponent must be a number, got {val!r}")
                power = -Fraction(val) if neg else Fraction(val)
            dims = [d * power for d in dims]
            factor = factor ** float(power)
        return dims, factor

    def atom(self) -> tuple[list[Fraction], float]:
        kind, val = self.take()
        if val == "(":
            out = self.expr()
            if self.peek() is None or self.take()[1] != ")":
                raise InputError(f"unit {self.text!r}: missing ')'")
            return out
        if val == "√":
            dims, factor = self.atom()
            return [d / 2 for d in dims], math.sqrt(factor)
        if kind == "num":
            return [Fraction(0)] * 3, float(val)
        if kind == "name":
            low = val.lower()
            if low in ("sqrt", "rt") and self.peek() is not None and self.peek()[1] == "(":
                dims, factor = self.atom()
                return [d / 2 for d in dims], math.sqrt(factor)
            if low.startswith("rt") and len(val) > 2:  # rtHz, rthr
                dims, factor = self._name(val[2:])
                return [d / 2 for d in dims], math.sqrt(factor)
            if low == "rt" and self.peek() is not None and self.peek()[1] == "-":  # rt-hr
                self.take()
                dims, factor = self.atom()
                return [d / 2 for d in dims], math.sqrt(factor)
            return self._name(val)
        raise InputError(f"unit {self.text!r}: unexpected {val!r}")

    def _name(self, name: str) -> tuple[list[Fraction], float]:
        key = name if name in _BASE_UNITS else _UNIT_ALIASES.get(name, _UNIT_ALIASES.get(
            name.lower(), name.lower() if name.lower() in _BASE_UNITS and name.lower() != "hz"
            else None))
        if key is None or key not in _BASE_UNITS:
            raise InputError(f"unit {self.text!r}: unknown unit {name!r} (known: "
                             + ", ".join(_BASE_UNITS) + ")")
        d, f = _BASE_UNITS[key]
        return [Fraction(x) for x in d], f


def coefficient_unit(text: str) -> CoefficientUnit:
    """Parse the unit of a datasheet coefficient, e.g. 'deg/sqrt(h)', 'deg/s/rtHz',
    'ug/sqrt(Hz)', 'm/s/h/sqrt(h)', 'mg', 'deg/h', '°/√h', 'rad/s^2/sqrt(Hz)'. ``g``, ``mg`` and
    ``ug`` are (milli-, micro-) standard gravity. An unreadable or unknown unit is an
    :class:`InputError` naming it."""
    dims, factor = _UnitParser(str(text)).parse()
    if not (math.isfinite(factor) and factor > 0):
        raise InputError(f"unit {text!r}: not a positive finite scale")
    return CoefficientUnit(str(text).strip(), (dims[0], dims[1], dims[2]), float(factor))


def convert(value: float, from_unit: str, to_unit: str) -> float:
    """``value`` in ``from_unit`` expressed in ``to_unit`` (same dimension required), e.g.
    ``convert(0.66, "deg/sqrt(h)", "rad/s/sqrt(Hz)")``."""
    a, b = coefficient_unit(from_unit), coefficient_unit(to_unit)
    if a.dims != b.dims:
        raise InputError(f"cannot convert {from_unit} ({a.describe()}) to {to_unit} "
                         f"({b.describe()})")
    return float(value) * a.factor / b.factor


#: Datasheet terms and the power of seconds by which each differs from the signal unit ``u``
#: (§10.1 forms): white N [u s^1/2], random walk K [u s^-1/2], quantization Q [u s], ramp R
#: [u s^-1], level (bias instability, GM sigma) [u]; ``time`` (a correlation time) is in s.
TERM_KINDS: Mapping[str, Fraction] = {"white": Fraction(1, 2), "random_walk": Fraction(-1, 2),
                                      "quantization": Fraction(1), "ramp": Fraction(-1),
                                      "level": Fraction(0)}
_SENSOR_DIMS = {"gyroscope": (Fraction(1), Fraction(0), Fraction(-1)),
                "accelerometer": (Fraction(0), Fraction(1), Fraction(-2))}


def _signal(signal_unit: str) -> tuple[str, float]:
    parsed = parse_unit(signal_unit)
    if parsed is None:
        raise InputError("a signal unit is needed to convert datasheet coefficients")
    key, scale, sensor = parsed
    return sensor, SIGNAL_UNITS[key][1] * scale


def _term_dims(kind: str, sensor: str) -> tuple[Fraction, Fraction, Fraction]:
    if kind == "time":
        return (Fraction(0), Fraction(0), Fraction(1))
    if kind not in TERM_KINDS:
        raise InputError(f"unknown term kind {kind!r}; use one of {', '.join(TERM_KINDS)}, time")
    a, length, t = _SENSOR_DIMS[sensor]
    return (a, length, t + TERM_KINDS[kind])


def to_signal_units(value: float, unit: str, kind: str, signal_unit: str) -> float:
    """A datasheet coefficient (``value`` in ``unit``) as the continuous coefficient of §10.1 in
    the signal unit ``u`` and seconds (white: u sqrt(s), random walk: u/sqrt(s), quantization:
    u s, ramp: u/s, level: u; ``kind="time"``: seconds). The unit's dimension must be the
    term's for the signal's sensor (a gyroscope unit for a gyroscope), else an InputError."""
    sensor, si = _signal(signal_unit)
    cu = coefficient_unit(unit)
    want = _term_dims(kind, sensor)
    if cu.dims != want:
        got = cu.describe()
        raise InputError(f"{value:g} {unit} ({got}) is not a {kind.replace('_', ' ')} term of a "
                         f"{sensor} signal in {signal_unit}")
    return float(value) * cu.factor / (1.0 if kind == "time" else si)


def from_signal_units(value: float, kind: str, signal_unit: str, unit: str) -> float:
    """Inverse of :func:`to_signal_units`: a continuous coefficient in the signal unit and seconds
    expressed in the datasheet unit ``unit``."""
    return float(value) / to_signal_units(1.0, unit, kind, signal_unit)


# --------------------------------------------------------------------------------------------------
# datasheet coefficients of a fit
# --------------------------------------------------------------------------------------------------


def _split(name: str) -> tuple[str, int, str]:
    comp, par = name.split(".", 1)
    ctype, k = comp[:-1].split("[")
    return ctype, int(k), par


def _entry(value: float | None, unit: str, ci: tuple[float, float] | None, params: Sequence[str]
           ) -> dict[str, Any]:
    return {"value": None if value is None or not np.isfinite(value) else float(value), "unit": unit,
            "ci95": None if ci is None else [float(ci[0]), float(ci[1])], "parameters": list(params)}


def _delta_ci(fn, theta: np.ndarray, cov: np.ndarray | None, z: float) -> tuple[float, float] | None:
    """CI of the positive quantity ``fn(theta)`` by the delta method on the log scale."""
    value = fn(theta)
    if cov is None or not np.all(np.isfinite(cov)) or not (value > 0 and np.isfinite(value)):
        return None
    grad = np.empty(theta.size)
    for i in range(theta.size):
        h = 1e-6 * max(abs(theta[i]), 1e-300)
        up, dn = theta.copy(), theta.copy()
        up[i] += h
        dn[i] -= h
        grad[i] = (fn(up) - fn(dn)) / (2 * h)
    if not np.all(np.isfinite(grad)):
        return None
    var = float(grad @ cov @ grad)
    if not np.isfinite(var) or var < 0:
        return None
    half = z * math.sqrt(var) / value
    if half > 700.0:  # a factor beyond e^700 either way: no usable interval (float overflow)
        return None
    return value * math.exp(-half), value * math.exp(half)


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

    ``result`` has ``params``, ``param_names``, ``se`` (and ``cov``), ``wv.freq`` [Hz]; ``units`` is
    the signal unit ('deg/s', 'rad/s', 'm/s^2', 'g' or any label). Returns e.g.
    ``{"ARW": {"value", "unit", "ci95", "parameters"}, "GM[1]": {"correlation_time": {...},
    "sigma": {...}}, "SIN[1]": {"frequency": {...}, "amplitude": {...}}}``; ``ci95`` is None when the
    fit has no usable standard error (e.g. a component at the boundary 0).
    """
    us = unit_system(units)
    freq = float(result.wv.freq)
    names = list(result.param_names)
    theta_all = np.asarray(result.params, float)
    z = NormalDist().inv_cdf(1 - alpha / 2)
    comps: dict[tuple[str, int], dict[str, int]] = {}
    for i, name in enumerate(names):
        ctype, k, par = _split(name)
        comps.setdefault((ctype, k), {})[par] = i
    counts: dict[str, int] = {}
    for ctype, _ in comps:
        counts[ctype] = counts.get(ctype, 0) + 1
    out: dict[str, dict] = {}

    def scalar(key: str, par_idx: int, fn, label_factor: tuple[str, float]) -> None:
        label, factor = label_factor
        theta = theta_all[[par_idx]]
        cov = _fit_cov(result, [par_idx])
        ci = _delta_ci(lambda t: factor * fn(t[0]), theta, cov, z)
        out[key] = _entry(factor * fn(theta[0]), label, ci, [names[par_idx]])

    def pair(idx: list[int], fns: dict[str, tuple[Any, tuple[str, float]]]) -> dict[str, Any]:
        theta = theta_all[idx]
        cov = _fit_cov(result, idx)
        entry: dict[str, Any] = {}
        for what, (fn, (label, factor)) in fns.items():
            ci = _delta_ci(lambda t, fn=fn, f=factor: f * fn(t), theta, cov, z)
            entry[what] = _entry(factor * fn(theta), label, ci, [names[i] for i in idx])
        return entry

    def blank_shape(entry: dict[str, Any], size: str, shape: str) -> dict[str, Any]:
        # a component estimated at 0 has no identifiable time scale or frequency
        if entry[size]["value"] == 0.0:
            entry[shape].update(value=None, ci95=None, note=f"not identified: {size} is 0")
        return entry

    gm_k = 0
    for (ctype, k), pars in comps.items():
        suffix = f"[{k}]" if counts[ctype] > 1 else ""
        if ctype == "WN":
            scalar(us.white_name + suffix, pars["sigma2"], lambda s: math.sqrt(max(s, 0.0) / freq),
                   us.white)
        elif ctype == "RW":
            scalar(us.rw_name + suffix, pars["gamma2"], lambda g: math.sqrt(max(g, 0.0) * freq), us.rw)
        elif ctype == "QN":
            scalar("QN" + suffix, pars["Q2"], lambda q: math.sqrt(max(q, 0.0)) / freq, us.qn)
        elif ctype == "DR":
            scalar("RR" + suffix, pars["omega"], lambda w: w * freq, us.ramp)
        elif ctype == "SIN":
            idx = [pars["alpha"], pars["beta"]]
            out[f"SIN[{k}]"] = blank_shape(pair(idx, {
                "frequency": (lambda t: t[1] * freq / (2 * math.pi), ("Hz", 1.0)),
                "amplitude": (lambda t: abs(t[0]), us.level)}), "amplitude", "frequency")
        elif ctype == "GM":
            gm_k += 1
            idx = [pars["beta"], pars["sigma2"]]
            out[f"GM[{gm_k}]"] = blank_shape(pair(idx, {
                "correlation_time": (lambda t: 1.0 / t[0] if t[0] > 0 else math.inf, ("s", 1.0)),
                "sigma": (lambda t: math.sqrt(max(t[1], 0.0)), us.level)}), "sigma",
                "correlation_time")
        elif ctype == "AR1":
            idx = [pars["phi"], pars["sigma2"]]
            phi = theta_all[idx[0]]
            sigma = {"sigma": (lambda t: math.sqrt(max(t[1], 0.0) / max(1.0 - t[0] ** 2, 1e-300)),
                               us.level)}
            if 0.0 < phi < 1.0:  # a Gauss-Markov process sampled at f_s
                gm_k += 1
                out[f"GM[{gm_k}]"] = blank_shape(pair(idx, {
                    "correlation_time": (lambda t: -1.0 / (freq * math.log(min(max(t[0], 1e-300),
                                                                             1 - 1e-16))), ("s", 1.0)),
                    **sigma}), "sigma", "correlation_time")
            else:  # phi <= 0 has no continuous-time counterpart: report the AR1 itself
                entry = pair(idx, sigma)
                entry["phi"] = _entry(phi, "", None, [names[idx[0]]])
                out[f"AR1[{k}]"] = entry
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
