"""Paper 003 simulations (SPEC 6.3): virtual gyroscopes of 6-gyro arrays by SVO, RDVG and equal
weights, Case 1 (WN + correlated RW) and Case 2 (WN + three correlated AR1).

Units: discrete time, per sample, deg^2/s^2 at 10 Hz (paper App. C). Streams: every array comes
from ``SeedSequence(seed, spawn_key=(crc32("svo"), crc32(case), crc32(role), replicate[, k]))``
with role ``train`` (the 50 arrays coefficients are estimated on), ``test`` (10 fresh arrays per
training array, ``k = 0..9``) or ``coverage``; so a replicate never depends on job layout.

Protocol (paper Sec. V-A): for each training array the four coefficient vectors (SVO omega_1,
SVO omega_2, RDVG, equal) are estimated; each is applied to that replicate's test arrays (the WV
of ``c'X`` is ``c' A_j c`` of the test array's WCCV, exact, no second pass); the virtual signals'
WVs are averaged and a WN+RW GMWM model is fitted to each.
"""

from __future__ import annotations

import math
import time
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.linalg import cholesky
from scipy.signal import lfilter
from scipy.stats import norm

from gmwm.errors import InputError
from gmwm.processes import ar1_unit_wv
from gmwm.svo import (PAPER_OMEGA_LONG, PAPER_OMEGA_SHORT, WaveletCrossCovariance, equal, rdvg,
                      svo, svo_coef, svo_weights, wccv)

METHODS = ("svo_w1", "svo_w2", "rdvg", "equal")
METHOD_LABELS = {"svo_w1": "SVO $\\omega_1$", "svo_w2": "SVO $\\omega_2$", "rdvg": "RDVG",
                 "equal": "Equal weights"}

# --- paper 003 App. C (deg^2/s^2, discrete, 10 Hz) -----------------------------------------------
R_DIAG = np.array([2.805556, 1.977778, 1.361111, 1.063889, 1.069444, 2.538889]) * 1e-7
Q_CASE1 = np.array([
    [0.255058, -0.008573, 0.102881, -0.162894, -0.240055, -0.055727],
    [-0.008573, 0.471536, 0.199331, 0.010717, 0.032150, 0.207905],
    [0.102881, 0.199331, 3.489369, -1.281722, 0.055727, -0.302212],
    [-0.162894, 0.010717, -1.281722, 2.091907, 0.409379, 0.544410],
    [-0.240055, 0.032150, 0.055727, 0.409379, 0.555127, 0.244342],
    [-0.055727, 0.207905, -0.302212, 0.544410, 0.244342, 2.501286]]) * 1e-13
P1 = np.array([
    [0.400813, -0.018061, -0.044770, -0.104857, 0.254671, -0.234950],
    [-0.018061, 1.177847, -0.012905, -0.374198, -0.051101, 0.284942],
    [-0.044770, -0.012905, 1.965775, 0.202629, -0.175089, 0.144629],
    [-0.104857, -0.374198, 0.202629, 1.309887, 0.023176, 0.412761],
    [0.254671, -0.051101, -0.175089, 0.023176, 1.928375, 0.571453],
    [-0.234950, 0.284942, 0.144629, 0.412761, 0.571453, 1.434466]]) * 1e-11
P2 = np.array([
    [6.713833, 1.515552, 1.245013, -0.071179, 0.428489, 0.957757],
    [1.515552, 5.607230, 2.264650, -0.773724, 0.281054, 1.440987],
    [1.245013, 2.264650, 7.499051, -0.162687, -0.529317, -0.999575],
    [-0.071179, -0.773724, -0.162687, 1.207920, -0.187305, 0.681702],
    [0.428489, 0.281054, -0.529317, -0.187305, 7.499327, 2.414762],
    [0.957757, 1.440987, -0.999575, 0.681702, 2.414762, 6.461646]]) * 1e-13
P3 = np.array([
    [5.062006, -0.643280, 0.326013, 0.697800, 1.727949, 0.738584],
    [-0.643280, 1.612038, -0.318449, -0.383634, -0.768214, -0.100044],
    [0.326013, -0.318449, 2.102923, 0.091458, 0.398505, -0.137760],
    [0.697800, -0.383634, 0.091458, 0.788177, -0.129179, 0.519119],
    [1.727949, -0.768214, 0.398505, -0.129179, 5.442670, 0.378632],
    [0.738584, -0.100044, -0.137760, 0.519119, 0.378632, 4.990004]]) * 1e-14
PHI_CASE2 = (0.9975214, 0.9998705, 0.9999933)


@dataclass(frozen=True)
class Case:
    """A simulated array: ``X_t = xi_t + sum of components``; ``R`` the WN covariance, ``rw`` the
    RW innovation covariance (or None), ``ar1`` pairs ``(phi, innovation covariance)``."""

    name: str
    R: np.ndarray
    rw: np.ndarray | None = None
    ar1: tuple[tuple[float, np.ndarray], ...] = ()

    @property
    def p(self) -> int:
        return int(self.R.shape[0])

    def wccv(self, scales: Any) -> np.ndarray:
        """True WCCV ``A_j`` ``(J, p, p)`` at filter lengths ``scales`` (samples): WN
        ``R / tau``, RW ``Q (tau^2 + 2) / (12 tau)``, AR1 ``P nu_AR1(phi, tau)`` (unit innovation)."""
        tau = np.asarray(scales, dtype=np.float64)
        A = self.R[None] / tau[:, None, None]
        if self.rw is not None:
            A = A + self.rw[None] * ((tau**2 + 2.0) / (12.0 * tau))[:, None, None]
        for phi, P in self.ar1:
            nu, _ = ar1_unit_wv(phi, tau)
            A = A + P[None] * nu[:, None, None]
        return A

    def simulate(self, T: int, rng: np.random.Generator) -> np.ndarray:
        """One array ``(T, p)``; RW starts at 0, AR1 components in their stationary law."""
        p = self.p
        X = rng.standard_normal((T, p)) * np.sqrt(np.diag(self.R))[None]
        if not np.allclose(self.R, np.diag(np.diag(self.R))):
            X = rng.standard_normal((T, p)) @ cholesky(self.R)
        if self.rw is not None:
            X += np.cumsum(rng.standard_normal((T, p)) @ cholesky(self.rw), axis=0)
        for phi, P in self.ar1:
            L = cholesky(P)
            eta = rng.standard_normal((T, p)) @ L
            b0 = (rng.standard_normal(p) @ L) / math.sqrt(1.0 - phi * phi)
            X += lfilter([1.0], [1.0, -phi], eta, axis=0, zi=(phi * b0)[None, :])[0]
        return X


CASES = {
    "case1": Case("case1", np.diag(R_DIAG), rw=Q_CASE1),
    "case2": Case("case2", np.diag(R_DIAG), ar1=tuple(zip(PHI_CASE2, (P1, P2, P3)))),
}

#: Paper omega vectors (J = 19) by the pipeline's names.
OMEGAS = {"w1": PAPER_OMEGA_LONG, "w2": PAPER_OMEGA_SHORT}


def case(name: str) -> Case:
    if name not in CASES:
        raise InputError(f"unknown SVO case {name!r}; known: {', '.join(CASES)}")
    return CASES[name]


def true_coefs(case_name: str, levels: int = 19) -> dict[str, np.ndarray]:
    """``c0(omega_1)``, ``c0(omega_2)`` from the true WCCV, ``c_RDVG`` from the true ``Q`` (Case 1
    only) and the equal weights."""
    cs = case(case_name)
    A = cs.wccv(2.0 ** np.arange(1, levels + 1))
    out = {"svo_w1": svo_coef(A, svo_weights("long", levels)),
           "svo_w2": svo_coef(A, svo_weights("short", levels)),
           "equal": np.full(cs.p, 1.0 / cs.p)}
    if cs.rw is not None:
        y = np.linalg.solve(cs.rw, np.ones(cs.p))
        out["rdvg"] = y / y.sum()
    return out


def omega(key: str, levels: int) -> np.ndarray:
    """Scale weights of method ``svo_w1`` / ``svo_w2`` for ``levels`` levels (paper vectors at
    J = 19; otherwise anchored as in :func:`gmwm.svo.svo_weights`)."""
    return svo_weights({"w1": "long", "w2": "short"}[key], levels)


# --- streams ---------------------------------------------------------------------------------------
def _crc(s: str) -> int:
    return zlib.crc32(s.encode("utf-8"))


def array_rng(seed: int, case_name: str, role: str, replicate: int, k: int = 0
              ) -> np.random.Generator:
    """Generator of one array: SeedSequence keyed by (study, case, role, replicate, k)."""
    key = (_crc("svo"), _crc(case_name), _crc(role), int(replicate), int(k))
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=key))


def boot_rng(seed: int, case_name: str, replicate: int) -> np.random.Generator:
    """Generator of the bootstrap draws of one coverage replicate (independent of its array)."""
    key = (_crc("svo"), _crc(case_name), _crc("coverage-mbb"), int(replicate))
    return np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=key))
