"""Numba kernels of :mod:`gmwm.processes`: the unit-innovation AR1 wavelet variance and its
derivative, one fused loop over the scales instead of ~25 NumPy calls on 20-element arrays (the
search evaluates it thousands of times per fit). Imported lazily (``processes._kernels``), so
that importing the library or computing a WV never loads Numba.

Formulas: docs/METHODS.md §3.6 in terms of ``a = -ln(phi)`` for ``phi > 0`` (cancellation-free when
phi -> 1; a 5-term series in ``a`` where ``m a < SERIES_SWITCH``, ``m = tau / 2``) and the
plain closed form for ``phi <= 0`` (no cancellation there). ``tau`` = filter lengths in samples.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# error_model="numpy": a division by zero gives inf/nan as in NumPy (the optimiser may probe
# phi = +-1), not a ZeroDivisionError

#: m a below which the series replaces the closed form (the closed form cancels there).
SERIES_SWITCH = 1e-2


@njit(cache=True, inline="always", error_model="numpy")
def _series(m: float, a: float) -> tuple[float, float]:
    """(nu, d nu / d a) from the series in ``a`` (coefficients polynomials in ``m``)."""
    c0 = m / 6 + 1 / (12 * m)
    c1 = -(m * m) / 8 + m / 6 + 1 / (12 * m)
    m2 = m * m
    m3 = m2 * m
    m4 = m3 * m
    m5 = m4 * m
    c2 = (7 * m4 - 15 * m3 + 5 * m2 + 3) / (120 * m)
    c3 = (-30 * m5 + 84 * m4 - 45 * m3 - 20 * m2 - 4) / (1440 * m)
    c4 = (m - 1) * (62 * m5 - 148 * m4 - m3 + 104 * m2 + 27 * m + 27) / (10080 * m)
    nu = c0 + a * (c1 + a * (c2 + a * (c3 + a * c4)))
    dnu = c1 + a * (2 * c2 + a * (3 * c3 + a * 4 * c4))
    return nu, dnu


@njit(cache=True, inline="always", error_model="numpy")
def _consts(a: float) -> tuple[float, float, float, float]:
    """phi = e^-a, 1 - phi^2 (without cancellation), the WV's denominator factor
    pp = (1 - phi)^2 (1 - phi^2) and its derivative in a."""
    phi = math.exp(-a)
    u1 = -math.expm1(-a)
    u2 = -math.expm1(-2 * a)
    pp = u1 * u1 * u2
    ppp = 2 * u1 * phi * u2 + 2 * (u1 * u1) * (phi * phi)
    return phi, u2, pp, ppp


@njit(cache=True, inline="always", error_model="numpy")
def _g(m: float, e: float, phi: float, u2: float) -> float:
    """Numerator of the closed form: nu = 2 g / (tau^2 pp), with e = 1 - phi^m."""
    return m * u2 - phi * e * (2 + e)


@njit(cache=True, error_model="numpy")
def ar1_a(a: float, tau: np.ndarray, nu: np.ndarray, dnu_da: np.ndarray) -> None:
    """WV of an AR1 with phi = exp(-a) > 0 and unit innovation variance into ``nu``, its
    derivative in ``a`` into ``dnu_da``."""
    phi, u2, pp, ppp = _consts(a)
    for j in range(tau.shape[0]):
        t = tau[j]
        m = t / 2
        ma = m * a
        if ma < SERIES_SWITCH:
            nu[j], dnu_da[j] = _series(m, a)
            continue
        e = -math.expm1(-ma)
        g = _g(m, e, phi, u2)
        gp = 2 * m * (phi * phi) + phi * e * (2 + e) - 2 * phi * m * (1 - e) * (1 + e)
        t2 = t * t
        nu[j] = 2 * g / (t2 * pp)
        dnu_da[j] = 2 / t2 * (gp * pp - g * ppp) / (pp * pp)


@njit(cache=True, error_model="numpy")
def ar1_direct(phi: float, tau: np.ndarray, nu: np.ndarray, dnu: np.ndarray) -> None:
    """Closed form for ``phi <= 0``: WV into ``nu`` and its derivative in phi into ``dnu``."""
    for j in range(tau.shape[0]):
        t = tau[j]
        m = t / 2
        pm = phi**m
        pt = pm * pm  # t = 2 m: one pow per scale
        n = (1 - phi * phi) * t - 2 * phi * (3 - 4 * pm + pt)
        d = t * t * (1 - phi) ** 3 * (1 + phi)
        pm1 = pm / phi if phi != 0 else (1.0 if m == 1 else 0.0)
        pt1 = pt / phi if phi != 0 else 0.0
        dn = -2 * phi * t - 6 + 8 * pm - 2 * pt + 8 * m * phi * pm1 - 2 * t * phi * pt1
        dd = -2 * t * t * (1 - phi) ** 2 * (1 + 2 * phi)
        nu[j] = n / d
        dnu[j] = (dn * d - n * dd) / (d * d)


@njit(cache=True, error_model="numpy")
def ar1_phi(phi: float, tau: np.ndarray, nu: np.ndarray, dnu: np.ndarray) -> None:
    """WV of a unit-innovation AR1 and its derivative in phi, any phi in (-1, 1)."""
    if phi > 0:
        ar1_a(-math.log(phi), tau, nu, dnu)
        for j in range(tau.shape[0]):
            dnu[j] = -dnu[j] / phi
    else:
        ar1_direct(phi, tau, nu, dnu)


@njit(cache=True, error_model="numpy")
def ar1_many(phi: np.ndarray, tau: np.ndarray, out: np.ndarray) -> None:
    """WV of unit-innovation AR1s for many phi: ``out[i, j]`` for ``phi[i]`` at ``tau[j]``
    (the formulas of :func:`ar1_phi`, without the derivative where it costs extra)."""
    J = tau.shape[0]
    dnu = np.empty(J)
    for i in range(phi.shape[0]):
        p = phi[i]
        if p <= 0:
            ar1_direct(p, tau, out[i], dnu)
            continue
        a = -math.log(p)
        _, u2, pp, _ = _consts(a)
        for j in range(J):
            t = tau[j]
            m = t / 2
            ma = m * a
            if ma < SERIES_SWITCH:
                out[i, j] = _series(m, a)[0]
            else:
                e = -math.expm1(-ma)
                out[i, j] = 2 * _g(m, e, p, u2) / (t * t * pp)
