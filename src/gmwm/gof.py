"""Goodness of fit of a GMWM (or ARMAV) fit: an over-identification test valid for any weights.

The GMWM matches ``J`` wavelet-variance moments with ``p < J`` parameters, so the residual WV
says whether the model fits. Its null distribution follows from the linearisation behind the
sandwich standard errors (:mod:`gmwm.inference`).

Residuals and their covariance
------------------------------
``f`` is the moment transform (identity for the GMWM, ``log10`` for ARMAV), ``A = d f(nu) /
d theta`` at the estimate, ``Omega`` the fit's weight matrix, ``V`` the covariance of
``nu_hat`` and ``V_f = F V F'`` (``F = d f / d nu``, the delta method for ARMAV). To first
order the residual ``r = f(nu_hat) - f(nu(theta_hat))`` is ``M e``, ``e = f(nu_hat) -
f(nu_0)``, with ``M = I - A (A' Omega A)^-1 A' Omega``, so ``Cov(r) = M V_f M'`` (rank ``df =
J - rank(A)``) for any weights; the weights enter through ``M``. ``V`` is the model-based
covariance of the WV estimate at the estimate (:func:`gmwm.inference.model_wv_cov`,
between-scale correlation included), or the fit's user covariance.

A component at the boundary 0 (a weak one, fitted at 0 in a share of the records) keeps its
column in ``A``: the test projects the fit's residual, ``r~ = M r``, onto the complement of the
full Jacobian. In the interior ``M r = r`` (the fit's first-order condition), so nothing
changes; at the boundary ``r~`` is, to first order, the residual of the fit with the
component's value free of its sign (for a model linear in theta, exactly that least-squares
fit's residual), ``M e`` again, with the covariance above. Holding the component at 0 instead
(its column dropped, the test of the model without it; ``hold_boundary=True``) leaves in ``r``
the component's own WV, which the fit's weights ignore at the longest scales but the test's
normal scores do not, while ``V`` at the estimate lacks that component's variance: issue 40's
WN + AR1 + RW (RW at 1-2 SE, at 0 in 31 % of the fits at T = 2^15) was rejected in 11.3 % of
true-model fits at 5 % and 5.2 % at 1 %, 5.0 % and 1.0 % with the projection (R = 400, the
calibration table of ``benchmarks/README.md``). The price is one degree of freedom per held
parameter, and a departure along the direction of a negative component is not tested (the
result's ``notes`` name the component). A component whose WV is quadratic in its scale
parameter (DR, SIN) has a zero column at 0: it is held as before.

Statistic
---------
Per scale, ``x_j = nu_j(theta_hat) + r~_j`` (``nu_hat_j`` in the interior; on the ``f`` scale
for ARMAV) is modelled as gamma with mean ``nu_j(theta_hat)`` and variance ``Cov(r)_jj`` (on the
``nu`` scale): at the long scales, where ``nu_hat_j`` has only ``eta_j = M_j / tau_j`` (1-3)
degrees of freedom, that is the scaled chi-square of the WV's own confidence interval; at short
scales it is Gaussian. Its normal score ``u_j = Phi^-1(G_j(x_j))`` is the per-scale
standardised residual (``residuals``: N(0, 1) under the model; a large ``|u_j|`` shows where
the model misses). The statistic is ``U = sum_j u_j^2`` with null
distribution ``sum_i lambda_i chi2_1``, ``lambda`` the eigenvalues of the correlation matrix of
``r`` (``df`` of them non-zero); reported as ``statistic = U df / J`` (null mean ``df``) with the
p-value from Imhof's numerical inversion of the characteristic function (the Lugannani-Rice
saddlepoint approximation below 1e-6).

Why this statistic (``benchmarks/bench_gof.py``): the minimised objective ``r' Omega r`` has the
same kind of null (weights ``lambda`` = eigenvalues of ``Omega^1/2 M V_f M' Omega^1/2``) and
the right size, but the default CI weights make the longest scales nearly weightless, so it does
not see a model that misses only there: a ramp left out of a white-noise model at 3-10 standard
errors was rejected in 5-18 % of the fits by the objective and in all of them by ``U``. The
generalised Wald statistic ``r' (M V_f M')^+ r`` (chi-square(df)) weights every direction fully
and over-rejects (up to 15 % at 5 %) because ``nu_hat`` is far from Gaussian at the long
scales; without the gamma marginals, ``sum (r_j / sd_j)^2`` over-rejects in the far tail for the
same reason. The first two are kept for comparison (:func:`objective_test`,
:func:`generalised_wald`). The Satterthwaite (moment-matched) p-value of ``U`` has the same size
at 5 % and is a little liberal at 1 %, hence the inversion.

A sinusoid whose frequency the data do not identify
---------------------------------------------------
A weak SIN's frequency ``beta`` is barely pinned by the WV: the fit's objective, profiled over
``ln beta`` (the other parameters at their best for each ``beta``), is nearly flat, and its
global minimum can seat the SIN far from the true frequency, where it absorbs noise at scales
the CI weights count, leaving the true sinusoid's WV in the residual at the long scales, which
the weights nearly ignore but the normal scores count in full. The linearisation in ``beta``
does not hold across such a profile: fits seated elsewhere are rejected more often than the
level, fits near the true frequency less, and the p-values are not uniform (issue 40's gyro
WN+SIN+RW, the sinusoid block of ``benchmarks/README.md``).

*Rule.* The profile is evaluated by the fit's own variable projection (:mod:`gmwm.search`:
NNLS for the scale parameters, coordinate moves for the other shapes) at ``SIN_PROFILE_POINTS``
values of ``ln beta``, and the lowest point of each cell of ``SIN_CELL`` (the search's coarse
step) is a seating. A seating competes with the fit's own when it lies more than 1.5x from the
fitted frequency and the fit with ``beta`` held there has an objective within ``SIN_COMPETE``
(6.63) times ``lambda_max`` of the fit's, ``lambda_max`` the largest eigenvalue of the
objective's null law (:func:`objective_test`): the 99 % point of ``lambda_max chi2_1``, a
profile interval for ``beta`` in the objective's own sampling noise. Only periods up to
``SIN_MAX_PERIOD`` (1/20) of the signal are seatings: a slower SIN's WV depends on its phase,
and past the longest scale it mimics a drift or a random walk's rise, so admitting it would take
the test's power against a missing RW. A SIN with no competing seating (a strong one, or a fast
one whose WV no other frequency reproduces) is identified, and the test is exactly the one at
the fit's frequency.

*Test.* Otherwise each competing held fit is tested as the model with ``beta`` known (its
column out of the Jacobian: one more degree of freedom; ``V`` at the held fit), and the
p-value is the largest of these and the fit's own. The result carries that seating's
statistic, df and p-value, the fit's own residuals, and a note naming the frequency. Why it is
valid: at the true frequency the held test is a test of the true model, and the maximum rejects
only where it does, so its size is at most the level as long as a seating lies within a basin
of the true frequency and inside the objective limit (the profile interval above). It is
conservative by construction (the largest of several p-values); how much is in the sinusoid
block of ``benchmarks/README.md``. Cost: one refit and one test per seating (about a dozen
for the gyro model at T = 2^17, tens of ms). ARMAV fits and ``sin_frequency=False`` keep the
test at the fit's own frequency.

What the test assumes and where it loses validity
--------------------------------------------------
* First-order asymptotics: the estimator linear in ``nu_hat``, the joint law of the ``u_j``
  close to Gaussian with the correlation of ``r`` (the gamma marginals fix the skew of single
  scales, not higher joint moments).
* The weights are treated as fixed; CI weights depend on ``nu_hat`` (a higher-order effect).
* A component at the boundary 0 enters through its direction only (above); ``V`` at the estimate
  lacks its variance. A shape parameter at the edge of its domain (AR1 phi -> +-1) breaks the
  linearisation.
* Deterministic components (SIN, DR) enter ``V`` only through their interaction with the noise
  (a SIN's own term is O(T^-2) given its phase). A sinusoid whose period is not short against
  the signal, or a drift with few scales to separate it, makes the test liberal.
* A weak sinusoid's frequency is not identified (the section above): the p-value is then the
  largest over the frequencies the objective cannot tell apart, valid but conservative.
* ARMAV (log scale, the delta method on ``V``): conservative on short signals (2.5 % of
  p-values below 5 % at T = 2^14, 4 % at 2^17 in the benchmark).
* A robust WV (``efficiency < 1``): the classical covariance is divided by the efficiency.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from scipy.special import chdtrc, gammainc, gammaincc, ndtr, ndtri

__all__ = ["GOFResult", "generalised_wald", "gof_test", "objective_test", "weighted_chi2_sf"]

#: p-values below this are taken from the saddlepoint approximation (the inversion integral
#: loses relative accuracy there)
SADDLE_BELOW = 1e-6
#: default level at which a fit is flagged as rejected, and at which model selection splits its
#: ranking (:mod:`gmwm.select`, :func:`gmwm.automodel.choose_model`). 1 %, not 5 %: the p-values
#: are calibrated at both levels, but a ranking consistent with the test ranks the generating
#: model first only where the test accepts it, and records whose components are all clearly
#: visible are those with larger residuals, so at 5 % the test's rejections capped the hit rate
#: of ``benchmarks/selection_penalty.py`` below 90 %; the price of 1 % is power at short lengths
#: (docs/METHODS.md §5.12 "Level"; both levels in ``benchmarks/README.md``'s tables).
ALPHA = 0.01


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
        return (0.5 * float(np.arctan(lu).sum()),
                u * math.exp(0.25 * float(np.log1p(lu * lu).sum())))

    def head(u: float) -> float:
        ph, d = phi_rho(u)
        return math.sin(ph - w * u) / d

    def env_sin(u: float) -> float:
        ph, d = phi_rho(u)
        return math.sin(ph) / d

    def env_cos(u: float) -> float:
        ph, d = phi_rho(u)
        return math.cos(ph) / d

    from scipy import integrate  # here: unpickling a result imports this module (the report)

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

    from scipy import optimize

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
        return float(chdtrc(lam.size, x)), "chi2"
    q = _saddle_sf(x, lam) if x > lam.sum() else float("nan")
    # far in the tail the saddlepoint is the answer either way (Imhof's p is below SADDLE_BELOW
    # there): the Imhof integral, most of a test's time, is skipped when the saddlepoint is a
    # thousand times below that switch (a rejected candidate of a model choice)
    if np.isfinite(q) and q < SADDLE_BELOW * 1e-3:
        return max(q, 0.0), "saddlepoint"
    p = _imhof_sf(x, lam)
    if p < SADDLE_BELOW and np.isfinite(q):
        return max(q, 0.0), "saddlepoint"
    return float(min(max(p, 0.0), 1.0)), "imhof"


# -- the test -------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class GOFResult:
    """Goodness-of-fit test of one fit (module docstring).

    ``statistic`` = ``U df / J`` (null mean ``df``), ``p_value`` from the weighted chi-square
    null with weights ``eigenvalues``; ``residuals`` the per-scale standardised residuals
    (normal scores ``u_j``) at ``scales`` [samples] (``scales_s`` [s]), NaN at a scale the fit
    reproduces exactly; ``objective`` the fit's objective; ``notes`` caveats for this fit.
    Immutable (read-only arrays); ``to_tree``/``from_tree`` store it losslessly in result files
    (:mod:`gmwm.codec`)."""

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

    def __post_init__(self) -> None:
        from .results import freeze_arrays

        freeze_arrays(self, ("eigenvalues", "residuals", "scales"))
        object.__setattr__(self, "notes", [str(n) for n in self.notes])

    def to_tree(self) -> dict[str, Any]:
        """Every field by name (arrays as arrays), for :mod:`gmwm.codec`."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_tree(cls, tree: dict[str, Any]) -> GOFResult:
        """The inverse of :meth:`to_tree` (lists read back as arrays)."""
        d = dict(tree)
        for name in ("eigenvalues", "residuals", "scales"):
            d[name] = np.asarray(d[name], dtype=float)
        return cls(**d)

    @property
    def scales_s(self) -> np.ndarray:
        return self.scales / self.freq

    def rejected(self, alpha: float = ALPHA) -> bool:
        """True if the model is rejected at level ``alpha``."""
        return bool(np.isfinite(self.p_value) and self.p_value < alpha)

    def worst_scales(self, k: int = 3) -> list[tuple[float, float]]:
        """Up to ``k`` (scale [s], u) with the largest ``|u|``, largest first."""
        z = np.asarray(self.residuals)
        order = np.argsort(-np.abs(np.nan_to_num(z, nan=0.0)))[:k]
        return [(float(self.scales_s[i]), float(z[i])) for i in order if np.isfinite(z[i])]

    def warning(self, alpha: float = ALPHA) -> str | None:
        """The one-line warning every surface prints when the model is rejected, else None."""
        if not self.rejected(alpha):
            return None
        worst = ", ".join(f"{s:.3g} s ({'>' if abs(z) >= _U_MAX else ''}{z:+.1f} SD)"
                          for s, z in self.worst_scales())
        return (f"goodness of fit: the model is rejected (p {fmt_p(self.p_value)}, statistic "
                f"{self.statistic:.4g} on {self.df} df): the WV departs from the fitted model, "
                f"most at scales {worst}; the estimates describe a wrong model")

    def line(self) -> str:
        """One summary line, e.g. ``goodness of fit: statistic 9.3 on 11 df, p = 0.59``."""
        if self.df == 0:
            return "goodness of fit: not testable (as many parameters as scales)"
        return (f"goodness of fit: statistic {self.statistic:.4g} on {self.df} df, "
                f"p {fmt_p(self.p_value)}" + ("  (REJECTED)" if self.rejected() else ""))

    def to_json_dict(self) -> dict[str, Any]:
        def num(v: float) -> float | None:
            return float(v) if np.isfinite(v) else None

        return {"statistic": num(self.statistic), "df": int(self.df),
                "p_value": num(self.p_value), "objective": num(self.objective),
                "method": self.method, "rejected": self.rejected(),
                "scales_s": [float(s) for s in self.scales_s],
                "residuals": [num(z) for z in self.residuals], "notes": list(self.notes)}


def fmt_p(p: float) -> str:
    """``= 0.031`` or ``< 1e-300`` (a p-value below double precision)."""
    return f"= {p:.3g}" if p > 0 or not np.isfinite(p) else "< 1e-300"


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
    """Covariance of nu_hat for the test: the caller's, the fit's user covariance (``weights``
    or ``se_cov`` a matrix), else the model-based one at the estimate (recomputed when the fit
    used the Gaussian one). The model-based covariance is the classical estimator's
    (:func:`gmwm.inference.model_wv_cov`): for a robust WV it is divided by the efficiency here,
    once; a user covariance is taken as given."""
    if V is not None:
        return np.asarray(V, dtype=float)
    s = result.settings
    if s.user_cov is not None:
        return np.asarray(s.user_cov, dtype=float)
    if s.se_cov_kind == "covariance":
        return np.asarray(s.se_cov, dtype=float)
    if s.se_cov_kind == "model" and result.wv_cov is not None:
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
    for c in model.components:
        note = c.process.gof_note(c.name, np.asarray(result.params)[c.slice], wv.n_samples)
        if note:
            notes.append(note)
    if np.any(wv.edof < 4):
        notes.append(f"{int(np.sum(wv.edof < 4))} longest scale(s) have fewer than 4 degrees of "
                     "freedom (non-Gaussian WV estimate)")
    return notes


def _boundary_notes(result: Any, pr: _Projection) -> list[str]:
    """The note of a test that projected out held components' directions (module docstring)."""
    fixed = _fixed(result)
    with np.errstate(all="ignore"):
        A = pr.prob.jac_theta(pr.theta)
    names = [c.name for c in result.model.components
             if fixed[c.slice].all() and np.any(np.isfinite(A[:, c.slice]) & (A[:, c.slice] != 0))]
    if not names:
        return []
    return [(f"{', '.join(names)} at the boundary 0: the test projects out the departure "
            "its value of either sign would explain (df as for the model with it free)")]


@dataclass
class _Projection:
    """The linearised pieces of a fit's residual (module docstring)."""

    prob: Any
    theta: np.ndarray
    keep: np.ndarray
    Vf: np.ndarray
    rw: np.ndarray          # L' r
    r: np.ndarray           # f(nu_hat) - f(nu(theta_hat))
    Qp: np.ndarray | None   # orthonormal basis of the complement of range(L' A), (J, df)
    Sw: np.ndarray | None   # L' V_f L


def _project(result: Any, V: np.ndarray | None, free: bool = False,
             held: np.ndarray | None = None) -> _Projection:
    """The linearised residual of ``result``; ``free``: every parameter enters the Jacobian,
    those of components held at the boundary 0 included (the test's projection, module
    docstring), else only the parameters not held. ``held``: parameters whose value the fit
    held (a sinusoid's frequency, :func:`_sin_frequency_max`), never in the Jacobian."""
    from .inference import Problem, f_jacobian

    prob = Problem.of(result)
    theta = np.asarray(result.params, dtype=float)
    J = result.wv.n_levels
    keep = np.ones(result.model.n_params, bool) if free else ~_fixed(result)
    if held is not None:
        keep &= ~held
    V = _wv_cov(result, V)
    F = f_jacobian(prob.nu_hat, prob.method)
    Vf = V * np.outer(F, F)
    L = prob.white.L
    with np.errstate(all="ignore"):
        rw = prob.residual(theta)
        r = prob.target - prob.f(result.model.wv(theta, prob.tau))
        Aw = L.T @ prob.jac_theta(theta)[:, keep]
    out = _Projection(prob, theta, keep, Vf, rw, r, None, None)
    if not (np.all(np.isfinite(Aw)) and np.all(np.isfinite(Vf)) and np.all(np.isfinite(rw))):
        return out
    # orthonormal basis of the complement of the whitened Jacobian's range (columns scaled:
    # parameters span many orders of magnitude)
    if Aw.shape[1]:
        norms = np.linalg.norm(Aw, axis=0)
        norms[norms == 0] = 1.0
        U, s, _ = np.linalg.svd(Aw / norms, full_matrices=True)
        rank = int(np.sum(s > 1e-10 * s[0])) if s.size and s[0] > 0 else 0
    else:
        U, rank = np.eye(J), 0
    out.Qp = U[:, rank:]
    out.Sw = L.T @ Vf @ L
    return out


def generalised_wald(result: Any, V: np.ndarray | None = None) -> tuple[float, int, float]:
    """``(S, df, p)`` of the generalised Wald statistic ``S = r' (M V_f M')^+ r``, chi-square
    with ``df`` degrees of freedom to first order under any weights. Kept for comparison: it
    over-rejects (module docstring); :func:`gof_test` is the test."""
    pr = _project(result, V)
    if pr.Qp is None or pr.Qp.shape[1] == 0:
        return float("nan"), 0, float("nan")
    z = pr.Qp.T @ pr.rw
    C = pr.Qp.T @ pr.Sw @ pr.Qp
    S = float(z @ np.linalg.lstsq((C + C.T) / 2, z, rcond=None)[0])
    df = pr.Qp.shape[1]
    return S, df, float(chdtrc(df, S))


def objective_test(result: Any, V: np.ndarray | None = None) -> tuple[float, int, float]:
    """``(Q / mean(lambda), df, p)`` of the minimised objective ``Q = r' Omega r`` against its
    null ``sum lambda_i chi2_1`` (``lambda`` = eigenvalues of ``P L' V_f L P``, ``Omega = L L'``,
    ``P`` the projector onto the complement of ``L' A``). Kept for comparison: with CI weights
    it misses misfits at the long scales (module docstring)."""
    pr = _project(result, V)
    if pr.Qp is None or pr.Qp.shape[1] == 0:
        return float("nan"), 0, float("nan")
    C = pr.Qp.T @ pr.Sw @ pr.Qp
    lam = np.clip(np.linalg.eigvalsh((C + C.T) / 2), 0.0, None)
    Q = float(pr.rw @ pr.rw)
    return Q / float(lam.mean()), pr.Qp.shape[1], weighted_chi2_sf(Q, lam)[0]


#: normal scores are capped here (a gamma tail beyond it underflows double precision)
_U_MAX = 38.0


def _from_f(y: np.ndarray, method: str) -> np.ndarray:
    """The inverse of the moment transform ``f`` (``log10`` for ARMAV), floored at a tiny
    positive WV (a projected residual below ``-nu`` is a gamma tail of 0: the score's cap)."""
    nu = 10.0 ** y if method == "armav" else y
    return np.maximum(nu, 1e-300)


def _normal_scores(nu_hat: np.ndarray, mean: np.ndarray, var: np.ndarray) -> np.ndarray:
    """``Phi^-1(G(nu_hat))`` for gamma laws with the given means and variances (computed from
    the nearer tail, capped at +-38)."""
    # the gamma and normal tails by scipy.special (what scipy.stats' gamma and norm call; their
    # import would cost ~0.5 s of every CLI call)
    shape = mean**2 / var
    scale = var / mean
    lower = gammainc(shape, nu_hat / scale)
    upper = gammaincc(shape, nu_hat / scale)
    with np.errstate(divide="ignore"):
        u = np.where(lower < upper, ndtri(lower), -ndtri(upper))
    return np.clip(u, -_U_MAX, _U_MAX)


def gof_test(result: Any, V: np.ndarray | None = None, *,
             hold_boundary: bool = False, sin_frequency: bool = True) -> GOFResult:
    """Goodness-of-fit test of a :class:`~gmwm.estimator.GMWMResult` (module docstring).

    ``V``: covariance (J, J) of the WV estimate under the null (default: model-based at the
    estimate, or the fit's own user covariance). ``hold_boundary=True``: the test before the
    boundary correction (a component at 0 held there, the test that of the model without it;
    oversized when the component is weak), kept for comparison (``benchmarks/bench_gof.py``).
    ``sin_frequency=False``: the test at the fit's own sinusoid frequencies only, even where
    the data do not identify them (before that correction, kept for comparison); by default
    the p-value is then the largest over the competing frequencies (module docstring)."""
    g = _test(result, V, hold_boundary)
    if hold_boundary or not sin_frequency:
        return g
    return _sin_frequency_max(result, V, g)


def _test(result: Any, V: np.ndarray | None, hold_boundary: bool = False,
          held: np.ndarray | None = None) -> GOFResult:
    """The test of one fit (``held``: parameters the fit held, outside the Jacobian)."""
    from .inference import f_jacobian

    pr = _project(result, V, free=not hold_boundary, held=held)
    prob, J = pr.prob, result.wv.n_levels
    objective = float(result.objective)
    nan = np.full(J, np.nan)
    if pr.Qp is None:
        return GOFResult(np.nan, 0, np.nan, objective, np.zeros(0), nan, prob.tau,
                         result.wv.freq, "none", ["the test could not be computed"])
    df = pr.Qp.shape[1]
    notes = _notes(result) + ([] if hold_boundary else _boundary_notes(result, pr))
    if df == 0:
        return GOFResult(np.nan, 0, np.nan, objective, np.zeros(0), nan, prob.tau,
                         result.wv.freq, "none",
                         notes + ["no degrees of freedom: as many parameters as scales"])
    # Cov(r) = M V_f M', M = I - A (A' Omega A)^+ A' Omega (columns scaled for the inverse)
    with np.errstate(all="ignore"):
        A = prob.jac_theta(pr.theta)[:, pr.keep]
        d = np.linalg.norm(prob.white @ A, axis=0)
        d[~np.isfinite(d) | (d == 0)] = 1.0
        As = A / d
        G = np.linalg.pinv(As.T @ prob.omega @ As, hermitian=True) @ As.T @ prob.omega
        M = np.eye(J) - As @ G
        S = M @ pr.Vf @ M.T
        S = (S + S.T) / 2
        var_f = np.diag(S).copy()
        # a scale the fit reproduces exactly (its residual variance ~ 0) carries no information
        use = np.isfinite(var_f) & (var_f > 1e-12 * np.abs(np.diag(pr.Vf)))
        mean = result.model.wv(pr.theta, prob.tau)
        # the residual projected onto the complement of the full Jacobian: the fit's own
        # residual (M r = r) unless a component is held at the boundary 0, where it removes
        # the departure the component's sign-free value would explain (module docstring)
        r = M @ pr.r
        x = _from_f(prob.f(mean) + r, prob.method)
        # on the nu scale: the delta method back from f
        fprime = f_jacobian(mean, prob.method)
        var_nu = var_f / fprime**2
        u = np.full(J, np.nan)
        u[use] = _normal_scores(x[use], mean[use], var_nu[use])
        sd = np.sqrt(var_f[use])
        R = S[np.ix_(use, use)] / np.outer(sd, sd)
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(u[use]))):
        return GOFResult(np.nan, df, np.nan, objective, np.zeros(0), u, prob.tau,
                         result.wv.freq, "none", notes + ["the test could not be computed"])
    lam = np.clip(np.linalg.eigvalsh(R), 0.0, None)
    U = float(u[use] @ u[use])
    p, method = weighted_chi2_sf(U, lam)
    stat = U * df / float(lam.sum())
    return GOFResult(float(stat), int(df), float(p), objective, lam, u, prob.tau,
                     result.wv.freq, method, notes)


# -- a sinusoid whose frequency the data do not identify ------------------------------------------
#: a seating of a sinusoid competes with the fit's when the fit with the frequency held there
#: has an objective within this many times the largest eigenvalue of the objective's null law
#: of the fit's (the 99 % point of chi-square(1): a profile interval for beta, module docstring)
SIN_COMPETE = 6.635
#: ... and lies at least this far from the fitted frequency (ln beta; a factor 1.5)
SIN_AWAY = math.log(1.5)
#: the profile of the objective over ln beta: points, and the width of the cells (ln beta) of
#: which each contributes its lowest point (the search's coarse grid step)
SIN_PROFILE_POINTS = 4000
SIN_CELL = 0.45
#: at most this many competing seatings are tested (the lowest objectives first)
SIN_MAX_SEATINGS = 40
#: competing seatings have periods of at most this share of the signal: a slower sinusoid's WV
#: depends on its phase (the test is liberal there, the SIN's ``gof_note``) and, past the
#: longest scale, mimics a drift or the rise of a random walk
SIN_MAX_PERIOD = 1 / 20


def _objective_lmax(result: Any, V: np.ndarray | None) -> float:
    """Largest eigenvalue of the null law of the fit's objective (:func:`objective_test`)."""
    pr = _project(result, V)
    if pr.Qp is None or pr.Qp.shape[1] == 0:
        return float("nan")
    C = pr.Qp.T @ pr.Sw @ pr.Qp
    return float(np.linalg.eigvalsh((C + C.T) / 2)[-1])


def _held_fit(result: Any, vp: Any, shapes: list[float], k: int, drift_sign: float
              ) -> tuple[float, np.ndarray]:
    """(objective, theta) of the fit with component k's shape (a SIN's ln beta) held at
    ``shapes[k]``: the fit's own variable projection (NNLS scales, coordinate moves of the
    other shapes); components below the fit's vanishing share set to 0 as the fit does."""
    from .inference import Problem
    from .search import theta_from_vp

    model = result.model
    shapes = list(shapes)
    vp.set_shapes(shapes)
    others = [j for j in vp.shaped if j != k]
    c, coef = vp.cost()
    for _ in range(3 if others else 0):
        previous = c
        for j in others:
            vp.best_along(shapes, j, True)
        c, coef = vp.cost()
        if c >= previous * (1 - 1e-6):
            break
    theta = theta_from_vp(model, shapes, coef, drift_sign)
    prob = Problem.of(result)
    vanished = prob.vanished(theta)
    for comp_k in model.components:
        if comp_k.name in vanished:
            theta[comp_k.start + comp_k.process.scale_index] = 0.0
    return prob.objective(theta), theta


def _sin_seatings(result: Any, V: np.ndarray | None) -> list[tuple[str, float, float, np.ndarray]]:
    """The competing seatings of the fit's sinusoids: (SIN label, beta [rad/sample], objective,
    theta of the fit with that beta held), those within ``SIN_COMPETE`` largest null eigenvalues
    of the fit's objective and ``SIN_AWAY`` from its frequency, lowest objective first."""
    from .inference import Problem
    from .search import VP, shapes_of

    model = result.model
    sins = [k for k, c in enumerate(model.components) if c.process.oscillating]
    if not sins or result.settings.method != "gmwm":
        return []
    lmax = _objective_lmax(result, V)
    if not (np.isfinite(lmax) and lmax > 0):
        return []
    prob = Problem.of(result)
    theta_hat = np.asarray(result.params, dtype=float)
    q_hat = float(result.objective)
    limit = q_hat + SIN_COMPETE * lmax
    drift_sign = -1.0 if any(c.process.signed and theta_hat[c.start] < 0
                             for c in model.components) else 1.0
    vp = VP(model, prob.tau, prob.nu_hat, prob.white, drift_sign, np.random.default_rng(0))
    base = shapes_of(model, theta_hat, prob.tau)
    out = []
    for k in sins:
        comp = model.components[k]
        lo, hi = comp.process.shape_bounds(prob.tau)
        lo = max(lo, math.log(2 * math.pi / (SIN_MAX_PERIOD * result.wv.n_samples)))
        if lo >= hi:
            continue
        u = np.linspace(lo, hi, SIN_PROFILE_POINTS)
        vp.set_shapes(base)
        others = [j for j in range(vp.ncomp) if j != k]
        G = prob.white @ comp.process.unit_wv_columns(u, prob.tau)
        gain, _ = vp.profile_gain(G, others)
        prof = vp.cost(others)[0] - gain
        # the lowest point of each cell away from the fitted frequency
        cell = np.floor((u - lo) / SIN_CELL).astype(int)
        far = np.abs(u - base[k]) > SIN_AWAY
        cand = []
        for c_id in np.unique(cell[far]):
            idx = np.flatnonzero((cell == c_id) & far)
            i = idx[int(np.argmin(prof[idx]))]
            if prof[i] <= limit:
                cand.append((float(prof[i]), float(u[i])))
        cand.sort()
        silent = False   # seatings where the SIN vanishes are one fit (the model without it)
        for _, uk in cand[:SIN_MAX_SEATINGS]:
            shapes = list(base)
            shapes[k] = uk
            q, theta = _held_fit(result, vp, shapes, k, drift_sign)
            if theta[comp.start + comp.process.scale_index] == 0:
                if silent:
                    continue
                silent = True
            if np.isfinite(q) and q <= limit:
                out.append((comp.name, float(np.exp(uk)), q, theta))
    out.sort(key=lambda t: t[2])
    return out


def _beta_index(model: Any, label: str) -> int:
    """Index in the parameter vector of the frequency ``beta`` of sinusoid ``label``."""
    comp = next(c for c in model.components if c.name == label)
    return comp.start + list(comp.process.param_names).index("beta")


def _held_test(result: Any, V: np.ndarray | None, labels: str | list[str], q: float,
               theta: np.ndarray) -> GOFResult:
    """The test of ``result``'s model with the frequencies of sinusoid(s) ``labels`` known: the
    held fit ``theta`` (objective ``q``, :func:`_held_fit`), those frequencies out of the
    Jacobian (one more df each)."""
    model = result.model
    held = np.zeros(model.n_params, bool)
    for label in [labels] if isinstance(labels, str) else labels:
        held[_beta_index(model, label)] = True
    diag = dict(result.diagnostics)
    diag["at_boundary"] = [c.name for c in model.components
                           if theta[c.start + c.process.scale_index] == 0]
    res_k = dataclasses.replace(result, params=theta, objective=q, wv_cov=None,
                                diagnostics=diag, gof=None)
    return _test(res_k, V, held=held)


def _sin_frequency_max(result: Any, V: np.ndarray | None, g: GOFResult) -> GOFResult:
    """The test's p-value as the largest over the seatings of a sinusoid whose frequency the
    data do not identify (module docstring): ``g`` itself when no other seating competes."""
    if not np.isfinite(g.p_value):
        return g
    try:
        with np.errstate(all="ignore"):
            return _largest_over_seatings(result, V, g)
    except (ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
        return dataclasses.replace(g, notes=[*g.notes, (
            f"the scan of the sinusoid's frequency failed ({err}): the p-value is the test's "
            "at the fitted frequency, liberal if that frequency is not identified")])


def _largest_over_seatings(result: Any, V: np.ndarray | None, g: GOFResult) -> GOFResult:
    seats = _sin_seatings(result, V)
    if not seats:
        return g
    model = result.model
    best, where = g, None
    for label, beta, q, theta in seats:
        gk = _held_test(result, V, label, q, theta)
        if np.isfinite(gk.p_value) and gk.p_value > best.p_value:
            best, where = gk, (label, beta)
    own = seats[0][0] if where is None else where[0]
    beta_hat = float(np.asarray(result.params)[_beta_index(model, own)])
    note = (f"{', '.join(sorted({s[0] for s in seats}))}: frequency not identified by the data "
            f"({len(seats)} other seating(s) within the objective's sampling noise); the p-value "
            "is the largest over them and the fit's own (conservative): ")
    if where is None:
        note += f"the fit's own, beta {beta_hat:.4g} rad/sample"
    else:
        note += (f"{where[0]} held at beta {where[1]:.4g} rad/sample (fitted {beta_hat:.4g}; "
                 f"the fit's own p {fmt_p(g.p_value)}; statistic and df are the held fit's)")
    return GOFResult(best.statistic, best.df, best.p_value, g.objective, best.eigenvalues,
                     g.residuals, g.scales, g.freq, best.method, [*g.notes, note])
