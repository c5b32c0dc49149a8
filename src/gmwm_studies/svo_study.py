"""[SVO] simulations (docs/METHODS.md §11.6): virtual gyroscopes of 6-gyro arrays by SVO, RDVG and equal
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
from numba import njit
from scipy.linalg import cholesky
from scipy.special import ndtri  # the normal quantile (scipy.stats costs ~0.5 s to import)

from gmwm.errors import InputError
from gmwm.processes import ar1_unit_wv
from gmwm.virtual import (
    PAPER_OMEGA_LONG,
    PAPER_OMEGA_SHORT,
    equal,
    rdvg,
    svo,
    svo_coef,
    svo_schemes,
    svo_weights,
)
from gmwm.wccv import WaveletCrossCovariance, wccv

METHODS = ("svo_w1", "svo_w2", "rdvg", "equal")
METHOD_LABELS = {"svo_w1": "SVO $\\omega_1$", "svo_w2": "SVO $\\omega_2$", "rdvg": "RDVG",
                 "equal": "Equal weights"}

# --- [SVO] App. C (deg^2/s^2, discrete, 10 Hz) -----------------------------------------------
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
        X = rng.standard_normal((T, p))
        X *= np.sqrt(np.diag(self.R))[None]
        if not np.allclose(self.R, np.diag(np.diag(self.R))):
            X = rng.standard_normal((T, p)) @ cholesky(self.R)
        if self.rw is not None:
            _add_cumsum(X, rng.standard_normal((T, p)) @ cholesky(self.rw))
        for phi, P in self.ar1:
            L = cholesky(P)
            eta = rng.standard_normal((T, p)) @ L
            b0 = (rng.standard_normal(p) @ L) / math.sqrt(1.0 - phi * phi)
            _add_ar1(X, eta, phi, phi * b0)
        return X


# The two recursions below replace ``X += np.cumsum(inc, axis=0)`` and ``X += scipy.signal.lfilter(
# [1], [1, -phi], eta, axis=0, zi=z0)[0]`` (same operations in the same order, so bit-identical
# arrays; tests/test_svo.py checks it) without the strided axis-0 passes and temporaries.


@njit(cache=True)
def _add_cumsum(X: np.ndarray, inc: np.ndarray) -> None:
    """``X += cumsum(inc, axis=0)`` (a random walk started at its first increment)."""
    T, p = inc.shape
    if T == 0:
        return
    acc = inc[0].copy()
    for i in range(p):
        X[0, i] += acc[i]
    for t in range(1, T):
        for i in range(p):
            acc[i] = acc[i] + inc[t, i]
            X[t, i] += acc[i]


@njit(cache=True)
def _add_ar1(X: np.ndarray, eta: np.ndarray, phi: float, z0: np.ndarray) -> None:
    """``X += y`` with ``y_t = eta_t + phi y_{t-1}`` and ``phi y_{-1} = z0`` (lfilter's state)."""
    T, p = eta.shape
    z = z0.copy()
    for t in range(T):
        for i in range(p):
            yv = z[i] + eta[t, i]
            z[i] = yv * phi
            X[t, i] += yv


CASES = {
    "case1": Case("case1", np.diag(R_DIAG), rw=Q_CASE1),
    "case2": Case("case2", np.diag(R_DIAG), ar1=tuple(zip(PHI_CASE2, (P1, P2, P3)))),
}

#: Input covariances drawn by [SVO] Fig. 1 (Case 1, the RW innovations Q, App. C1) and Fig. 6
#: (Case 2, the AR1 innovations P_1..P_3, App. C2), per case.
INPUT_MATRICES = {"case1": {"Q": Q_CASE1}, "case2": {"P1": P1, "P2": P2, "P3": P3}}

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
    J = 19; otherwise anchored as in :func:`gmwm.virtual.svo_weights`)."""
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


# --- protocol --------------------------------------------------------------------------------------
def method_coefs(X: np.ndarray, levels: int) -> tuple[dict[str, np.ndarray], WaveletCrossCovariance]:
    """The four coefficient vectors of one training array (no bootstrap) and its WCCV."""
    W = wccv(X, levels)
    coefs = {"svo_w1": svo(W, omega("w1", levels)).coef,
             "svo_w2": svo(W, omega("w2", levels)).coef,
             "rdvg": rdvg(W).coef,
             "equal": equal(W).coef}
    return coefs, W


def _wn_rw_fit(wv: Any) -> tuple[float, float]:
    """GMWM WN+RW estimates (sigma2, gamma2) of a virtual signal's WV (paper Fig. 3). Only the
    estimates are kept: ``se_cov="gaussian"`` spares the model-based WV covariance and the
    goodness-of-fit test (~90 % of the fit's time), which the estimates do not depend on."""
    import gmwm

    res = gmwm.fit(wv, "WN+RW", n_starts=1, se_cov="gaussian")
    d = res.as_dict()
    return float(d["WN[1].sigma2"]), float(d["RW[1].gamma2"])


def train_chunk(case_name: str, replicates: Sequence[int], n_samples: int, levels: int,
                n_test: int, seed: int) -> dict[str, np.ndarray]:
    """Replicates ``r``: coefficients of the 4 methods on training array r, then the WV of the
    virtual signal of each method on test arrays (r, 0..n_test-1) and its WN+RW GMWM fit.
    Arrays: ``coef (R, 4, p)``, ``wv (R, n_test, 4, J)``, ``gmwm (R, n_test, 4, 2)``,
    ``gyro_wv (p, J)`` (the gyros of the first test array of the first replicate), ``seconds (R,)``."""
    cs = case(case_name)
    R, M, p = len(replicates), len(METHODS), cs.p
    coef = np.empty((R, M, p))
    wv = np.empty((R, n_test, M, levels))
    par = np.empty((R, n_test, M, 2))
    gyro = np.empty((p, levels))
    secs = np.empty(R)
    for a, r in enumerate(replicates):
        t0 = time.perf_counter()
        X = cs.simulate(n_samples, array_rng(seed, case_name, "train", r))
        cdict, _ = method_coefs(X, levels)
        coef[a] = [cdict[m] for m in METHODS]
        for k in range(n_test):
            W = wccv(cs.simulate(n_samples, array_rng(seed, case_name, "test", r, k)), levels)
            if a == 0 and k == 0:
                gyro[:] = np.einsum("jii->ij", W.cov)
            for b, m in enumerate(METHODS):
                # the eta_3 interval: the fit's default weights (ci-eta3) and wv read no other
                # interval, and the default mixture interval costs more than the fit
                v = W.combine(coef[a, b], ci="eta3")
                wv[a, k, b] = v.variance
                par[a, k, b] = _wn_rw_fit(v)
        secs[a] = time.perf_counter() - t0
    return {"replicates": np.asarray(replicates), "coef": coef, "wv": wv, "gmwm": par,
            "gyro_wv": gyro, "seconds": secs}


def scheme_caps(caps: Mapping[str, Any] | None, schemes: Sequence[str]) -> dict[str, int]:
    """Validated per-scheme replication caps (config ``svo.coverage.scheme_replicates``): a
    scheme named here runs on replications ``r < cap`` only, the others on all."""
    out: dict[str, int] = {}
    for name, cap in dict(caps or {}).items():
        if str(name) not in [str(s) for s in schemes]:
            raise InputError(f"scheme_replicates names MBB scheme {name!r}, which is not among "
                             f"the schemes run ({', '.join(map(str, schemes))})")
        if isinstance(cap, bool) or not isinstance(cap, (int, np.integer)) or cap < 1:
            raise InputError(f"scheme_replicates[{name!r}] must be a positive integer, got "
                             f"{cap!r}")
        out[str(name)] = int(cap)
    return out


def coverage_chunk(case_name: str, replicates: Sequence[int], n_samples: int, levels: int,
                   n_boot: int, block_const: float, alpha: float, seed: int,
                   schemes: Sequence[str] = ("paper",),
                   scheme_replicates: Mapping[str, int] | None = None) -> dict[str, np.ndarray]:
    """Coverage replicates: c_hat(omega_2) with MBB SEs on a fresh array, one SE per MBB scheme
    (same array; each scheme its own fresh draw stream); ``hit[s]`` = 1.0 if |c_hat - c0| <=
    z se else 0.0, c0 from the true WCCV. A scheme capped in ``scheme_replicates`` runs only on
    replications ``r < cap``: its other cells are NaN in ``se`` and ``hit``. Arrays: ``coef (R,
    p)``, ``se``/``hit`` ``(S, R, p)`` (``hit`` float)."""
    caps = scheme_caps(scheme_replicates, schemes)
    cs = case(case_name)
    om = omega("w2", levels)
    c0 = svo_coef(cs.wccv(2.0 ** np.arange(1, levels + 1)), om)
    z = ndtri(1.0 - alpha / 2.0)
    R, S = len(replicates), len(schemes)
    coef, se, secs = np.empty((R, cs.p)), np.full((S, R, cs.p), np.nan), np.empty(R)
    hit = np.full((S, R, cs.p), np.nan)
    block = 0
    for a, r in enumerate(replicates):
        t0 = time.perf_counter()
        X = cs.simulate(n_samples, array_rng(seed, case_name, "coverage", r))
        # only the schemes active at r go to svo_schemes, each with its own fresh boot_rng
        # stream: every SE equals that of a separate svo() call bit for bit, so a capped scheme
        # leaves the others' numbers unchanged (one WCCV and one pass over the array for all)
        active = [k for k, s in enumerate(schemes) if int(r) < caps.get(str(s), math.inf)]
        if active:
            fits = svo_schemes(X, om, levels=levels, n_boot=n_boot, block_const=block_const,
                               alpha=alpha, seeds=[boot_rng(seed, case_name, r) for _ in active],
                               mbb=[schemes[k] for k in active])
        else:  # every scheme capped below r: the estimate only (no draws)
            fits = []
            coef[a] = svo_schemes(X, om, levels=levels, n_boot=0, alpha=alpha, seeds=[0],
                                  mbb=[schemes[0]])[0].coef
        for k, res in zip(active, fits, strict=True):
            se[k, a] = res.se
            coef[a], block = res.coef, res.block
            hit[k, a] = (np.abs(res.coef - c0) <= z * res.se).astype(float)
        secs[a] = time.perf_counter() - t0
    return {"replicates": np.asarray(replicates), "coef": coef, "se": se, "hit": hit, "c0": c0,
            "block": np.array(block), "schemes": np.asarray(schemes), "seconds": secs}


def merge(parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Concatenate chunk results along replicates (keys that are per-run are taken once; a
    chunk whose capped schemes all ran nowhere has block 0, so the largest block is kept)."""
    once = {"gyro_wv", "c0", "block", "schemes"}
    axis1 = {"se", "hit"}                # (schemes, replicates, p)
    first = min(parts, key=lambda d: int(np.min(d["replicates"])))
    out = {k: np.asarray(first[k]) for k in once if k in first}
    if "block" in first:
        out["block"] = np.asarray(max(int(d["block"]) for d in parts))
    for k in parts[0]:
        if k not in once:
            out[k] = np.concatenate([np.asarray(d[k], dtype=float if k == "hit" else None)
                                     for d in parts],
                                    axis=1 if k in axis1 and "schemes" in parts[0] else 0)
    return out


def wilson(k: int, n: int, conf: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion k/n."""
    z = ndtri(0.5 + conf / 2.0)
    ph = k / n
    d = 1 + z * z / n
    mid = (ph + z * z / (2 * n)) / d
    h = z * math.sqrt(ph * (1 - ph) / n + z * z / (4 * n * n)) / d
    return mid - h, mid + h


# --- input matrices ([SVO] Figs. 1 and 6) ---------------------------------------------------------
def abs_correlation(cov: np.ndarray) -> np.ndarray:
    """``|corr|`` of a covariance matrix (symmetric, positive definite, else :class:`InputError`)."""
    cov = np.asarray(cov, dtype=np.float64)
    if cov.ndim != 2 or cov.shape[0] != cov.shape[1] or not np.allclose(cov, cov.T):
        raise InputError(f"a covariance matrix must be square and symmetric, got {cov.shape}")
    if np.linalg.eigvalsh(cov)[0] <= 0:
        raise InputError("covariance matrix is not positive definite")
    d = 1.0 / np.sqrt(np.diag(cov))
    return np.clip(np.abs(cov * d[:, None] * d[None, :]), 0.0, 1.0)  # 1 + 1 ulp on the diagonal


def input_table(case_name: str) -> list[dict[str, Any]]:
    """The case's input covariances ([SVO] App. C) entry by entry (upper triangle): covariance
    [deg^2/s^2 per sample], correlation, and per matrix its smallest eigenvalue (positive
    definiteness) and the largest off-diagonal |correlation|."""
    if case_name not in INPUT_MATRICES:
        raise InputError(f"unknown SVO case {case_name!r}; known: {', '.join(INPUT_MATRICES)}")
    rows = []
    for name, cov in INPUT_MATRICES[case_name].items():
        r = abs_correlation(cov)
        off = r[~np.eye(len(r), dtype=bool)]
        d = np.sqrt(np.diag(cov))
        for i in range(len(cov)):
            for k in range(i, len(cov)):
                rows.append({"matrix": name, "gyro_i": i + 1, "gyro_k": k + 1,
                             "covariance": float(cov[i, k]),
                             "correlation": float(cov[i, k] / (d[i] * d[k])),
                             "abs_correlation": float(r[i, k]),
                             "min_eigenvalue": float(np.linalg.eigvalsh(cov)[0]),
                             "max_offdiag_abs_correlation": float(off.max())})
    return rows


def figure_inputs(case_name: str) -> Any:
    """[SVO] Fig. 1 (Case 1: Q) / Fig. 6 (Case 2: P_1, P_2, P_3): absolute correlation matrices of
    the innovation covariances of App. C, one heat map per matrix on the common scale [0, 1],
    entries printed."""
    from gmwm.plots import subplots

    mats = INPUT_MATRICES[case(case_name).name]
    fig, axes = subplots(1, len(mats), figsize=(3.3 * len(mats) + 0.8, 3.4))
    axes = np.atleast_1d(axes)
    im = None
    for ax, (name, cov) in zip(axes, mats.items(), strict=True):
        r = abs_correlation(cov)
        im = ax.imshow(r, vmin=0.0, vmax=1.0, cmap="viridis")
        p = len(r)
        for i in range(p):
            for k in range(p):
                ax.text(k, i, f"{r[i, k]:.2f}", ha="center", va="center", fontsize=6,
                        color="white" if r[i, k] < 0.6 else "black")
        ax.set_xticks(range(p), [str(g + 1) for g in range(p)])
        ax.set_yticks(range(p), [str(g + 1) for g in range(p)])
        ax.set_xlabel("gyro")
        ax.set_title(f"|corr| of {name}", fontsize=9)
        ax.grid(False)
    axes[0].set_ylabel("gyro")
    fig.colorbar(im, ax=list(axes), shrink=0.8, label="absolute correlation")
    return fig


# --- tables and figures ----------------------------------------------------------------------------
def coef_table(res: Mapping[str, np.ndarray], case_name: str, levels: int) -> list[dict[str, Any]]:
    """Per method and gyro: mean, SD, minimum and maximum of the 50 estimated coefficients, true
    value (if known)."""
    truth = true_coefs(case_name, levels)
    rows = []
    for b, m in enumerate(METHODS):
        for i in range(res["coef"].shape[2]):
            c = res["coef"][:, b, i]
            rows.append({"method": m, "gyro": i + 1, "mean": float(c.mean()),
                         "sd": float(c.std(ddof=1)) if c.size > 1 else float("nan"),
                         "min": float(c.min()), "max": float(c.max()),
                         "true": float(truth[m][i]) if m in truth else float("nan")})
    return rows


def gmwm_table(res: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
    """[SVO] Fig. 3 in numbers: per method and parameter (WN ``sigma2``, RW ``gamma2``, per
    sample) the median, quartiles, maximum, mean and SD of the WN+RW GMWM estimates of the
    out-of-sample virtual signals, the median relative to the equal-weights one, and
    ``share_lowest``: the share of test signals on which this method's estimate is the lowest of
    the four (the methods are applied to the same test arrays, so this is a paired comparison)."""
    par = res["gmwm"].reshape(-1, len(METHODS), 2)
    eq = METHODS.index("equal")
    rows = []
    for k, name in enumerate(("sigma2", "gamma2")):
        ref = float(np.median(par[:, eq, k]))
        lowest = np.argmin(par[:, :, k], axis=1)
        for b, m in enumerate(METHODS):
            v = par[:, b, k]
            q25, med, q75 = (float(q) for q in np.percentile(v, [25, 50, 75]))
            rows.append({"method": m, "parameter": name, "median": med, "q25": q25, "q75": q75,
                         "max": float(v.max()),
                         "iqr_over_median": (q75 - q25) / med if med > 0 else float("nan"),
                         "mean": float(v.mean()),
                         "sd": float(v.std(ddof=1)) if v.size > 1 else float("nan"),
                         "median_to_equal": med / ref if ref > 0 else float("nan"),
                         "share_lowest": float(np.mean(lowest == b)),
                         "n_signals": int(v.size)})
    return rows


def wv_table(res: Mapping[str, np.ndarray], freq: float,
             case_name: str | None = None) -> list[dict[str, Any]]:
    """Average WV of the out-of-sample virtual signals per method and level, its 95 % CI (normal,
    over all test signals) and the ratio of averages to equal weights; with ``case_name`` also
    ``true_ratio_to_equal``, the same ratio for the method's population coefficients (c0(omega),
    c_RDVG from the true Q: Case 1 only) on the true WCCV, i.e. without estimation error."""
    wv = res["wv"].reshape(-1, len(METHODS), res["wv"].shape[-1])
    n, J = wv.shape[0], wv.shape[-1]
    mean = wv.mean(axis=0)
    half = 1.96 * wv.std(axis=0, ddof=1) / math.sqrt(n) if n > 1 else np.zeros_like(mean)
    true_ratio: dict[str, np.ndarray] = {}
    if case_name is not None:
        A = case(case_name).wccv(2.0 ** np.arange(1, J + 1))
        nu = {m: np.einsum("i,jik,k->j", c, A, c) for m, c in true_coefs(case_name, J).items()}
        true_ratio = {m: v / nu["equal"] for m, v in nu.items()}
    rows = []
    for b, m in enumerate(METHODS):
        for j in range(mean.shape[1]):
            row = {"method": m, "level": j + 1, "scale_s": 2.0 ** (j + 1) / freq,
                   "mean_wv": float(mean[b, j]), "ci_low": float(mean[b, j] - half[b, j]),
                   "ci_high": float(mean[b, j] + half[b, j]),
                   "ratio_to_equal": float(mean[b, j] / mean[METHODS.index("equal"), j]),
                   "n_signals": n}
            if case_name is not None:
                row["true_ratio_to_equal"] = (float(true_ratio[m][j]) if m in true_ratio
                                              else float("nan"))
            rows.append(row)
    return rows


def _hits_ses(cov: Mapping[str, np.ndarray]) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Scheme names, ``hit`` as float (NaN = not computed) and ``se``, both ``(S, R, p)``."""
    hits = np.asarray(cov["hit"], dtype=float)  # old chunks stored bool: every cell computed
    if hits.ndim == 2:
        hits = hits[None]
    ses = np.asarray(cov["se"], dtype=float).reshape(hits.shape)
    schemes = [str(x) for x in np.atleast_1d(cov.get("schemes", ["paper"]))]
    return schemes, hits, ses


def coverage_table(cov: Mapping[str, np.ndarray], conf: float = 0.95) -> list[dict[str, Any]]:
    """Empirical coverage per MBB scheme and coefficient with its Wilson interval (MC error),
    each over the replications that scheme ran on (``replicates`` = their number; ``sd_coef``
    and ``mean_coef`` over the same replications as ``mean_se``)."""
    schemes, hits, ses = _hits_ses(cov)
    coefs = np.asarray(cov["coef"], dtype=float)
    rows = []
    for s_i, scheme in enumerate(schemes):
        for i in range(hits.shape[2]):
            done = ~np.isnan(hits[s_i, :, i])
            n = int(done.sum())
            if n == 0:
                continue
            c = coefs[done, i]
            sd = float(c.std(ddof=1)) if n > 1 else math.nan
            k = int(hits[s_i, done, i].sum())
            lo, hi = wilson(k, n, conf)
            mse = float(ses[s_i, done, i].mean())
            rows.append({"mbb": scheme, "gyro": i + 1, "coverage": k / n, "wilson_low": lo,
                         "wilson_high": hi, "c0": float(cov["c0"][i]),
                         "mean_coef": float(c.mean()), "sd_coef": sd, "mean_se": mse,
                         "se_over_sd": mse / sd, "replicates": n})
    return rows


# --- per-replicate files (reports/svo/<case>/replicates/; docs/pipeline.md "Per-replicate
# tables and counts"): what the tables above summarise, one row per array or replication ---------
PER_REPLICATE_FORMAT = "%.10g"
"""Ten significant digits, as the other per-replicate tables (gmwm_studies.replicates)."""


def array_coef_table(res: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
    """One row per training array and method: the coefficient vector (``c1..cp``, the columns of
    :func:`coef_table`'s summaries)."""
    rows = []
    for a, r in enumerate(np.asarray(res["replicates"]).tolist()):
        for b, m in enumerate(METHODS):
            rows.append({"replicate": int(r), "method": m,
                         **{f"c{i + 1}": float(c) for i, c in enumerate(res["coef"][a, b])}})
    return rows


def virtual_fit_table(res: Mapping[str, np.ndarray]) -> list[dict[str, Any]]:
    """One row per out-of-sample virtual signal (training array ``replicate``, test array ``test``)
    and method: the WN+RW GMWM estimates ``sigma2``, ``gamma2`` (per sample) that
    :func:`gmwm_table` summarises (its ``share_lowest`` compares the methods on each signal)."""
    rows = []
    for a, r in enumerate(np.asarray(res["replicates"]).tolist()):
        for k in range(res["gmwm"].shape[1]):
            for b, m in enumerate(METHODS):
                sigma2, gamma2 = res["gmwm"][a, k, b]
                rows.append({"replicate": int(r), "test": k, "method": m,
                             "sigma2": float(sigma2), "gamma2": float(gamma2)})
    return rows


def coverage_replicate_table(cov: Mapping[str, np.ndarray], alpha: float
                             ) -> list[dict[str, Any]]:
    """One row per MBB scheme, coverage replication and coefficient that scheme ran on: the
    estimate, its MBB SE, the interval ``coef -+ z se`` (z the normal ``1 - alpha/2``
    quantile) and ``covered`` (1/0: c0 inside, the ``hit`` :func:`coverage_table` averages; c0
    per gyro is in that table). A capped scheme (``scheme_replicates``) has no rows beyond it."""
    schemes, hits, ses = _hits_ses(cov)
    z = float(ndtri(1.0 - alpha / 2.0))
    reps = np.asarray(cov["replicates"]).tolist()
    rows = []
    for s_i, scheme in enumerate(schemes):
        for a, r in enumerate(reps):
            for i in range(hits.shape[2]):
                if np.isnan(hits[s_i, a, i]):
                    continue
                c, se = float(cov["coef"][a, i]), float(ses[s_i, a, i])
                rows.append({"mbb": scheme, "replicate": int(r), "gyro": i + 1, "coef": c,
                             "se": se, "ci_low": c - z * se, "ci_high": c + z * se,
                             "covered": int(hits[s_i, a, i])})
    return rows


def _colors() -> dict[str, str]:
    from gmwm.plots import PALETTE

    return dict(zip(METHODS, (PALETTE[1], PALETTE[2], PALETTE[3], PALETTE[0]), strict=True))


def figure_wv(res: Mapping[str, np.ndarray], freq: float, case_name: str) -> Any:
    """Paper Fig. 2/7: lower = mean WV of the virtual signals with CI band and one test array's
    gyros; upper = ratio of the mean WV to the equal-weights one."""
    from gmwm.plots import subplots
    from gmwm_studies.figures import REPLICATE_COLOR

    rows = wv_table(res, freq)
    J = res["wv"].shape[-1]
    x = 2.0 ** np.arange(1, J + 1) / freq
    fig, (top, bot) = subplots(2, 1, figsize=(6.4, 6.4), sharex=True,
                               gridspec_kw={"height_ratios": [1, 2]})
    col = _colors()
    for i, g in enumerate(res["gyro_wv"]):
        bot.loglog(x, g, color=REPLICATE_COLOR, lw=0.8, label="gyros (one test array)" if i == 0
                   else None)
    for m in METHODS:
        r = [row for row in rows if row["method"] == m]
        mean = np.array([row["mean_wv"] for row in r])
        bot.fill_between(x, [row["ci_low"] for row in r], [row["ci_high"] for row in r],
                         color=col[m], alpha=0.25, lw=0)
        bot.loglog(x, mean, color=col[m], lw=1.6, marker="o", ms=2.5, label=METHOD_LABELS[m])
        top.semilogx(x, [row["ratio_to_equal"] for row in r], color=col[m], lw=1.4, marker="o",
                     ms=2.5)
    top.axhline(1.0, color="k", lw=0.6)
    top.set_yscale("log")
    top.set_ylabel("WV ratio to equal")
    bot.set_xlabel("Scale τ [s]")
    bot.set_ylabel("Wavelet variance [(deg/s)²]")
    n = res["wv"].shape[0] * res["wv"].shape[1]
    top.set_title(f"{case_name}: mean WV of {n} out-of-sample virtual signals (95 % CI)")
    bot.legend(fontsize="small")
    return fig


def figure_coefs(res: Mapping[str, np.ndarray], case_name: str, levels: int) -> Any:
    """Paper Fig. 4/8: boxplots of the estimated coefficients per gyro and method, true c0 marks."""
    from gmwm.plots import subplots

    truth = true_coefs(case_name, levels)
    methods = [m for m in METHODS if m != "equal"]
    fig, axes = subplots(1, len(methods), figsize=(3.6 * len(methods), 3.4), sharey=True)
    col = _colors()
    p = res["coef"].shape[2]
    for ax, m in zip(axes, methods, strict=True):
        b = METHODS.index(m)
        ax.boxplot([res["coef"][:, b, i] for i in range(p)], widths=0.6,
                   medianprops={"color": col[m]})
        if m in truth:
            ax.plot(np.arange(1, p + 1), truth[m], "x", color="k", ms=7, label="true $c_0$")
            ax.legend(fontsize="small")
        ax.axhline(1.0 / p, color="grey", lw=0.6, ls="--")
        ax.set_title(METHOD_LABELS[m])
        ax.set_xlabel("gyro")
    axes[0].set_ylabel(f"coefficient ({res['coef'].shape[0]} arrays)")
    return fig


def figure_gmwm(res: Mapping[str, np.ndarray]) -> Any:
    """Paper Fig. 3: WN+RW GMWM estimates (sigma2, gamma2) of the virtual signals per method."""
    from gmwm.plots import subplots

    par = res["gmwm"].reshape(-1, len(METHODS), 2)
    fig, axes = subplots(1, 2, figsize=(7.6, 3.4))
    for k, (ax, name) in enumerate(zip(axes, ("WN $\\sigma^2$", "RW $\\gamma^2$"), strict=True)):
        ax.boxplot([par[:, b, k] for b in range(len(METHODS))], widths=0.6)
        ax.set_xticks(np.arange(1, len(METHODS) + 1), [METHOD_LABELS[m] for m in METHODS],
                      rotation=20)
        ax.set_yscale("log")
        ax.set_title(name + f" ({par.shape[0]} virtual signals)")
    return fig


def figure_coverage(rows: Sequence[Mapping[str, Any]], conf: float = 0.95) -> Any:
    """Paper Fig. 5: coverage per coefficient and MBB scheme with Wilson intervals; band = the
    Wilson interval a nominal-coverage study of each scheme's size n would give (one band per
    distinct n; n in every legend entry)."""
    from gmwm.plots import PALETTE, new_axes

    ax = new_axes()
    schemes = list(dict.fromkeys(r["mbb"] for r in rows))
    n_of = {s: int(next(r["replicates"] for r in rows if r["mbb"] == s)) for s in schemes}
    for j, n in enumerate(sorted(set(n_of.values()), reverse=True)):
        lo, hi = wilson(round(conf * n), n, 0.95)
        ax.axhspan(lo, hi, color="grey", alpha=0.25 if j == 0 else 0.12, lw=0,
                   hatch=None if j == 0 else "//", label=f"MC band at {conf:g} (n = {n})")
    ax.axhline(conf, color="k", lw=0.6)
    for k, scheme in enumerate(schemes):
        rs = [r for r in rows if r["mbb"] == scheme]
        g = np.array([r["gyro"] for r in rs]) + 0.12 * (k - (len(schemes) - 1) / 2)
        cov = np.array([r["coverage"] for r in rs])
        err = np.array([[c - r["wilson_low"], r["wilson_high"] - c]
                        for c, r in zip(cov, rs, strict=True)]).T
        ax.errorbar(g, cov, yerr=err, fmt="os"[k % 2], color=PALETTE[1 + k],
                    label=f"MBB {scheme}, n = {n_of[scheme]}: coverage (Wilson 95 %)")
    ax.set_xlabel("coefficient (gyro)")
    ax.set_ylabel("coverage of 95 % CI")
    ax.legend(fontsize="small")
    return ax.figure
