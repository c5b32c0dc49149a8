"""The GMWM inference core: one place for the objective, its weights and whitening, the analytic
Jacobian, the bounded solve, the covariance of the WV estimate and the sandwich covariance.

Every estimator path (:func:`gmwm.fit`, :mod:`gmwm.identify`, :mod:`gmwm.bootstrap`, the paper
studies) builds a :class:`Problem` and calls it; nothing else re-implements these formulas.

Conventions. ``f(x) = x`` (GMWM) or ``f = log10`` (ARMAV, the GMWFM class of [GMWFM]). The
objective is ``Q(theta) = (f(nu_hat) - f(nu(theta)))' Omega (f(nu_hat) - f(nu(theta)))``. The
covariance ``V`` of ``nu_hat`` (not of ``sqrt(T) nu_hat``) feeds the finite-sample sandwich of
docs/METHODS.md §5.9, ``(A'WA)^-1 A'W V_f W A (A'WA)^-1`` with ``A = d f(nu) / d theta`` and
``V_f = F V F'``, ``F = d f / d nu``.

Kinds of ``V`` (``se_cov``):

* ``"model"`` (default): the covariance of the boundary-free Haar WV estimator under the fitted
  model (:func:`gmwm.wvcov.wv_covariance`) with the correlation between scales. SIN components
  enter only through their cross term with the noise (their own term is O(T^-2), [Vibration]
  Theorem 1).
* ``"gaussian"``: the diagonal ``2 nu_hat_j^2 / eta_j`` (ignores the between-scale correlation
  and counts the SIN's WV; kept for comparison).
* a (J, J) matrix: the caller's covariance (e.g. a bootstrap's).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from .diagnostics import VANISH_SHARE, condition_number, free_jacobian
from .errors import InputError
from .model import Model, spec_of
from .wv import WaveletVariance

_LOG10E = np.log10(np.e)
METHODS = ("gmwm", "armav")
WEIGHT_KINDS = ("ci", "ci-eta3", "ci-mixture", "gaussian", "identity", "efficient")
#: The interval whose widths the default ``"ci"`` weights use: eta_3. The mixture-EDF widths
#: (``"ci-mixture"``) lower the weakest parameter's RMSE a little but leave its standard errors
#: and the GOF test off their nominal levels (bench_ci_weights, bench_intervals, bench_gof
#: sections of benchmarks/README.md; docs/METHODS.md §5.2).
CI_WEIGHTS = "ci-eta3"
#: Half-width of the bounded search box in free coordinates around a start (a factor e^40).
BOX = 40.0


# -- Levenberg-Marquardt ----------------------------------------------------------------------------
#: MINPACK's exit codes as ``least_squares`` reports them: (status, message).
_LM_STATUS = {
    1: (2, "`ftol` termination condition is satisfied."),
    2: (3, "`xtol` termination condition is satisfied."),
    3: (4, "Both `ftol` and `xtol` termination conditions are satisfied."),
    4: (1, "`gtol` termination condition is satisfied."),
    5: (0, "The maximum number of function evaluations is exceeded."),
}
_LM_IMPROPER = (-1, "Improper input parameters status returned from `leastsq`")


@dataclass
class _LMResult:
    x: np.ndarray
    cost: float
    status: int
    message: str
    nfev: int


def _lm(fun: Any, jac: Any, x0: np.ndarray, *, ftol: float, xtol: float, gtol: float,
        max_nfev: int) -> _LMResult:
    """MINPACK's lmder with Jacobian-norm scaling: the iterates of ``least_squares(method="lm",
    x_scale="jac")`` without its per-call wrappers and its final extra Jacobian (about a third
    of a small solve's time). Status and message follow ``least_squares``."""
    from scipy.optimize import leastsq  # lazily: ~0.3 s of imports that `gmwm plan` does not use

    x, _, info, _, ier = leastsq(fun, x0, Dfun=jac, full_output=True, ftol=ftol, xtol=xtol,
                                 gtol=gtol, maxfev=max_nfev, factor=100.0, diag=None)
    f = info["fvec"]
    status, message = _LM_STATUS.get(ier, _LM_IMPROPER)
    return _LMResult(np.atleast_1d(x), 0.5 * float(f @ f), status, message, int(info["nfev"]))


# -- weights --------------------------------------------------------------------------------------
def gaussian_wv_cov(nu: np.ndarray, edof: np.ndarray) -> np.ndarray:
    """Diagonal Gaussian covariance ``2 nu_j^2 / eta_j`` of the WV estimate."""
    return np.diag(2 * np.asarray(nu, float) ** 2 / np.asarray(edof, float))


def f_jacobian(nu: np.ndarray, method: str) -> np.ndarray:
    """Diagonal of ``F = d f / d nu`` at ``nu``."""
    if method == "armav":
        return _LOG10E / np.maximum(np.asarray(nu, float), 1e-300)
    return np.ones(np.asarray(nu).shape)


def check_cov(V: Any, J: int, what: str = "weight covariance") -> np.ndarray:
    """A caller's (J, J) covariance of nu_hat, validated."""
    V = np.asarray(V, dtype=float)
    if V.shape != (J, J):
        raise InputError(f"{what} must be {J}x{J} (one row per level), got {V.shape}")
    if not np.all(np.isfinite(V)) or np.any(np.diag(V) <= 0):
        raise InputError(f"{what} must be finite with a positive diagonal")
    return V


def omega_from_cov(V: np.ndarray, nu_hat: np.ndarray, method: str) -> np.ndarray:
    """Efficient weight ``(F V F')^-1`` for a covariance V of nu_hat (pseudo-inverse; symmetric)."""
    F = f_jacobian(nu_hat, method)
    Vf = V * np.outer(F, F)
    # scale to unit diagonal first: V spans many orders of magnitude across scales
    d = np.sqrt(np.diag(Vf))
    W = np.linalg.pinv(Vf / np.outer(d, d), hermitian=True, rcond=1e-12) / np.outer(d, d)
    return (W + W.T) / 2


def weight_matrix(wv: WaveletVariance, weights: str | np.ndarray, method: str = "gmwm",
                  model_wv: np.ndarray | None = None) -> np.ndarray:
    """Weight matrix Omega for ``f(nu_hat)``.

    ``"ci"``: inverse squared width of the WV interval :data:`CI_WEIGHTS` (eta_3, the ``simts``
    "fast" rule of the papers' software); ``"ci-eta3"`` / ``"ci-mixture"`` name the interval
    explicitly (``"ci-mixture"``: the mixture-EDF interval of :mod:`gmwm.wvci`); ``"gaussian"``: ``eta_j / (2 nu_j^2)``
    with ``nu = model_wv`` if given (re-weighting with the fitted model) else ``nu_hat``;
    ``"identity"``; a (J, J) covariance V of nu_hat: ``(F V F')^-1``. ARMAV's named kinds use
    the delta method ``Var(log10 nu_hat_j) ~ 2 (log10 e)^2 / eta_j`` (``"ci"``/``"gaussian"``).
    ``"efficient"`` is a two-step procedure of :func:`gmwm.fit`, not a fixed matrix.
    """
    J = wv.n_levels
    if not isinstance(weights, str):
        return omega_from_cov(check_cov(weights, J), wv.variance, method)
    if weights not in WEIGHT_KINDS or weights == "efficient":
        raise InputError(f"unknown weights {weights!r}; use one of {', '.join(WEIGHT_KINDS)} "
                         "or a covariance matrix")
    if weights == "identity":
        return np.eye(J)
    if method == "armav":
        return np.diag(wv.edof / (2 * _LOG10E**2))
    if weights.startswith("ci") and model_wv is None:
        low, high = ci_bounds(wv, CI_WEIGHTS if weights == "ci" else weights)
        return np.diag(1.0 / (high - low) ** 2)
    nu = wv.variance if model_wv is None else model_wv
    return np.diag(wv.edof / (2 * nu**2))


def ci_bounds(wv: WaveletVariance, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """``(low, high)`` of the WV interval behind the weights ``kind``: ``"ci-eta3"`` the eta_3
    interval (:meth:`WaveletVariance.eta3_ci`: a table's own bounds), ``"ci-mixture"`` the
    mixture-EDF interval (:mod:`gmwm.wvci`; computed from the WV when it carries another kind),
    whatever interval the WV itself carries."""
    if kind == "ci-eta3":
        return wv.eta3_ci()
    if kind != "ci-mixture":
        raise InputError(f"unknown CI weights {kind!r}; use ci-eta3 or ci-mixture")
    if wv.ci_kind == "mixture":
        return wv.ci_low, wv.ci_high
    from .wv import chi2_ci
    from .wvci import edof_for

    edof = edof_for("mixture", wv.variance, wv.scales, wv.n, wv.n_samples, wv.efficiency)
    return chi2_ci(wv.variance, edof, wv.alpha)


def whitener(omega: np.ndarray) -> np.ndarray:
    """L with ``Omega = L L'`` (Cholesky; eigen-factor when Omega is only semi-definite)."""
    omega = np.asarray(omega, dtype=float)
    if np.count_nonzero(omega - np.diag(np.diag(omega))) == 0:
        return np.diag(np.sqrt(np.clip(np.diag(omega), 0, None)))
    try:
        return np.linalg.cholesky(omega)
    except np.linalg.LinAlgError:
        w, U = np.linalg.eigh(omega)
        return U * np.sqrt(np.clip(w, 0, None))


class Whitener:
    """Multiply by ``L'`` (``Omega = L L'``); elementwise when Omega is diagonal."""

    def __init__(self, omega: np.ndarray):
        self.L = whitener(omega)
        lt = self.L.T
        self.diag = np.diag(lt).copy() if np.count_nonzero(lt - np.diag(np.diag(lt))) == 0 \
            else None
        self.lt = lt

    def __matmul__(self, other: np.ndarray) -> np.ndarray:
        if self.diag is None:
            return self.lt @ other
        return (self.diag * np.asarray(other).T).T


# -- covariance of the WV estimate ---------------------------------------------------------------
def model_wv_cov(model: Model, theta: np.ndarray, wv: WaveletVariance) -> np.ndarray:
    """Covariance of the boundary-free Haar WV estimate at ``wv``'s scales and length under the
    model at ``theta`` (:func:`gmwm.wvcov.wv_covariance`): the random components' exact
    finite-sample covariance, between-scale correlation included, plus each SIN's cross term
    with them (a SIN's own term is O(T^-2), [Vibration] Theorem 1). Components at the boundary 0
    contribute nothing."""
    from .wvcov import wv_covariance

    theta = np.asarray(theta, dtype=float)
    sub, sub_theta = nonzero_part(model, theta)
    J = wv.n_levels
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        V = np.zeros((J, J)) if sub is None else wv_covariance(sub, sub_theta, wv.scales,
                                                                 int(wv.n_samples))
    # a model whose random part vanishes at some scale would make V singular there: floor the
    # diagonal at a tiny share of the Gaussian WV-estimate variance
    floor = 1e-12 * np.diag(gaussian_wv_cov(wv.variance, wv.edof))
    return V + np.diag(np.where(np.diag(V) < floor, floor, 0.0))


def nonzero_part(model: Model, theta: np.ndarray, exclude: tuple[str, ...] = ()
                 ) -> tuple[Model | None, np.ndarray]:
    """The submodel of components with a non-zero scale parameter (not in ``exclude``) and its
    parameters (a component at the boundary 0 adds nothing to the WV or its covariance)."""
    keep = []
    for c in model.components:
        p = theta[c.slice]
        scale = p[c.process.scale_index]
        if c.process.name not in exclude and scale != 0 and np.all(np.isfinite(p)):
            keep.append(c)
    if not keep:
        return None, np.zeros(0)
    counts: dict[str, int] = {}
    for c in keep:
        counts[c.process.name] = counts.get(c.process.name, 0) + 1
    sub = Model(spec_of(counts), model.freq)
    # components of one type keep their relative (canonical) order
    order = [c.process.name for c in sub.components]
    grouped = {name: [theta[c.slice] for c in keep if c.process.name == name] for name in counts}
    sub_theta = np.concatenate([grouped[n].pop(0) for n in order])
    return sub, sub_theta


def wv_cov(kind: str | np.ndarray, model: Model, theta: np.ndarray,
           wv: WaveletVariance) -> np.ndarray:
    """Covariance V of nu_hat of a given kind (module docstring)."""
    if not isinstance(kind, str):
        return check_cov(kind, wv.n_levels)
    if kind == "gaussian":
        return gaussian_wv_cov(wv.variance, wv.edof)
    if kind == "model":
        return model_wv_cov(model, theta, wv)
    raise InputError(f"unknown se_cov {kind!r}; use 'model', 'gaussian' or a covariance matrix")


# -- the problem ----------------------------------------------------------------------------------
@dataclass
class Solution:
    """Outcome of one bounded solve: raw (not relabelled) parameters, objective and status."""

    theta: np.ndarray
    eta: np.ndarray
    objective: float
    ok: bool
    message: str
    edge: list[str]
    nfev: int = 0
    capped: bool = False   # stopped by the evaluation budget


class Problem:
    """The GMWM (or ARMAV) problem for one WV, model, method and weight matrix."""

    def __init__(self, model: Model, wv: WaveletVariance, omega: np.ndarray,
                 method: str = "gmwm"):
        if method not in METHODS:
            raise InputError(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
        self.model, self.wv, self.method = model, wv, method
        self.omega = np.asarray(omega, dtype=float)
        self.tau = wv.scales.astype(float)
        self.nu_hat = np.asarray(wv.variance, dtype=float)
        self.target = self.f(self.nu_hat)
        self.white = Whitener(self.omega)
        self._scale_mask = np.zeros(model.n_params, bool)
        for c in model.components:
            self._scale_mask[c.start + c.process.scale_index] = True
        # residual normalisation for the optimiser only (the argmin is unchanged)
        self.scale = float(np.linalg.norm(self.white @ self.target)) or 1.0

    @classmethod
    def of(cls, result: Any) -> Problem:
        """The problem a fit result was solved on (its own weights and method)."""
        return cls(result.model, result.wv, result.weights, result.method)

    def f(self, nu: np.ndarray) -> np.ndarray:
        if self.method == "armav":
            return np.log10(np.maximum(nu, 1e-300))
        return nu

    # objective and derivatives in theta
    def residual(self, theta: np.ndarray) -> np.ndarray:
        """Whitened residual ``L' (f(nu_hat) - f(nu(theta)))`` (unnormalised)."""
        return self.white @ (self.target - self.f(self.model.wv(theta, self.tau)))

    def vanished(self, theta: np.ndarray) -> set[str]:
        """Components whose WV at ``theta`` is below ``VANISH_SHARE`` of ``nu_hat`` at every scale
        (set to exactly 0 by the fit: docs/METHODS.md §5.8)."""
        with np.errstate(all="ignore"):
            comp = self.model.component_wv(theta, self.tau)
        return {k for k, v in comp.items() if np.max(v / self.nu_hat) < VANISH_SHARE}

    def objective(self, theta: np.ndarray) -> float:
        with np.errstate(all="ignore"):
            r = self.residual(np.asarray(theta, dtype=float))
        return float(r @ r)

    def jac_theta(self, theta: np.ndarray) -> np.ndarray:
        """``d f(nu(theta)) / d theta``, shape (J, p)."""
        A = self.model.jacobian(theta, self.tau)
        if self.method == "armav":
            A = A * f_jacobian(self.model.wv(theta, self.tau), "armav")[:, None]
        return A

    # free coordinates (what the optimiser sees)
    def free_residual(self, eta: np.ndarray) -> np.ndarray:
        return self.residual(self.model.from_free(eta)) / self.scale

    def free_jac(self, eta: np.ndarray) -> np.ndarray:
        theta = self.model.from_free(eta)
        return -(self.white @ self.jac_theta(theta)) * self.model.dtheta_deta(eta) / self.scale

    def solve(self, theta0: np.ndarray, *, max_nfev: int = 1000, box: float = BOX,
              center: np.ndarray | None = None) -> Solution:
        """Least squares in free coordinates from ``theta0`` within ``center +- box`` (default:
        around the start), with the analytic Jacobian; never past ``Model.free_limits``, where
        a transform rounds onto its domain's bound (phi = 1). ``edge``
        names parameters that ended within 1e-3 of the box (a variance running to the boundary
        0, i.e. a vanishing component, is not counted)."""
        model = self.model
        with np.errstate(all="ignore"):
            eta0 = model.to_free(theta0)
        eta0 = np.clip(np.nan_to_num(eta0, nan=0.0, posinf=30.0, neginf=-30.0), -60, 60)
        c = eta0 if center is None else center
        lim_lo, lim_hi = model.free_limits()
        hi = np.minimum(c + box, lim_hi)
        lo = np.minimum(np.maximum(c - box, lim_lo), hi - 1.0)
        eta0 = np.clip(eta0, lim_lo + 1e-6, lim_hi - 1e-6)
        x0 = np.clip(eta0, lo + 1e-9, hi - 1e-9)
        opts = {"jac": self.free_jac, "x_scale": "jac", "xtol": 1e-10, "ftol": 1e-12,
                "gtol": 1e-10, "max_nfev": max_nfev}
        sol = None
        try:
            with np.errstate(all="ignore"):
                # Levenberg-Marquardt (MINPACK) first: several times less overhead per step than
                # the bounded trust region. The box only guards against runaway, so the bounded
                # solve reruns when LM ends outside it (or fails)
                sol = _lm(self.free_residual, self.free_jac, x0, ftol=opts["ftol"],
                          xtol=opts["xtol"], gtol=opts["gtol"], max_nfev=max_nfev)
        except (TypeError, ValueError, FloatingPointError, np.linalg.LinAlgError):
            # (leastsq raises TypeError when there are fewer levels than parameters)
            sol = None
        if sol is not None and sol.status >= 0 and np.all(np.isfinite(sol.x)):
            # a vanishing scale (variance, amplitude, drift) runs to -inf in free coordinates;
            # back at the box its contribution is unchanged. Any other coordinate outside the
            # box (a phi at +-1, a runaway) goes to the bounded solve
            xc = np.clip(sol.x, lo, hi)
            if np.any((xc != sol.x) & ~(self._scale_mask & (sol.x < lo))):
                sol = None
            elif not np.array_equal(xc, sol.x):
                with np.errstate(all="ignore"):
                    rc = self.free_residual(xc)
                cost_c = 0.5 * float(rc @ rc)
                if np.isfinite(cost_c) and cost_c <= sol.cost * (1 + 1e-10) + 1e-300:
                    sol.x, sol.cost = xc, cost_c
                else:
                    sol = None
        else:
            sol = None
        if sol is None:
            from scipy.optimize import least_squares

            try:
                with np.errstate(all="ignore"):
                    sol = least_squares(self.free_residual, x0, method="trf", bounds=(lo, hi),
                                        **opts)
            except (ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
                return Solution(np.asarray(theta0, float), eta0, np.inf, False,
                                f"optimiser failed: {err}", [], 0, False)
        raw = model.from_free(sol.x)
        obj = self.objective(raw)
        ok = bool(sol.status > 0 and np.all(np.isfinite(raw)) and np.isfinite(obj))
        vanished = self.vanished(raw)
        edge = [n for n, e, a, b in zip(model.param_names, sol.x, lo, hi, strict=True)
                if min(e - a, b - e) < 1e-3
                and not (n.split(".")[0] in vanished and e - a < 1e-3)]
        return Solution(raw, sol.x, obj if np.isfinite(obj) else np.inf, ok,
                        str(sol.message) if ok else f"stopped: {sol.message}", edge,
                        int(sol.nfev), bool(sol.status == 0))

    def chi2_scale(self, V: np.ndarray) -> float:
        """``c = tr(Omega V_f) / J``: the objective divided by c is on the chi-square scale
        (c = 1 for the efficient weights Omega = V_f^-1, V the covariance of nu_hat)."""
        F = f_jacobian(self.nu_hat, self.method)
        with np.errstate(all="ignore"):
            return float(np.trace(self.omega @ (V * np.outer(F, F))) / self.wv.n_levels)

    # covariance of the estimate
    def sandwich(self, theta: np.ndarray, V: np.ndarray,
                 fixed: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, float]:
        """Sandwich covariance of theta_hat (docs/METHODS.md §5.9) for a covariance V of nu_hat, its SEs and
        the condition number of the whitened Jacobian in free coordinates
        (:func:`gmwm.diagnostics.free_jacobian`). Parameters flagged in ``fixed`` (at the
        boundary) are held fixed: their rows/columns are NaN."""
        theta = np.asarray(theta, dtype=float)
        p = theta.size
        keep = np.ones(p, bool) if fixed is None else ~np.asarray(fixed, bool)
        cov = np.full((p, p), np.nan)
        se = np.full(p, np.nan)
        cond = np.inf
        if not keep.any():
            return cov, se, cond
        with np.errstate(all="ignore"):
            A = self.jac_theta(theta)[:, keep]
            F = f_jacobian(self.nu_hat, self.method)
            Vf = V * np.outer(F, F)
            W = self.omega
            # scale the columns first: parameters live on scales from 1e-13 to 1, and an
            # unscaled pseudo-inverse would cut the small-scale directions to zero variance
            d = np.linalg.norm(self.white @ A, axis=0)
            d[~np.isfinite(d) | (d == 0)] = 1.0
            As = A / d
            try:
                Binv = np.linalg.pinv(As.T @ W @ As, hermitian=True)
                G = (Binv @ As.T @ W) / d[:, None]
                ck = G @ Vf @ G.T
                cov[np.ix_(keep, keep)] = ck
                se[keep] = np.sqrt(np.clip(np.diag(ck), 0, None))
            except np.linalg.LinAlgError:
                pass
            cond = condition_number(free_jacobian(self, theta, keep))
        return cov, se, cond
