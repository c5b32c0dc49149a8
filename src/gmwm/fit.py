"""GMWM (and ARMAV) estimation of composite error models from a signal or its wavelet variance.

The estimator minimises ``(f(nu_hat) - f(nu(theta)))' Omega (f(nu_hat) - f(nu(theta)))`` over the
levels j = 1..J, with ``f(x) = x`` (GMWM) or ``f = log10`` applied to the Allan variance (ARMAV,
the GMWFM class of paper 004).

How the optimum is found (no user starting values):

1. Variable projection. Every process's WV is linear in one "scale" parameter (sigma2, Q2,
   gamma2, omega^2, the AR1 innovation variance, the GM variance, alpha^2) once its "shape"
   parameter (AR1 phi, GM beta, SIN beta) is fixed. For fixed shapes the best non-negative scale
   parameters solve a small non-negative least-squares problem (NNLS) on the whitened system:
   for models made only of QN, WN, RW and DR that *is* the closed-form GMWM of paper 004
   (eqs. 5-7), solved as NNLS so that no variance comes out negative.
2. Starts. The shapes are searched on log-spaced grids covering the observed scales (coordinate
   sweeps from several seeded initial placements); the distinct best grid points give the starts.
3. Refinement. Levenberg-Marquardt on the whitened residuals in unconstrained coordinates (logs,
   scaled logit for AR1 phi, pi*logistic for SIN beta) with the analytic Jacobian; the best
   objective over the starts is kept. Non-convergence is reported in ``converged``/``message``.

Standard errors use the finite-sample sandwich of SPEC 5.5,
``(A'WA)^-1 A'W V W A (A'WA)^-1`` with ``A = d f(nu) / d theta`` and ``V`` the covariance of the
WV estimate: the caller's matrix when one is given as ``weights``, else the Gaussian diagonal
``2 nu_hat_j^2 / eta_j``, which ignores the correlation between scales (pass a bootstrap covariance,
see :mod:`gmwm.bootstrap`, for better SEs).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares, minimize_scalar, nnls
from scipy.stats import norm

from .errors import IdentifiabilityError, InputError
from .model import Model, as_model
from .processes import ar1_wv_a
from .wv import WaveletVariance, wvar

_LOG10E = np.log10(np.e)
_METHODS = ("gmwm", "armav")
_WEIGHTS = ("ci", "gaussian", "identity")


# -- result ---------------------------------------------------------------------------------------
@dataclass
class GMWMResult:
    """Outcome of :func:`fit`. ``params``/``se`` follow ``param_names`` (canonical order)."""

    model: Model
    params: np.ndarray
    se: np.ndarray
    cov: np.ndarray
    objective: float
    weights: np.ndarray
    converged: bool
    message: str
    wv: WaveletVariance
    method: str = "gmwm"
    diagnostics: dict[str, Any] = field(default_factory=dict)
    seconds_wv: float = 0.0
    seconds_fit: float = 0.0

    @property
    def param_names(self) -> list[str]:
        return self.model.param_names

    def as_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.params)

    def se_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.se)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Wald intervals ``params -/+ z se`` (asymptotic; see :mod:`gmwm.bootstrap` for better)."""
        z = norm.ppf(1 - alpha / 2)
        return np.column_stack([self.params - z * self.se, self.params + z * self.se])

    def model_wv(self, scales: np.ndarray | None = None) -> np.ndarray:
        return self.model.wv(self.params, self.wv.scales if scales is None else scales)

    def component_wv(self, scales: np.ndarray | None = None) -> dict[str, np.ndarray]:
        return self.model.component_wv(self.params, self.wv.scales if scales is None else scales)

    def summary(self) -> str:
        """Plain-text table of estimates, standard errors and fit diagnostics."""
        lines = [(f"GMWM fit ({self.method}) of {self.model.spec}  |  T = {self.wv.n_samples}, "
                  f"J = {self.wv.n_levels}, freq = {self.wv.freq:g} Hz"),
                 f"objective = {self.objective:.6g}   converged = {self.converged}"
                 + ("" if self.converged else f"   ({self.message})"),
                 f"{'parameter':<16}{'estimate':>14}{'std. error':>14}",
                 "-" * 44]
        for name, est, se in zip(self.param_names, self.params, self.se, strict=True):
            lines.append(f"{name:<16}{est:>14.6g}{se:>14.4g}")
        for w in self.diagnostics.get("warnings", []):
            lines.append(f"warning: {w}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-able summary (model, n, params, se, objective, converged, WV, timings)."""
        return {
            "model": self.model.spec,
            "method": self.method,
            "n": int(self.wv.n_samples),
            "freq": self.wv.freq,
            "params": self.as_dict(),
            "se": self.se_dict(),
            "objective": float(self.objective),
            "converged": bool(self.converged),
            "message": self.message,
            "warnings": list(self.diagnostics.get("warnings", [])),
            "wv": self.wv.to_dict(),
            "seconds_wv": self.seconds_wv,
            "seconds_fit": self.seconds_fit,
        }

    def plot(self, ax=None, **kwargs):
        """Log-log WV with CI band, fitted model and its components (see gmwm.plots.plot_wv)."""
        from .plots import plot_wv

        return plot_wv(self.wv, result=self, ax=ax, **kwargs)


# -- objective ------------------------------------------------------------------------------------
@dataclass
class _Problem:
    """The whitened least-squares problem ``|| L' (f(nu_hat) - f(nu(theta))) ||^2``."""

    model: Model
    tau: np.ndarray
    target: np.ndarray        # f(nu_hat)
    chol: np.ndarray          # L with Omega = L L'
    method: str
    scale: float              # residual normalisation for the optimiser (argmin unchanged)

    def f(self, nu: np.ndarray) -> np.ndarray:
        if self.method == "armav":
            return np.log10(np.maximum(nu, 1e-300))
        return nu

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self.chol.T @ (self.target - self.f(self.model.wv(theta, self.tau))) / self.scale

    def jac_theta(self, theta: np.ndarray) -> np.ndarray:
        """d f(nu(theta)) / d theta."""
        jac = self.model.jacobian(theta, self.tau)
        if self.method == "armav":
            nu = np.maximum(self.model.wv(theta, self.tau), 1e-300)
            jac = jac * (_LOG10E / nu)[:, None]
        return jac

    def objective(self, theta: np.ndarray) -> float:
        r = self.residual(theta) * self.scale
        return float(r @ r)

    def free_residual(self, eta: np.ndarray) -> np.ndarray:
        return self.residual(self.model.from_free(eta))

    def free_jac(self, eta: np.ndarray) -> np.ndarray:
        theta = self.model.from_free(eta)
        return -(self.chol.T @ self.jac_theta(theta)) * self.model.dtheta_deta(eta) / self.scale


# -- weights --------------------------------------------------------------------------------------
def _wv_cov_gaussian(nu: np.ndarray, edof: np.ndarray) -> np.ndarray:
    return np.diag(2 * nu**2 / edof)


def weight_matrix(wv: WaveletVariance, weights: str | np.ndarray, method: str = "gmwm",
                  model_wv: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Return ``(Omega, V)``: the weight matrix for ``f(nu)`` and the covariance V of ``nu_hat``
    used for standard errors. ``model_wv`` replaces ``nu_hat`` in the Gaussian variances
    (re-weighting with the fitted model)."""
    nu = wv.variance if model_wv is None else model_wv
    J = wv.n_levels
    if isinstance(weights, np.ndarray) or not isinstance(weights, str):
        V = np.asarray(weights, dtype=float)
        if V.shape != (J, J):
            raise InputError(f"weight covariance must be {J}x{J} (one row per level), "
                             f"got {V.shape}")
        if not np.all(np.isfinite(V)) or np.any(np.diag(V) <= 0):
            raise InputError("weight covariance must be finite with a positive diagonal")
        Vf = V
        if method == "armav":
            F = np.diag(_LOG10E / wv.variance)
            Vf = F @ V @ F.T
        return np.linalg.pinv(Vf, hermitian=True), V
    V = _wv_cov_gaussian(nu, wv.edof)
    if weights not in _WEIGHTS:
        raise InputError(f"unknown weights {weights!r}; use one of {', '.join(_WEIGHTS)} "
                         "or a covariance matrix")
    if weights == "identity":
        return np.eye(J), V
    if method == "armav":
        # delta method: Var(log10 nu_hat_j) ~ 2 (log10 e)^2 / eta_j
        return np.diag(wv.edof / (2 * _LOG10E**2)), V
    if weights == "ci" and model_wv is None:
        width = wv.ci_high - wv.ci_low
        return np.diag(1.0 / width**2), V
    return np.diag(1.0 / np.diag(V)), V


def _cholesky(omega: np.ndarray) -> np.ndarray:
    if np.allclose(omega, np.diag(np.diag(omega))):
        return np.diag(np.sqrt(np.diag(omega)))
    try:
        return np.linalg.cholesky(omega)
    except np.linalg.LinAlgError:
        w, U = np.linalg.eigh(omega)
        return U * np.sqrt(np.clip(w, 0, None))


# -- starting values by variable projection --------------------------------------------------------
def _unit_column(name: str, shape: float, tau: np.ndarray) -> np.ndarray:
    """WV of a component with unit scale parameter at the given shape (AR1/GM: a = -ln phi;
    SIN: beta); for WN/QN/RW/DR the shape is ignored."""
    if name in ("AR1", "GM"):
        col = ar1_wv_a(shape, tau)[0]
        return col * -np.expm1(-2 * shape) if name == "GM" else col
    if name == "SIN":
        return _sin_columns(np.array([shape]), tau)[:, 0]
    from .processes import PROCESSES

    return PROCESSES[name].wv(np.ones(1), tau)


def _sin_columns(beta: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Unit-amplitude SIN WV for many beta at once, shape (J, len(beta))."""
    b = np.asarray(beta)[None, :]
    t = tau[:, None]
    return 2 * np.sin(b * t / 4) ** 4 / (t**2 * np.sin(b / 2) ** 2)


def _shape_grid(name: str, tau: np.ndarray, n_grid: int) -> np.ndarray | None:
    """Log-spaced shape grid covering the observed scales (None: no shape parameter)."""
    if name in ("AR1", "GM"):  # phi from 1e-3 (white-noise like) to a correlation time ~5x
        return np.geomspace(0.2 / tau[-1], 7.0, n_grid)  # the longest scale
    if name == "SIN":  # bump locations from below the first to beyond the last scale
        return np.geomspace(1.0 / tau[-1], 0.999 * np.pi, n_grid)
    return None


def _sin_envelope_columns(beta: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Smooth stand-in for the SIN WV used to locate the bump on a coarse grid: past the first
    peak, sin^4(beta tau / 4) is replaced by its mean 3/8, removing the oscillation in beta
    that makes a coarse grid land on arbitrary phases."""
    b = np.asarray(beta)[None, :]
    t = tau[:, None]
    x = b * t / 4
    s4 = np.where(x < 1.1656, np.sin(np.minimum(x, 1.1656)) ** 4, 0.375)
    return 2 * s4 / (t**2 * np.sin(b / 2) ** 2)


@lru_cache(maxsize=128)
def _grid_columns(name: str, tau: tuple[float, ...], n_grid: int) -> tuple[np.ndarray, np.ndarray]:
    """Shape grid and its unit-scale WV columns (J, G) (SIN: smooth envelope); they depend on
    the scales only, so they are cached."""
    t = np.asarray(tau)
    grid = _shape_grid(name, t, n_grid)
    if name == "SIN":
        cols = _sin_envelope_columns(grid, t)
    else:
        cols = np.column_stack([_unit_column(name, g, t) for g in grid])
    cols.setflags(write=False)
    return grid, cols


class _Whitener:
    """Multiply by L' (Omega = L L'), elementwise when Omega is diagonal (the usual case)."""

    def __init__(self, lt: np.ndarray):
        self.diag = np.diag(lt).copy() if np.count_nonzero(lt - np.diag(np.diag(lt))) == 0 \
            else None
        self.lt = lt

    def __matmul__(self, other: np.ndarray) -> np.ndarray:
        if self.diag is None:
            return self.lt @ other
        return (self.diag * other.T).T


def _nnls_cost(Xw: np.ndarray, yw: np.ndarray) -> tuple[float, np.ndarray]:
    colnorm = np.linalg.norm(Xw, axis=0)
    colnorm[colnorm == 0] = 1.0
    coef, rnorm = nnls(Xw / colnorm, yw, maxiter=50 * Xw.shape[1])
    return rnorm**2, coef / colnorm


def _theta_from_vp(model: Model, shapes: list[float], coef: np.ndarray, nu_hat: np.ndarray,
                   tau: np.ndarray, drift_sign: float) -> np.ndarray:
    """Shapes + NNLS scale coefficients -> parameter vector (zeros lifted to a small positive
    value so the log transforms are defined)."""
    theta = np.empty(model.n_params)
    for c, shape, k in zip(model.components, shapes, range(len(shapes)), strict=True):
        name = c.process.name
        col = _unit_column(name, shape, tau)
        floor = 1e-3 * np.min(nu_hat / np.where(col > 0, col, np.inf))
        s = max(coef[k], floor)
        if name in ("WN", "QN", "RW"):
            theta[c.slice] = [s]
        elif name == "DR":
            theta[c.slice] = [drift_sign * np.sqrt(s)]
        elif name == "AR1":
            theta[c.slice] = [np.exp(-shape), s]
        elif name == "GM":
            theta[c.slice] = [shape * model.freq, s]
        else:  # SIN
            theta[c.slice] = [np.sqrt(s), shape]
    return theta


def _shapes_of(model: Model, theta: np.ndarray) -> list[float]:
    """Shape coordinates (AR1/GM: a = -ln phi; SIN: beta; others 0.1) of a parameter vector."""
    out = []
    for c in model.components:
        p = theta[c.slice]
        name = c.process.name
        if name == "AR1":
            out.append(float(-np.log(p[0])) if p[0] > 0 else 2.0)
        elif name == "GM":
            out.append(float(p[0] / model.freq))
        elif name == "SIN":
            out.append(float(p[1]))
        else:
            out.append(0.1)
    return out


def _vp_starts(model: Model, tau: np.ndarray, nu_hat: np.ndarray, chol: np.ndarray,
               n_starts: int, rng: np.random.Generator, drift_sign: float,
               n_grid: int = 40) -> tuple[list[np.ndarray], list[float]]:
    """Distinct good starting points: coordinate descent over the shape parameters of the
    variable-projection (NNLS) cost, each step a grid scan then a 1-D bounded refinement."""
    names = [c.process.name for c in model.components]
    tau_key = tuple(float(t) for t in tau)
    grids: list[np.ndarray | None] = []
    gcols: list[np.ndarray | None] = []
    Lt = _Whitener(chol.T)
    for n in names:
        if _shape_grid(n, tau, n_grid) is None:
            grids.append(None)
            gcols.append(None)
        else:
            g, c = _grid_columns(n, tau_key, n_grid)
            grids.append(g)
            gcols.append(Lt @ c)
    shaped = [k for k, g in enumerate(grids) if g is not None]
    yw = Lt @ nu_hat
    ncomp = len(names)
    # whitened columns of the current shapes; only the column being varied is recomputed
    cols = np.column_stack([Lt @ _unit_column(names[k], 0.1, tau) for k in range(ncomp)])

    def cost_with(k: int | None, col: np.ndarray | None,
                  active: list[int] | None = None) -> tuple[float, np.ndarray]:
        X = cols.copy() if k is not None else cols
        if k is not None:
            X[:, k] = col
        keep = list(range(ncomp)) if active is None else active
        c, coef = _nnls_cost(X[:, keep], yw)
        full = np.zeros(ncomp)
        full[keep] = coef
        return c, full

    def profile_gain(G: np.ndarray, others: list[int], with_resid: bool = False):
        """Drop in LS cost from adding each column of G to the others (Frisch-Waugh), in one
        shot; only columns with a positive coefficient count. Returns (gain, coefficient)
        and, if asked, the LS cost of the others alone."""
        if others:
            Q, _ = np.linalg.qr(cols[:, others])
            y_perp = yw - Q @ (Q.T @ yw)
            G_perp = G - Q @ (Q.T @ G)
        else:
            y_perp, G_perp = yw, G
        num = G_perp.T @ y_perp
        den = np.einsum("jg,jg->g", G_perp, G_perp)
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = (num > 0) & (den > 0)
            out = np.where(ok, num**2 / den, 0.0), np.where(ok, num / den, 0.0)
        return (*out, float(y_perp @ y_perp)) if with_resid else out

    def best_along(shapes: list[float], k: int, refine: bool,
                   active: list[int] | None = None) -> float:
        grid, G = grids[k], gcols[k]
        others = [i for i in (range(ncomp) if active is None else active) if i != k]
        gain, coef = profile_gain(G, others)
        top = np.argsort(-gain)[:3]
        values = grid[top]
        step = np.log(grid[1] / grid[0])
        if names[k] == "SIN" and refine:
            # the SIN WV oscillates in beta at long scales (nulls at beta tau / 4 = k pi), so
            # its basins are ~1/(beta tau_J) wide: scan finely around the best coarse points
            # (0.5 rad of phase per step at the longest scale where the SIN still reaches 1 %
            # of the WV; beyond it the phase does not matter)
            fine = []
            for i in top:
                lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
                share = coef[i] * _sin_envelope_columns(grid[i:i + 1], tau)[:, 0] / nu_hat
                tau_eff = tau[share >= 0.01].max(initial=tau[0])
                n = int(np.clip(hi * tau_eff * np.log(hi / lo) / 2, 16, 3000))
                fine.append(np.geomspace(lo, hi, n))
            fine_v = np.concatenate(fine)
            gain_f, _ = profile_gain(Lt @ _sin_columns(fine_v, tau), others)
            values = fine_v[np.argsort(-gain_f)[:3]]
            step = float(np.log(fine[0][1] / fine[0][0]))
        exact = [cost_with(k, Lt @ _unit_column(names[k], v, tau), active)[0] for v in values]
        best = float(values[int(np.argmin(exact))])
        best_cost = min(exact)
        if refine:
            lo, hi = np.log(best) - step, min(np.log(best) + step, np.log(grid[-1]))
            res = minimize_scalar(
                lambda lv: cost_with(k, Lt @ _unit_column(names[k], np.exp(lv), tau), active)[0],
                bounds=(lo, hi), method="bounded", options={"xatol": 0.02 * step})
            if res.fun <= best_cost:
                best = float(np.exp(res.x))
        shapes[k] = best
        cols[:, k] = Lt @ _unit_column(names[k], best, tau)
        return best

    def set_shapes(shapes: list[float]) -> None:
        for k in shaped:
            cols[:, k] = Lt @ _unit_column(names[k], shapes[k], tau)

    def descend(shapes: list[float], refine: bool) -> tuple[list[float], float, np.ndarray]:
        set_shapes(shapes)
        best = cost_with(None, None)
        for _ in range(4):
            previous = best[0]
            for k in shaped:
                best_along(shapes, k, refine)
            best = cost_with(None, None)
            if best[0] >= previous * (1 - 1e-6):
                break
        return shapes, best[0], best[1]

    found: list[tuple[float, list[float], np.ndarray]] = []
    n_init = max(n_starts, 2) if shaped else 1
    for s in range(n_init):
        shapes = [0.1] * ncomp
        if s == 0:
            # greedy: add shaped components one at a time at their best place, then refine all
            # shapes continuously (a coarse grid leaves residuals that a second bump would
            # otherwise be spent on)
            active = [k for k in range(ncomp) if k not in shaped]
            for k in shaped:
                active.append(k)
                best_along(shapes, k, True, sorted(active))
            shapes, c, coef = descend(shapes, refine=True)
        else:
            for k in shaped:
                shapes[k] = float(rng.choice(grids[k]))
            shapes, c, coef = descend(shapes, refine=False)
        theta = model.canonical(_theta_from_vp(model, shapes, coef, nu_hat, tau, drift_sign))
        if not any(np.allclose(theta, t, rtol=1e-3) for _, t, _ in found):
            found.append((c, theta, coef))
    found.sort(key=lambda item: item[0])
    kept = found[: max(n_starts, 1)]
    # pair moves: a SIN bump hidden under another component (e.g. a slow SIN under a slow AR1)
    # is invisible to one-at-a-time moves. Scan (SIN shape, other shape) jointly on the coarse
    # grids (for each grid value of the other, the SIN's whole profile is one projection), then
    # descend from the best pair. The best such start is always refined.
    sins = [k for k in shaped if names[k] == "SIN"]
    if sins and len(shaped) > 1 and found:
        base = _shapes_of(model, found[0][1])
        moved: list[tuple[float, np.ndarray]] = []
        # exact SIN columns here (the envelope is crude for a bump at the last scales, which is
        # the case these moves are for), 4x denser than the coarse grid
        sin_grid = np.geomspace(grids[sins[0]][0], grids[sins[0]][-1], 4 * n_grid)
        sin_cols = Lt @ _sin_columns(sin_grid, tau)
        for k in sins:
            for j in shaped:
                if j == k:
                    continue
                shapes = list(base)
                set_shapes(shapes)
                others = [i for i in range(ncomp) if i != k]
                best_pair, best_cost = None, np.inf
                for gj in range(grids[j].size):
                    cols[:, j] = gcols[j][:, gj] if names[j] != "SIN" else \
                        Lt @ _sin_columns(grids[j][gj:gj + 1], tau)[:, 0]
                    gain, _, resid = profile_gain(sin_cols, others, with_resid=True)
                    gk = int(np.argmax(gain))
                    if resid - gain[gk] < best_cost:
                        best_cost, best_pair = resid - gain[gk], (gj, gk)
                shapes[j] = float(grids[j][best_pair[0]])
                shapes[k] = float(sin_grid[best_pair[1]])
                set_shapes(shapes)
                best_along(shapes, k, True)
                best_along(shapes, j, True)
                shapes, c, coef = descend(shapes, refine=True)
                moved.append((c, model.canonical(
                    _theta_from_vp(model, shapes, coef, nu_hat, tau, drift_sign))))
        c, theta = min(moved, key=lambda item: item[0])
        if not any(np.allclose(theta, t, rtol=1e-3) for _, t, _ in kept):
            kept.append((c, theta, None))
    return [t for _, t, _ in kept], [c for c, _, _ in kept]


# -- main entry -----------------------------------------------------------------------------------
def _prepare(data, levels: int | None, freq: float | None,
             alpha: float) -> tuple[WaveletVariance, float, float]:
    """WV of the input (computed if a signal), the drift sign and the seconds spent."""
    if isinstance(data, WaveletVariance):
        wv = data if levels is None else data.subset(np.arange(1, levels + 1))
        return wv, 1.0, 0.0
    x = np.asarray(data, dtype=float)
    t0 = time.perf_counter()
    wv = wvar(x, levels=levels, alpha=alpha, freq=1.0 if freq is None else freq)
    seconds = time.perf_counter() - t0
    drift = (x[-1] - x[0]) / max(x.size - 1, 1)
    return wv, (1.0 if drift >= 0 else -1.0), seconds


def fit(data: np.ndarray | WaveletVariance, model: str | Model, *, levels: int | None = None,
        freq: float | None = None, weights: str | np.ndarray = "ci", method: str = "gmwm",
        n_starts: int = 4, seed: int = 0, reweight: int = 0, alpha: float = 0.05,
        max_nfev: int = 1000) -> GMWMResult:
    """Estimate ``model`` by GMWM (or ARMAV) from a signal or a precomputed wavelet variance.

    Parameters
    ----------
    data : 1-D signal (per-sample units) or a :class:`~gmwm.wv.WaveletVariance`.
    model : model string such as ``"WN+RW+AR1+SIN"`` or a :class:`~gmwm.model.Model`.
    levels : number of dyadic levels J (default: all of a given WV, or floor(log2 T) - 1).
    freq : sampling frequency [Hz] of a raw signal (GM parameters and scales in seconds use it).
    weights : ``"ci"`` (inverse squared CI width, default), ``"gaussian"`` (eta_j / (2 nu_j^2)),
        ``"identity"``, or a (J, J) covariance of ``nu_hat`` (e.g. from a bootstrap), whose
        inverse is used (efficient GMWM) and which also feeds the standard errors.
    method : ``"gmwm"`` (f(x) = x) or ``"armav"`` (f = log10 of the Allan variance).
    n_starts : number of distinct starting points refined by the optimiser.
    seed : seed of the randomised start placements (results are deterministic given it).
    reweight : extra passes re-weighting with the fitted model's WV (reduces the downward bias
        of variance parameters caused by data-dependent weights, SPEC 5.1).
    alpha : CI level of a WV computed here.
    max_nfev : evaluation budget per start.

    Returns
    -------
    GMWMResult with estimates in canonical component order.
    """
    if method not in _METHODS:
        raise InputError(f"unknown method {method!r}; use one of {', '.join(_METHODS)} "
                         "(the slope method is gmwm.avsm.fit_avsm)")
    # sampling frequency: explicit argument > a Model's own > the WV's > 1 Hz
    if freq is None and isinstance(model, Model):
        freq = model.freq
    if freq is None and isinstance(data, WaveletVariance):
        freq = data.freq
    wv, drift_sign, seconds_wv = _prepare(data, levels, freq, alpha)
    if freq is not None and wv.freq != freq:
        wv = dataclasses.replace(wv, freq=float(freq))
    model = as_model(model, wv.freq)
    if model.n_params > wv.n_levels:
        raise IdentifiabilityError(
            f"model {model.spec} has {model.n_params} parameters but only {wv.n_levels} wavelet "
            "scales are available; use a longer signal, more levels or a smaller model")
    if np.any(wv.variance <= 0):
        raise InputError("wavelet variance must be positive at every level (constant signal?)")
    t0 = time.perf_counter()

    rng = np.random.default_rng(seed)
    omega, V = weight_matrix(wv, weights, method)
    result = _fit_once(wv, model, omega, V, method, n_starts, rng, drift_sign, max_nfev)
    user_cov = not isinstance(weights, str)
    for _ in range(reweight if not user_cov else 0):
        omega, V = weight_matrix(wv, "gaussian", method, model_wv=result["nu"])
        result = _fit_once(wv, model, omega, V, method, n_starts, rng, drift_sign, max_nfev,
                           extra_starts=[result["theta"]])
    seconds_fit = time.perf_counter() - t0

    theta = result["theta"]
    prob = result["problem"]
    cov, se, cond = _sandwich(prob, theta, omega, V, method, wv.variance)
    # no standard error for a component at the boundary: the sandwich needs an interior optimum
    for c in model.components:
        if c.name in result["diagnostics"].get("at_boundary", []):
            se[c.slice] = np.nan
    warnings = list(result["warnings"])
    if not np.isfinite(cond) or cond > 1e12:
        warnings.append(f"Jacobian of the WV is near rank deficient (condition number {cond:.2g}); "
                        "some parameters are weakly identified")
    if isinstance(data, WaveletVariance) and model.count("DR"):
        warnings.append("drift sign is not identified from a WV; reported positive")
    settings = {"weights": weights if isinstance(weights, str) else "covariance",
                "method": method, "n_starts": n_starts, "reweight": reweight, "seed": seed,
                "levels": int(wv.n_levels), "max_nfev": max_nfev}
    diagnostics = dict(result["diagnostics"], warnings=warnings, condition_number=cond,
                       settings=settings)
    return GMWMResult(model=model, params=theta, se=se, cov=cov, objective=result["objective"],
                      weights=omega, converged=result["converged"], message=result["message"],
                      wv=wv, method=method, diagnostics=diagnostics, seconds_wv=seconds_wv,
                      seconds_fit=seconds_fit)


def _fit_once(wv: WaveletVariance, model: Model, omega: np.ndarray, V: np.ndarray, method: str,
              n_starts: int, rng: np.random.Generator, drift_sign: float, max_nfev: int,
              extra_starts: list[np.ndarray] | None = None) -> dict[str, Any]:
    tau = wv.scales.astype(float)
    chol = _cholesky(omega)
    nu_hat = wv.variance
    # Starts always come from the GMWM-form (linear) problem: for ARMAV it is a good start too.
    if method == "armav":
        gchol = _cholesky(weight_matrix(wv, "gaussian", "gmwm")[0])
    else:
        gchol = chol
    starts, vp_costs = _vp_starts(model, tau, nu_hat, gchol, n_starts, rng, drift_sign)
    # the projected cost is already the optimum over the linear parameters and the refinement
    # only polishes shapes: a start far above the best one never wins, so it is not refined
    best_vp = min(vp_costs)
    starts = [t for t, c in zip(starts, vp_costs, strict=True) if c <= best_vp + max(25.0, best_vp)]
    target = np.log10(nu_hat) if method == "armav" else nu_hat
    scale0 = np.linalg.norm(chol.T @ target) or 1.0
    prob = _Problem(model, tau, target, chol, method, scale0)
    warnings: list[str] = []

    if model.is_linear and method == "gmwm":
        # closed form (NNLS on the whitened system) is the exact minimiser: no iterations needed
        theta = starts[0]
        at_zero = [c.name for c in model.components
                   if _is_floor(theta[c.slice], c, nu_hat, tau)]
        if at_zero:
            warnings.append("closed form put " + ", ".join(at_zero) + " at the boundary 0 "
                            "(non-negative least squares); that component is not supported "
                            "by the data")
            for c in model.components:
                if c.name in at_zero:
                    theta[c.slice] = 0.0
        obj = prob.objective(theta)
        return {"theta": theta, "objective": obj, "converged": True,
                "message": "closed-form non-negative weighted least squares", "problem": prob,
                "nu": model.wv(theta, tau), "warnings": warnings,
                "diagnostics": {"n_starts": 1, "start_objectives": [obj], "closed_form": True,
                                "at_boundary": at_zero}}

    candidates = list(starts) + list(extra_starts or [])
    runs = []
    for theta0 in candidates:
        eta0 = model.to_free(theta0)
        lo, hi = _free_bounds(eta0)
        try:
            sol = least_squares(prob.free_residual, np.clip(eta0, lo + 1e-9, hi - 1e-9),
                                jac=prob.free_jac, method="trf", bounds=(lo, hi), x_scale="jac",
                                xtol=1e-10, ftol=1e-12, gtol=1e-10, max_nfev=max_nfev)
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as err:
            runs.append((np.inf, None, f"optimiser failed: {err}", False, []))
            continue
        raw = model.from_free(sol.x)
        obj = prob.objective(raw)
        ok = bool(sol.status > 0 and np.all(np.isfinite(raw)) and np.isfinite(obj))
        # edge of this run's own search box, judged before the canonical relabelling; a variance
        # drifting to the lower edge is the boundary 0 (warned below), not a failure
        raw_vanished = {k for k, v in model.component_wv(raw, tau).items()
                        if np.max(v / nu_hat) < 1e-6}
        edge = [n for n, e, a, b in zip(model.param_names, sol.x, lo, hi, strict=True)
                if min(e - a, b - e) < 1e-3
                and not (n.split(".")[0] in raw_vanished and e - a < 1e-3)]
        runs.append((obj if np.isfinite(obj) else np.inf, model.canonical(raw),
                     sol.message if ok else f"stopped: {sol.message}", ok, edge))
    objs = np.array([r[0] for r in runs])
    best = int(np.argmin(objs))
    obj, theta, msg, ok, edge = runs[best]
    converged = theta is not None and ok and np.isfinite(obj)
    if theta is None:
        theta = candidates[0]
        obj = prob.objective(theta)
    shares = {k: np.max(v / nu_hat) for k, v in model.component_wv(theta, tau).items()}
    vanished = [k for k, s in shares.items() if s < 1e-6]
    if edge:
        converged = False
        msg = "parameter(s) at the edge of the search region: " + ", ".join(edge)
    if vanished:
        warnings.append("component(s) " + ", ".join(vanished) + " contribute less than 1e-6 of "
                        "the WV at every scale (estimate at the boundary 0)")
    near = np.sort(objs[np.isfinite(objs)])
    gap = float(near[1] - near[0]) if near.size > 1 else None
    return {"theta": theta, "objective": obj, "converged": bool(converged), "message": str(msg),
            "problem": prob, "nu": model.wv(theta, tau), "warnings": warnings,
            "diagnostics": {"at_boundary": vanished, "n_starts": len(candidates),
                            "start_objectives": objs.tolist(), "vp_costs": vp_costs,
                            "closed_form": False, "second_best_gap": gap}}


def _free_bounds(eta0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Search box in free coordinates: +-40 (a factor e^40 ~ 2e17) around the start, which
    contains every sensible optimum and keeps wild trial steps finite."""
    return eta0 - 40.0, eta0 + 40.0


def _is_floor(p: np.ndarray, comp, nu_hat: np.ndarray, tau: np.ndarray) -> bool:
    """True if a linear component's start sits at the positivity floor (NNLS returned 0)."""
    col = comp.process.wv(np.ones(1), tau)
    floor = 1e-3 * np.min(nu_hat / col)
    value = p[0] ** 2 if comp.process.name == "DR" else p[0]
    return bool(value <= floor * (1 + 1e-9))


def _sandwich(prob: _Problem, theta: np.ndarray, omega: np.ndarray, V: np.ndarray, method: str,
              nu_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Finite-sample sandwich covariance of theta_hat (SPEC 5.5) and the condition number of
    the whitened Jacobian in the unconstrained coordinates."""
    A = prob.jac_theta(theta)
    Vf = V
    if method == "armav":
        F = np.diag(_LOG10E / nu_hat)
        Vf = F @ V @ F.T
    with np.errstate(all="ignore"):
        try:
            # scale the columns first: parameters live on scales from 1e-12 to 1, and an
            # unscaled pseudo-inverse would cut the small-scale directions to zero variance
            d = np.linalg.norm(prob.chol.T @ A, axis=0)
            d[~np.isfinite(d) | (d == 0)] = 1.0
            As = A / d
            Binv = np.linalg.pinv(As.T @ omega @ As, hermitian=True)
            G = (Binv @ As.T @ omega) / d[:, None]
            cov = G @ Vf @ G.T
        except np.linalg.LinAlgError:
            cov = np.full((theta.size, theta.size), np.nan)
        se = np.sqrt(np.clip(np.diag(cov), 0, None))
        eta = prob.model.to_free(np.where(theta == 0, np.nan, theta))
        Aeta = prob.chol.T @ A * prob.model.dtheta_deta(eta)
        cond = _condition(Aeta)
    return cov, se, cond


def _condition(A: np.ndarray) -> float:
    """2-norm condition number of A with unit-norm columns (inf if singular or non-finite)."""
    norms = np.linalg.norm(A, axis=0)
    if not np.all(np.isfinite(A)) or np.any(norms == 0):
        return np.inf
    try:
        sv = np.linalg.svd(A / norms, compute_uv=False)
    except np.linalg.LinAlgError:
        return np.inf
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
