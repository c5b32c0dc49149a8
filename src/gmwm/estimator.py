"""GMWM (and ARMAV) estimation of composite error models from a signal or its wavelet variance.

The objective, weights, Jacobian, bounded solve and sandwich live in :mod:`gmwm.inference`; this
module finds the optimum and reports it.

How the optimum is found (no user starting values):

1. Variable projection (VP). Every process's WV is linear in one "scale" parameter (sigma2, Q2,
   gamma2, omega^2, the AR1 innovation variance, the GM variance, alpha^2) once its "shape"
   (AR1 phi, GM beta, SIN beta) is fixed. For fixed shapes the best non-negative scale
   parameters solve a small non-negative least-squares problem (NNLS) on the whitened system;
   for models made only of QN, WN, RW and DR that *is* the closed-form GMWM of paper 004.
2. Shapes are searched in coordinates where a uniform grid is natural: AR1 ``xi = 2 atanh(phi)``
   over the whole domain phi in (-1, 1) (log-spaced towards both ends), GM ``log(beta / freq)``,
   SIN ``log(beta)``. A greedy placement and ``n_init`` seeded random placements are each
   improved by coordinate descent, every coordinate profiled over its whole grid in one
   vectorised projection (SIN: smooth envelope, then a phase-resolving fine scan), then a 1-D
   bounded refinement. Joint (SIN, other) pair scans find a SIN bump hidden under another
   component.
3. Nested models. The fit of a model includes the fits of its submodels obtained by dropping one
   component (recursively, memoised): each submodel's optimum, with the dropped component added
   at its best VP shape, is a further start, and the submodel's optimum with that component at
   exactly zero is a candidate. A submodel that drops a linear component (QN, WN, RW, DR) is
   searched with shaped drops only below it (its other linear components are left to the NNLS,
   which can set each of them to zero at every shape). So a model with L linear components and
   a lattice of S shaped submodels searches about S (1 + L) nodes instead of S 2^L (the
   8-parameter QN+WN+2*GM+RW+DR: 15 instead of 47). A model never ends above a submodel that
   drops shaped components (the same search, nested) nor above its direct submodels as searched
   inside it; that it never ends above a submodel fitted alone is measured
   (``benchmarks/hard_cases.py --submodels``). The linear-drop submodels are kept: without them
   the search misses the optimum on real-data WVs where a fast GM stands in for the white noise
   (``benchmarks/hard_cases_boot.json``).
4. Refinement: Levenberg-Marquardt (bounded trust region where it leaves the box) in free
   coordinates (logs, scaled logit for phi, pi*logistic for SIN beta) with the analytic Jacobian
   from the best distinct starts; the best objective wins.

Standard errors use the sandwich of SPEC 5.5 with ``V`` the covariance of the WV estimate under
the fitted model (between-scale correlation included, SIN only through its cross term with the
noise; :func:`gmwm.inference.model_wv_cov`), or the caller's covariance. ``weights="efficient"``
is the two-step efficient GMWM: a first fit with CI weights, then ``Omega = V(theta_1)^-1``.
"""

from __future__ import annotations

import dataclasses
import time
import zlib
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import numpy as np
from scipy.optimize import least_squares, nnls
from scipy.special import ndtri

from .errors import IdentifiabilityError, InputError
from .inference import METHODS, Problem, Whitener, check_cov, omega_from_cov, weight_matrix, wv_cov
from .model import Model, as_model, spec_of
from .processes import PROCESSES, ar1_unit_wv_many, sin_unit_wv
from .wv import WaveletVariance, wvar


def _nnls_core() -> Any:
    """SciPy's Lawson-Hanson kernel without the public wrapper's input checks (a third of a
    small call's time; the VP search makes thousands), if this SciPy has the private kernel
    with the expected signature; else None (the public ``nnls`` is used)."""
    try:
        from scipy.optimize._slsqplib import nnls as core
        x, _, info = core(np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]),
                          np.array([1.0, -1.0, 0.0]), 6)
        return core if info == 1 and abs(x[0] - 0.5) < 1e-12 and x[1] == 0.0 else None
    except Exception:  # noqa: BLE001 - any failure means: use the public function
        return None


_NNLS = _nnls_core()


def _nnls(A: np.ndarray, b: np.ndarray, maxiter: int) -> tuple[np.ndarray, float]:
    """``scipy.optimize.nnls`` on finite C-contiguous float64 input."""
    if _NNLS is None:
        return nnls(A, b, maxiter=maxiter)
    x, rnorm, info = _NNLS(A, b, maxiter)
    if info == 3:
        raise RuntimeError("Maximum number of iterations reached.")
    return x, rnorm

__all__ = ["GMWMResult", "fit", "weight_matrix"]

#: A component whose WV share is below this at every scale is "at the boundary 0".
VANISH_SHARE = 1e-6
#: Evaluation budget of each exploratory solve (the winner continues to max_nfev).
EXPLORE_NFEV = 60
#: default number of starts of :func:`fit`
N_STARTS = 4
#: Condition number of the whitened free-coordinate Jacobian above which a fit is flagged.
COND_WARN = 1e8
#: a SIN whose period exceeds this many times the longest scale has a drift's WV (within 2 % at
#: that scale: (sin x / x)**4 with x = beta * tau / 4 <= pi / 20)
SLOW_SIN_PERIODS = 10.0


# -- result ---------------------------------------------------------------------------------------
@dataclass
class GMWMResult:
    """Outcome of :func:`fit`. ``params``/``se`` follow ``param_names`` (canonical order).

    ``weights`` is the weight matrix Omega the objective used, ``wv_cov`` the covariance V of
    the WV estimate behind ``cov``/``se``, and ``settings`` every option needed to repeat the
    fit (``weights`` kind, method, starts, seed, levels, reweighting; the user covariance, if
    one was given, is ``settings["weights_cov"]``)."""

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
    wv_cov: np.ndarray | None = None
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def param_names(self) -> list[str]:
        return self.model.param_names

    @property
    def warnings(self) -> list[str]:
        return list(self.diagnostics.get("warnings", []))

    def as_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.params)

    def se_dict(self) -> dict[str, float]:
        return self.model.as_dict(self.se)

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """Wald intervals ``params -/+ z se`` (asymptotic; see :mod:`gmwm.bootstrap` for better)."""
        z = ndtri(1 - alpha / 2)
        return np.column_stack([self.params - z * self.se, self.params + z * self.se])

    def datasheet(self, units: str | None = None, alpha: float = 0.05) -> dict[str, Any]:
        """Continuous datasheet coefficients (ARW/VRW, RRW, QN, RR, GM, SIN) in ``units``
        (see :func:`gmwm.units.datasheet`)."""
        from .units import datasheet

        return datasheet(self, units, alpha)

    def problem(self) -> Problem:
        """The objective this result minimised (:class:`gmwm.inference.Problem`)."""
        return Problem.of(self)

    def fit_kwargs(self) -> dict[str, Any]:
        """Keyword arguments of :func:`fit` that repeat this fit on another WV (bootstrap)."""
        s = self.settings
        w = s.get("weights", "ci")
        kw = {"weights": s["weights_cov"] if w == "covariance" else w,
              "method": self.method, "n_starts": s.get("n_starts", 4),
              "reweight": s.get("reweight", 0), "max_nfev": s.get("max_nfev", 1000),
              "se_cov": s.get("se_cov", "model"), "nested": s.get("nested", True)}
        return kw

    def model_wv(self, scales: np.ndarray | None = None) -> np.ndarray:
        return self.model.wv(self.params, self.wv.scales if scales is None else scales)

    def component_wv(self, scales: np.ndarray | None = None) -> dict[str, np.ndarray]:
        return self.model.component_wv(self.params, self.wv.scales if scales is None else scales)

    def summary(self) -> str:
        """Plain-text table of estimates, standard errors and fit diagnostics."""
        lines = [(f"GMWM fit ({self.method}, {self.settings.get('weights', '?')} weights) of "
                  f"{self.model.spec}  |  T = {self.wv.n_samples}, J = {self.wv.n_levels}, "
                  f"freq = {self.wv.freq:g} Hz"),
                 f"objective = {self.objective:.6g}   converged = {self.converged}"
                 + ("" if self.converged else f"   ({self.message})"),
                 f"{'parameter':<16}{'estimate':>14}{'std. error':>14}",
                 "-" * 44]
        for name, est, se in zip(self.param_names, self.params, self.se, strict=True):
            lines.append(f"{name:<16}{est:>14.6g}{se:>14.4g}")
        for w in self.warnings:
            lines.append(f"warning: {w}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self) -> dict[str, Any]:
        """JSON-able summary (model, n, params, se, objective, converged, warnings, WV, timings)."""
        settings = {k: v for k, v in self.settings.items() if k != "weights_cov"}
        return {
            "model": self.model.spec,
            "method": self.method,
            "n": int(self.wv.n_samples),
            "freq": self.wv.freq,
            "params": self.as_dict(),
            "se": {k: (None if not np.isfinite(v) else v) for k, v in self.se_dict().items()},
            "objective": float(self.objective),
            "converged": bool(self.converged),
            "message": self.message,
            "warnings": self.warnings,
            "settings": settings,
            "condition_number": _finite_or_none(self.diagnostics.get("condition_number")),
            "wv": self.wv.to_dict(),
            "seconds_wv": self.seconds_wv,
            "seconds_fit": self.seconds_fit,
        }

    def plot(self, ax=None, **kwargs):
        """Log-log WV with CI band, fitted model and its components (see gmwm.plots.plot_wv)."""
        from .plots import plot_wv

        return plot_wv(self.wv, result=self, ax=ax, **kwargs)


def _finite_or_none(x: Any) -> float | None:
    return float(x) if x is not None and np.isfinite(x) else None


# -- shape coordinates of the variable projection -------------------------------------------------
# AR1: xi = 2 atanh(phi) (phi in (-1, 1)); GM: log a, a = beta / freq (phi = e^-a in (0, 1));
# SIN: log beta. In these coordinates a uniform grid resolves both ends of each domain.
_XI_NEG = -np.log(2 / 2e-6)   # phi = -1 + 2e-6


def _shape_bounds(name: str, tau: np.ndarray) -> tuple[float, float] | None:
    if name == "AR1":  # up to a correlation time ~5x the longest scale
        return _XI_NEG, float(np.log(2 * 5 * tau[-1]))
    if name == "GM":
        return float(np.log(0.2 / tau[-1])), float(np.log(7.0))
    if name == "SIN":
        return float(np.log(1.0 / tau[-1])), float(np.log(0.999 * np.pi))
    return None


def _grid(name: str, tau: np.ndarray, step: float) -> np.ndarray | None:
    b = _shape_bounds(name, tau)
    if b is None:
        return None
    return np.linspace(b[0], b[1], max(int(np.ceil((b[1] - b[0]) / step)) + 1, 8))


def _unit_columns(name: str, u: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Unit-scale WV columns (J, G) at shape coordinates u (G,)."""
    u = np.atleast_1d(np.asarray(u, dtype=float))
    if name == "AR1":
        return ar1_unit_wv_many(np.tanh(u / 2), tau).T
    if name == "GM":
        a = np.exp(u)
        return (-np.expm1(-2 * a)[:, None] * ar1_unit_wv_many(np.exp(-a), tau)).T
    if name == "SIN":
        return sin_unit_wv(np.exp(u)[None, :], tau[:, None])
    col = PROCESSES[name].wv(np.ones(1), tau)
    return np.repeat(col[:, None], u.size, axis=1)


def _sin_envelope_columns(u: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """Smooth stand-in for the SIN WV used to locate the bump on a coarse grid: past the first
    peak, sin^4(beta tau / 4) is replaced by its mean 3/8, removing the oscillation in beta
    that makes a coarse grid land on arbitrary phases."""
    b = np.exp(np.asarray(u))[None, :]
    t = tau[:, None]
    x = b * t / 4
    s2 = np.sin(np.minimum(x, 1.1656))
    s2 *= s2
    s4 = np.where(x < 1.1656, s2 * s2, 0.375)
    d = np.sin(b / 2)
    return 2 * s4 / (t**2 * (d * d))


@lru_cache(maxsize=128)
def _grid_columns(name: str, tau: tuple[float, ...], step: float) -> tuple[np.ndarray, np.ndarray]:
    """Shape grid and its unit-scale columns (SIN: smooth envelope); cached per scale set."""
    t = np.asarray(tau)
    grid = _grid(name, t, step)
    cols = _sin_envelope_columns(grid, t) if name == "SIN" else _unit_columns(name, grid, t)
    grid.setflags(write=False)
    cols.setflags(write=False)
    return grid, cols


def _theta_from_vp(model: Model, shapes: list[float], coef: np.ndarray, drift_sign: float,
                   floor: np.ndarray | None = None) -> np.ndarray:
    """Shape coordinates + NNLS scale coefficients -> parameter vector. Zero coefficients are
    lifted to ``floor`` (if given) so that free coordinates are defined."""
    theta = np.empty(model.n_params)
    for k, (c, u) in enumerate(zip(model.components, shapes, strict=True)):
        s = coef[k] if floor is None else max(coef[k], floor[k])
        name = c.process.name
        if name in ("WN", "QN", "RW"):
            theta[c.slice] = [s]
        elif name == "DR":
            theta[c.slice] = [drift_sign * np.sqrt(s)]
        elif name == "AR1":
            theta[c.slice] = [np.tanh(u / 2), s]
        elif name == "GM":
            theta[c.slice] = [np.exp(u) * model.freq, s]
        else:  # SIN
            theta[c.slice] = [np.sqrt(s), np.exp(u)]
    return theta


def _shapes_of(model: Model, theta: np.ndarray, tau: np.ndarray) -> list[float]:
    """Shape coordinates of a parameter vector (0 for components without a shape)."""
    out = []
    for c in model.components:
        p = theta[c.slice]
        name = c.process.name
        lo, hi = _shape_bounds(name, tau) or (0.0, 0.0)
        if name == "AR1":
            u = 2 * np.arctanh(np.clip(p[0], -1 + 1e-15, 1 - 1e-15))
        elif name == "GM":
            u = np.log(max(p[0] / model.freq, 1e-300))
        elif name == "SIN":
            u = np.log(max(p[1], 1e-300))
        else:
            u = 0.0
        out.append(float(np.clip(u, lo, hi)))
    return out


class _VP:
    """Variable-projection search over the shapes of one model on one whitened WV."""

    STEP = 0.45          # grid spacing in shape coordinates
    N_INIT = 4           # random placements besides the greedy one

    def __init__(self, model: Model, tau: np.ndarray, nu_hat: np.ndarray, white: Whitener,
                 drift_sign: float, rng: np.random.Generator,
                 col_cache: dict[tuple[Any, ...], np.ndarray] | None = None):
        self.model, self.tau, self.nu_hat = model, tau, nu_hat
        self.white, self.drift_sign, self.rng = white, drift_sign, rng
        self.names = [c.process.name for c in model.components]
        key = tuple(float(t) for t in tau)
        self.grids: list[np.ndarray | None] = []
        self.gcols: list[np.ndarray | None] = []
        self.rawcols: list[np.ndarray | None] = []  # unwhitened (SIN: the smooth envelope)
        for n in self.names:
            if _shape_bounds(n, tau) is None:
                self.grids.append(None)
                self.gcols.append(None)
                self.rawcols.append(None)
            else:
                g, c = _grid_columns(n, key, self.STEP)
                self.grids.append(g)
                self.gcols.append(white @ c)
                self.rawcols.append(c)
        self.shaped = [k for k, g in enumerate(self.grids) if g is not None]
        self.yw = white @ nu_hat
        self.ncomp = len(self.names)
        # whitened unit columns by (process, shape); shared by the nodes of one nested search
        self._cols = {} if col_cache is None else col_cache
        self.cols = np.column_stack([self.col(k, 0.0) for k in range(self.ncomp)])

    def col(self, k: int, u: float) -> np.ndarray:
        key = (self.names[k], float(u))
        c = self._cols.get(key)
        if c is None:
            c = self.white @ _unit_columns(self.names[k], np.array([u]), self.tau)[:, 0]
            self._cols[key] = c
        return c

    def prefetch(self, k: int, values: np.ndarray) -> None:
        """Whitened columns of component k at several shapes, computed in one call."""
        name = self.names[k]
        new = [float(v) for v in values if (name, float(v)) not in self._cols]
        if len(new) > 1:
            cols = self.white @ _unit_columns(name, np.array(new), self.tau)
            for i, v in enumerate(new):
                self._cols[(name, v)] = cols[:, i]

    def floors(self, shapes: list[float]) -> np.ndarray:
        out = np.empty(self.ncomp)
        for k in range(self.ncomp):
            c = _unit_columns(self.names[k], np.array([shapes[k]]), self.tau)[:, 0]
            with np.errstate(divide="ignore"):
                out[k] = 1e-3 * np.min(self.nu_hat / np.where(c > 0, c, np.inf))
        return out

    def cost(self, active: list[int] | None = None) -> tuple[float, np.ndarray]:
        keep = list(range(self.ncomp)) if active is None else active
        X = self.cols[:, keep]
        norm_ = np.sqrt((X * X).sum(axis=0))  # = np.linalg.norm(X, axis=0), without its wrapper
        norm_[norm_ == 0] = 1.0
        coef, rnorm = _nnls(X / norm_, self.yw, 50 * X.shape[1])
        full = np.zeros(self.ncomp)
        full[keep] = coef / norm_
        return rnorm**2, full

    def residual(self, others: list[int]) -> tuple[np.ndarray | None, np.ndarray]:
        """Orthonormal basis Q of the ``others`` columns (None if empty) and the whitened WV
        with their span projected out."""
        if not others:
            return None, self.yw
        Q, _ = np.linalg.qr(self.cols[:, others])
        return Q, self.yw - Q @ (Q.T @ self.yw)

    def profile_gain(self, G: np.ndarray, others: list[int],
                     proj: tuple[np.ndarray | None, np.ndarray] | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Drop in LS cost from adding each column of G to the others (Frisch-Waugh); only
        columns entering with a positive coefficient count. ``proj``: ``residual(others)``,
        when the caller scans several grids against the same others."""
        Q, y = self.residual(others) if proj is None else proj
        if Q is not None:
            G = G - Q @ (Q.T @ G)
        num = G.T @ y
        den = np.einsum("jg,jg->g", G, G)
        with np.errstate(divide="ignore", invalid="ignore"):
            ok = (num > 0) & (den > 0)
            return np.where(ok, num**2 / den, 0.0), np.where(ok, num / den, 0.0)

    def best_along(self, shapes: list[float], k: int, refine: bool,
                   active: list[int] | None = None) -> None:
        """Move shape k to its best value given the others (grid scan, then 1-D refinement)."""
        grid, G = self.grids[k], self.gcols[k]
        others = [i for i in (range(self.ncomp) if active is None else active) if i != k]
        proj = self.residual(others)
        gain, coef = self.profile_gain(G, others, proj)
        top = np.argsort(-gain)[:3]
        values, step = grid[top], self.STEP
        if self.names[k] == "SIN" and refine:
            # the SIN WV oscillates in beta at long scales (nulls at beta tau / 4 = k pi): its
            # basins are ~1/(beta tau_J) wide, so scan finely around the best coarse points
            # (0.5 rad of phase per step at the longest scale where the SIN still reaches 1 %)
            fine, fcols = [], []
            for i in top:
                lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
                share = coef[i] * self.rawcols[k][:, i] / self.nu_hat
                tau_eff = self.tau[share >= 0.01].max(initial=self.tau[0])
                n = int(np.clip(np.exp(hi) * tau_eff * (hi - lo) / 2, 16, 3000))
                fine.append(np.linspace(lo, hi, n))
                # the same (grid point, length) recurs through a search: whitened columns cached
                fkey = ("SIN-fine", int(i), n)
                if fkey not in self._cols:
                    self._cols[fkey] = self.white @ _unit_columns("SIN", fine[-1], self.tau)
                fcols.append(self._cols[fkey])
            fv = np.concatenate(fine)
            gain_f, _ = self.profile_gain(np.concatenate(fcols, axis=1), others, proj)
            values = fv[np.argsort(-gain_f)[:3]]
            step = float(fine[0][1] - fine[0][0])
        if refine:
            # a local scan of 17 points over +-1 step around each candidate, profiled in one
            # projection, with a parabolic vertex; the final trust-region solve polishes it
            lo_b, hi_b = grid[0], grid[-1]
            local = np.clip((values[:, None] + step * np.linspace(-1, 1, 17)[None, :]).ravel(),
                            lo_b, hi_b)
            g_loc, _ = self.profile_gain(self.white @ _unit_columns(self.names[k], local,
                                                                     self.tau), others, proj)
            g_loc = g_loc.reshape(values.size, 17)
            refined = []
            for row, v in zip(g_loc, values, strict=True):
                i = int(np.argmax(row))
                u = v + step * (i / 8 - 1)
                if 0 < i < 16:
                    den = row[i - 1] - 2 * row[i] + row[i + 1]
                    if den < 0:
                        u += step / 8 * 0.5 * (row[i - 1] - row[i + 1]) / den
                refined.append(float(np.clip(u, lo_b, hi_b)))
            values = np.concatenate([values, refined])
        self.prefetch(k, values)
        exact = []
        for v in values:
            self.cols[:, k] = self.col(k, v)
            exact.append(self.cost(active)[0])
        best = float(values[int(np.argmin(exact))])
        shapes[k] = best
        self.cols[:, k] = self.col(k, best)

    def set_shapes(self, shapes: list[float]) -> None:
        for k in self.shaped:
            self.cols[:, k] = self.col(k, shapes[k])

    def move(self, shapes: list[float], k: int, refine: bool, dirty: set[int]) -> None:
        """Move shape k to its best value given the others. A move depends only on the other
        shapes (``best_along`` does not look at shape k itself), so k is clean afterwards and
        stays so until another shape changes: a change marks the others dirty."""
        old = shapes[k]
        self.best_along(shapes, k, refine)
        dirty.discard(k)
        if shapes[k] != old:
            dirty.update(j for j in self.shaped if j != k)

    def sweep(self, shapes: list[float], refine: bool, dirty: set[int]) -> None:
        """One coordinate-descent round over the dirty shaped components."""
        for k in self.shaped:
            if k in dirty:
                self.move(shapes, k, refine, dirty)

    def descend(self, shapes: list[float], refine: bool, first: tuple[int, ...] = ()
                ) -> tuple[list[float], float, np.ndarray]:
        """Coordinate descent from ``shapes`` (components ``first`` moved first, in that order)."""
        self.set_shapes(shapes)
        dirty = set(self.shaped)
        for k in first:
            self.move(shapes, k, refine, dirty)
        best = self.cost()
        for _ in range(4 if refine else 3):
            previous = best[0]
            self.sweep(shapes, refine, dirty)
            best = self.cost()
            if not dirty or best[0] >= previous * (1 - 1e-6):
                break
        return shapes, best[0], best[1]

    def polish(self, shapes: list[float]) -> tuple[list[float], float, np.ndarray]:
        """Minimise the projected cost over the shapes alone (NNLS for the scales inside).
        Where two components trade variance (an AR1 with phi ~ 0 against the WN, two AR1 of
        close phi) the full-parameter solve crawls along a curved valley; over the shapes
        the same valley is a smooth low-dimensional problem."""
        idx = self.shaped
        lo = np.array([self.grids[k][0] for k in idx])
        hi = np.array([self.grids[k][-1] for k in idx])

        def resid(u: np.ndarray) -> np.ndarray:
            for k, uk in zip(idx, u, strict=True):
                self.cols[:, k] = self.col(k, uk)
            return self.yw - self.cols @ self.cost()[1]

        x0 = np.clip([shapes[k] for k in idx], lo + 1e-9, hi - 1e-9)
        try:
            with np.errstate(all="ignore"):
                sol = least_squares(resid, x0, bounds=(lo, hi), method="trf", diff_step=1e-6,
                                    xtol=1e-12, ftol=1e-14, gtol=1e-12, max_nfev=200)
            x = sol.x
        except (ValueError, np.linalg.LinAlgError):
            x = x0
        out = list(shapes)
        for k, uk in zip(idx, x, strict=True):
            out[k] = float(uk)
        self.set_shapes(out)
        c, coef = self.cost()
        return out, c, coef

    def theta(self, shapes: list[float], coef: np.ndarray) -> np.ndarray:
        return self.model.canonical(_theta_from_vp(self.model, shapes, coef, self.drift_sign,
                                                   self.floors(shapes)))

    def starts(self, n_starts: int, n_random: int | None = None, pairs: bool = True
               ) -> list[tuple[float, np.ndarray]]:
        """Distinct good starts (VP cost, theta), best first."""
        found: list[tuple[float, np.ndarray]] = []

        def add(c: float, th: np.ndarray) -> None:
            if not any(np.allclose(th, t, rtol=1e-3) for _, t in found):
                found.append((c, th))

        if not self.shaped:
            c, coef = self.cost()
            return [(c, self.theta([0.0] * self.ncomp, coef))]
        # greedy: add shaped components one at a time at their best place, then refine all
        shapes = [0.0] * self.ncomp
        active = [k for k in range(self.ncomp) if k not in self.shaped]
        for k in self.shaped:
            active.append(k)
            self.best_along(shapes, k, True, sorted(active))
        shapes, c, coef = self.descend(shapes, refine=True)
        add(c, self.theta(shapes, coef))
        if len(self.shaped) == 1:
            # one shape: the profile over its whole grid was already exhaustive
            return found
        # random placements: cheap coarse descents, the best few refined
        coarse = []
        for _ in range(max(self.N_INIT, n_starts) if n_random is None else n_random):
            sh = [0.0] * self.ncomp
            for k in self.shaped:
                sh[k] = float(self.rng.choice(self.grids[k]))
            sh, c, coef = self.descend(sh, refine=False)
            coarse.append((c, list(sh)))
        coarse.sort(key=lambda x: x[0])
        for c, sh in coarse[:2]:
            sh, c, coef = self.descend(list(sh), refine=True)
            add(c, self.theta(sh, coef))
        if pairs:
            self.pair_moves(found[0][1] if found else None, add)
        found.sort(key=lambda x: x[0])
        return found

    def pair_moves(self, theta_best: np.ndarray | None, add) -> None:
        """A SIN bump hidden under another component (e.g. a slow SIN under a slow AR1) is
        invisible to one-at-a-time moves: scan (SIN shape, other shape) jointly."""
        sins = [k for k in self.shaped if self.names[k] == "SIN"]
        if not sins or len(self.shaped) < 2 or theta_best is None:
            return
        base = _shapes_of(self.model, theta_best, self.tau)
        sg = self.grids[sins[0]]
        sin_grid = np.linspace(sg[0], sg[-1], 4 * sg.size)
        sin_cols = self.white @ _unit_columns("SIN", sin_grid, self.tau)
        moved = []
        for k in sins:
            for j in self.shaped:
                if j == k:
                    continue
                shapes = list(base)
                self.set_shapes(shapes)
                fixed = [i for i in range(self.ncomp) if i not in (j, k)]
                best_pair = self.pair_scan(fixed, j, sin_cols)
                shapes[j] = float(self.grids[j][best_pair[0]])
                shapes[k] = float(sin_grid[best_pair[1]])
                shapes, c, coef = self.descend(shapes, refine=True, first=(k, j))
                moved.append((c, self.theta(shapes, coef)))
        c, th = min(moved, key=lambda x: x[0])
        add(c, th)

    def hop_sins(self, theta: np.ndarray) -> tuple[float, np.ndarray] | None:
        """A SIN's WV oscillates in beta, so a solve ends in whichever of its narrow basins it
        started in: rescan each SIN's beta finely with the other shapes at ``theta``'s. Returns
        (VP cost, theta) of the best placement, or None if no SIN moved."""
        sins = [k for k in self.shaped if self.names[k] == "SIN"]
        if not sins:
            return None
        shapes = _shapes_of(self.model, theta, self.tau)
        self.set_shapes(shapes)
        before = list(shapes)
        for k in sins:
            self.best_along(shapes, k, True)
        if shapes == before:
            return None
        c, coef = self.cost()
        return c, self.theta(shapes, coef)

    def pair_scan(self, fixed: list[int], j: int, S: np.ndarray) -> tuple[int, int]:
        """(grid index of component j, column of S) with the least LS cost of the whitened WV
        on the ``fixed`` columns, j's grid column and one column of S, a positive coefficient
        on the S column. All pairs at once: the fixed span is projected out once, and each
        j column enters as a rank-one update (Frisch-Waugh)."""
        Q, y = self.residual(fixed)
        G = self.gcols[j] if self.names[j] != "SIN" else self.white @ _unit_columns(
            "SIN", self.grids[j], self.tau)
        if Q is not None:
            G = G - Q @ (Q.T @ G)
            S = S - Q @ (Q.T @ S)
        nrm = np.linalg.norm(G, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            q = G / nrm
            a = q.T @ y                       # (Gj,)
            B = q.T @ S                       # (Gj, Gs)
            num = (S.T @ y)[None, :] - a[:, None] * B
            den = np.einsum("js,js->s", S, S)[None, :] - B**2
            gain = np.where((num > 0) & (den > 0), num**2 / den, 0.0)
            cost = (y @ y - a**2)[:, None] - gain
        cost[~np.isfinite(cost) | (nrm == 0)[:, None]] = np.inf
        gj, gk = np.unravel_index(int(np.argmin(cost)), cost.shape)
        return int(gj), int(gk)

    def extend(self, theta_sub: np.ndarray, k_new: int) -> tuple[float, np.ndarray]:
        """Start from a submodel optimum (shapes of ``theta_sub``, embedded in this model, with
        component ``k_new`` off) and place component k_new at its best shape."""
        shapes = _shapes_of(self.model, theta_sub, self.tau)
        self.set_shapes(shapes)
        dirty = set(self.shaped)
        if k_new in self.shaped:
            self.move(shapes, k_new, True, dirty)
        c, coef = self.cost()
        for _ in range(2):  # a short descent: the submodel's shapes are already optimal
            previous = c
            self.sweep(shapes, True, dirty)
            c, coef = self.cost()
            if not dirty or c >= previous * (1 - 1e-6):
                break
        return c, self.theta(shapes, coef)


# -- nested submodels ---------------------------------------------------------------------------
def _drop_one(model: Model) -> list[tuple[Model, int]]:
    """Distinct submodels with one component fewer, with the index of a dropped component."""
    out: dict[str, tuple[Model, int]] = {}
    for k, c in enumerate(model.components):
        counts: dict[str, int] = {}
        for cc in model.components:
            counts[cc.process.name] = counts.get(cc.process.name, 0) + 1
        counts[c.process.name] -= 1
        spec = spec_of(counts)
        if spec and spec not in out:
            out[spec] = (Model(spec, model.freq), k)
    return list(out.values())


def _embed(model: Model, sub: Model, theta_sub: np.ndarray, k_drop: int,
           tau: np.ndarray) -> np.ndarray:
    """Parameters of ``model`` equal to the submodel's, with component ``k_drop`` at zero
    (scale 0; its shape at the middle of its range)."""
    theta = np.zeros(model.n_params)
    used = {c.name: False for c in sub.components}
    for k, c in enumerate(model.components):
        if k == k_drop:
            if c.process.name == "AR1":
                theta[c.slice] = [0.5, 0.0]
            elif c.process.name == "GM":
                theta[c.slice] = [model.freq * 0.1, 0.0]
            elif c.process.name == "SIN":
                theta[c.slice] = [0.0, 1.0]
            continue
        sc = next(s for s in sub.components
                  if s.process.name == c.process.name and not used[s.name])
        used[sc.name] = True
        theta[c.slice] = theta_sub[sc.slice]
    return theta


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


@dataclass
class _Node:
    theta: np.ndarray
    objective: float
    converged: bool
    message: str
    edge: list[str]
    n_refined: int
    from_submodel: str | None = None


def _node_seed(seed: int, spec: str) -> np.random.Generator:
    """Per-model stream: a submodel's search is identical whether fitted alone or nested."""
    return np.random.default_rng([int(seed), zlib.crc32(spec.encode())])


def _node_key(spec: str, mode: str) -> str:
    return spec + "|shaped" if mode == "shaped" else spec


def _search(problem: Problem, model: Model, n_starts: int, seed: int, drift_sign: float,
            max_nfev: int, mode: str, cache: dict[str, _Node],
            extra_starts: list[np.ndarray] | None = None) -> _Node:
    """Global search for ``model`` on ``problem``'s objective (memoised per model spec and mode).

    ``mode``: ``"off"`` (no submodels), ``"full"`` (every drop-one submodel: those dropping a
    shaped component in mode full, those dropping a linear one in mode shaped) or ``"shaped"``
    (only the submodels dropping a shaped component, in mode shaped)."""
    key = _node_key(model.spec, mode)
    nested = mode != "off"
    if key in cache and not extra_starts:
        return cache[key]  # type: ignore[return-value]
    prob = problem if problem.model == model else Problem(model, problem.wv, problem.omega,
                                                         problem.method)
    tau, nu_hat = prob.tau, prob.nu_hat
    # starts always come from the GMWM-form (linear) problem; for ARMAV too
    if prob.method == "armav":
        gw = Whitener(weight_matrix(prob.wv, "gaussian", "gmwm"))
    else:
        gw = prob.white
    vp = _VP(model, tau, nu_hat, gw, drift_sign, _node_seed(seed, model.spec),
             cache.setdefault("__columns__", {}))  # type: ignore[arg-type]

    if model.is_linear and prob.method == "gmwm":
        # closed form: NNLS on the whitened system is the exact minimiser
        c, coef = vp.cost()
        theta = _theta_from_vp(model, [0.0] * vp.ncomp, coef, drift_sign)
        node = _Node(theta, prob.objective(theta), True,
                     "closed-form non-negative weighted least squares", [], 0)
        cache[key] = node
        return node

    # nested: the submodels' optima, extended, are the diverse starts that random placements
    # provide otherwise; random placements only beyond the default number of starts
    n_random = max(n_starts - N_STARTS, 0) if nested and len(model.components) > 1 else None
    pool = list(vp.starts(n_starts, n_random, pairs=mode != "shaped"))
    subs: list[tuple[str, str, np.ndarray]] = []
    if nested and len(model.components) > 1:
        for sub, k in _drop_one(model):
            linear_drop = model.components[k].process.linear
            if mode == "shaped" and linear_drop:
                continue
            child = "shaped" if linear_drop else mode
            node = _search(problem, sub, n_starts, seed, drift_sign, max_nfev, child, cache)
            emb = _embed(model, sub, node.theta, k, tau)
            subs.append((_node_key(sub.spec, child), sub.spec, emb))
            pool.append(vp.extend(emb, k))
    pool.sort(key=lambda item: item[0])
    # the projected (VP) cost is already optimal over the linear parameters and close to a local
    # optimum in the shapes; the trust-region solve polishes. Refined: the best start and any
    # other distinct one within 10 % of it, at most n_starts (+ extra starts given)
    cand: list[np.ndarray] = []
    best_vp = pool[0][0]
    for c, th in pool:
        if len(cand) >= n_starts or (cand and c > 1.1 * best_vp + 1e-12):
            break
        if not any(np.allclose(th, t, rtol=1e-3) for t in cand):
            cand.append(th)
    cand += list(extra_starts or [])
    runs: list[tuple[float, np.ndarray, str, bool, list[str], str | None]] = []
    # explore with a small evaluation budget (ill-conditioned valleys make the trust region
    # crawl); the winner, if it was stopped by the budget, continues with the full one
    budget = min(max_nfev, EXPLORE_NFEV)
    sols = [prob.solve(theta0, max_nfev=budget) for theta0 in cand]
    if prob.method == "gmwm" and vp.shaped:
        # a solve stopped by the budget is crawling along a valley: polish its shapes in the
        # projected problem (the valley is straightened there), then solve again from there
        for i, sol in enumerate(sols):
            if sol.capped:
                sh, _, coef = vp.polish(_shapes_of(model, sol.theta, tau))
                again = prob.solve(vp.theta(sh, coef), max_nfev=budget)
                if again.objective < sol.objective:
                    sols[i] = again
    if sols:
        i = int(np.argmin([s_.objective for s_ in sols]))
        if sols[i].capped and max_nfev > budget:
            sols[i] = prob.solve(sols[i].theta, max_nfev=max_nfev - budget)
    if prob.method == "gmwm" and sols:
        i = int(np.argmin([s_.objective for s_ in sols]))
        hop = vp.hop_sins(sols[i].theta)
        if hop is not None and hop[0] < sols[i].objective * (1 - 1e-9):
            again = prob.solve(hop[1], max_nfev=max_nfev)
            if again.objective < sols[i].objective:
                sols.append(again)
    for sol in sols:
        runs.append((sol.objective, model.canonical(sol.theta), sol.message, sol.ok, sol.edge,
                     None))
    for sub_key, spec, emb in subs:  # the submodel's optimum itself (component exactly 0)
        sub_node = cache[sub_key]
        runs.append((prob.objective(emb), model.canonical(emb), sub_node.message,
                     sub_node.converged, list(sub_node.edge), spec))
    i = int(np.argmin([r[0] for r in runs]))
    obj, theta, msg, ok, edge, from_sub = runs[i]
    node = _Node(theta, obj, bool(ok and np.isfinite(obj)), msg, edge, len(cand), from_sub)
    if not extra_starts:
        cache[key] = node
    return node


def fit(data: np.ndarray | WaveletVariance, model: str | Model, *, levels: int | None = None,
        freq: float | None = None, weights: str | np.ndarray = "ci", method: str = "gmwm",
        n_starts: int = N_STARTS, seed: int = 0, reweight: int = 0, alpha: float = 0.05,
        max_nfev: int = 1000, se_cov: str | np.ndarray = "model",
        nested: bool = True) -> GMWMResult:
    """Estimate ``model`` by GMWM (or ARMAV) from a signal or a precomputed wavelet variance.

    Parameters
    ----------
    data : 1-D signal (per-sample units) or a :class:`~gmwm.wv.WaveletVariance`.
    model : model string such as ``"WN+RW+AR1+SIN"`` or a :class:`~gmwm.model.Model`.
    levels : number of dyadic levels J (default: all of a given WV, or floor(log2 T) - 1).
    freq : sampling frequency [Hz] of a raw signal (GM parameters and scales in seconds use it).
    weights : ``"ci"`` (inverse squared CI width, default), ``"gaussian"`` (eta_j / (2 nu_j^2)),
        ``"identity"``, ``"efficient"`` (two-step: CI weights, then the inverse of the model
        covariance of the WV estimate at the first estimate), or a (J, J) covariance of
        ``nu_hat`` (e.g. from a bootstrap), whose inverse is the weight and which also feeds
        the standard errors.
    method : ``"gmwm"`` (f(x) = x) or ``"armav"`` (f = log10 of the Allan variance).
    n_starts : distinct starting points refined by the optimiser (per model and submodel).
    seed : seed of the randomised start placements (results are deterministic given it).
    reweight : extra passes re-weighting with the fitted model's WV (Gaussian weights).
    alpha : CI level of a WV computed here.
    max_nfev : evaluation budget per start.
    se_cov : covariance V of the WV estimate behind the standard errors: ``"model"`` (default;
        under the fitted model, with the between-scale correlation), ``"gaussian"`` (the
        diagonal 2 nu_hat^2 / eta) or a (J, J) matrix. A covariance given as ``weights``
        is used for both.
    nested : include the fits of the submodels (one component dropped, recursively) so that the
        result is never worse than any submodel's.

    Returns
    -------
    GMWMResult with estimates in canonical component order; ``diagnostics["warnings"]`` lists
    boundary estimates, weak identification and non-convergence.
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; use one of {', '.join(METHODS)} "
                         "(the slope method is gmwm.avsm.fit_avsm)")
    if not isinstance(reweight, (int, np.integer)) or reweight < 0:
        raise InputError(f"reweight must be a non-negative integer, got {reweight!r}")
    if not isinstance(n_starts, (int, np.integer)) or n_starts < 1:
        raise InputError(f"n_starts must be a positive integer, got {n_starts!r}")
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
    if np.any(wv.variance <= 0) or not np.all(np.isfinite(wv.variance)):
        raise InputError("wavelet variance must be positive and finite at every level "
                         "(constant signal?)")
    user_cov = not isinstance(weights, str)
    if user_cov:
        weights = check_cov(weights, wv.n_levels)
    elif weights not in ("ci", "gaussian", "identity", "efficient"):
        raise InputError(f"unknown weights {weights!r}; use ci, gaussian, identity, efficient "
                         "or a covariance matrix")
    efficient = isinstance(weights, str) and weights == "efficient"
    mode = "full" if nested else "off"
    if any(c.process.name in ("AR1", "GM") for c in model.components):
        # load the AR1 kernels (Numba's start-up, ~0.3 s once per process) before the clock
        # starts, so that seconds_fit is the search's time, as on every later fit
        ar1_unit_wv_many(np.array([0.5]), wv.scales[:1])
    t0 = time.perf_counter()
    with np.errstate(all="ignore"):
        omega = weight_matrix(wv, "ci" if efficient else weights, method)
        prob = Problem(model, wv, omega, method)
        cache: dict[str, Any] = {}
        node = _search(prob, model, n_starts, seed, drift_sign, max_nfev, mode, cache)
        for _ in range(0 if user_cov or efficient else reweight):
            omega = weight_matrix(wv, "gaussian", method, model_wv=model.wv(node.theta, prob.tau))
            prob = Problem(model, wv, omega, method)
            cache = {}
            node = _search(prob, model, n_starts, seed, drift_sign, max_nfev, mode, cache,
                           extra_starts=[node.theta])
        if efficient:
            V1 = wv_cov("model", model, node.theta, wv)
            omega = omega_from_cov(V1, wv.variance, method)
            prob = Problem(model, wv, omega, method)
            cache = {}
            node = _search(prob, model, n_starts, seed, drift_sign, max_nfev, mode, cache,
                           extra_starts=[node.theta])
    seconds_fit = time.perf_counter() - t0
    theta = node.theta
    with np.errstate(all="ignore"):
        comp_wv = model.component_wv(theta, prob.tau)
    vanished = [k for k, v in comp_wv.items() if np.max(v / wv.variance) < VANISH_SHARE]
    fixed = np.zeros(model.n_params, bool)
    for c in model.components:
        if c.name in vanished:
            fixed[c.slice] = True
            theta[c.start + c.process.scale_index] = 0.0
    V = weights if user_cov else wv_cov(se_cov, model, theta, wv)
    cov, se, cond = prob.sandwich(theta, V, fixed)
    warnings = _warnings(model, theta, se, cond, vanished, fixed, data, float(wv.scales[-1]))
    unsupported = _unsupported(prob, model, node, V, vanished, cache) if nested else []
    if unsupported:
        warnings.append("component(s) " + ", ".join(n for n, _ in unsupported) + " not supported "
                        "by the data: dropping one raises the objective by less than 2 per "
                        "parameter on the chi-square scale ("
                        + ", ".join(f"{n}: {d:.2g}" for n, d in unsupported)
                        + "); a smaller model fits as well")
    settings = {"weights": "covariance" if user_cov else weights, "method": method,
                "n_starts": int(n_starts), "reweight": int(reweight), "seed": int(seed),
                "levels": int(wv.n_levels), "max_nfev": int(max_nfev), "nested": bool(nested),
                "se_cov": "covariance" if not isinstance(se_cov, str) else se_cov}
    if user_cov:
        settings["weights_cov"] = weights
    diagnostics = {"warnings": warnings, "condition_number": cond, "at_boundary": vanished,
                   "closed_form": bool(model.is_linear and method == "gmwm"),
                   "n_refined": node.n_refined, "from_submodel": node.from_submodel,
                   "n_models_searched": sum(k != "__columns__" for k in cache),
                   "settings": settings}
    converged = node.converged and not node.edge
    message = node.message if not node.edge else (
        "parameter(s) at the edge of the search region: " + ", ".join(node.edge))
    if not converged:
        warnings.insert(0, f"the optimiser did not converge ({message})")
    return GMWMResult(model=model, params=theta, se=se, cov=cov, objective=node.objective,
                      weights=omega, converged=converged, message=message, wv=wv,
                      method=method, diagnostics=diagnostics, seconds_wv=seconds_wv,
                      seconds_fit=seconds_fit, wv_cov=V, settings=settings)


def _warnings(model: Model, theta: np.ndarray, se: np.ndarray, cond: float,
              vanished: list[str], fixed: np.ndarray, data: Any, tau_max: float) -> list[str]:
    """Human-readable problems of a fit (boundary, weak identification, missing SEs);
    ``tau_max`` = the longest scale fitted, in samples."""
    out: list[str] = []
    if vanished:
        out.append("component(s) " + ", ".join(vanished) + " contribute less than "
                   f"{VANISH_SHARE:g} of the WV at every scale: estimate at the boundary 0 "
                   "(no standard error); a smaller model fits as well")
    for c in model.components:
        if c.name in vanished:
            continue
        p = theta[c.slice]
        name = c.process.name
        if name == "AR1" and abs(p[0]) > 1 - 1e-6:
            out.append(f"{c.name}.phi = {p[0]:.8g} is at the edge of the stationary domain "
                       f"(|phi| -> 1): {'a random walk' if p[0] > 0 else 'an alternating process'}"
                       " over the observed scales, not an AR1")
        if name == "SIN" and p[1] > np.pi * (1 - 1e-6):
            out.append(f"{c.name}.beta = {p[1]:.6g} is at the Nyquist bound pi")
        if name == "SIN" and 0 < p[1] and 2 * np.pi / p[1] > SLOW_SIN_PERIODS * tau_max:
            # beta * tau / 4 -> 0: the WV tends to alpha**2 beta**2 tau**2 / 16, a drift's
            out.append(f"{c.name}: its period 2 pi / beta = {2 * np.pi / p[1]:.3g} samples is over "
                       f"{SLOW_SIN_PERIODS:g} times the longest scale ({tau_max:.0f} samples), so "
                       "its WV is that of a drift of slope alpha * beta = "
                       f"{p[0] * p[1]:.3g}: alpha and beta are not identified separately "
                       "(a DR fits the same)")
    if np.isfinite(cond) and cond > COND_WARN or not np.isfinite(cond):
        out.append(f"the WV Jacobian is ill-conditioned (condition number {cond:.3g}): more "
                   "parameters than the WV can identify; try a smaller model or `--check`")
    bad_se = [n for n, s, f in zip(model.param_names, se, fixed, strict=True)
              if not np.isfinite(s) and not f]
    if bad_se:
        out.append("standard errors could not be computed for " + ", ".join(bad_se)
                   + " (singular sandwich)")
    weak = []
    for c in model.components:
        if c.name in vanished:
            continue
        i = c.start + c.process.scale_index
        if np.isfinite(se[i]) and abs(theta[i]) < 1.96 * se[i]:
            weak.append(c.name)
    if weak:
        out.append("component(s) " + ", ".join(weak) + " not distinguishable from zero "
                   "(estimate below 1.96 standard errors)")
    if isinstance(data, WaveletVariance) and model.count("DR"):
        out.append("drift sign is not identified from a WV; reported positive")
    return out


def _unsupported(prob: Problem, model: Model, node: _Node, V: np.ndarray, vanished: list[str],
                 cache: dict[str, Any]) -> list[tuple[str, float]]:
    """Components whose removal raises the objective by less than 2 per parameter on the
    chi-square scale (the objective divided by ``c = tr(Omega V_f) / J``; an AIC-type rule). The
    drop-one submodels were fitted by the nested search (memoised in ``cache``)."""
    c = prob.chi2_scale(V)
    if not np.isfinite(c) or c <= 0:
        return []
    out = []
    for sub, k in _drop_one(model):
        comp = model.components[k]
        sub_node = cache.get(sub.spec) or cache.get(_node_key(sub.spec, "shaped"))
        if sub_node is None or any(v.startswith(comp.process.name) for v in vanished):
            continue
        delta = (sub_node.objective - node.objective) / c
        if np.isfinite(delta) and delta < 2 * comp.process.n_params:
            name = comp.process.name if model.count(comp.process.name) == 1 else \
                f"one {comp.process.name}"
            out.append((name, float(delta)))
    return out

