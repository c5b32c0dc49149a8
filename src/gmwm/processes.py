"""Latent error processes: theoretical Haar wavelet variance, its Jacobian, simulation, transforms.

Conventions (see docs/METHODS.md §3): parameters are discrete-time, per sample, except GM, whose
``beta`` is an inverse correlation time in 1/s and needs the sampling frequency ``freq`` [Hz].
Scales ``tau`` are Haar filter lengths ``2**j`` in samples. Every process maps its own parameter
vector ``p`` (in the order of ``param_names``) to the WV ``nu_j = E[W_{j,t}^2]``.

Each process also defines a bijection between its domain and R^k (``to_free``/``from_free``) so
optimisers work unconstrained; ``dp_deta`` is the (diagonal) derivative of that map.

Everything else the library knows about one process lives on its class, so no other module
branches on process names: the variable-projection coordinates of the estimator's search
(:meth:`Process.shape_bounds`, :meth:`Process.unit_wv_columns`, :meth:`Process.from_vp`,
:meth:`Process.shape_of`), the primitive form the WV covariance and the fast simulator work with
(:meth:`Process.primitive`), each parameter's domain (the one estimates and confidence intervals
keep to, :attr:`Process.domain`) and the process's own diagnostics
(:meth:`Process.fit_warnings`, :meth:`Process.degeneracies`, thresholds in
:mod:`gmwm.diagnostics`).
"""

from __future__ import annotations

import contextlib
import math
import sys
from functools import cache, cached_property
from typing import Any

import numpy as np

from . import diagnostics as dg
from .errors import ModelError

# Free-space values are clamped so that wild optimiser steps cannot overflow exp().
_ETA_MAX = 300.0


def _exp(eta: np.ndarray | float) -> np.ndarray:
    # minimum/maximum rather than np.clip: same values, a fraction of the call overhead
    return np.exp(np.minimum(np.maximum(eta, -_ETA_MAX), _ETA_MAX))


#: Kinds of free coordinate: "log" p = e^eta (positive parameters), "phi" p = 2 expit(eta) - 1
#: (AR1 phi in (-1, 1)), "pi" p = pi expit(eta) (SIN beta in (0, pi)).
FREE_KINDS = ("log", "phi", "pi")


def expit(x: np.ndarray) -> np.ndarray:
    """SciPy's logistic function, imported on first use: scipy.special costs ~0.25 s to import,
    and a command that never maps free coordinates (``gmwm plan``, ``gmwm wv``) need not pay it."""
    from scipy.special import expit as f

    return f(x)


def logit(x: np.ndarray) -> np.ndarray:
    """SciPy's logit (the inverse of :func:`expit`), imported on first use."""
    from scipy.special import logit as f

    return f(x)


class FreeMap:
    """The map free coordinates -> parameters of a parameter vector whose entries have the given
    kinds (``FREE_KINDS``), applied to the whole vector at once; its inverse and derivative.
    Processes and models both use it, so each transform is written once."""

    def __init__(self, kinds: tuple[str, ...]):
        k = np.array(kinds, dtype=object)
        unknown = set(kinds) - set(FREE_KINDS)
        if unknown:
            raise ValueError(f"unknown free-coordinate kind(s) {sorted(unknown)}")
        self.log = np.flatnonzero(k == "log")
        self.phi = np.flatnonzero(k == "phi")
        self.pi = np.flatnonzero(k == "pi")

    def from_free(self, eta: np.ndarray) -> np.ndarray:
        eta = np.asarray(eta, dtype=float)
        out = _exp(eta)  # every "log" entry; the others are overwritten
        if self.phi.size:
            out[self.phi] = 2 * expit(eta[self.phi]) - 1
        if self.pi.size:
            out[self.pi] = np.pi * expit(eta[self.pi])
        return out

    def dp_deta(self, eta: np.ndarray) -> np.ndarray:
        eta = np.asarray(eta, dtype=float)
        out = _exp(eta)
        if self.phi.size:
            s = expit(eta[self.phi])
            out[self.phi] = 2 * s * (1 - s)
        if self.pi.size:
            s = expit(eta[self.pi])
            out[self.pi] = np.pi * s * (1 - s)
        return out

    def to_free(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        out = np.log(p)  # every "log" entry; the others are overwritten
        if self.phi.size:
            out[self.phi] = logit((p[self.phi] + 1) / 2)
        if self.pi.size:
            out[self.pi] = logit(np.clip(p[self.pi] / np.pi, 1e-300, 1 - 1e-12))
        return out


class Process:
    """Base class. Subclasses set ``name``, ``param_names`` and implement the methods."""

    name: str = ""
    param_names: tuple[str, ...] = ()
    #: True if nu is linear in a transform h(p) with a parameter-free column (QN, WN, RW, DR).
    linear: bool = False
    #: Index of the scale parameter (variance, amplitude or drift; the one that is 0 when the
    #: component vanishes).
    scale_index: int = 0
    #: The WV is linear in ``p[scale_index] ** scale_power`` (2 for an amplitude or a slope).
    scale_power: int = 1
    #: At most one per model: a sum of two is the same process (QN, WN, RW, DR).
    singleton: bool = False
    #: A correlated term the automatic model choice adds 0..``max_gm`` of (GM, or AR1 on request).
    slow_term: bool = False
    #: The noise term of a navigation filter's configuration this process is
    #: (``"noise_density"``: WN, ``"random_walk"``: RW); every automatically chosen model of an
    #: inertial sensor contains these (:data:`gmwm.automodel.REQUIRED`), and the filter exports
    #: (:mod:`gmwm.exports`) read them. None for the other processes.
    filter_term: str | None = None
    #: What the process gives on a datasheet (:func:`gmwm.datasheet.datasheet`): one continuous
    #: coefficient, :meth:`coefficient`, printed with the :class:`gmwm.units.UnitSystem` entry of
    #: that name (``"white"``, ``"rw"``, ``"qn"``, ``"ramp"``); or ``"sinusoid"`` (frequency and
    #: amplitude), ``"gauss_markov"`` (correlation time and sigma), ``"ar1"`` (a GM when 0 < phi <
    #: 1, else sigma and phi). None: the datasheet does not know the process (an error there).
    datasheet_kind: str | None = None

    def coefficient(self, value: float, freq: float) -> float:
        """The continuous-time datasheet coefficient (SI seconds, signal units) of the scale
        parameter ``value`` at ``freq`` [Hz], monotone in ``value`` (one-coefficient processes)."""
        raise NotImplementedError(f"{self.name} has no single datasheet coefficient")

    def gof_note(self, label: str, p: np.ndarray, n_samples: int) -> str | None:
        """A caveat on the goodness-of-fit test (:mod:`gmwm.gof`) the component brings, if any."""
        return None

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def wv(self, p: np.ndarray, tau: np.ndarray, freq: float = 1.0) -> np.ndarray:
        raise NotImplementedError

    def jacobian(self, p: np.ndarray, tau: np.ndarray, freq: float = 1.0) -> np.ndarray:
        """d nu / d p, shape (len(tau), n_params)."""
        raise NotImplementedError

    def simulate(self, p: np.ndarray, n: int, rng: np.random.Generator,
                 freq: float = 1.0) -> np.ndarray:
        raise NotImplementedError

    #: Kind of each parameter's free coordinate (``FREE_KINDS``).
    free_kinds: tuple[str, ...] = ()

    @property
    def free_map_kinds(self) -> tuple[str, ...]:
        return self.free_kinds or ("log",) * self.n_params

    @cached_property
    def free_map(self) -> FreeMap:
        return FreeMap(self.free_map_kinds)

    def to_free(self, p: np.ndarray) -> np.ndarray:
        return self.free_map.to_free(p)

    def from_free(self, eta: np.ndarray) -> np.ndarray:
        return self.free_map.from_free(eta)

    def free_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Limits of the free coordinates within which ``from_free`` stays inside the open
        domain in floating point (none by default)."""
        return np.full(self.n_params, -np.inf), np.full(self.n_params, np.inf)

    def dp_deta(self, eta: np.ndarray) -> np.ndarray:
        return self.free_map.dp_deta(eta)

    def check(self, p: np.ndarray) -> str | None:
        """Return a message if ``p`` is outside the domain, else None."""
        if np.any(~np.isfinite(p)):
            return "parameters must be finite"
        if np.any(np.asarray(p) <= 0):
            return "parameters must be positive"
        return None

    def order_key(self, p: np.ndarray, freq: float = 1.0) -> float:
        """Key sorting same-type components by the time scale they act on, shortest first."""
        return 0.0

    #: True if the sign of the parameters is not identified by the WV (DR: taken from the signal).
    signed: bool = False

    @property
    def domain(self) -> tuple[tuple[float, float], ...]:
        """Closed domain ``(low, high)`` of each parameter (the order of ``param_names``): where
        estimates and confidence-interval ends may lie (:mod:`gmwm.intervals`). A ``signed``
        process lists the domain of the magnitude (DR: |omega| >= 0, the sign from the signal)."""
        return ((0.0, math.inf),) * self.n_params

    def off_params(self, freq: float = 1.0) -> np.ndarray:
        """Parameters of the component switched off: scale 0, any other parameter at a fixed
        interior value (the WV is then exactly 0)."""
        return np.zeros(self.n_params)

    def wv_many(self, P: np.ndarray, tau: np.ndarray, freq: float = 1.0) -> np.ndarray:
        """WV of many parameter rows at once: P (N, n_params) -> (N, J)."""
        return np.array([self.wv(p, tau, freq) for p in P])

    def primitive(self, p: np.ndarray, freq: float = 1.0) -> tuple[Any, ...]:
        """The primitive form of the process: ``("wn", sigma2)``, ``("qn", Q2)``,
        ``("rw", gamma2)``, ``("dr", omega)``, ``("ar1", phi, a, s2)`` (``a = -ln|phi|``, ``s2``
        the innovation variance) or ``("sin", alpha, beta)``: what the WV covariance
        (:mod:`gmwm.wvcov`) and the fast simulator (:meth:`gmwm.model.Model.simulate_fast`)
        are written for."""
        raise NotImplementedError

    def load_kernels(self) -> None:
        """Load any compiled kernel the process's WV needs (nothing by default)."""

    # -- variable-projection coordinates (gmwm.search) --------------------------------------
    # The WV is linear in the scale parameter once the shape (AR1 phi, GM beta, SIN beta) is
    # fixed. Shapes are searched in a coordinate u where a uniform grid resolves both ends of
    # the domain; processes without a shape (QN, WN, RW, DR) have none (u = 0).

    #: True if the WV oscillates in the shape (SIN: nulls at beta tau / 4 = k pi), so that the
    #: search needs a phase-resolving fine scan and joint scans with the other shapes.
    oscillating: bool = False

    def shape_bounds(self, tau: np.ndarray) -> tuple[float, float] | None:
        """Search range of the shape coordinate for scales ``tau`` (None: no shape)."""
        return None

    def unit_wv_columns(self, u: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """WV at unit scale for shape coordinates u (G,): (J, G)."""
        u = np.atleast_1d(np.asarray(u, dtype=float))
        col = self.wv(np.ones(1), tau)
        return np.repeat(col[:, None], u.size, axis=1)

    def scan_wv_columns(self, u: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """The columns a coarse grid scan uses (default: :meth:`unit_wv_columns`)."""
        return self.unit_wv_columns(u, tau)

    def from_vp(self, u: float, s: float, freq: float, sign: float = 1.0) -> list[float]:
        """Parameters from shape coordinate ``u`` and the (non-negative) coefficient ``s`` of
        the unit-scale WV column; ``sign`` of a signed parameter."""
        return [s]

    def shape_of(self, p: np.ndarray, freq: float) -> float:
        """Shape coordinate of parameters ``p`` (0 without a shape)."""
        return 0.0

    def random_shape(self, p: np.ndarray, rng: np.random.Generator, tau_max: float,
                     freq: float) -> np.ndarray:
        """``p`` with its shape drawn at random over the observed scales (``tau_max`` the
        longest, in samples); unchanged, and no draw, without a shape."""
        return p

    # -- diagnostics (thresholds: gmwm.diagnostics) ------------------------------------------
    #: Relative difference of :meth:`pair_key` below which two components of this process are
    #: identified only through their sum (None: at most one per model, or no rule).
    pair_rel: float | None = None
    #: What :meth:`pair_key` measures, for the message.
    pair_what: str = ""
    #: How two components of this process exchange their parts between near-equal optima.
    swap_verb: str = ""

    def pair_key(self, p: np.ndarray, freq: float) -> float:
        return np.nan

    def fit_warnings(self, label: str, p: np.ndarray, tau_max: float, freq: float) -> list[str]:
        """Warnings of a fit with this component at ``p`` (``tau_max`` the longest scale)."""
        return []

    def degeneracies(self, label: str, p: np.ndarray, tau_max: float, model: Any) -> list[str]:
        """Non-identifiable configurations of this component at ``p`` within ``model``."""
        return []


class WhiteNoise(Process):
    """WN(sigma2): iid N(0, sigma2). nu_j = sigma2 / tau."""

    name = "WN"
    param_names = ("sigma2",)
    linear = True
    singleton = True
    filter_term = "noise_density"
    datasheet_kind = "white"

    def coefficient(self, value, freq):
        return math.sqrt(max(value, 0.0) / freq)   # N = sqrt(sigma2 / f_s) [u sqrt(s)]

    def wv(self, p, tau, freq=1.0):
        return p[0] / tau

    def jacobian(self, p, tau, freq=1.0):
        return (1.0 / tau)[:, None]

    def simulate(self, p, n, rng, freq=1.0):
        z = rng.standard_normal(n)
        z *= np.sqrt(p[0])  # in place: one 8n-byte array per component at 1e7 samples
        return z

    def primitive(self, p, freq=1.0):
        return ("wn", p[0])

    def wv_many(self, P, tau, freq=1.0):
        return P[:, :1] * self.wv(np.ones(1), tau, freq)


class QuantizationNoise(Process):
    """QN(Q2): X_t = Q (V_{t+1} - V_t), V_t = sqrt(12) U_t, U_t ~ U(0,1). nu_j = 6 Q2 / tau^2."""

    name = "QN"
    param_names = ("Q2",)
    linear = True
    singleton = True
    datasheet_kind = "qn"

    def coefficient(self, value, freq):
        return math.sqrt(max(value, 0.0)) / freq   # Q = sqrt(Q2) / f_s [u s]

    def wv(self, p, tau, freq=1.0):
        return 6.0 * p[0] / tau**2

    def jacobian(self, p, tau, freq=1.0):
        return (6.0 / tau**2)[:, None]

    def simulate(self, p, n, rng, freq=1.0):
        v = rng.random(n + 1)
        v *= np.sqrt(12.0 * p[0])
        return np.diff(v)

    def primitive(self, p, freq=1.0):
        return ("qn", p[0])

    def wv_many(self, P, tau, freq=1.0):
        return P[:, :1] * self.wv(np.ones(1), tau, freq)


class RandomWalk(Process):
    """RW(gamma2): X_t = X_{t-1} + N(0, gamma2). nu_j = gamma2 (tau^2 + 2) / (12 tau)."""

    name = "RW"
    param_names = ("gamma2",)
    linear = True
    singleton = True
    filter_term = "random_walk"
    datasheet_kind = "rw"

    def coefficient(self, value, freq):
        return math.sqrt(max(value, 0.0) * freq)   # K = sqrt(gamma2 f_s) [u / sqrt(s)]

    def wv(self, p, tau, freq=1.0):
        return p[0] * (tau**2 + 2.0) / (12.0 * tau)

    def jacobian(self, p, tau, freq=1.0):
        return ((tau**2 + 2.0) / (12.0 * tau))[:, None]

    def simulate(self, p, n, rng, freq=1.0):
        z = rng.standard_normal(n)
        z *= np.sqrt(p[0])
        return np.cumsum(z, out=z)

    def primitive(self, p, freq=1.0):
        return ("rw", p[0])

    def wv_many(self, P, tau, freq=1.0):
        return P[:, :1] * self.wv(np.ones(1), tau, freq)


class Drift(Process):
    """DR(omega): X_t = omega t. nu_j = omega^2 tau^2 / 16 (the sign of omega is not identified
    by the WV; the free parameter is log|omega| and the sign is kept positive)."""

    name = "DR"
    param_names = ("omega",)
    linear = True
    signed = True
    singleton = True
    scale_power = 2
    datasheet_kind = "ramp"

    def coefficient(self, value, freq):
        return value * freq   # R = omega f_s [u / s]

    def wv(self, p, tau, freq=1.0):
        return p[0] ** 2 * tau**2 / 16.0

    def jacobian(self, p, tau, freq=1.0):
        return (p[0] * tau**2 / 8.0)[:, None]

    def simulate(self, p, n, rng, freq=1.0):
        t = np.arange(1, n + 1, dtype=float)
        t *= p[0]
        return t

    def to_free(self, p):
        return np.log(np.abs(np.asarray(p, dtype=float)))

    def primitive(self, p, freq=1.0):
        return ("dr", p[0])

    def wv_many(self, P, tau, freq=1.0):
        # nu = omega^2 * column
        return P[:, :1] ** 2 * self.wv(np.ones(1), tau, freq)

    def from_vp(self, u, s, freq, sign=1.0):
        return [sign * np.sqrt(s)]

    def check(self, p):
        if not np.all(np.isfinite(p)) or p[0] == 0:
            return "omega must be finite and non-zero"
        return None


# --- AR1 ---------------------------------------------------------------------------------------
# Evaluated in terms of a = -ln(phi) (phi in (0,1)) with the cancellation-free form of docs/METHODS.md §3.6;
# the textbook formula loses up to all digits when phi -> 1 (Simulation 2 uses phi = 0.999995).
# The loops are Numba kernels (gmwm._ar1kernels), loaded on first use.


@cache
def _kernels() -> Any:
    from . import _ar1kernels

    return _ar1kernels


def _scales(tau: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(tau, dtype=np.float64).reshape(-1)


def _with_derivative(kernel: Any, x: float, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    tau = _scales(tau)
    nu, dnu = np.empty(tau.size), np.empty(tau.size)
    kernel(float(x), tau, nu, dnu)
    return nu, dnu


#: calls of :func:`ar1_wv_a` answered in Python before it loads the Numba kernel (see there)
_PY_CALLS = 256
_py_calls = 0


def _ar1_a_py(a: float, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gmwm._ar1kernels.ar1_a` in plain Python: the same operations in the same order on
    the same libm functions, so the same bits (tests/test_processes_ar1py.py); ZeroDivisionError
    or OverflowError where the kernel gives inf/nan (the caller then asks the kernel)."""
    switch = 1e-2  # _ar1kernels.SERIES_SWITCH
    phi = math.exp(-a)
    u1 = -math.expm1(-a)
    u2 = -math.expm1(-2 * a)
    pp = u1 * u1 * u2
    ppp = 2 * u1 * phi * u2 + 2 * (u1 * u1) * (phi * phi)
    nu, dnu = [], []
    for t in tau.tolist():
        m = t / 2
        ma = m * a
        if ma < switch:  # _ar1kernels._series
            c0 = m / 6 + 1 / (12 * m)
            c1 = -(m * m) / 8 + m / 6 + 1 / (12 * m)
            m2 = m * m
            m3 = m2 * m
            m4 = m3 * m
            m5 = m4 * m
            c2 = (7 * m4 - 15 * m3 + 5 * m2 + 3) / (120 * m)
            c3 = (-30 * m5 + 84 * m4 - 45 * m3 - 20 * m2 - 4) / (1440 * m)
            c4 = (m - 1) * (62 * m5 - 148 * m4 - m3 + 104 * m2 + 27 * m + 27) / (10080 * m)
            nu.append(c0 + a * (c1 + a * (c2 + a * (c3 + a * c4))))
            dnu.append(c1 + a * (2 * c2 + a * (3 * c3 + a * 4 * c4)))
            continue
        e = -math.expm1(-ma)
        g = m * u2 - phi * e * (2 + e)  # _ar1kernels._g
        gp = 2 * m * (phi * phi) + phi * e * (2 + e) - 2 * phi * m * (1 - e) * (1 + e)
        t2 = t * t
        nu.append(2 * g / (t2 * pp))
        dnu.append(2 / t2 * (gp * pp - g * ppp) / (pp * pp))
    return np.array(nu, dtype=np.float64), np.array(dnu, dtype=np.float64)


def ar1_wv_a(a: float, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """WV of an AR1 with unit innovation variance and phi = exp(-a) > 0, and its derivative in
    a.

    Until the Numba kernels are loaded (a fit loads them, :meth:`Process.load_kernels`) the
    first :data:`_PY_CALLS` calls are answered by :func:`_ar1_a_py`, bit for bit the kernel's
    result: a process that only draws a fitted model's WV or plans a recording (a few hundred
    calls) then never pays Numba's ~0.5 s start-up for this kernel."""
    global _py_calls
    if "gmwm._ar1kernels" not in sys.modules and _py_calls < _PY_CALLS:
        _py_calls += 1
        with contextlib.suppress(ZeroDivisionError, OverflowError):  # the kernel's inf/nan
            return _ar1_a_py(float(a), _scales(tau))
    return _with_derivative(_kernels().ar1_a, a, tau)


def ar1_unit_wv(phi: float, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(nu, d nu / d phi) of an AR1 with unit innovation variance, phi in (-1, 1)."""
    return _with_derivative(_kernels().ar1_phi, phi, tau)


def ar1_unit_wv_many(phi: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Unit-innovation AR1 WV for many phi at once: phi (N,) -> (N, J), with the numerics of
    :func:`ar1_unit_wv`."""
    phi = np.ascontiguousarray(phi, dtype=np.float64).reshape(-1)
    tau = _scales(tau)
    out = np.empty((phi.size, tau.size))
    _kernels().ar1_many(phi, tau, out)
    return out


def sin_unit_wv(beta: np.ndarray | float, tau: np.ndarray) -> np.ndarray:
    """Unit-amplitude SIN WV ``2 sin^4(beta tau / 4) / (tau^2 sin^2(beta / 2))`` (the stable
    form of docs/METHODS.md §3.8); ``beta`` broadcasts against ``tau`` (e.g. beta (G, 1) x tau (J,))."""
    beta = np.asarray(beta, dtype=float)
    tau = np.asarray(tau, dtype=float)
    # squares by multiplication: ** 4 goes through pow() and doubles the cost of VP grid scans
    s = np.sin(beta * tau / 4)
    s *= s
    s *= s
    d = np.sin(beta / 2)
    return 2 * s / (tau**2 * (d * d))


def _simulate_ar1(phi: float, s2: float, n: int, rng: np.random.Generator) -> np.ndarray:
    e = rng.standard_normal(n)
    e *= np.sqrt(s2)
    e[0] /= np.sqrt(1.0 - phi**2)  # stationary start
    from scipy.signal import lfilter  # ~0.6 s of imports that only simulation needs

    return lfilter([1.0], [1.0, -phi], e)


# shape coordinate of the AR1 at phi = -1 + 2e-6 (xi = 2 atanh(phi))
_XI_NEG = -np.log(2 / 2e-6)


class _AR1Like(Process):
    """What AR1 and GM share: an AR1 in disguise (GM: phi = exp(-beta / freq)), searched by its
    decay rate, diagnosed by its correlation time against the scales and the white noise."""

    scale_index = 1
    pair_rel = dg.PAIR_REL_AR
    pair_what = "correlation time"
    swap_verb = "trade variance"

    def load_kernels(self) -> None:
        # Numba's start-up (~0.3 s once per process), so that a timed fit does not include it
        ar1_unit_wv_many(np.array([0.5]), np.array([2.0]))

    def rate(self, p: np.ndarray, freq: float) -> float:
        """Decay rate a = -ln(phi) per sample (inf for phi <= 0)."""
        raise NotImplementedError

    def pair_key(self, p, freq):
        return self.rate(p, freq)

    def _rate_from_draw(self, rng: np.random.Generator, tau_max: float) -> float:
        # correlation times from 1/3 sample to 5 longest scales
        return np.exp(rng.uniform(np.log(0.2 / tau_max), np.log(3.0)))

    def _rate_notes(self, label: str, a: float, tau_max: float, model: Any) -> list[str]:
        if a > dg.COLLAPSE_RATE and model.count(WhiteNoise.name):
            return [(f"{label} collapses into white noise (phi = {np.exp(-a):.3g}, correlation "
                    "time below one sample): its split with WN[1] is not identified")]
        if a * tau_max * dg.RW_LIKE < 1:
            return [(f"{label} behaves like a random walk over the observed scales (correlation "
                    f"time {1 / a:.3g} samples > {dg.RW_LIKE:g} x the longest scale "
                    f"{tau_max:g}): phi is not identified")]
        return []


class AR1(_AR1Like):
    """AR1(phi, sigma2): X_t = phi X_{t-1} + N(0, sigma2), sigma2 the innovation variance,
    |phi| < 1, stationary start. Free parameters: scaled logit of phi on (-1, 1), log sigma2."""

    name = "AR1"
    param_names = ("phi", "sigma2")
    free_kinds = ("phi", "log")
    domain = ((-1.0, 1.0), (0.0, math.inf))
    slow_term = True
    datasheet_kind = "ar1"

    @staticmethod
    def correlation_time(phi: float, freq: float) -> float:
        """Correlation time [s] of the Gauss-Markov process an AR1 with ``phi`` samples at ``freq``
        [Hz]: ``-1 / (f_s ln phi)``, increasing on (0, 1); 0 for phi <= 0, inf for phi >= 1."""
        if phi <= 0:
            return 0.0
        return math.inf if phi >= 1 else -1.0 / (freq * math.log(phi))

    @staticmethod
    def stationary_variance(phi: float, sigma2: float) -> float:
        """Stationary variance ``sigma2 / (1 - phi^2)`` [u^2] (innovation variance clamped at 0)."""
        return max(sigma2, 0.0) / max(1.0 - phi ** 2, 1e-300)

    def free_limits(self):
        # 2 expit(eta) - 1 rounds to 1 from eta ~ 37 on: phi = 1 is a random walk, not an AR1
        return np.array([-36.0, -np.inf]), np.array([36.0, np.inf])

    def wv(self, p, tau, freq=1.0):
        return p[1] * ar1_unit_wv(p[0], tau)[0]

    def jacobian(self, p, tau, freq=1.0):
        nu, dphi = ar1_unit_wv(p[0], tau)
        return np.column_stack([p[1] * dphi, nu])

    def simulate(self, p, n, rng, freq=1.0):
        return _simulate_ar1(p[0], p[1], n, rng)

    def wv_many(self, P, tau, freq=1.0):
        return P[:, 1:2] * ar1_unit_wv_many(P[:, 0], tau)

    def primitive(self, p, freq=1.0):
        phi, s2 = float(p[0]), float(p[1])
        return ("ar1", phi, -np.log(abs(phi)) if phi != 0 else np.inf, s2)

    def off_params(self, freq=1.0):
        return np.array([0.5, 0.0])

    # shape coordinate xi = 2 atanh(phi) over the whole domain phi in (-1, 1)
    def shape_bounds(self, tau):
        # up to a correlation time ~5x the longest scale
        return _XI_NEG, float(np.log(2 * 5 * tau[-1]))

    def unit_wv_columns(self, u, tau):
        u = np.atleast_1d(np.asarray(u, dtype=float))
        return ar1_unit_wv_many(np.tanh(u / 2), tau).T

    def from_vp(self, u, s, freq, sign=1.0):
        return [np.tanh(u / 2), s]

    def shape_of(self, p, freq):
        return 2 * np.arctanh(np.clip(p[0], -1 + 1e-15, 1 - 1e-15))

    def random_shape(self, p, rng, tau_max, freq):
        p = np.array(p, dtype=float)
        p[0] = np.exp(-self._rate_from_draw(rng, tau_max))
        return p

    def rate(self, p, freq):
        return float(-np.log(p[0])) if p[0] > 0 else np.inf

    def fit_warnings(self, label, p, tau_max, freq):
        if abs(p[0]) > 1 - dg.PHI_EDGE:
            return [(f"{label}.phi = {p[0]:.8g} is at the edge of the stationary domain "
                    f"(|phi| -> 1): {'a random walk' if p[0] > 0 else 'an alternating process'}"
                    " over the observed scales, not an AR1")]
        return []

    def degeneracies(self, label, p, tau_max, model):
        if p[0] > 0:
            return self._rate_notes(label, self.rate(p, model.freq), tau_max, model)
        if p[0] < -dg.PHI_NEG_EDGE:
            return [(f"{label} is at the edge phi -> -1 (phi = {p[0]:.7g}): an alternating "
                    "process whose WV is concentrated at the first scale; its phi and variance "
                    "are not separately identified")]
        if p[0] > -dg.PHI_ZERO and model.count(WhiteNoise.name):
            return [(f"{label} collapses into white noise (phi = {p[0]:.3g} ~ 0): its split with "
                    "WN[1] is not identified")]
        return []

    def check(self, p):
        if not np.all(np.isfinite(p)):
            return "parameters must be finite"
        if not -1 < p[0] < 1:
            return f"phi must lie in (-1, 1), got {p[0]:g}"
        if p[1] <= 0:
            return "innovation variance sigma2 must be positive"
        return None

    def order_key(self, p, freq=1.0):
        return float(p[0])


class GaussMarkov(_AR1Like):
    """GM(beta, sigma2): exactly sampled Gauss-Markov process = AR1 with phi = exp(-beta/freq),
    innovation variance sigma2 (1 - phi^2). beta in 1/s (inverse correlation time), sigma2 the
    stationary variance."""

    name = "GM"
    param_names = ("beta", "sigma2")
    slow_term = True
    datasheet_kind = "gauss_markov"

    @staticmethod
    def correlation_time(beta: float) -> float:
        """Correlation time ``1 / beta`` [s] (inf for beta <= 0)."""
        return 1.0 / beta if beta > 0 else math.inf

    def _ar1(self, p, freq):
        a = p[0] / freq
        return a, p[1] * -np.expm1(-2 * a)

    def wv(self, p, tau, freq=1.0):
        a, s2 = self._ar1(p, freq)
        return s2 * ar1_wv_a(a, tau)[0]

    def jacobian(self, p, tau, freq=1.0):
        a, s2 = self._ar1(p, freq)
        nu, dnu_da = ar1_wv_a(a, tau)
        # d/dbeta: through a (= beta/freq) both directly and via the innovation variance.
        dbeta = (s2 * dnu_da + nu * p[1] * 2 * np.exp(-2 * a)) / freq
        dsig = nu * -np.expm1(-2 * a)
        return np.column_stack([dbeta, dsig])

    def simulate(self, p, n, rng, freq=1.0):
        a, s2 = self._ar1(p, freq)
        return _simulate_ar1(np.exp(-a), s2, n, rng)

    def wv_many(self, P, tau, freq=1.0):
        a = P[:, 0] / freq
        return (P[:, 1] * -np.expm1(-2 * a))[:, None] * ar1_unit_wv_many(np.exp(-a), tau)

    def primitive(self, p, freq=1.0):
        a = float(p[0]) / freq
        return ("ar1", float(np.exp(-a)), a, float(p[1] * -np.expm1(-2 * a)))

    def off_params(self, freq=1.0):
        return np.array([freq * 0.1, 0.0])

    # shape coordinate log(a), a = beta / freq (phi = e^-a in (0, 1))
    def shape_bounds(self, tau):
        return float(np.log(0.2 / tau[-1])), float(np.log(7.0))

    def unit_wv_columns(self, u, tau):
        a = np.exp(np.atleast_1d(np.asarray(u, dtype=float)))
        return (-np.expm1(-2 * a)[:, None] * ar1_unit_wv_many(np.exp(-a), tau)).T

    def from_vp(self, u, s, freq, sign=1.0):
        return [np.exp(u) * freq, s]

    def shape_of(self, p, freq):
        return np.log(max(p[0] / freq, 1e-300))

    def random_shape(self, p, rng, tau_max, freq):
        p = np.array(p, dtype=float)
        p[0] = self._rate_from_draw(rng, tau_max) * freq
        return p

    def rate(self, p, freq):
        return float(p[0] / freq)

    def degeneracies(self, label, p, tau_max, model):
        return self._rate_notes(label, self.rate(p, model.freq), tau_max, model)

    def order_key(self, p, freq=1.0):
        return float(1.0 / p[0])


class Sinusoid(Process):
    """SIN(alpha, beta): X_t = alpha sin(beta t + U), U ~ U(0, 2 pi); alpha > 0 amplitude,
    beta in (0, pi] rad/sample. nu_j = 2 alpha^2 sin^4(beta tau/4) / (tau^2 sin^2(beta/2))."""

    name = "SIN"
    param_names = ("alpha", "beta")
    free_kinds = ("log", "pi")
    domain = ((0.0, math.inf), (0.0, math.pi))
    oscillating = True
    scale_power = 2
    datasheet_kind = "sinusoid"

    @staticmethod
    def frequency_hz(beta: float, freq: float) -> float:
        """Frequency [Hz] of angular frequency ``beta`` [rad/sample] at ``freq`` [Hz]."""
        return beta * freq / (2 * math.pi)

    def gof_note(self, label, p, n_samples):
        beta = float(p[1])
        if beta > 0 and 2 * np.pi / beta > float(n_samples) / 20:
            return (f"{label} has a period over 1/20 of the signal: its WV depends on the phase "
                    "and the test is liberal")
        return None
    pair_rel = dg.PAIR_REL_SIN
    pair_what = "beta"
    swap_verb = "swap roles"
    #: x = beta tau / 4 at the WV's peak: the root of tan x = 2 x (sin^4 x / x^2 is largest)
    PEAK_X = 1.1656

    def wv(self, p, tau, freq=1.0):
        return p[0] ** 2 * sin_unit_wv(p[1], tau)

    def jacobian(self, p, tau, freq=1.0):
        alpha, beta = float(p[0]), float(p[1])
        x = beta * tau / 4
        s = np.sin(x)
        c = np.cos(x)
        s1, c1 = math.sin(beta / 2), math.cos(beta / 2)
        s3 = s * s * s
        out = np.empty((tau.size, 2))
        out[:, 0] = 4 * alpha * s3 * s / (tau * tau * (s1 * s1))
        out[:, 1] = 2 * alpha * alpha / (tau * tau) * s3 * (tau * c * s1 - s * c1) / (s1 * s1 * s1)
        return out

    def simulate(self, p, n, rng, freq=1.0):
        u = rng.uniform(0.0, 2 * np.pi)
        return p[0] * np.sin(p[1] * np.arange(1, n + 1, dtype=float) + u)

    def wv_many(self, P, tau, freq=1.0):
        return P[:, :1] ** 2 * sin_unit_wv(P[:, 1:2], tau)

    def primitive(self, p, freq=1.0):
        return ("sin", float(p[0]), float(p[1]))

    def off_params(self, freq=1.0):
        return np.array([0.0, 1.0])

    # shape coordinate log(beta)
    def shape_bounds(self, tau):
        return float(np.log(1.0 / tau[-1])), float(np.log(0.999 * np.pi))

    def unit_wv_columns(self, u, tau):
        u = np.atleast_1d(np.asarray(u, dtype=float))
        return sin_unit_wv(np.exp(u)[None, :], tau[:, None])

    def scan_wv_columns(self, u, tau):
        """Smooth stand-in for the WV used to locate the bump on a coarse grid: past the first
        peak, sin^4(beta tau / 4) is replaced by its mean 3/8, removing the oscillation in beta
        that makes a coarse grid land on arbitrary phases."""
        b = np.exp(np.asarray(u))[None, :]
        t = tau[:, None]
        x = b * t / 4
        s2 = np.sin(np.minimum(x, self.PEAK_X))
        s2 *= s2
        s4 = np.where(x < self.PEAK_X, s2 * s2, 0.375)
        d = np.sin(b / 2)
        return 2 * s4 / (t**2 * (d * d))

    def from_vp(self, u, s, freq, sign=1.0):
        return [np.sqrt(s), np.exp(u)]

    def shape_of(self, p, freq):
        return np.log(max(p[1], 1e-300))

    def random_shape(self, p, rng, tau_max, freq):
        p = np.array(p, dtype=float)
        p[1] = np.exp(rng.uniform(np.log(1.0 / tau_max), np.log(0.999 * np.pi)))
        return p

    def pair_key(self, p, freq):
        return p[1]

    def is_slow(self, p: np.ndarray, tau_max: float) -> bool:
        """True if the WV peaks beyond the longest scale ``tau_max`` (the slow-SIN rule of
        :mod:`gmwm.diagnostics`): alpha and beta are then confounded with a drift."""
        return bool(p[1] * tau_max < 4 * self.PEAK_X)

    def _slow_note(self, label: str, p: np.ndarray, tau_max: float) -> list[str]:
        if not self.is_slow(p, tau_max):
            return []
        with np.errstate(divide="ignore"):
            period = 2 * np.pi / np.float64(p[1])
        return [(f"{label} has a period of {period:.3g} samples: its WV peaks beyond the longest "
                f"scale ({tau_max:.0f} samples) and rises like a drift's over the observed scales "
                f"(like a drift of slope alpha * beta / sqrt(2) = {p[0] * p[1] / np.sqrt(2):.3g}, the "
                "sinusoid's RMS slope), so alpha and beta are not identified "
                "separately: confounded with a drift (DR)")]

    def fit_warnings(self, label, p, tau_max, freq):
        out = []
        if p[1] > np.pi * (1 - dg.SIN_NYQUIST_EDGE):
            out.append(f"{label}.beta = {p[1]:.6g} is at the Nyquist bound pi")
        return out + self._slow_note(label, p, tau_max)

    def degeneracies(self, label, p, tau_max, model):
        return self._slow_note(label, p, tau_max)

    def check(self, p):
        if not np.all(np.isfinite(p)):
            return "parameters must be finite"
        if p[0] <= 0:
            return "amplitude alpha must be positive"
        if not 0 < p[1] <= np.pi:
            return f"beta must lie in (0, pi] rad/sample, got {p[1]:g}"
        return None

    def order_key(self, p, freq=1.0):
        return float(-p[1])


PROCESSES: dict[str, Process] = {
    proc.name: proc
    for proc in (QuantizationNoise(), WhiteNoise(), AR1(), GaussMarkov(), Sinusoid(),
                 RandomWalk(), Drift())
}
"""Registry in canonical model order (roughly the time scale each process dominates)."""

#: Processes of which a model may hold at most one (sums of them are the same process).
SINGLETONS = frozenset(n for n, proc in PROCESSES.items() if proc.singleton)


def process(name: str) -> Process:
    """The registered process ``name`` (:data:`PROCESSES`); a ModelError naming the known ones
    for any other name."""
    try:
        return PROCESSES[name]
    except KeyError:
        raise ModelError(f"unknown process {name!r}; known: {', '.join(PROCESSES)}") from None
