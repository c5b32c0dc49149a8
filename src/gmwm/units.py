"""Datasheet (continuous) coefficients <-> discrete per-sample parameters.

Conventions (docs/METHODS.md §10, §10.5, §12.5). ``u`` is the measurement unit (deg/s, rad/s, m/s^2); ``f_s`` = ``freq``
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


# --- datasheet coefficients of a fit ----------------------------------------------------------

def datasheet(result, units: str | None = None, alpha: float = 0.05) -> dict[str, dict]:
    """Continuous datasheet coefficients (ARW/VRW, RRW/AccRW, QN, RR, GM[k], SIN[k]) of a fit in
    the units datasheets print for a signal in ``units`` ('deg/s', 'rad/s', 'm/s^2', 'g'), with
    95 % CIs; see :func:`gmwm.datasheet.datasheet`."""
    from gmwm.datasheet import datasheet as _datasheet

    return _datasheet(result, units, alpha)
