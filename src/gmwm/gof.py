"""Goodness of fit of a GMWM (or ARMAV) fit: an over-identification test valid for any weights.

The GMWM matches ``J`` wavelet-variance moments with ``p < J`` parameters, so the minimised
objective measures how far the WV is from every model WV. Its null distribution follows from
the same linearisation as the sandwich standard errors (:mod:`gmwm.inference`).

Statistic
---------
Write ``f`` for the moment transform (identity for the GMWM, ``log10`` for ARMAV), ``A = d f(nu)
/ d theta`` at the estimate (columns of parameters at the boundary dropped: those components are
held at 0), ``Omega = L L'`` the weight matrix of the fit, ``V_f = F V F'`` the covariance of
``f(nu_hat)`` (``V`` the covariance of ``nu_hat``, ``F = d f / d nu``, the delta method for
ARMAV) and ``r = f(nu_hat) - f(nu(theta_hat))``. To first order ``L' r = P L' e`` with ``e = f(
nu_hat) - f(nu_0)`` and ``P`` the orthogonal projector onto the complement of ``L'A`` (rank
``df = J - rank(A)``). Under a correct model and Gaussian ``e``, the objective

    Q = r' Omega r  ~  sum_i lambda_i chi2_1,   lambda = eigenvalues of  P L' V_f L P,

a weighted sum of ``df`` independent chi-square(1) variables. With efficient weights
(``Omega = V_f^-1``) every ``lambda_i`` is 1 and this is Hansen's J test (chi-square with ``df``
degrees of freedom); with the default CI weights the ``lambda_i`` differ and a chi-square
reference would be wrong by a large factor. ``V`` is the model-based covariance of the WV
estimate at the estimate (:func:`gmwm.inference.model_wv_cov`, between-scale correlation
included); a fit with a user covariance uses that matrix. Reported: ``statistic = Q / c`` with
``c = mean(lambda)`` (so its null mean is ``df``, and it is Hansen's J under efficient weights),
``df`` and the p-value ``P(sum lambda_i chi2_1 > Q)``, computed by Imhof's numerical inversion
of the characteristic function, with the Lugannani-Rice saddlepoint approximation in the far
tail (below 1e-6, where the inversion integral is dominated by rounding). Choice by evidence
(``benchmarks/bench_gof.py``): the moment-matched scaled chi-square (Satterthwaite) gives the
same size at 5 % but errs in the tail; the generalised Wald statistic ``r' (M V_f M')^+ r``
(exactly chi-square(df) to first order, ``M = I - A (A' Omega A)^-1 A' Omega``) over-rejects
because its pseudo-inverse gives full weight to the long scales, where ``nu_hat`` is far from
Gaussian.

Per-scale standardised residuals ``z_j = r_j / sqrt((M V_f M')_jj)`` have unit variance under
the model; large ``|z_j|`` show where the model misses.

What the test assumes and where it loses validity
--------------------------------------------------
* First-order asymptotics: ``nu_hat`` Gaussian around ``nu(theta_0)``, the estimator linear in
  it. At the longest scales ``nu_hat_j`` has about ``eta_j = M_j / tau_j`` (1-3 at the default
  levels) degrees of freedom and is skewed; the CI weights make those scales light, which keeps
  the test close to its size (the benchmark's table), but weights that emphasise them (e.g.
  efficient weights) over-reject somewhat.
* The weights are treated as fixed; CI weights depend on ``nu_hat`` (a higher-order effect).
* Parameters inside their domain. A component at the boundary 0 is held there: the test is then
  that of the model without it. A shape parameter at the edge of its domain (AR1 phi -> +-1)
  breaks the linearisation.
* Deterministic components (SIN, DR) enter ``V`` only through their interaction with the noise
  (a SIN's own term is O(T^-2) given its phase). A sinusoid whose period is not short against
  the signal length, or a drift with too few scales to separate it, makes the test liberal.
* A robust WV (``efficiency < 1``): the classical covariance is divided by the efficiency.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import integrate, optimize
from scipy.special import ndtr

__all__ = ["GOFResult", "gof_test", "weighted_chi2_sf"]

#: p-values below this are taken from the saddlepoint approximation (the inversion integral
#: loses relative accuracy there)
SADDLE_BELOW = 1e-6
#: default level at which a fit is flagged as rejected
ALPHA = 0.05


# -- the null distribution ------------------------------------------------------------------------
def _imhof_sf(x: float, lam: np.ndarray) -> float:
    """``P(sum lam_i chi2_1 > x)`` by Imhof's inversion formula (lam > 0, scaled to max 1):
    ``1/2 + 1/pi int_0^inf sin(phi(u) - x u / 2) / (u rho(u)) du`` with ``phi = sum arctan(lam
    u) / 2`` and ``rho = prod (1 + lam^2 u^2)^(1/4)``. Beyond a few oscillations the integral is
    split into Fourier integrals of the slowly varying ``sin phi / (u rho)`` and ``cos phi /
    (u rho)`` (QUADPACK's QAWF), which converge fast however slowly the envelope decays."""
    w = 0.5 * x

    def phi_rho(u: float) -> tuple[float, float]:
        lu = lam * u
        return 0.5 * float(np.sum(np.arctan(lu))), u * math.exp(0.25 * float(np.sum(np.log1p(lu * lu))))

    def head(u: float) -> float:
        ph, d = phi_rho(u)
        return math.sin(ph - w * u) / d

    def env_sin(u: float) -> float:
        ph, d = phi_rho(u)
        return math.sin(ph) / d

    def env_cos(u: float) -> float:
        ph, d = phi_rho(u)
        return math.cos(ph) / d

    a = 8.0 * math.pi / w      # four periods of the carrier
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", integrate.IntegrationWarning)
        h, _ = integrate.quad(head, 0.0, a, limit=200, epsabs=1e-14, epsrel=1e-11)
        # sin(phi - w u) = sin(phi) cos(w u) - cos(phi) sin(w u)
        c1, _ = integrate.quad(env_sin, a, np.inf, weight="cos", wvar=w, limlst=100)
        c2, _ = integrate.quad(env_cos, a, np.inf, weight="sin", wvar=w, limlst=100)
    return 0.5 + (h + c1 - c2) / math.pi


def _saddle_sf(x: float, lam: np.ndarray) -> float:
    """Lugannani-Rice saddlepoint approximation of ``P(sum lam_i chi2_1 > x)``, x > mean."""
    lmax = float(lam.max())

    def k1(s: float) -> float:
        return float(np.sum(lam / (1.0 - 2.0 * s * lam)))

    hi = (1.0 - 1e-12) / (2.0 * lmax)
    lo = min(0.0, -1.0 / x)
    while k1(lo) > x:
        lo *= 2.0
    s = optimize.brentq(lambda t: k1(t) - x, lo, hi, xtol=1e-15, rtol=1e-14, maxiter=200)
    K = -0.5 * float(np.sum(np.log1p(-2.0 * s * lam)))
    K2 = 2.0 * float(np.sum(lam**2 / (1.0 - 2.0 * s * lam) ** 2))
    w = math.copysign(math.sqrt(max(2.0 * (s * x - K), 0.0)), s)
    u = s * math.sqrt(K2)
    if abs(w) < 1e-8 or u == 0:
        return float("nan")
    return float(ndtr(-w) + math.exp(-0.5 * w * w) / math.sqrt(2 * math.pi) * (1 / u - 1 / w))


def weighted_chi2_sf(x: float, lam: np.ndarray) -> tuple[float, str]:
    """``P(sum_i lam_i chi2_1 > x)`` for weights ``lam >= 0`` and the method used
    (``"imhof"`` or ``"saddlepoint"``; ``"chi2"`` when all weights are equal)."""
    lam = np.asarray(lam, dtype=float)
    lam = lam[lam > 0]
    if lam.size == 0 or not np.isfinite(x):
        return float("nan"), "none"
    if x <= 0:
        return 1.0, "exact"
    scale = float(lam.max())
    lam = lam / scale
    x = x / scale
    if np.ptp(lam) < 1e-12:
        from scipy.stats import chi2

        return float(chi2.sf(x, lam.size)), "chi2"
    p = _imhof_sf(x, lam)
    if p < SADDLE_BELOW and x > lam.sum():
        q = _saddle_sf(x, lam)
        if np.isfinite(q):
            return max(q, 0.0), "saddlepoint"
    return float(min(max(p, 0.0), 1.0)), "imhof"


# -- the test -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GOFResult:
    """Over-identification test of one fit (module docstring).

    ``statistic`` = objective / mean(lambda) (null mean ``df``), ``p_value`` from the weighted
    chi-square null, ``residuals`` the per-scale standardised residuals at ``scales`` [samples]
    (``scales_s`` [s]), ``eigenvalues`` the weights ``lambda`` (objective units), ``notes``
    caveats that apply to this fit."""

    statistic: float
    df: int
    p_value: float
    objective: float
    eigenvalues: np.ndarray
    residuals: np.ndarray
    scales: np.ndarray
    freq: float = 1.0
    method: str = "imhof"
    notes: list[str] = field(default_factory=list)

    @property
    def scales_s(self) -> np.ndarray:
        return self.scales / self.freq

    def rejected(self, alpha: float = ALPHA) -> bool:
        """True if the model is rejected at level ``alpha``."""
        return bool(np.isfinite(self.p_value) and self.p_value < alpha)

    def worst_scales(self, k: int = 3) -> list[tuple[float, float]]:
        """Up to ``k`` (scale [s], z) with the largest ``|z|``, largest first."""
        z = np.asarray(self.residuals)
        order = np.argsort(-np.abs(np.nan_to_num(z, nan=0.0)))[:k]
        return [(float(self.scales_s[i]), float(z[i])) for i in order if np.isfinite(z[i])]

    def warning(self, alpha: float = ALPHA) -> str | None:
        """The one-line warning every surface prints when the model is rejected, else None."""
        if not self.rejected(alpha):
            return None
        worst = ", ".join(f"{s:.3g} s (z = {z:+.1f})" for s, z in self.worst_scales())
        return (f"goodness of fit: the model is rejected (p = {self.p_value:.2g}, statistic "
                f"{self.statistic:.4g} on {self.df} df): the WV departs from the fitted model, "
                f"most at scales {worst}; the estimates describe a wrong model")

    def line(self) -> str:
        """One summary line, e.g. ``goodness of fit: statistic 9.3 on 11 df, p = 0.59``."""
        if self.df == 0:
            return "goodness of fit: not testable (as many parameters as scales)"
        return (f"goodness of fit: statistic {self.statistic:.4g} on {self.df} df, "
                f"p = {self.p_value:.3g}" + ("  (REJECTED)" if self.rejected() else ""))

    def to_json_dict(self) -> dict[str, Any]:
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {"statistic": num(self.statistic), "df": int(self.df),
                "p_value": num(self.p_value), "objective": num(self.objective),
                "method": self.method, "rejected": self.rejected(),
                "scales_s": [float(s) for s in self.scales_s],
                "residuals": [num(z) for z in self.residuals], "notes": list(self.notes)}


def _fixed(result: Any) -> np.ndarray:
    """Parameters held at the boundary: every parameter of a component reported at 0."""
    model = result.model
    fixed = np.zeros(model.n_params, bool)
    vanished = set(result.diagnostics.get("at_boundary", []) or [])
    for c in model.components:
        p = np.asarray(result.params, float)[c.slice]
        if c.name in vanished or p[c.process.scale_index] == 0:
            fixed[c.slice] = True
    return fixed


def _wv_cov(result: Any, V: np.ndarray | None) -> np.ndarray:
    """Covariance of nu_hat for the test: the caller's, the fit's user covariance, else the
    model-based one at the estimate (recomputed when the fit used another kind)."""
    if V is not None:
        return np.asarray(V, dtype=float)
    s = result.settings
    if s.get("weights") == "covariance" and "weights_cov" in s:
        return np.asarray(s["weights_cov"], dtype=float)
    if s.get("se_cov", "model") == "model" and result.wv_cov is not None:
        V = np.asarray(result.wv_cov, dtype=float)
    else:
        from .inference import model_wv_cov

        V = model_wv_cov(result.model, np.asarray(result.params, float), result.wv)
    if result.wv.robust:  # the model covariance is that of the classical estimator
        V = V / result.wv.efficiency
    return V


def _notes(result: Any) -> list[str]:
    notes = []
    model, wv = result.model, result.wv
    names = {c.process.name for c in model.components}
    if "SIN" in names:
        T = float(wv.n_samples)
        for c in model.components:
            if c.process.name == "SIN":
                beta = float(np.asarray(result.params)[c.slice][1])
                if beta > 0 and 2 * np.pi / beta > T / 20:
                    notes.append(f"{c.name} has a period over 1/20 of the signal: its WV depends "
                                 "on the phase and the test is liberal")
    if np.any(wv.edof < 4):
        notes.append(f"{int(np.sum(wv.edof < 4))} longest scale(s) have fewer than 4 degrees of "
                     "freedom (non-Gaussian WV estimate)")
    return notes


def gof_test(result: Any, V: np.ndarray | None = None) -> GOFResult:
    """Goodness-of-fit test of a :class:`~gmwm.estimator.GMWMResult` (module docstring).

    ``V``: covariance (J, J) of the WV estimate under the null (default: model-based at the
    estimate, or the fit's own user covariance)."""
    from .inference import Problem, f_jacobian

    prob = Problem.of(result)
    theta = np.asarray(result.params, dtype=float)
    J = result.wv.n_levels
    keep = ~_fixed(result)
    V = _wv_cov(result, V)
    F = f_jacobian(prob.nu_hat, prob.method)
    Vf = V * np.outer(F, F)
    L = prob.white.L
    with np.errstate(all="ignore"):
        rw = prob.residual(theta)                     # L' r
        r = prob.target - prob.f(result.model.wv(theta, prob.tau))
        Aw = L.T @ prob.jac_theta(theta)[:, keep]
    objective = float(rw @ rw)
    nan = np.full(J, np.nan)
    if not (np.all(np.isfinite(Aw)) and np.all(np.isfinite(Vf)) and np.isfinite(objective)):
        return GOFResult(np.nan, 0, np.nan, objective, np.zeros(0), nan, prob.tau,
                         result.wv.freq, "none", ["the test could not be computed"])
    # orthonormal basis of the complement of the whitened Jacobian's range (columns scaled:
    # parameters span many orders of magnitude)
    if Aw.shape[1]:
        norms = np.linalg.norm(Aw, axis=0)
        norms[norms == 0] = 1.0
        U, s, _ = np.linalg.svd(Aw / norms, full_matrices=True)
        rank = int(np.sum(s > 1e-10 * s[0])) if s.size and s[0] > 0 else 0
    else:
        U, rank = np.eye(J), 0
    Qp = U[:, rank:]
    df = Qp.shape[1]
    Sw = L.T @ Vf @ L
    C = Qp.T @ Sw @ Qp
    lam = np.clip(np.linalg.eigvalsh((C + C.T) / 2), 0.0, None)
    # standardised residuals: Cov(r) = M V_f M', M = I - A (A' Omega A)^+ A' Omega
    with np.errstate(all="ignore"):
        A = prob.jac_theta(theta)[:, keep]
        d = np.linalg.norm(L.T @ A, axis=0)
        d[~np.isfinite(d) | (d == 0)] = 1.0
        As = A / d
        G = np.linalg.pinv(As.T @ prob.omega @ As, hermitian=True) @ As.T @ prob.omega
        M = np.eye(J) - As @ G
        z = r / np.sqrt(np.diag(M @ Vf @ M.T))
    notes = _notes(result)
    if df == 0:
        return GOFResult(np.nan, 0, np.nan, objective, lam, z, prob.tau, result.wv.freq,
                         "none", notes + ["no degrees of freedom: as many parameters as scales"])
    c = float(lam.mean())
    p, method = weighted_chi2_sf(objective, lam)
    stat = objective / c if c > 0 else np.nan
    return GOFResult(float(stat), int(df), float(p), objective, lam, z, prob.tau,
                     result.wv.freq, method, notes)
