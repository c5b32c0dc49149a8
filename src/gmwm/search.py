"""The global search behind :func:`gmwm.fit`: variable projection over the process shapes, the
nested submodels, and the refinement of the best starts (no user starting values).

1. Variable projection (VP). Every process's WV is linear in one "scale" parameter (sigma2, Q2,
   gamma2, omega^2, the AR1 innovation variance, the GM variance, alpha^2) once its "shape"
   (AR1 phi, GM beta, SIN beta) is fixed. For fixed shapes the best non-negative scale
   parameters solve a small non-negative least-squares problem (NNLS) on the whitened system;
   for models made only of QN, WN, RW and DR that *is* the closed-form GMWM of [GMWFM].
2. Shapes are searched in coordinates where a uniform grid is natural (each process's
   :meth:`~gmwm.processes.Process.shape_bounds`): AR1 ``xi = 2 atanh(phi)`` over the whole
   domain phi in (-1, 1) (log-spaced towards both ends), GM ``log(beta / freq)``, SIN
   ``log(beta)``. A greedy placement and ``n_init`` seeded random placements are each improved
   by coordinate descent, every coordinate profiled over its whole grid in one vectorised
   projection (an oscillating WV, the SIN's: smooth envelope, then a phase-resolving fine
   scan), then a 1-D bounded refinement. Joint (SIN, other) pair scans find a SIN bump hidden
   under another component.
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
   from the best distinct starts; the best objective wins. The winner's SIN frequencies are
   then rescanned (``hop_sins``), and a SIN it leaves below the WV's noise at every scale is
   re-seated jointly with another shape (``reseat_sins``: a slow SIN absorbed by a phi ~ 1 AR1
   while the SIN keeps a spurious bump elsewhere). Last, a SIN within a few standard deviations
   of the noise hops to the best minima of its tangent profile (``tangent_hops``: the profile
   with the other shapes' first-order response projected out), each solved in all the
   parameters: the weak SIN's joint optimum with the fast AR1 or beside the strong SIN lies in
   another basin of its frequency than its one-at-a-time profile shows.

:class:`Search` runs it for one model and problem and keeps the fitted submodels, from which
:func:`gmwm.fit` judges whether each component is supported by the data. Inside
:func:`shared_memo` the fits of several models on the same objective (a ranking of candidates)
share the memoised nodes: each distinct (sub)model is searched once. This is exact: a node's
search depends only on its model, its mode, the objective and the search settings (its random
stream is seeded by its own model string), never on the model that nested it.
"""

from __future__ import annotations

import hashlib
import zlib
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np

from .inference import Problem, Whitener, weight_matrix
from .model import Model, spec_of
from .processes import Process
from .settings import N_STARTS

__all__ = ["EXPLORE_NFEV", "VP", "Node", "Search", "shapes_of", "shared_memo", "theta_from_vp"]

#: Evaluation budget of each exploratory solve (the winner continues to max_nfev).
EXPLORE_NFEV = 60
#: A SIN whose WV stays below this many standard deviations of the WV estimate at every scale is
#: re-seated jointly with another shape (``VP.reseat_sins``).
RESEAT_NOISE = 3.0
#: ... and moved at least this far in ln beta from where it was.
RESEAT_AWAY = 1.0
#: A SIN whose WV stays below this many standard deviations at every scale is also moved to the
#: best minima of its tangent profile (``VP.tangent_hops``), each solved in all the parameters.
HOP_NOISE = 10.0
#: points of the tangent profile over the whole ln-beta range (~0.004 apart; each chosen minimum
#: is refined on a 16x finer local grid)
HOP_POINTS = 4000
#: how many of the tangent profile's best local minima are solved (per weak SIN)
HOP_MINIMA = 3
#: at most this many successive hops
HOP_ROUNDS = 3


# -- NNLS ---------------------------------------------------------------------------------------
def _nnls_core() -> Any:
    """SciPy's Lawson-Hanson kernel without the public wrapper's input checks, if this SciPy has
    the private kernel with the expected signature (checked on a small problem); else None and
    the public ``scipy.optimize.nnls`` is used. The search solves thousands of small NNLS
    problems per fit, on which the wrapper costs several times the kernel
    (``benchmarks/bench_nnls.py`` measures both, and that the estimates are identical)."""
    try:
        from scipy.optimize._slsqplib import nnls as core
        x, _, info = core(np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]),
                          np.array([1.0, -1.0, 0.0]), 6)
        return core if info == 1 and abs(x[0] - 0.5) < 1e-12 and x[1] == 0.0 else None
    except Exception:  # noqa: BLE001 - any failure means: use the public function
        return None


_UNSET: Any = object()
#: the kernel of :func:`_nnls_core` (None: the public function), found on the first call, so
#: that importing this module does not import scipy.optimize (~0.25 s; a process that only
#: unpickles results, as the report's calling process does, imports it through gmwm.select)
_NNLS: Any = _UNSET


def _nnls(A: np.ndarray, b: np.ndarray, maxiter: int) -> tuple[np.ndarray, float]:
    """``scipy.optimize.nnls`` on finite C-contiguous float64 input."""
    global _NNLS
    if _NNLS is _UNSET:
        _NNLS = _nnls_core()
    if _NNLS is None:
        from scipy.optimize import nnls

        return nnls(A, b, maxiter=maxiter)
    x, rnorm, info = _NNLS(A, b, maxiter)
    if info == 3:
        raise RuntimeError("Maximum number of iterations reached.")
    return x, rnorm


# -- shape coordinates of the variable projection -------------------------------------------------
def _grid(proc: Process, tau: np.ndarray, step: float) -> np.ndarray | None:
    b = proc.shape_bounds(tau)
    if b is None:
        return None
    return np.linspace(b[0], b[1], max(int(np.ceil((b[1] - b[0]) / step)) + 1, 8))


@lru_cache(maxsize=128)
def _grid_columns(proc: Process, tau: tuple[float, ...], step: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Shape grid and its coarse-scan columns (SIN: smooth envelope); cached per scale set."""
    t = np.asarray(tau)
    grid = _grid(proc, t, step)
    cols = proc.scan_wv_columns(grid, t)
    grid.setflags(write=False)
    cols.setflags(write=False)
    return grid, cols


def theta_from_vp(model: Model, shapes: list[float], coef: np.ndarray, drift_sign: float,
                   floor: np.ndarray | None = None) -> np.ndarray:
    """Shape coordinates + NNLS scale coefficients -> parameter vector. Zero coefficients are
    lifted to ``floor`` (if given) so that free coordinates are defined."""
    theta = np.empty(model.n_params)
    for k, (c, u) in enumerate(zip(model.components, shapes, strict=True)):
        s = coef[k] if floor is None else max(coef[k], floor[k])
        theta[c.slice] = c.process.from_vp(u, s, model.freq, drift_sign)
    return theta


def shapes_of(model: Model, theta: np.ndarray, tau: np.ndarray) -> list[float]:
    """Shape coordinates of a parameter vector (0 for components without a shape)."""
    out = []
    for c in model.components:
        lo, hi = c.process.shape_bounds(tau) or (0.0, 0.0)
        out.append(float(np.clip(c.process.shape_of(theta[c.slice], model.freq), lo, hi)))
    return out


class VP:
    """Variable-projection search over the shapes of one model on one whitened WV."""

    STEP = 0.45          # grid spacing in shape coordinates
    N_INIT = 4           # random placements besides the greedy one

    def __init__(self, model: Model, tau: np.ndarray, nu_hat: np.ndarray, white: Whitener,
                 drift_sign: float, rng: np.random.Generator,
                 col_cache: dict[tuple[Any, ...], np.ndarray] | None = None):
        self.model, self.tau, self.nu_hat = model, tau, nu_hat
        self.white, self.drift_sign, self.rng = white, drift_sign, rng
        self.procs = [c.process for c in model.components]
        key = tuple(float(t) for t in tau)
        self.grids: list[np.ndarray | None] = []
        self.gcols: list[np.ndarray | None] = []
        self.rawcols: list[np.ndarray | None] = []  # unwhitened (SIN: the smooth envelope)
        for proc in self.procs:
            if proc.shape_bounds(tau) is None:
                self.grids.append(None)
                self.gcols.append(None)
                self.rawcols.append(None)
            else:
                g, c = _grid_columns(proc, key, self.STEP)
                self.grids.append(g)
                self.gcols.append(white @ c)
                self.rawcols.append(c)
        self.shaped = [k for k, g in enumerate(self.grids) if g is not None]
        self.yw = white @ nu_hat
        self.ncomp = len(self.procs)
        # whitened unit columns by (process, shape); shared by the nodes of one nested search
        self._cols = {} if col_cache is None else col_cache
        self.cols = np.column_stack([self.col(k, 0.0) for k in range(self.ncomp)])

    def col(self, k: int, u: float) -> np.ndarray:
        key = (self.procs[k].name, float(u))
        c = self._cols.get(key)
        if c is None:
            c = self.white @ self.procs[k].unit_wv_columns(np.array([u]), self.tau)[:, 0]
            self._cols[key] = c
        return c

    def prefetch(self, k: int, values: np.ndarray) -> None:
        """Whitened columns of component k at several shapes, computed in one call."""
        name = self.procs[k].name
        new = [float(v) for v in values if (name, float(v)) not in self._cols]
        if len(new) > 1:
            cols = self.white @ self.procs[k].unit_wv_columns(np.array(new), self.tau)
            for i, v in enumerate(new):
                self._cols[(name, v)] = cols[:, i]

    def floors(self, shapes: list[float]) -> np.ndarray:
        out = np.empty(self.ncomp)
        for k in range(self.ncomp):
            c = self.procs[k].unit_wv_columns(np.array([shapes[k]]), self.tau)[:, 0]
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
        proc = self.procs[k]
        if proc.oscillating and refine:
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
                fkey = (proc.name, "fine", int(i), n)
                if fkey not in self._cols:
                    self._cols[fkey] = self.white @ proc.unit_wv_columns(fine[-1], self.tau)
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
            g_loc, _ = self.profile_gain(self.white @ proc.unit_wv_columns(local, self.tau),
                                         others, proj)
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
        from scipy.optimize import least_squares

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
        return self.model.canonical(theta_from_vp(self.model, shapes, coef, self.drift_sign,
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
        sins = [k for k in self.shaped if self.procs[k].oscillating]
        if not sins or len(self.shaped) < 2 or theta_best is None:
            return
        c, th = self.pair_descents(shapes_of(self.model, theta_best, self.tau), sins)
        add(c, th)

    def pair_descents(self, base: list[float], sins: list[int], away: float | None = None,
                      partners: list[int] | None = None) -> tuple[float, np.ndarray]:
        """(VP cost, theta) of the best joint (SIN k, other shape j) placement from ``base``
        over the SINs ``sins`` and every other shaped j, each followed by a coordinate descent.
        ``away``: SIN k is placed at least this far (in ln beta) from ``base[k]``."""
        sg = self.grids[sins[0]]
        sin_grid = np.linspace(sg[0], sg[-1], 4 * sg.size)
        sin_cols = self.white @ self.procs[sins[0]].unit_wv_columns(sin_grid, self.tau)
        moved = []
        for k in sins:
            allowed = None if away is None else np.abs(sin_grid - base[k]) > away
            for j in (self.shaped if partners is None else partners):
                if j == k:
                    continue
                shapes = list(base)
                self.set_shapes(shapes)
                fixed = [i for i in range(self.ncomp) if i not in (j, k)]
                best_pair = self.pair_scan(fixed, j, sin_cols, allowed)
                shapes[j] = float(self.grids[j][best_pair[0]])
                shapes[k] = float(sin_grid[best_pair[1]])
                shapes, c, coef = self.descend(shapes, refine=True, first=(k, j))
                moved.append((c, self.theta(shapes, coef)))
        return min(moved, key=lambda x: x[0])

    def reseat_sins(self, theta: np.ndarray, noise: np.ndarray
                    ) -> tuple[float, np.ndarray] | None:
        """Re-seat the sinusoids that ``theta`` leaves below the noise. A SIN whose WV is below
        ``noise`` (the WV's standard deviation, per scale) at every scale explains nothing the
        data can tell; typically a slow SIN was absorbed by an AR1 with phi ~ 1 and the SIN
        kept a tiny spurious bump elsewhere, a local optimum that no one-shape move leaves (the
        SIN alone has nowhere better to go while the AR1 covers its scales, and the AR1 alone
        loses by giving them up). Joint (SIN, other shape) scans from ``theta``'s shapes move
        both at once. Returns (VP cost, theta) of the best placement, None if no SIN is below
        the noise."""
        sins = [k for k in self.shaped if self.procs[k].oscillating]
        if not sins or len(self.shaped) < 2:
            return None
        comp = self.model.component_wv(theta, self.tau)
        weak = [k for k in sins
                if np.max(comp[self.model.components[k].name] / noise) < RESEAT_NOISE]
        if not weak:
            return None
        # the shape that absorbed the SIN's power is a smooth one (AR1 / GM), not another SIN
        partners = [j for j in self.shaped if not self.procs[j].oscillating]
        if not partners:
            return None
        return self.pair_descents(shapes_of(self.model, theta, self.tau), weak, RESEAT_AWAY,
                                  partners)

    def hop_sins(self, theta: np.ndarray) -> tuple[float, np.ndarray] | None:
        """A SIN's WV oscillates in beta, so a solve ends in whichever of its narrow basins it
        started in: rescan each SIN's beta finely with the other shapes at ``theta``'s. Returns
        (VP cost, theta) of the best placement, or None if no SIN moved."""
        sins = [k for k in self.shaped if self.procs[k].oscillating]
        if not sins:
            return None
        shapes = shapes_of(self.model, theta, self.tau)
        self.set_shapes(shapes)
        before = list(shapes)
        for k in sins:
            self.best_along(shapes, k, True)
        if shapes == before:
            return None
        c, coef = self.cost()
        return c, self.theta(shapes, coef)

    def tangent_hops(self, theta: np.ndarray, noise: np.ndarray) -> list[np.ndarray]:
        """Starts that move each SIN ``theta`` leaves within ``HOP_NOISE`` standard deviations
        of the WV (``noise``, per scale) to another basin of its frequency. A weak SIN trades
        variance with its neighbours: at high frequency with the fast AR1 (both raise the
        short scales), next to a strong SIN as a beat pair, and the strong SIN's phase at the
        long scales moves by ~1e-6 with it. Its profile with the other shapes held fixed then
        has its minimum where it is, while the joint optimum sits in another basin. The
        tangent profile projects out, besides the other columns, their derivatives in their
        shapes (the first-order response of the others, Frisch-Waugh); its ``HOP_MINIMA`` best
        local minima below its value at the current frequency (a predicted drop), each refined
        locally, are returned as starts (the SIN there, the other shapes moved by the
        Gauss-Newton step of that profile, the scales by NNLS), best first."""
        sins = [k for k in self.shaped if self.procs[k].oscillating]
        if not sins:
            return []
        comp = self.model.component_wv(theta, self.tau)
        weak = [k for k in sins
                if np.max(comp[self.model.components[k].name] / noise) < HOP_NOISE]
        if not weak:
            return []
        base = shapes_of(self.model, theta, self.tau)
        found: list[tuple[float, np.ndarray]] = []
        for k in weak:
            self.set_shapes(base)
            others = [i for i in range(self.ncomp) if i != k]
            X = [self.cols[:, others]]
            for i in others:
                if self.grids[i] is None:
                    continue
                # central difference in the shape coordinate; a SIN's long-scale phase needs a
                # small step, a smooth shape a larger one for accuracy
                h = 1e-6 if self.procs[i].oscillating else 1e-4
                d = self.white @ self.procs[i].unit_wv_columns(
                    np.array([base[i] + h, base[i] - h]), self.tau)
                X.append(((d[:, 0] - d[:, 1]) / (2 * h))[:, None])
            Q, _ = np.linalg.qr(np.column_stack(X))
            y = self.yw - Q @ (Q.T @ self.yw)
            grid = np.linspace(self.grids[k][0], self.grids[k][-1], HOP_POINTS)
            key = (self.procs[k].name, "hop", HOP_POINTS)
            if key not in self._cols:
                self._cols[key] = self.white @ self.procs[k].unit_wv_columns(grid, self.tau)
            G = self._cols[key] - Q @ (Q.T @ self._cols[key])
            num = G.T @ y
            den = np.einsum("jg,jg->g", G, G)
            with np.errstate(divide="ignore", invalid="ignore"):
                cost = -np.where((num > 0) & (den > 0), num**2 / den, 0.0)
            # the profile at the current frequency is the current cost (there the others'
            # derivatives are orthogonal to the residual): only predicted drops are tried
            here = self.col(k, base[k])[:, None]
            here = here - Q @ (Q.T @ here)
            g_here = float(here[:, 0] @ y)
            c_here = -g_here**2 / float(here[:, 0] @ here[:, 0]) if g_here > 0 else 0.0
            mins = np.flatnonzero((cost[1:-1] < cost[:-2]) & (cost[1:-1] < cost[2:])) + 1
            mins = mins[cost[mins] < c_here - 1e-9 * (y @ y)]
            shaped_others = [i for i in others if self.grids[i] is not None]
            dg = float(grid[1] - grid[0])
            for m in mins[np.argsort(cost[mins])][:HOP_MINIMA]:
                # the grid resolves the SIN's ripples only roughly at the long scales: the same
                # profile on 33 points over +-1 grid step around the minimum
                loc = np.clip(grid[m] + dg * np.linspace(-1, 1, 33), grid[0], grid[-1])
                L = self.white @ self.procs[k].unit_wv_columns(loc, self.tau)
                L = L - Q @ (Q.T @ L)
                nl = L.T @ y
                dl = np.einsum("jg,jg->g", L, L)
                with np.errstate(divide="ignore", invalid="ignore"):
                    gl = np.where((nl > 0) & (dl > 0), nl**2 / dl, 0.0)
                shapes = list(base)
                shapes[k] = float(loc[int(np.argmax(gl))])
                # the others take the first-order response the profile assumed: in the least
                # squares on [their columns, their derivatives, the SIN's column] the
                # derivative's coefficient over the column's is the Gauss-Newton shape step
                A = np.column_stack([*X, self.col(k, shapes[k])])
                b = np.linalg.lstsq(A, self.yw, rcond=None)[0]
                for n_, i in enumerate(shaped_others):
                    a_i = b[others.index(i)]
                    if a_i > 0:
                        step = float(np.clip(b[len(others) + n_] / a_i, -self.STEP, self.STEP))
                        lo_i, hi_i = self.grids[i][0], self.grids[i][-1]
                        shapes[i] = float(np.clip(base[i] + step, lo_i, hi_i))
                self.set_shapes(shapes)
                found.append((float(cost[m]), self.theta(shapes, self.cost()[1])))
        self.set_shapes(base)
        found.sort(key=lambda x: x[0])
        return [th for _, th in found]

    def pair_scan(self, fixed: list[int], j: int, S: np.ndarray,
                  allowed: np.ndarray | None = None) -> tuple[int, int]:
        """(grid index of component j, column of S) with the least LS cost of the whitened WV
        on the ``fixed`` columns, j's grid column and one column of S, a positive coefficient
        on the S column (``allowed``: mask of the S columns considered). All pairs at once: the
        fixed span is projected out once, and each j column enters as a rank-one update
        (Frisch-Waugh)."""
        Q, y = self.residual(fixed)
        proc = self.procs[j]
        G = self.white @ proc.unit_wv_columns(self.grids[j], self.tau) if proc.oscillating \
            else self.gcols[j]
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
        if allowed is not None:
            cost[:, ~allowed] = np.inf
        gj, gk = np.unravel_index(int(np.argmin(cost)), cost.shape)
        return int(gj), int(gk)

    def extend(self, theta_sub: np.ndarray, k_new: int) -> tuple[float, np.ndarray]:
        """Start from a submodel optimum (shapes of ``theta_sub``, embedded in this model, with
        component ``k_new`` off) and place component k_new at its best shape."""
        shapes = shapes_of(self.model, theta_sub, self.tau)
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
            theta[c.slice] = c.process.off_params(model.freq)
            continue
        sc = next(s for s in sub.components
                  if s.process.name == c.process.name and not used[s.name])
        used[sc.name] = True
        theta[c.slice] = theta_sub[sc.slice]
    return theta


# -- the search -----------------------------------------------------------------------------------
@dataclass
class Node:
    """The outcome of the search for one model: its best parameters (canonical order) and
    objective, whether the winning solve converged (``edge``: parameters that ended at the edge
    of the search box), how many starts were refined and, if the optimum is a submodel's with one
    component at zero, that submodel."""

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
            max_nfev: int, mode: str, cache: dict[str, Node],
            extra_starts: list[np.ndarray] | None = None) -> Node:
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
    vp = VP(model, tau, nu_hat, gw, drift_sign, _node_seed(seed, model.spec),
             cache.setdefault("__columns__", {}))  # type: ignore[arg-type]

    if model.is_linear and prob.method == "gmwm":
        # closed form: NNLS on the whitened system is the exact minimiser
        c, coef = vp.cost()
        theta = theta_from_vp(model, [0.0] * vp.ncomp, coef, drift_sign)
        node = Node(theta, prob.objective(theta), True,
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

    def polished(sol: Any) -> Any:
        """A solve stopped by the budget is crawling along a valley: its shapes polished in the
        projected problem (the valley is straightened there) and solved again from there, if
        that ends lower."""
        if not sol.capped:
            return sol
        sh, _, coef = vp.polish(shapes_of(model, sol.theta, tau))
        again = prob.solve(vp.theta(sh, coef), max_nfev=budget)
        return again if again.objective < sol.objective else sol

    if prob.method == "gmwm" and vp.shaped:
        sols = [polished(sol) for sol in sols]
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
        i = int(np.argmin([s_.objective for s_ in sols]))
        noise = prob.nu_hat * np.sqrt(2.0 / prob.wv.edof)
        seat = vp.reseat_sins(sols[i].theta, noise)
        # the descent ends near, not at, the new basin's minimum: solve unless clearly worse
        if seat is not None and seat[0] < sols[i].objective * 1.1:
            again = prob.solve(seat[1], max_nfev=max_nfev)
            if again.objective < sols[i].objective:
                sols.append(again)
        # the joint move of a weak SIN to another basin of its frequency, solved in the full
        # parameters (the analytic Jacobian follows the strong SIN's ~1e-6 phase shift); again
        # from where a hop lands (its own tangent profile), while the objective drops
        for _ in range(HOP_ROUNDS):
            i = int(np.argmin([s_.objective for s_ in sols]))
            hops = [prob.solve(th, max_nfev=budget)
                    for th in vp.tangent_hops(sols[i].theta, noise)]
            if not hops:
                break
            j = int(np.argmin([h.objective for h in hops]))
            if hops[j].objective >= sols[i].objective * (1 - 1e-9):
                break
            again = polished(hops[j])  # as the starts above, then the full budget
            if again.capped and max_nfev > budget:
                again = prob.solve(again.theta, max_nfev=max_nfev - budget)
            if again.objective >= sols[i].objective:
                break
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
    node = Node(theta, obj, bool(ok and np.isfinite(obj)), msg, edge, len(cand), from_sub)
    if not extra_starts:
        cache[key] = node
    return node


_MEMO: ContextVar[dict[str, dict[str, Any]] | None] = ContextVar("gmwm_search_memo",
                                                                  default=None)


@contextmanager
def shared_memo() -> Iterator[None]:
    """Within this block, searches on the same objective (WV, weight matrix, method, starts,
    seed, drift sign, budget) share their memoised nodes (module docstring); re-entrant: an inner
    block joins the outer one."""
    if _MEMO.get() is not None:
        yield
        return
    token = _MEMO.set({})
    try:
        yield
    finally:
        _MEMO.reset(token)


def _objective_key(problem: Problem, *settings: Any) -> str:
    h = hashlib.blake2b(digest_size=16)
    for a in (problem.nu_hat, problem.omega, problem.tau):
        h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    h.update(repr((problem.method, *settings)).encode())
    return h.hexdigest()


def _tree(model: Model, mode: str) -> Iterator[tuple[str, Model, str]]:
    """(key, model, mode) of every node the nested search of ``model`` in ``mode`` visits
    (the recursion of :func:`_search`; repeated keys possible)."""
    yield _node_key(model.spec, mode), model, mode
    if mode == "off" or len(model.components) < 2:
        return
    for sub, k in _drop_one(model):
        linear_drop = model.components[k].process.linear
        if mode == "shaped" and linear_drop:
            continue
        yield from _tree(sub, "shaped" if linear_drop else mode)


class Search:
    """The search with one configuration: ``run(problem)`` finds the optimum of
    ``problem.model`` (memoising the submodels), ``drop_one(model)`` then returns the fitted
    drop-one submodels of that run."""

    def __init__(self, n_starts: int, seed: int, drift_sign: float, max_nfev: int,
                 nested: bool):
        self.n_starts, self.seed, self.drift_sign = n_starts, seed, drift_sign
        self.max_nfev = max_nfev
        self.mode = "full" if nested else "off"
        self.cache: dict[str, Any] = {}
        self._model: Model | None = None

    def run(self, problem: Problem, extra_starts: list[np.ndarray] | None = None) -> Node:
        """The best node of ``problem.model`` (``extra_starts``: further starting points)."""
        memo = _MEMO.get()
        if memo is None:
            self.cache = {}
        else:
            self.cache = memo.setdefault(_objective_key(
                problem, self.n_starts, self.seed, self.drift_sign, self.max_nfev, self.mode), {})
        self._model = problem.model
        return _search(problem, problem.model, self.n_starts, self.seed, self.drift_sign,
                       self.max_nfev, self.mode, self.cache, extra_starts)

    @property
    def n_models_searched(self) -> int:
        """Distinct nodes of the last run's nested search (found in the shared memo or not)."""
        if self._model is None:
            return 0
        return len({key for key, _, _ in _tree(self._model, self.mode) if key in self.cache})

    def drop_one(self, model: Model) -> list[tuple[int, Node]]:
        """(index of the dropped component, node) of every drop-one submodel of ``model`` that
        the last run fitted."""
        out = []
        for sub, k in _drop_one(model):
            node = self.cache.get(sub.spec) or self.cache.get(_node_key(sub.spec, "shaped"))
            if node is not None:
                out.append((k, node))
        return out
