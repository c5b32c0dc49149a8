"""Datasheet values of the sensors the paper studies use, and the models built from them.

* STIM-300 ([GMWFM], Table I): :data:`STIM300_TABLE_I`, its discrete-time parameters
  (:func:`stim300_truth`) and the conversion of estimates back to the table's units
  (:func:`to_table_units`, :func:`table_unit`).
* Navchip (product brief as quoted by gui4gmwm): :class:`DatasheetModel`,
  :func:`navchip_datasheet` and the WV of its components (:func:`datasheet_wv`), with bias
  instability drawn as band-limited flicker noise (:func:`bias_instability_wv`).

Unit conventions: :mod:`gmwm.units` (which holds the generic conversions used here).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import log, pi
from types import MappingProxyType

import numpy as np
from scipy.special import sici

from gmwm.errors import InputError, ModelError
from gmwm.units import (
    DEG2RAD,
    G0,
    HOUR2,
    HOUR_SQRT_HOUR,
    SQRT_HOUR,
    check_freq,
    deg_per_hour_to_rad_per_second,
    dr_coefficient_from_omega,
    dr_from_per_hour2,
    micro_g_to_si,
    qn_coefficient_from_q2,
    qn_q2_from_coefficient,
    rw_coefficient_from_gamma2,
    rw_from_per_hour_sqrt_hour,
    wn_density_from_sigma2,
    wn_from_arw_per_sqrt_hour,
    wn_from_density,
)

BI_WV_FACTOR = log(2.0) / pi  # idealised flicker: WV per scale = (ln2/pi) B^2

_SENSORS = {"gyro": "gyroscope", "gyroscope": "gyroscope", "accel": "accelerometer",
            "accelerometer": "accelerometer"}


def canonical_sensor(sensor: str) -> str:
    """'gyro'/'gyroscope' -> 'gyroscope', 'accel'/'accelerometer' -> 'accelerometer'."""
    key = str(sensor).strip().lower()
    if key not in _SENSORS:
        raise InputError(f"unknown sensor {sensor!r}: expected 'gyroscope' or 'accelerometer'")
    return _SENSORS[key]


# --- STIM-300 ([GMWFM], Table I) ------------------------------------------------------------

#: Table I of [GMWFM] in its own units (gyro u = deg/s, accel u = m/s^2).
STIM300_TABLE_I = MappingProxyType({
    "gyroscope": MappingProxyType({"WN": (0.157, "deg/sqrt(h)"), "RW": (1.34, "deg/h/sqrt(h)")}),
    "accelerometer": MappingProxyType({
        "QN": (1.79e-6, "m/s"), "WN": (4.70e-2, "m/s/sqrt(h)"),
        "RW": (4.35e1, "m/s/h/sqrt(h)"), "DR": (4.14e1, "m/s/h/h")}),
})

_TABLE_UNITS = MappingProxyType({
    "gyroscope": MappingProxyType({"QN": "deg", "WN": "deg/sqrt(h)", "RW": "deg/h/sqrt(h)",
                                   "DR": "deg/h/h"}),
    "accelerometer": MappingProxyType({"QN": "m/s", "WN": "m/s/sqrt(h)", "RW": "m/s/h/sqrt(h)",
                                       "DR": "m/s/h/h"}),
})


def stim300_truth(sensor: str, freq: float = 250.0) -> dict[str, float]:
    """Discrete STIM-300 parameters computed from [GMWFM] Table I (gyro in deg/s, accel in m/s^2).

    Gyro (WN+RW): {'WN[1].sigma2', 'RW[1].gamma2'}; accel (QN+WN+RW+DR): {'QN[1].Q2', 'WN[1].sigma2',
    'RW[1].gamma2', 'DR[1].omega'}; keys in the canonical model order.
    """
    tab = STIM300_TABLE_I[canonical_sensor(sensor)]
    out: dict[str, float] = {}
    if "QN" in tab:
        out["QN[1].Q2"] = float(qn_q2_from_coefficient(tab["QN"][0], freq))
    out["WN[1].sigma2"] = float(wn_from_arw_per_sqrt_hour(tab["WN"][0], freq))
    out["RW[1].gamma2"] = float(rw_from_per_hour_sqrt_hour(tab["RW"][0], freq))
    if "DR" in tab:
        out["DR[1].omega"] = float(dr_from_per_hour2(tab["DR"][0], freq))
    return out


def _split_name(name: str) -> tuple[str, str]:
    try:
        comp, par = name.split(".", 1)
        ctype = comp[: comp.index("[")]
    except ValueError:
        raise ModelError(f"malformed parameter name {name!r}: expected like 'WN[1].sigma2'") from None
    return ctype, par


def table_unit(name: str, sensor: str) -> str:
    """Unit label of Table I for a parameter name, e.g. ('RW[1].gamma2', 'gyro') -> 'deg/h/sqrt(h)'."""
    ctype, _ = _split_name(name)
    units = _TABLE_UNITS[canonical_sensor(sensor)]
    if ctype not in units:
        raise ModelError(f"no Table I unit for {name!r} (only QN, WN, RW, DR)")
    return units[ctype]


def to_table_units(name: str, value, sensor: str, freq: float = 250.0):
    """Discrete parameter -> [GMWFM] Table I units (label from :func:`table_unit`).

    The signal is assumed in deg/s (gyro) or m/s^2 (accel). Q2 -> Q [deg | m/s]; sigma2 -> N
    [deg/sqrt(h) | m/s/sqrt(h)]; gamma2 -> K [deg/h/sqrt(h) | m/s/h/sqrt(h)]; omega -> R [deg/h/h |
    m/s/h/h]. Works elementwise on arrays. Negative variances raise InputError.
    """
    ctype, par = _split_name(name)
    table_unit(name, sensor)  # validates sensor and type
    expected = {"QN": "Q2", "WN": "sigma2", "RW": "gamma2", "DR": "omega"}[ctype]
    if par != expected:
        raise ModelError(f"unknown parameter {name!r}: {ctype} has parameter {expected!r}")
    if ctype == "QN":
        return qn_coefficient_from_q2(value, freq)
    if ctype == "WN":
        return wn_density_from_sigma2(value, freq) * SQRT_HOUR
    if ctype == "RW":
        return rw_coefficient_from_gamma2(value, freq) * HOUR_SQRT_HOUR
    return dr_coefficient_from_omega(value, freq) * HOUR2


# --- bias instability (flicker) WV --------------------------------------------------------------

def _cin(z: np.ndarray) -> np.ndarray:
    """Cin(z) = int_0^z (1 - cos t)/t dt, by series for small z (no cancellation) else via Ci."""
    z = np.asarray(z, dtype=float)
    out = np.empty_like(z)
    small = z <= 1.0
    zs = z[small]
    term = zs * zs / 4.0  # k = 1: z^2 / (2 * 2!)
    acc = term.copy()
    for k in range(2, 12):
        # ratio of consecutive terms (-1)^{k+1} z^{2k} / (2k (2k)!)
        term = -term * zs * zs * (2 * k - 2) / ((2 * k) * (2 * k - 1) * (2 * k))
        acc += term
    out[small] = acc
    zl = z[~small]
    out[~small] = np.euler_gamma + np.log(zl) - sici(zl)[1]
    return out


def _bi_bracket(x: np.ndarray) -> np.ndarray:
    """int_0^x sin^4(u)/u^3 du = ln2 - sin^3x (sin x + 4x cos x)/(2x^2) + Ci(2x) - Ci(4x)."""
    x = np.asarray(x, dtype=float)
    s, c = np.sin(x), np.cos(x)
    # ln2 + Ci(2x) - Ci(4x) = Cin(4x) - Cin(2x), evaluated without cancellation for small x
    return _cin(4.0 * x) - _cin(2.0 * x) - s ** 3 * (s + 4.0 * x * c) / (2.0 * x * x)


def bias_instability_av(b: float, f0: float, tau_s) -> np.ndarray:
    """Allan variance [u^2] of band-limited flicker noise, PSD B^2/(2 pi f) on (0, f0] (El-Sheimy form).

    ``b`` = B [u], ``f0`` = cut-off [Hz], ``tau_s`` = cluster time(s) [s].
    """
    tau = np.asarray(tau_s, dtype=float)
    if f0 <= 0 or np.any(tau <= 0):
        raise InputError("bias instability needs f0 > 0 and positive cluster times")
    return 2.0 * b * b / pi * _bi_bracket(pi * f0 * tau)


def bias_instability_wv(b: float, f0: float, scales, freq: float) -> np.ndarray:
    """Haar WV [u^2] of band-limited flicker at filter lengths ``scales`` = 2^j [samples].

    WV at level j = AV(tau = 2^{j-1} / f_s) / 2. As f0 tau -> inf it tends to (ln2/pi) B^2.
    """
    tau_s = np.asarray(scales, dtype=float) / (2.0 * check_freq(freq))
    return bias_instability_av(b, f0, tau_s) / 2.0


def bias_instability_wv_ideal(b: float, scales) -> np.ndarray:
    """Idealised flicker (no cut-off): constant WV (ln2/pi) B^2 [u^2] at every scale."""
    return np.full(np.shape(scales), BI_WV_FACTOR * b * b, dtype=float)


# --- Navchip datasheet model (docs/METHODS.md §10.5, data README) -----------------------------------------------

@dataclass(frozen=True)
class DatasheetModel:
    """Manufacturer datasheet noise model converted to the signal units and sampling rate.

    ``components`` maps a term to its values in signal units; ``missing`` names the terms the
    datasheet does not give (e.g. {'RW': 'not given'}).
    """
    sensor: str
    freq: float
    unit: str
    components: dict[str, dict[str, float]]
    missing: dict[str, str]
    datasheet: dict[str, str]
    source: str
    notes: str = ""


def navchip_datasheet(sensor: str, freq: float = 250.0, g: float = G0) -> DatasheetModel:
    """Navchip datasheet model in the units of the public data (gyro rad/s, accel m/s^2).

    WN: density 0.003 deg/s/sqrt(Hz) (gyro) or 50 micro-g/sqrt(Hz) (accel), sigma2 = N^2 f_s.
    BI: B = 10 deg/h with f0 = 0.5 Hz (gyro) or 0.05 mg with f0 = 0.2 Hz (accel); f0 from gui4gmwm
    (secondary source). RW, QN, DR: not given.
    """
    sensor = canonical_sensor(sensor)
    freq = check_freq(freq)
    if sensor == "gyroscope":
        density = 0.003 * DEG2RAD
        b = deg_per_hour_to_rad_per_second(10.0)
        f0 = 0.5
        unit = "rad/s"
        sheet = {"WN": "0.003 deg/s/sqrt(Hz)", "BI": "10 deg/h"}
    else:
        density = micro_g_to_si(50.0, g)
        b = 0.05e-3 * g
        f0 = 0.2
        unit = "m/s^2"
        sheet = {"WN": "50 micro-g/sqrt(Hz)", "BI": "0.05 mg"}
    comps = {
        "WN": {"density": density, "sigma2": float(wn_from_density(density, freq))},
        "BI": {"B": b, "f0": f0, "B2": b * b},
    }
    return DatasheetModel(
        sensor=sensor, freq=freq, unit=unit, components=comps,
        missing={"RW": "not given", "QN": "not given", "DR": "not given"},
        datasheet=sheet,
        source="Navchip product brief as quoted by gui4gmwm (secondary); f0 from gui4gmwm",
        notes=f"BI drawn as band-limited flicker (El-Sheimy form); g = {g:.5f} m/s^2",
    )


def datasheet_wv(model: DatasheetModel, scales, bi_form: str = "band-limited") -> dict[str, np.ndarray]:
    """WV per datasheet component at filter lengths ``scales`` [samples]; keys 'WN', 'BI', 'total'.

    ``bi_form``: 'band-limited' (PSD cut at f0) or 'ideal' (constant (ln2/pi) B^2).
    """
    scales = np.asarray(scales, dtype=float)
    if np.any(scales <= 0):
        raise InputError("scales must be positive filter lengths in samples")
    wn = model.components["WN"]["sigma2"] / scales
    bi = model.components["BI"]
    if bi_form == "band-limited":
        bwv = bias_instability_wv(bi["B"], bi["f0"], scales, model.freq)
    elif bi_form == "ideal":
        bwv = bias_instability_wv_ideal(bi["B"], scales)
    else:
        raise InputError(f"unknown bi_form {bi_form!r}: use 'band-limited' or 'ideal'")
    return {"WN": wn, "BI": bwv, "total": wn + bwv}
