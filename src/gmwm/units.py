"""Units: the signal units of inertial sensors, the unit systems datasheets print coefficients
in, datasheet coefficient units, and the conversions between continuous (datasheet) coefficients
and the discrete per-sample parameters. The one module for units; the datasheet of a fit
(:func:`gmwm.datasheet.datasheet`) and the sensor datasheet files (:mod:`gmwm.sensor_datasheet`)
use it. Imports only NumPy at load (fast CLI start; the readers use :func:`parse_unit`).

Conventions (docs/METHODS.md §10, §10.5, §12.5). ``u`` is the measurement unit (deg/s, rad/s,
m/s^2); ``f_s`` = ``freq`` is the sampling frequency in Hz. Continuous coefficients are in SI
seconds:

* QN  Q [u s]          <-> ``QN[k].Q2``     Q2 = (Q f_s)^2
* WN  N [u sqrt(s)]    <-> ``WN[k].sigma2`` sigma2 = N^2 f_s   (a density in u/sqrt(Hz) is the same number)
* RW  K [u / sqrt(s)]  <-> ``RW[k].gamma2`` gamma2 = K^2 / f_s
* DR  R [u / s]        <-> ``DR[k].omega``  omega = R / f_s   (per sample, per sample)
* GM  beta [1/s], sigma2_GM [u^2] <-> AR1 phi = exp(-beta/f_s), innovation sigma2_GM (1 - phi^2)
* SIN frequency f [Hz] <-> beta = 2 pi f / f_s [rad/sample]

Hour-based datasheet units: N[./sqrt(s)] = N[./sqrt(h)] / 60, K[./s/sqrt(s)] = K[./h/sqrt(h)] / 216000,
R[./s/s] = R[./h/h] / 1.296e7. How a datasheet prints each coefficient of a signal unit:
:class:`UnitSystem` (:func:`unit_system`); a datasheet's own coefficient units (deg/sqrt(h),
ug/sqrt(Hz), ...): :func:`coefficient_unit`, :func:`to_signal_units`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from math import log, pi

import numpy as np

from gmwm.errors import InputError

SQRT_HOUR = 60.0  # sqrt(3600 s)
HOUR = 3600.0
HOUR_SQRT_HOUR = HOUR * SQRT_HOUR  # 216000
HOUR2 = HOUR * HOUR  # 1.296e7
G0 = 9.80665  # standard gravity, m/s^2
DEG2RAD = pi / 180.0
BI_AD_FACTOR = float(np.sqrt(2.0 * log(2.0) / pi))  # AD floor = 0.6643 B


def check_freq(freq: float) -> float:
    """``freq`` [Hz] as a float; an InputError unless it is finite and positive."""
    freq = float(freq)
    if not np.isfinite(freq) or freq <= 0:
        raise InputError(f"sampling frequency must be positive, got {freq}")
    return freq


def _nonneg(x, what: str):
    a = np.asarray(x, dtype=float)
    if np.any(a < 0):
        raise InputError(f"{what} must be non-negative, got {x}")
    return a if a.ndim else float(a)


# --- hour-based datasheet units -> SI seconds ---------------------------------------------------

def per_sqrt_hour_to_per_sqrt_second(n_h: float) -> float:
    """N in unit/sqrt(h) (e.g. deg/sqrt(h), m/s/sqrt(h)) -> unit/sqrt(s): divide by 60."""
    return n_h / SQRT_HOUR


def per_hour_sqrt_hour_to_per_second_sqrt_second(k_h: float) -> float:
    """K in unit/h/sqrt(h) (deg/h/sqrt(h), m/s/h/sqrt(h)) -> unit/s/sqrt(s): divide by 216000."""
    return k_h / HOUR_SQRT_HOUR


def per_hour2_to_per_second2(r_h: float) -> float:
    """R in unit/h/h (deg/h/h, m/s/h/h) -> unit/s/s: divide by 1.296e7."""
    return r_h / HOUR2


def deg_per_hour_to_rad_per_second(x: float) -> float:
    """deg/h -> rad/s (e.g. a gyro bias instability)."""
    return x * DEG2RAD / HOUR


def micro_g_to_si(x: float, g: float = G0) -> float:
    """micro-g (or micro-g/sqrt(Hz)) -> m/s^2 (or m/s^2/sqrt(Hz))."""
    return x * 1e-6 * g


# --- QN ---------------------------------------------------------------------------------------

def qn_q2_from_coefficient(q: float, freq: float) -> float:
    """Quantisation coefficient Q [u s] -> discrete Q2 = (Q f_s)^2 [u^2]."""
    return (_nonneg(q, "Q") * check_freq(freq)) ** 2


def qn_coefficient_from_q2(q2: float, freq: float) -> float:
    """Discrete Q2 [u^2] -> Q [u s] = sqrt(Q2) / f_s."""
    return np.sqrt(_nonneg(q2, "Q2")) / check_freq(freq)


# --- WN ---------------------------------------------------------------------------------------

def wn_from_density(density: float, freq: float) -> float:
    """White-noise density N [u/sqrt(Hz) = u sqrt(s)] -> per-sample variance sigma2 = N^2 f_s [u^2]."""
    return _nonneg(density, "white-noise density") ** 2 * check_freq(freq)


def wn_density_from_sigma2(sigma2: float, freq: float) -> float:
    """Per-sample WN variance sigma2 [u^2] -> density N = sqrt(sigma2 / f_s) [u sqrt(s)]."""
    return np.sqrt(_nonneg(sigma2, "sigma2") / check_freq(freq))


def wn_from_arw_per_sqrt_hour(arw: float, freq: float) -> float:
    """Angle/velocity random walk in unit/sqrt(h) (deg/sqrt(h) for u = deg/s) -> sigma2 [u^2]."""
    return wn_from_density(per_sqrt_hour_to_per_sqrt_second(arw), freq)


# --- RW ---------------------------------------------------------------------------------------

def rw_gamma2_from_coefficient(k: float, freq: float) -> float:
    """Rate random walk K [u/sqrt(s)] -> discrete innovation variance gamma2 = K^2 / f_s [u^2]."""
    return _nonneg(k, "K") ** 2 / check_freq(freq)


def rw_coefficient_from_gamma2(gamma2: float, freq: float) -> float:
    """gamma2 [u^2] -> K = sqrt(gamma2 f_s) [u/sqrt(s)]."""
    return np.sqrt(_nonneg(gamma2, "gamma2") * check_freq(freq))


def rw_from_per_hour_sqrt_hour(k_h: float, freq: float) -> float:
    """K in unit/h/sqrt(h) (deg/h/sqrt(h) for u = deg/s; m/s/h/sqrt(h) for m/s^2) -> gamma2."""
    return rw_gamma2_from_coefficient(per_hour_sqrt_hour_to_per_second_sqrt_second(k_h), freq)


# --- DR ---------------------------------------------------------------------------------------

def dr_omega_from_coefficient(r: float, freq: float) -> float:
    """Rate ramp R [u/s] -> per-sample slope omega = R / f_s [u per sample]."""
    return r / check_freq(freq)


def dr_coefficient_from_omega(omega: float, freq: float) -> float:
    """omega [u per sample] -> R = omega f_s [u/s]."""
    return omega * check_freq(freq)


def dr_from_per_hour2(r_h: float, freq: float) -> float:
    """R in unit/h/h (m/s/h/h for u = m/s^2) -> omega [u per sample]."""
    return dr_omega_from_coefficient(per_hour2_to_per_second2(r_h), freq)


# --- GM and SIN ------------------------------------------------------------------------------

def gm_to_ar1(beta: float, sigma2_gm: float, freq: float) -> tuple[float, float]:
    """Gauss-Markov (beta [1/s], stationary variance [u^2]) -> AR1 (phi, innovation variance)."""
    phi = float(np.exp(-_nonneg(beta, "GM beta") / check_freq(freq)))
    return phi, float(_nonneg(sigma2_gm, "GM sigma2") * -np.expm1(-2.0 * beta / freq))


def ar1_to_gm(phi: float, sigma2: float, freq: float) -> tuple[float, float]:
    """AR1 (phi in (0, 1), innovation variance) -> Gauss-Markov (beta [1/s], stationary variance)."""
    if not 0.0 < phi < 1.0:
        raise InputError(f"AR1 phi must be in (0, 1) to map to a Gauss-Markov process, got {phi}")
    return float(-np.log(phi) * check_freq(freq)), float(sigma2 / (1.0 - phi * phi))


def sin_beta_from_hz(f_hz: float, freq: float) -> float:
    """Sinusoid frequency [Hz] -> beta = 2 pi f / f_s [rad/sample]."""
    return 2.0 * pi * f_hz / check_freq(freq)


def sin_hz_from_beta(beta: float, freq: float) -> float:
    """beta [rad/sample] -> frequency [Hz] = beta f_s / (2 pi)."""
    return beta * check_freq(freq) / (2.0 * pi)


# --- unit systems: how a datasheet prints a signal's coefficients ---------------------------



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

    def coefficient(self, kind: str) -> tuple[str, tuple[str, float]]:
        """``(name, (label, factor))`` of a one-number datasheet coefficient of ``kind`` (one of
        :data:`COEFFICIENT_KINDS`, a process's ``datasheet_kind``): e.g. ``("ARW", ("deg/sqrt(h)",
        ...))`` for ``"white"`` of a gyroscope."""
        if kind == "white":
            return self.white_name, self.white
        if kind == "rw":
            return self.rw_name, self.rw
        if kind == "qn":
            return "QN", self.qn
        if kind == "ramp":
            return "RR", self.ramp
        raise ValueError(f"unknown coefficient kind {kind!r}; known: {', '.join(COEFFICIENT_KINDS)}")


#: the one-number datasheet coefficients a :class:`UnitSystem` prints (a process's
#: ``datasheet_kind``): white noise, random walk, quantisation, rate ramp
COEFFICIENT_KINDS = ("white", "rw", "qn", "ramp")


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
