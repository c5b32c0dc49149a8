"""Sensor datasheets in datasheet units: read a small YAML file, turn it into a GMWM model at a
sampling rate, draw its WV / Allan deviation, and judge a fit against it (docs/METHODS.md §17).

The file (documented in docs/METHODS.md §17.1; examples under ``gmwm/data/datasheets/``)::

    part: Xsens MTi-1            # free text
    source: "..."                # the public document the numbers come from (title, revision)
    rate: 100 Hz                 # optional: output data rate, the default rate of a plan
    gyroscope:
      white: 0.007 deg/s/sqrt(Hz)      # ARW / noise density
      bias_instability: 10 deg/h       # or {value: 10 deg/h, correlation_time: 60 s}
      random_walk: 1.5 deg/h/sqrt(h)   # RRW
    accelerometer:
      white: 120 ug/sqrt(Hz)           # VRW / noise density
      bias_instability: 0.03 mg

Terms (per sensor): ``white``, ``bias_instability``, ``random_walk``, ``quantization``, ``ramp``,
``gauss_markov`` (a mapping or list of mappings with ``sigma`` and ``correlation_time``). Every value
is ``"NUMBER UNIT"`` (or ``{value: NUMBER, unit: UNIT}``) in any unit of the right dimension
(:func:`gmwm.units.coefficient_unit`).

Bias instability. The flicker floor of a datasheet has no finite model among the GMWM processes. For
a **plan** (and the simulation benchmark) it becomes one Gauss-Markov component whose Allan
deviation peaks at the floor, 0.6643 B (:func:`bi_as_gauss_markov`); the plan reports B as that
peak / 0.6643. The datasheet's own curve (plots) keeps the idealised floor, and the **verdict**
compares B with the recording's own IEEE 952 reading (its Allan-deviation minimum / 0.6643,
:func:`gmwm.datasheet.allan_readings`), the definition datasheets use; a single GM has no floor, so
the AD minimum of a fitted model would depend on the recording length.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from statistics import NormalDist
from typing import Any

import numpy as np

from gmwm.datasheet import datasheet
from gmwm.errors import InputError
from gmwm.units import (
    BI_AD_FACTOR,
    coefficient_unit,
    convert,
    parse_unit,
    to_signal_units,
    unit_system,
)

__all__ = [
    "GM_PEAK_AD",
    "GM_PEAK_X",
    "SENSORS",
    "VERDICT_RULE",
    "Datasheet",
    "DatasheetModel",
    "Quantity",
    "SensorSpec",
    "bi_as_gauss_markov",
    "bi_of_gauss_markov",
    "compare",
    "datasheet_curves",
    "example_datasheets",
    "judge",
    "load_datasheet",
    "parse_datasheet",
    "resolve_datasheet",
    "to_model",
]

SENSORS = ("gyroscope", "accelerometer")
#: A GM with correlation time T_c: its Allan deviation peaks at cluster time GM_PEAK_X * T_c with
#: value GM_PEAK_AD * sigma (maximum of (2x - 3 + 4 e^-x - e^-2x) / x^2, x = tau / T_c).
GM_PEAK_X = 1.8926178073412692
GM_PEAK_AD = 0.6173642831444414
#: the verdict rule, printed with every verdict table
VERDICT_RULE = ("within: the datasheet value lies inside the measured 95 % interval; better / "
                "worse: the whole interval lies below / above it (less / more noise than the "
                "datasheet states); a correlation time is shorter / longer")
_Z95 = NormalDist().inv_cdf(0.975)

#: YAML term key -> (coefficient kind of gmwm.units.TERM_KINDS, process)
_TERMS = {"white": ("white", "WN"), "random_walk": ("random_walk", "RW"),
          "quantization": ("quantization", "QN"), "ramp": ("ramp", "DR"),
          "bias_instability": ("level", "BI")}
_TERM_ALIASES = {"arw": "white", "vrw": "white", "noise_density": "white", "rrw": "random_walk",
                 "accrw": "random_walk", "arrw": "random_walk", "bi": "bias_instability",
                 "bias_stability": "bias_instability", "qn": "quantization",
                 "rate_ramp": "ramp", "gm": "gauss_markov"}
_TOP_KEYS = ("part", "source", "notes", "rate", *SENSORS)
_NUMBER_UNIT = re.compile(r"^\s*(?P<num>[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?)\s*"
                          r"(?P<unit>\S.*?)?\s*$")


# --------------------------------------------------------------------------------------------------
# the file
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Quantity:
    """A datasheet number with its unit as written (``value`` > 0)."""

    value: float
    unit: str

    def __str__(self) -> str:
        return f"{self.value:g} {self.unit}"


@dataclass(frozen=True)
class SensorSpec:
    """The noise terms a datasheet gives for one sensor type (None: not given)."""

    sensor: str
    white: Quantity | None = None
    random_walk: Quantity | None = None
    quantization: Quantity | None = None
    ramp: Quantity | None = None
    bias_instability: Quantity | None = None
    bi_correlation_time: Quantity | None = None
    gauss_markov: tuple[tuple[Quantity, Quantity], ...] = ()   # (sigma, correlation time)

    def terms(self) -> dict[str, Quantity]:
        """The scalar terms given, by YAML key."""
        return {k: q for k in ("white", "bias_instability", "random_walk", "quantization", "ramp")
                if (q := getattr(self, k)) is not None}


@dataclass(frozen=True)
class Datasheet:
    """A parsed datasheet file: per sensor type the terms it gives."""

    part: str
    source: str
    sensors: Mapping[str, SensorSpec]
    notes: str = ""
    rate: float | None = None
    path: str | None = None

    def sensor(self, name: str) -> SensorSpec:
        """The terms of ``name`` ('gyroscope' or 'accelerometer'); an InputError if absent."""
        if name not in self.sensors:
            have = ", ".join(self.sensors) or "none"
            raise InputError(f"datasheet {self.where}: no {name} section (it has: {have})")
        return self.sensors[name]

    @property
    def where(self) -> str:
        return self.path or self.part


def _err(where: str, key: str, msg: str) -> InputError:
    return InputError(f"datasheet {where}: {key}: {msg}")


def _quantity(raw: Any, where: str, key: str) -> Quantity:
    """'0.15 deg/sqrt(h)' or {value: 0.15, unit: deg/sqrt(h)} (the unit checked for syntax)."""
    unit = None
    if isinstance(raw, Mapping):
        extra = sorted(set(raw) - {"value", "unit"})
        if extra:
            raise _err(where, key, f"unknown key(s) {', '.join(map(str, extra))}; "
                                   "a value is 'NUMBER UNIT' or {value: NUMBER, unit: UNIT}")
        if "value" not in raw:
            raise _err(where, key, "missing 'value'")
        unit = raw.get("unit")
        raw = raw["value"]
    if isinstance(raw, bool) or raw is None:
        raise _err(where, key, f"expected 'NUMBER UNIT', got {raw!r}")
    if isinstance(raw, int | float):
        number, text_unit = float(raw), None
    else:
        m = _NUMBER_UNIT.match(str(raw))
        if m is None:
            raise _err(where, key, f"expected 'NUMBER UNIT', got {raw!r}")
        number, text_unit = float(m.group("num")), m.group("unit")
    if text_unit and unit and text_unit != unit:
        raise _err(where, key, f"two units given ({text_unit!r} and {unit!r})")
    unit = unit or text_unit
    if not unit:
        raise _err(where, key, f"{raw!r} has no unit (write e.g. '0.15 deg/sqrt(h)')")
    if not (math.isfinite(number) and number > 0):
        raise _err(where, key, f"value must be positive and finite, got {number:g}")
    try:
        coefficient_unit(str(unit))
    except InputError as exc:
        raise _err(where, key, str(exc)) from None
    return Quantity(number, str(unit).strip())


def _check_kind(q: Quantity, kind: str, sensor: str, where: str, key: str) -> None:
    """The unit's dimension must be that of the term for the sensor."""
    probe = "rad/s" if sensor == "gyroscope" else "m/s^2"
    try:
        to_signal_units(q.value, q.unit, kind, probe)
    except InputError:
        what = "time" if kind == "time" else f"{kind.replace('_', ' ')} term of a {sensor}"
        raise _err(where, key, f"{q} is not a {what} (its dimension is "
                               f"{coefficient_unit(q.unit).describe()})") from None


def _sensor(raw: Any, sensor: str, where: str) -> SensorSpec:
    if not isinstance(raw, Mapping):
        raise _err(where, sensor, "expected a mapping of terms (white, bias_instability, ...)")
    found: dict[str, Any] = {}
    for k, v in raw.items():
        key = _TERM_ALIASES.get(str(k).lower(), str(k).lower())
        if key not in _TERMS and key != "gauss_markov":
            raise _err(where, f"{sensor}.{k}", "unknown term; use white, bias_instability, "
                                               "random_walk, quantization, ramp, gauss_markov")
        if key in found:
            raise _err(where, f"{sensor}.{k}", f"{key} given twice")
        found[key] = (k, v)
    out: dict[str, Any] = {"sensor": sensor}
    for key, (k, v) in found.items():
        path = f"{sensor}.{k}"
        if key == "bias_instability" and isinstance(v, Mapping) and "correlation_time" in v:
            rest = {a: b for a, b in v.items() if a != "correlation_time"}
            q = _quantity(rest, where, path)
            tc = _quantity(v["correlation_time"], where, f"{path}.correlation_time")
            _check_kind(tc, "time", sensor, where, f"{path}.correlation_time")
            out["bi_correlation_time"] = tc
        elif key == "gauss_markov":
            items = v if isinstance(v, list) else [v]
            gms = []
            for i, item in enumerate(items):
                p = path if len(items) == 1 else f"{path}[{i}]"
                if not isinstance(item, Mapping) or set(item) != {"sigma", "correlation_time"}:
                    raise _err(where, p, "expected {sigma: NUMBER UNIT, correlation_time: "
                                         "NUMBER UNIT}")
                sig = _quantity(item["sigma"], where, f"{p}.sigma")
                tc = _quantity(item["correlation_time"], where, f"{p}.correlation_time")
                _check_kind(sig, "level", sensor, where, f"{p}.sigma")
                _check_kind(tc, "time", sensor, where, f"{p}.correlation_time")
                gms.append((sig, tc))
            out["gauss_markov"] = tuple(gms)
            continue
        else:
            q = _quantity(v, where, path)
        _check_kind(q, _TERMS[key][0], sensor, where, path)
        out[key] = q
    spec = SensorSpec(**out)
    if not spec.terms() and not spec.gauss_markov:
        raise _err(where, sensor, "no noise term given")
    return spec


def parse_datasheet(raw: Any, where: str = "<datasheet>") -> Datasheet:
    """A :class:`Datasheet` from the parsed YAML mapping ``raw``; every problem is one
    InputError naming the key."""
    if not isinstance(raw, Mapping):
        raise InputError(f"datasheet {where}: expected a mapping with 'gyroscope' and/or "
                         "'accelerometer' sections")
    unknown = [str(k) for k in raw if str(k) not in _TOP_KEYS]
    if unknown:
        raise _err(where, unknown[0], f"unknown key; use {', '.join(_TOP_KEYS)}")
    sensors = {s: _sensor(raw[s], s, where) for s in SENSORS if s in raw}
    if not sensors:
        raise InputError(f"datasheet {where}: needs a 'gyroscope' or 'accelerometer' section")
    rate = None
    if "rate" in raw:
        q = _quantity(raw["rate"], where, "rate")
        try:
            rate = convert(q.value, q.unit, "Hz")
        except InputError as exc:
            raise _err(where, "rate", str(exc)) from None
    for k in ("part", "source", "notes"):
        if k in raw and not isinstance(raw[k], str):
            raise _err(where, k, "expected text")
    return Datasheet(part=str(raw.get("part", Path(where).stem)), source=str(raw.get("source", "")),
                     sensors=sensors, notes=str(raw.get("notes", "")), rate=rate, path=where)


def example_datasheets() -> dict[str, Path]:
    """The packaged example datasheets, by name (file stem)."""
    root = resources.files("gmwm") / "data" / "datasheets"
    return {Path(str(p)).stem: Path(str(p)) for p in sorted(root.iterdir(), key=str)
            if str(p).endswith(".yaml")}


def resolve_datasheet(name: str | Path) -> Path:
    """A datasheet file: an existing path, or the name of a packaged example (e.g. 'stim300')."""
    p = Path(name)
    if p.is_file():
        return p
    examples = example_datasheets()
    key = p.stem if p.suffix in (".yaml", ".yml") and not p.exists() else str(name)
    if key.lower() in examples:
        return examples[key.lower()]
    raise InputError(f"datasheet {name} not found (a YAML file, or a packaged example: "
                     f"{', '.join(examples)})")


def load_datasheet(name: str | Path) -> Datasheet:
    """Read and validate a datasheet YAML file (or a packaged example by name)."""
    import yaml

    path = resolve_datasheet(name)
    try:
        raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        raise InputError(f"datasheet {name}: not valid YAML{at}: "
                         f"{getattr(exc, 'problem', None) or exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"datasheet {name}: cannot read it ({exc})") from None
    return parse_datasheet(raw, str(name))


# --------------------------------------------------------------------------------------------------
# datasheet -> model
# --------------------------------------------------------------------------------------------------


@dataclass
class DatasheetModel:
    """A datasheet as a GMWM model at a rate: ``model`` at ``theta`` (per-sample parameters in
    ``unit``), with ``notes`` saying how each term was represented, ``bi`` the GM that stands for
    the bias instability (its component name, or None) and ``values`` the datasheet coefficients
    (name -> (value, unit as written))."""

    model: Any
    theta: np.ndarray
    unit: str
    sensor: str
    notes: list[str] = field(default_factory=list)
    bi: str | None = None
    values: dict[str, tuple[float, str]] = field(default_factory=dict)


def _coef(q: Quantity | None, kind: str, unit: str) -> float | None:
    return None if q is None else to_signal_units(q.value, q.unit, kind, unit)


def bi_as_gauss_markov(b: float, correlation_time: float) -> tuple[float, float]:
    """The GM (beta [1/s], stationary variance [u^2]) standing for a bias instability ``b`` [u]:
    correlation time ``correlation_time`` [s] and an Allan-deviation peak equal to the flicker
    floor 0.6643 b (docs/METHODS.md §17.2)."""
    sigma = BI_AD_FACTOR * b / GM_PEAK_AD
    return 1.0 / correlation_time, sigma * sigma


def bi_of_gauss_markov(sigma2: float) -> float:
    """Inverse of :func:`bi_as_gauss_markov`: the bias instability [u] a GM of stationary variance
    ``sigma2`` stands for (its Allan-deviation peak / 0.6643)."""
    return GM_PEAK_AD * math.sqrt(max(sigma2, 0.0)) / BI_AD_FACTOR


def _bi_correlation_time(spec: SensorSpec, unit: str) -> tuple[float, str]:
    """The GM correlation time [s] for the bias instability and how it was chosen."""
    if spec.bi_correlation_time is not None:
        return to_signal_units(spec.bi_correlation_time.value, spec.bi_correlation_time.unit,
                               "time", unit), "from the datasheet file"
    n, k = _coef(spec.white, "white", unit), _coef(spec.random_walk, "random_walk", unit)
    b = _coef(spec.bias_instability, "level", unit)
    floor = (2 * math.log(2) / math.pi) * b * b  # Allan variance of the flicker floor
    if n is not None and k is not None:
        peak, why = math.sqrt(3.0) * n / k, "where the white-noise and random-walk lines cross"
    elif n is not None:
        peak, why = 10.0 * n * n / floor, "a decade past where the white-noise line meets the floor"
    elif k is not None:
        peak, why = 0.1 * 3.0 * floor / (k * k), "a decade before the random-walk line meets the floor"
    else:
        raise InputError("bias_instability without white noise or random walk needs a "
                         "correlation_time (bias_instability: {value: ..., correlation_time: ...})")
    tc = peak / GM_PEAK_X
    return tc, (f"not given: Allan-deviation peak placed at {peak:.3g} s, {why} "
                "(set bias_instability.correlation_time to choose it)")


def to_model(spec: SensorSpec, freq: float, unit: str | None = None) -> DatasheetModel:
    """The datasheet ``spec`` as a GMWM model at ``freq`` Hz with the signal in ``unit`` (default
    rad/s for a gyroscope, m/s^2 for an accelerometer). White -> WN, random walk -> RW,
    quantization -> QN, ramp -> DR, each Gauss-Markov -> GM, bias instability -> one more GM
    (:func:`bi_as_gauss_markov`) with the correlation time of the file or of the rule of
    docs/METHODS.md §17.2."""
    from gmwm import units as u
    from gmwm.model import Model

    unit = unit or ("rad/s" if spec.sensor == "gyroscope" else "m/s^2")
    parsed = parse_unit(unit)
    if parsed is None or parsed[2] != spec.sensor:
        raise InputError(f"unit {unit!r} is not a {spec.sensor} unit")
    freq = float(freq)
    if not (math.isfinite(freq) and freq > 0):
        raise InputError(f"sampling frequency must be positive, got {freq}")
    params: dict[str, float] = {}
    counts: dict[str, int] = {}
    notes: list[str] = []
    values: dict[str, tuple[float, str]] = {}
    us = unit_system(unit)
    if spec.quantization is not None:
        q = _coef(spec.quantization, "quantization", unit)
        params["QN[1].Q2"] = float(u.qn_q2_from_coefficient(q, freq))
        counts["QN"] = 1
        values["QN"] = (spec.quantization.value, spec.quantization.unit)
    if spec.white is not None:
        params["WN[1].sigma2"] = float(u.wn_from_density(_coef(spec.white, "white", unit), freq))
        counts["WN"] = 1
        values[us.white_name] = (spec.white.value, spec.white.unit)
    gms: list[tuple[float, float, str | None]] = []
    for sig, tc in spec.gauss_markov:
        s = _coef(sig, "level", unit)
        t = to_signal_units(tc.value, tc.unit, "time", unit)
        gms.append((1.0 / t, s * s, None))
    bi_tc = None
    if spec.bias_instability is not None:
        b = _coef(spec.bias_instability, "level", unit)
        bi_tc, how = _bi_correlation_time(spec, unit)
        beta, s2 = bi_as_gauss_markov(b, bi_tc)
        gms.append((beta, s2, "BI"))
        values["BI"] = (spec.bias_instability.value, spec.bias_instability.unit)
        notes.append(f"bias instability {spec.bias_instability} modelled as a Gauss-Markov "
                     f"component with correlation time {bi_tc:.3g} s ({how}) and Allan-deviation "
                     "peak 0.6643 B")
    # GM components are numbered by correlation time, shortest first (canonical order)
    gms.sort(key=lambda g: 1.0 / g[0])
    bi_name = None
    for k, (beta, s2, tag) in enumerate(gms, start=1):
        params[f"GM[{k}].beta"] = beta
        params[f"GM[{k}].sigma2"] = s2
        if tag == "BI":
            bi_name = f"GM[{k}]"
    if gms:
        counts["GM"] = len(gms)
    for k, (sig, tc) in enumerate(spec.gauss_markov, start=1):
        values[f"GM({k}).sigma"] = (sig.value, sig.unit)
        values[f"GM({k}).correlation_time"] = (tc.value, tc.unit)
    if spec.random_walk is not None:
        params["RW[1].gamma2"] = float(u.rw_gamma2_from_coefficient(
            _coef(spec.random_walk, "random_walk", unit), freq))
        counts["RW"] = 1
        values[us.rw_name] = (spec.random_walk.value, spec.random_walk.unit)
    if spec.ramp is not None:
        params["DR[1].omega"] = float(u.dr_omega_from_coefficient(_coef(spec.ramp, "ramp", unit),
                                                                   freq))
        counts["DR"] = 1
        values["RR"] = (spec.ramp.value, spec.ramp.unit)
    absent = [k.replace("_", " ") for k in ("white", "bias_instability", "random_walk")
              if getattr(spec, k) is None]
    if absent:
        notes.append(f"not on the datasheet, so absent from the model: {', '.join(absent)}")
    order = ("QN", "WN", "GM", "RW", "DR")
    from gmwm.model import spec_of

    model = Model(spec_of({k: counts[k] for k in order if k in counts}), freq)
    theta = model.theta(params)
    return DatasheetModel(model, theta, unit, spec.sensor, notes, bi_name, values)


# --------------------------------------------------------------------------------------------------
# the datasheet's own curves (plots): idealised flicker floor for the bias instability
# --------------------------------------------------------------------------------------------------


def datasheet_curves(spec: SensorSpec, scales: Sequence[float], freq: float, unit: str
                     ) -> dict[str, np.ndarray]:
    """WV of what the datasheet states, at Haar filter lengths ``scales`` [samples] for a signal in
    ``unit`` at ``freq`` Hz: ``"wv"`` (total) and ``"adev"`` (Allan deviation at cluster times
    ``scales / 2 / freq``). White, random walk, quantization, ramp and Gauss-Markov terms use their
    exact WV (§3); the bias instability is the idealised flicker floor, WV (ln 2 / pi) B^2 at every
    scale (§3.9), not the GM of a plan."""
    tau = np.asarray(scales, dtype=float)
    finite = SensorSpec(spec.sensor, spec.white, spec.random_walk, spec.quantization, spec.ramp,
                        None, None, spec.gauss_markov)
    total = np.zeros(tau.size)
    if finite.terms() or finite.gauss_markov:
        dm = to_model(finite, freq, unit)
        total += dm.model.wv(dm.theta, tau)
    if spec.bias_instability is not None:
        b = _coef(spec.bias_instability, "level", unit)
        total += (math.log(2.0) / math.pi) * b * b
    return {"wv": total, "adev": np.sqrt(2.0 * total)}


# --------------------------------------------------------------------------------------------------
# bias instability of a model, and the verdict
# --------------------------------------------------------------------------------------------------


def _interval_verdict(ds: float, ci: Sequence[float] | None, shape: bool) -> str:
    if ci is None:
        return "no interval"
    lo, hi = float(ci[0]), float(ci[1])
    if lo <= ds <= hi:
        return "within"
    if shape:
        return "shorter" if hi < ds else "longer"
    return "better" if hi < ds else "worse"


def compare(result: Any, spec: SensorSpec, unit: str, alpha: float = 0.05) -> list[dict[str, Any]]:
    """The verdict table of a fit against a datasheet: per datasheet term the datasheet value, the
    measured value with its 95 % interval (both in the datasheet's unit) and a verdict by
    :data:`VERDICT_RULE`. ``unit`` is the fitted signal's unit (it fixes the sensor type).

    Terms: white (from WN), random walk (RW), quantization (QN), ramp (DR), each Gauss-Markov term
    (GM[k] in order of correlation time), and the bias instability: the IEEE 952 reading of the
    fitted WV's Allan deviation (its minimum / 0.6643 with the chi-square interval of that point;
    ``note`` says where, and when the minimum is the last cluster time, i.e. the floor was not
    reached and the reading is an upper bound)."""
    parsed = parse_unit(unit)
    if parsed is None or parsed[2] != spec.sensor:
        raise InputError(f"signal unit {unit!r} is not a {spec.sensor} unit: cannot compare "
                         f"with the datasheet's {spec.sensor} section")
    us = unit_system(unit)
    fitted = datasheet(result, unit, alpha)
    rows: list[dict[str, Any]] = []

    def row(term: str, quantity: str, q: Quantity, entry: dict[str, Any] | None, label: str,
            shape: bool = False, note: str = "") -> None:
        out = {"term": term, "quantity": quantity, "datasheet": q.value, "unit": q.unit,
               "measured": None, "ci95": None, "verdict": "not in the fitted model", "note": note}
        if entry is not None:
            v = entry.get("value")
            if v is not None:
                out["measured"] = convert(v, label, q.unit)
                ci = entry.get("ci95")
                out["ci95"] = None if not ci else [convert(c, label, q.unit) for c in ci]
                out["verdict"] = ("not detected (estimate at 0)" if v == 0 else
                                  _interval_verdict(q.value, out["ci95"], shape))
            else:
                out["verdict"] = "not identified"
        rows.append(out)

    for key, name, label in (("white", us.white_name, us.white[0]),
                             ("random_walk", us.rw_name, us.rw[0]),
                             ("quantization", "QN", us.qn[0]), ("ramp", "RR", us.ramp[0])):
        q = getattr(spec, key)
        if q is not None:
            row(name, "", q, fitted.get(name), label)
    gm_fit = [fitted[k] for k in fitted if k.startswith("GM[")]
    for k, (sig, tc) in enumerate(spec.gauss_markov):
        e = gm_fit[k] if k < len(gm_fit) else None
        row(f"GM[{k + 1}]", "sigma", sig, None if e is None else e["sigma"], us.level[0])
        row(f"GM[{k + 1}]", "correlation_time", tc, None if e is None else e["correlation_time"],
            "s", shape=True)
    if spec.bias_instability is not None:
        from gmwm.datasheet import allan_readings
        from gmwm.wv import AllanVariance

        try:
            b = allan_readings(AllanVariance.from_wv(result.wv), unit)["B"]
        except InputError:
            b = None
        note = "" if b is None else (
            f"IEEE 952 reading: AD minimum of the recording at {b['tau_s']:.3g} s"
            + (" (the longest cluster time: floor not reached, an upper bound)"
               if b["at_end"] else ""))
        row("BI", "", spec.bias_instability, b, b["unit"] if b else us.level[0], note=note)
    return rows


def judge(result: Any, sheet: Datasheet, unit: str, alpha: float = 0.05) -> dict[str, Any]:
    """Everything a fit, a report or their plots show about a datasheet for one signal: the
    verdict rows (:func:`compare`), the rule, and the datasheet's WV and Allan deviation at the
    fitted WV's scales (:func:`datasheet_curves`). ``unit`` (the signal's) picks the sensor
    section; a unit of no known sensor, or a datasheet without that section, is an InputError."""
    parsed = parse_unit(unit) if unit else None
    if parsed is None:
        raise InputError("comparing with a datasheet (`sheet`) needs the signal unit (`unit`) to "
                         "tell a gyroscope from an accelerometer")
    spec = sheet.sensor(parsed[2])
    wv = result.wv
    scales = np.asarray(wv.scales, float)
    curves = datasheet_curves(spec, scales, float(wv.freq), unit)
    return {"part": sheet.part, "source": sheet.source, "file": sheet.path, "sensor": spec.sensor,
            "rule": VERDICT_RULE, "rows": compare(result, spec, unit, alpha),
            "curves": {"scales_s": (scales / wv.freq).tolist(), "wv": curves["wv"].tolist(),
                       "tau_s": (scales / 2.0 / wv.freq).tolist(),
                       "adev": curves["adev"].tolist()},
            "label": f"{sheet.part} datasheet"}
