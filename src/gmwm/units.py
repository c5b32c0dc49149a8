"""Datasheet (continuous) coefficients <-> discrete per-sample parameters, and the datasheet model.

Conventions (SPEC sections 3, 4.2, 7). ``u`` is the measurement unit (deg/s, rad/s, m/s^2); ``f_s`` = ``freq``
is the sampling frequency in Hz. Continuous coefficients are in SI seconds:

* QN  Q [u s]          <-> ``QN[k].Q2``     Q2 = (Q f_s)^2
* WN  N [u sqrt(s)]    <-> ``WN[k].sigma2`` sigma2 = N^2 f_s   (a density in u/sqrt(Hz) is the same number)
* RW  K [u / sqrt(s)]  <-> ``RW[k].gamma2`` gamma2 = K^2 / f_s
* DR  R [u / s]        <-> ``DR[k].omega``  omega = R / f_s   (per sample, per sample)
* GM  beta [1/s], sigma2_GM [u^2] <-> AR1 phi = exp(-beta/f_s), innovation sigma2_GM (1 - phi^2)
* SIN frequency f [Hz] <-> beta = 2 pi f / f_s [rad/sample]

Hour-based datasheet units: N[./sqrt(s)] = N[./sqrt(h)] / 60, K[./s/sqrt(s)] = K[./h/sqrt(h)] / 216000,
R[./s/s] = R[./h/h] / 1.296e7.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import log, pi
from types import MappingProxyType

import numpy as np
from scipy.special import sici

from gmwm.errors import InputError, ModelError

SQRT_HOUR = 60.0  # sqrt(3600 s)
HOUR = 3600.0
HOUR_SQRT_HOUR = HOUR * SQRT_HOUR  # 216000
HOUR2 = HOUR * HOUR  # 1.296e7
G0 = 9.80665  # standard gravity, m/s^2
DEG2RAD = pi / 180.0
BI_WV_FACTOR = log(2.0) / pi  # idealised flicker: WV per scale = (ln2/pi) B^2
BI_AD_FACTOR = float(np.sqrt(2.0 * log(2.0) / pi))  # AD floor = 0.6643 B

_SENSORS = {"gyro": "gyroscope", "gyroscope": "gyroscope", "accel": "accelerometer",
            "accelerometer": "accelerometer"}


def canonical_sensor(sensor: str) -> str:
    """'gyro'/'gyroscope' -> 'gyroscope', 'accel'/'accelerometer' -> 'accelerometer'."""
    key = str(sensor).strip().lower()
    if key not in _SENSORS:
        raise InputError(f"unknown sensor {sensor!r}: expected 'gyroscope' or 'accelerometer'")
    return _SENSORS[key]


def _check_freq(freq: float) -> float:
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
    return (_nonneg(q, "Q") * _check_freq(freq)) ** 2


def qn_coefficient_from_q2(q2: float, freq: float) -> float:
    """Discrete Q2 [u^2] -> Q [u s] = sqrt(Q2) / f_s."""
    return np.sqrt(_nonneg(q2, "Q2")) / _check_freq(freq)


# --- WN ---------------------------------------------------------------------------------------

def wn_from_density(density: float, freq: float) -> float:
    """White-noise density N [u/sqrt(Hz) = u sqrt(s)] -> per-sample variance sigma2 = N^2 f_s [u^2]."""
    return _nonneg(density, "white-noise density") ** 2 * _check_freq(freq)


def wn_density_from_sigma2(sigma2: float, freq: float) -> float:
    """Per-sample WN variance sigma2 [u^2] -> density N = sqrt(sigma2 / f_s) [u sqrt(s)]."""
    return np.sqrt(_nonneg(sigma2, "sigma2") / _check_freq(freq))


def wn_from_arw_per_sqrt_hour(arw: float, freq: float) -> float:
    """Angle/velocity random walk in unit/sqrt(h) (deg/sqrt(h) for u = deg/s) -> sigma2 [u^2]."""
    return wn_from_density(per_sqrt_hour_to_per_sqrt_second(arw), freq)


# --- RW ---------------------------------------------------------------------------------------

def rw_gamma2_from_coefficient(k: float, freq: float) -> float:
    """Rate random walk K [u/sqrt(s)] -> discrete innovation variance gamma2 = K^2 / f_s [u^2]."""
    return _nonneg(k, "K") ** 2 / _check_freq(freq)


def rw_coefficient_from_gamma2(gamma2: float, freq: float) -> float:
    """gamma2 [u^2] -> K = sqrt(gamma2 f_s) [u/sqrt(s)]."""
    return np.sqrt(_nonneg(gamma2, "gamma2") * _check_freq(freq))


def rw_from_per_hour_sqrt_hour(k_h: float, freq: float) -> float:
    """K in unit/h/sqrt(h) (deg/h/sqrt(h) for u = deg/s; m/s/h/sqrt(h) for m/s^2) -> gamma2."""
    return rw_gamma2_from_coefficient(per_hour_sqrt_hour_to_per_second_sqrt_second(k_h), freq)


# --- DR ---------------------------------------------------------------------------------------

def dr_omega_from_coefficient(r: float, freq: float) -> float:
    """Rate ramp R [u/s] -> per-sample slope omega = R / f_s [u per sample]."""
    return r / _check_freq(freq)


def dr_coefficient_from_omega(omega: float, freq: float) -> float:
    """omega [u per sample] -> R = omega f_s [u/s]."""
    return omega * _check_freq(freq)


def dr_from_per_hour2(r_h: float, freq: float) -> float:
    """R in unit/h/h (m/s/h/h for u = m/s^2) -> omega [u per sample]."""
    return dr_omega_from_coefficient(per_hour2_to_per_second2(r_h), freq)


# --- GM and SIN ------------------------------------------------------------------------------

def gm_to_ar1(beta: float, sigma2_gm: float, freq: float) -> tuple[float, float]:
    """Gauss-Markov (beta [1/s], stationary variance [u^2]) -> AR1 (phi, innovation variance)."""
    phi = float(np.exp(-_nonneg(beta, "GM beta") / _check_freq(freq)))
    return phi, float(_nonneg(sigma2_gm, "GM sigma2") * -np.expm1(-2.0 * beta / freq))


def ar1_to_gm(phi: float, sigma2: float, freq: float) -> tuple[float, float]:
    """AR1 (phi in (0, 1), innovation variance) -> Gauss-Markov (beta [1/s], stationary variance)."""
    if not 0.0 < phi < 1.0:
        raise InputError(f"AR1 phi must be in (0, 1) to map to a Gauss-Markov process, got {phi}")
    return float(-np.log(phi) * _check_freq(freq)), float(sigma2 / (1.0 - phi * phi))


def sin_beta_from_hz(f_hz: float, freq: float) -> float:
    """Sinusoid frequency [Hz] -> beta = 2 pi f / f_s [rad/sample]."""
    return 2.0 * pi * f_hz / _check_freq(freq)


def sin_hz_from_beta(beta: float, freq: float) -> float:
    """beta [rad/sample] -> frequency [Hz] = beta f_s / (2 pi)."""
    return beta * _check_freq(freq) / (2.0 * pi)


# --- STIM-300 (paper 004, Table I) ------------------------------------------------------------

#: Table I of paper 004 in its own units (gyro u = deg/s, accel u = m/s^2).
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
    """Discrete STIM-300 parameters computed from paper 004 Table I (gyro in deg/s, accel in m/s^2).

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
    """Discrete parameter -> paper 004 Table I units (label from :func:`table_unit`).

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
    tau_s = np.asarray(scales, dtype=float) / (2.0 * _check_freq(freq))
    return bias_instability_av(b, f0, tau_s) / 2.0


def bias_instability_wv_ideal(b: float, scales) -> np.ndarray:
    """Idealised flicker (no cut-off): constant WV (ln2/pi) B^2 [u^2] at every scale."""
    return np.full(np.shape(scales), BI_WV_FACTOR * b * b, dtype=float)


# --- Navchip datasheet model (SPEC 7, data README) -----------------------------------------------

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
    freq = _check_freq(freq)
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


# --- datasheet coefficients of a fit ----------------------------------------------------------

def datasheet(result, units: str | None = None, alpha: float = 0.05) -> dict[str, dict]:
    """Continuous datasheet coefficients (ARW/VRW, RRW/AccRW, QN, RR, GM[k], SIN[k]) of a fit in
    the units datasheets print for a signal in ``units`` ('deg/s', 'rad/s', 'm/s^2', 'g'), with
    95 % CIs; see :func:`gmwm.datasheet.datasheet`."""
    from gmwm.datasheet import datasheet as _datasheet

    return _datasheet(result, units, alpha)
