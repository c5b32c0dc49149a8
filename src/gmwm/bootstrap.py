"""Parametric bootstrap of a GMWM fit (docs/METHODS.md §7): WV covariance, refits, confidence intervals.

Draw ``b`` simulates a signal of the fitted length ``T`` from ``F_theta_hat`` with its own stream,
``SeedSequence(seed, spawn_key=(b,))`` (equal to ``SeedSequence(seed).spawn(B)[b]``), so a draw
never depends on ``B`` or on how draws are split into chunks: ``draws=range(a, b)`` computes just
those draws, and :meth:`BootstrapResult.combine` joins chunks. One signal is held in memory at a
time; the cost is dominated by simulation + WV (+ the refit when ``refit=True``).

Outputs:

* ``wv_bootstrap`` / ``bootstrap_cov``: the (B, J) WV draws and their covariance, usable as
  ``gmwm.fit(..., weights=cov)`` (efficient GMWM, SEs from the sandwich with that V).
* ``parametric_bootstrap``: refits every draw with the original settings; percentile CI
  ``[q(a/2), q(1-a/2)]`` and basic CI ``[2 theta_hat - q(1-a/2), 2 theta_hat - q(a/2)]`` of
  ``theta*`` (canonical component order; scale parameters on the log scale, every end inside the
  parameter space: :func:`gmwm.intervals.bootstrap_basic`), bootstrap SEs. Refits that fail or do not converge are
  excluded from CIs and SEs and counted (``n_failed``).
* ``coverage``: share of Monte Carlo replicates whose interval covers the truth, with its
  Monte Carlo SE ``sqrt(c (1 - c) / R)``.

The paper's uncertainty study (chunks on disk, Table 1, the coverage study) is built on these in
:mod:`gmwm_studies.uncertainty`.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from itertools import permutations
from typing import Any, NamedTuple

import numpy as np

from .errors import GMWMError, InputError
from .estimator import GMWMResult, fit
from .model import Model
from .processes import PROCESSES
from .results import check_alpha, freeze_arrays, json_safe, readonly
from .settings import FitSettings
from .wv import wvar

__all__ = ["BootstrapResult", "Coverage", "bootstrap_cov", "coverage", "covers", "draw_seed",
           "parametric_bootstrap", "simulate_draw", "wv_bootstrap"]

Progress = Callable[[int, int], None]


def _free(model: Model, theta: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        eta = model.to_free(np.asarray(theta, dtype=float))
    return np.nan_to_num(eta, nan=0.0, posinf=50.0, neginf=-50.0)


SeedLike = int | np.random.SeedSequence


# -- streams and simulation -----------------------------------------------------------------------
def draw_seed(seed: SeedLike, draw: int) -> np.random.SeedSequence:
    """Seed sequence of bootstrap draw ``draw``: ``seed``'s spawn key extended by ``(draw,)``.

    For an int seed this equals ``np.random.SeedSequence(seed).spawn(B)[draw]`` for every
    ``B > draw``; a ``SeedSequence`` (e.g. a pipeline replicate's) is extended the same way.
    """
    if int(draw) != draw or draw < 0:
        raise InputError(f"bootstrap draw index must be a non-negative integer, got {draw!r}")
    if isinstance(seed, np.random.SeedSequence):
        return np.random.SeedSequence(seed.entropy, spawn_key=tuple(seed.spawn_key) + (int(draw),),
                                      pool_size=seed.pool_size)
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be a non-negative integer or a SeedSequence, got {seed!r}")
    return np.random.SeedSequence(int(seed), spawn_key=(int(draw),))


def _fit_seed(ss: np.random.SeedSequence) -> int:
    """Integer seed for the refit's random starts, from a stream separate from the signal's."""
    sub = np.random.SeedSequence(ss.entropy, spawn_key=tuple(ss.spawn_key) + (1,),
                                 pool_size=ss.pool_size)
    return int(sub.generate_state(1, np.uint64)[0] >> np.uint64(1))


def simulate_draw(model: Model, theta: np.ndarray, n_samples: int,
                  rng: np.random.Generator) -> np.ndarray:
    """One signal of ``n_samples`` from ``model`` at ``theta`` (:meth:`Model.simulate_fast`: the
    model's distribution up to an additive constant, which every WV statistic ignores).

    A linear component estimated at the boundary 0 (closed-form NNLS) contributes nothing instead
    of being rejected; any other parameter out of its domain is an InputError.
    """
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (model.n_params,):
        raise InputError(f"model {model.spec} has {model.n_params} parameters, got {theta.size}")
    for c in model.components:
        p = theta[c.slice]
        if c.process.linear and p[0] == 0:
            continue
        msg = c.process.check(p)
        if msg:
            raise InputError(f"cannot simulate from the estimate: {c.name}: {msg}")
    return model.simulate_fast(theta, int(n_samples), rng, boundary_ok=True)


def _wv_values(x: np.ndarray, levels: int | None) -> np.ndarray:
    """The WV of a draw at ``levels`` (only its values are kept: the eta_3 interval, cheaper
    than the default mixture one, is computed and dropped)."""
    return wvar(x, levels=levels, ci="eta3").variance


def _draw_list(draws: Iterable[int] | None, B: int | None) -> np.ndarray:
    if draws is None:
        if B is None or int(B) != B or B < 1:
            raise InputError(f"number of bootstrap draws B must be a positive integer, got {B!r}")
        return np.arange(int(B))
    idx = np.asarray(list(draws))
    if idx.size == 0 or idx.dtype.kind not in "iu" or np.any(idx < 0):
        raise InputError("draws must be a non-empty list of non-negative integer draw indices")
    if np.unique(idx).size != idx.size:
        raise InputError("draws contains repeated draw indices")
    return idx.astype(np.int64)


def wv_bootstrap(model: Model, theta: np.ndarray, n_samples: int, B: int | None = None, *,
                 levels: int | None = None, seed: SeedLike = 0,
                 draws: Iterable[int] | None = None,
                 progress: Progress | None = None) -> np.ndarray:
    """WV of ``B`` signals of length ``n_samples`` simulated from ``model`` at ``theta``.

    Returns an array (number of draws, J) in the order of ``draws`` (default ``range(B)``);
    ``levels`` = J (default ``floor(log2 T) - 1``). Draw ``b`` always uses the stream
    :func:`draw_seed` ``(seed, b)``, so chunked and unchunked runs agree exactly.
    ``progress(done, total)`` is called after each draw.
    """
    idx = _draw_list(draws, B)
    out: list[np.ndarray] = []
    for i, b in enumerate(idx):
        rng = np.random.default_rng(draw_seed(seed, int(b)))
        x = simulate_draw(model, theta, n_samples, rng)
        out.append(_wv_values(x, levels))
        del x
        if progress is not None:
            progress(i + 1, idx.size)
    return np.vstack(out)


def bootstrap_cov(wv_draws: np.ndarray) -> np.ndarray:
    """Covariance (J, J) of ``nu_hat`` from WV draws (B, J) (unbiased, ``ddof = 1``).

    Pass it as ``gmwm.fit(..., weights=cov)`` for the efficient GMWM; it is invertible only when
    B > J (the fit uses a pseudo-inverse otherwise), and B >= 10 J is advisable.
    """
    X = np.asarray(wv_draws, dtype=float)
    if X.ndim != 2 or X.shape[0] < 2:
        raise InputError(f"need a (B, J) array of WV draws with B >= 2, got shape {X.shape}")
    if not np.all(np.isfinite(X)):
        raise InputError("WV draws contain NaN or inf")
    return np.atleast_2d(np.cov(X, rowvar=False, ddof=1))


# -- parametric bootstrap -------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class BootstrapResult:
    """Draws of a parametric bootstrap of ``estimate``; rows follow ``draws`` (the result protocol
    of :mod:`gmwm.results`: ``params`` are the estimate's, ``se`` the bootstrap SEs and
    ``conf_int`` the percentile intervals, NaN without at least two converged refits).

    ``theta`` (n, p) holds the refits in canonical order (NaN where a refit raised),
    ``converged`` (n,) marks refits used for CIs/SEs, ``wv`` (n, J) the simulated WVs,
    ``settings`` the :class:`~gmwm.settings.FitSettings` of the refits (their seeds come from the
    draws' streams), ``refit`` False when only the WVs were drawn.
    """

    estimate: GMWMResult
    draws: np.ndarray
    theta: np.ndarray
    converged: np.ndarray
    wv: np.ndarray
    seed: Any = 0
    settings: FitSettings = field(default_factory=FitSettings)
    messages: dict[int, str] = field(default_factory=dict)
    seconds: float = 0.0
    refit: bool = True

    def __post_init__(self) -> None:
        freeze_arrays(self, ("theta", "wv"))
        freeze_arrays(self, ("draws",), dtype=np.int64)
        freeze_arrays(self, ("converged",), dtype=bool)
        if isinstance(self.settings, dict):  # stored by gmwm_studies.uncertainty
            object.__setattr__(self, "settings", FitSettings.from_tree(self.settings))
        object.__setattr__(self, "refit", bool(self.refit))

    # -- sizes -----------------------------------------------------------------------------------
    @property
    def params(self) -> np.ndarray:
        """The estimate's parameters (the bootstrap's centre)."""
        return self.estimate.params

    @property
    def param_names(self) -> list[str]:
        return self.estimate.param_names

    @property
    def n_draws(self) -> int:
        return int(self.draws.size)

    @property
    def n_converged(self) -> int:
        return int(np.count_nonzero(self.converged)) if self.refit else 0

    @property
    def n_failed(self) -> int:
        """Refits excluded from CIs and SEs (raised an error or did not converge)."""
        return self.n_draws - self.n_converged if self.refit else 0

    @property
    def theta_used(self) -> np.ndarray:
        """Converged refits (n_converged, p)."""
        return self.theta[self.converged]

    # -- WV covariance and the efficient GMWM ----------------------------------------------------
    @property
    def wv_cov(self) -> np.ndarray:
        """Bootstrap covariance (J, J) of the WV estimate (all draws; refits play no role)."""
        return bootstrap_cov(self.wv)

    def efficient_fit(self, **kwargs: Any) -> GMWMResult:
        """Refit the original WV with the bootstrap covariance as weight matrix (efficient GMWM,
        SEs ``(A' V^-1 A)^-1`` from the sandwich with this V); ``kwargs`` go to :func:`gmwm.fit`.
        The drift sign (not identified by a WV) is copied from the estimate."""
        est = self.estimate
        opts: dict[str, Any] = {"method": est.method, "seed": 0,
                                "n_starts": self.settings.n_starts}
        opts.update(kwargs)
        res = fit(est.wv, est.model, weights=self.wv_cov, **opts)
        params = np.array(res.params)
        for c in est.model.components:
            if c.process.signed:
                flip = est.params[c.slice] < 0
                params[c.slice] = np.where(flip, -params[c.slice], params[c.slice])
        return dataclasses.replace(res, params=params)

    # -- intervals -------------------------------------------------------------------------------
    def _need_refits(self) -> np.ndarray:
        if not self.refit:
            raise InputError("this bootstrap has no refits (refit=False): only the WV covariance "
                             "is available")
        used = self.theta_used
        if used.shape[0] < 2:
            raise InputError(f"only {used.shape[0]} of {self.n_draws} bootstrap refits converged; "
                             "no interval can be formed")
        return used

    @cached_property
    def se(self) -> np.ndarray:
        """Bootstrap standard errors: SD (ddof = 1) of the converged, label-aligned refits (NaN
        without at least two)."""
        if not self.refit or self.n_converged < 2:
            return readonly(np.full(len(self.param_names), np.nan))
        return readonly(np.std(self.aligned(), axis=0, ddof=1))

    def conf_int(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) percentile intervals (:meth:`percentile_ci`; NaN without at least two
        converged refits)."""
        check_alpha(alpha)
        if not self.refit or self.n_converged < 2:
            return np.full((len(self.param_names), 2), np.nan)
        return self.percentile_ci(alpha)

    def aligned(self) -> np.ndarray:
        """Converged refits with same-type components relabelled to match the estimate (the
        permutation closest to it in free coordinates), so quantiles do not mix label-switched
        draws, and a signed parameter (DR omega) carrying the estimate's sign: the WV identifies
        only |omega|, the sign is the signal's (a weak drift's refits take either), so the
        intervals are those of |omega| on the estimate's side, as the fit's are."""
        used = self._need_refits().copy()
        model = self.estimate.model
        for c in model.components:
            if c.process.signed:
                sign = np.where(self.estimate.params[c.slice] < 0, -1.0, 1.0)
                used[:, c.slice] = sign * np.abs(used[:, c.slice])
        est_eta = _free(model, self.estimate.params)
        for proc in PROCESSES.values():
            comps = [c for c in model.components if c.process is proc]
            if len(comps) < 2:
                continue
            perms = list(permutations(range(len(comps))))
            targets = [est_eta[c.slice] for c in comps]
            for row in used:
                eta = _free(model, row)
                blocks = [row[c.slice].copy() for c in comps]
                eblocks = [eta[c.slice] for c in comps]
                cost = [sum(float(np.sum((eblocks[src] - t) ** 2))
                            for t, src in zip(targets, perm, strict=True)) for perm in perms]
                best = perms[int(np.argmin(cost))]
                for c, src in zip(comps, best, strict=True):
                    row[c.slice] = blocks[src]
        return used

    def quantiles(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) quantiles ``q(alpha/2), q(1 - alpha/2)`` of the converged refits.

        Quantile ``q(a)`` is the order statistic ``a (n + 1)`` (interpolated; numpy's 'weibull'
        rule), which gives nominal coverage for exchangeable draws even at small ``n``; numpy's
        default ``a (n - 1) + 1`` makes 95% intervals from 50 draws cover only about 91%.
        """
        check_alpha(alpha)
        q = np.quantile(self.aligned(), [alpha / 2, 1 - alpha / 2], axis=0,
                        method="weibull")
        return q.T

    def percentile_ci(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) percentile intervals ``[q(alpha/2), q(1 - alpha/2)]``."""
        return self.quantiles(alpha)

    def basic_ci(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) basic intervals inside the parameter space, by the rule of the fit's own
        intervals (:func:`gmwm.intervals.bootstrap_basic`): for a scale parameter (variance,
        amplitude, |drift|) the basic interval on the log scale, ``[theta_hat^2 / q_hi,
        theta_hat^2 / q_lo]``, or ``[0, q_hi]`` where that does not exist (estimate or lower
        quantile at 0); for a shape (AR1 phi, GM beta, SIN beta) ``[2 theta_hat - q_hi,
        2 theta_hat - q_lo]`` cut to its domain."""
        from .intervals import bootstrap_basic

        return bootstrap_basic(self.estimate.model, self.estimate.params, self.quantiles(alpha))

    def ci(self, alpha: float = 0.05, kind: str = "percentile") -> np.ndarray:
        """(p, 2) intervals of ``kind`` 'percentile' or 'basic'."""
        if kind == "percentile":
            return self.percentile_ci(alpha)
        if kind == "basic":
            return self.basic_ci(alpha)
        raise InputError(f"unknown interval kind {kind!r}; use 'percentile' or 'basic'")

    # -- tables ----------------------------------------------------------------------------------
    def to_frame(self, alpha: float = 0.05, kind: str = "percentile"):
        """pandas DataFrame, one row per parameter: parameter, estimate, ci_low, ci_high, boot_se,
        sandwich_se, se_ratio (boot / sandwich), n_used (converged refits), n_failed."""
        import pandas as pd

        ci = self.ci(alpha, kind)
        boot = self.se
        sand = np.asarray(self.estimate.se, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = boot / sand
        df = pd.DataFrame({
            "parameter": self.param_names, "estimate": self.estimate.params,
            "ci_low": ci[:, 0], "ci_high": ci[:, 1], "boot_se": boot, "sandwich_se": sand,
            "se_ratio": ratio, "n_used": self.n_converged, "n_failed": self.n_failed})
        df.attrs.update(level=1 - alpha, kind=kind, model=self.estimate.model.spec,
                        n_draws=self.n_draws, n_samples=int(self.estimate.wv.n_samples))
        return df

    def _usable(self) -> bool:
        return self.refit and self.n_converged >= 2

    def summary(self, alpha: float = 0.05, kind: str = "percentile") -> str:
        """Plain-text table: parameter, estimate, CI low, CI high, boot SE, sandwich SE (NaN
        without at least two converged refits)."""
        est = self.estimate
        head = (f"parametric bootstrap of {est.model.spec} ({est.method}), T = "
                f"{est.wv.n_samples}: {self.n_draws} draws, {self.n_converged} refits used, "
                f"{self.n_failed} failed/not converged; {100 * (1 - alpha):g}% {kind} CIs")
        ci = self.ci(alpha, kind) if self._usable() else self.conf_int(alpha)
        boot = self.se
        lines = [head, (f"{'parameter':<16}{'estimate':>13}{'CI low':>13}{'CI high':>13}"
                       f"{'boot SE':>12}{'sandwich SE':>13}"), "-" * 80]
        for i, name in enumerate(self.param_names):
            lines.append(f"{name:<16}{est.params[i]:>13.5g}{ci[i, 0]:>13.5g}{ci[i, 1]:>13.5g}"
                         f"{boot[i]:>12.4g}{est.se[i]:>13.4g}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary()

    def to_json_dict(self, alpha: float = 0.05) -> dict[str, Any]:
        """JSON-able summary: settings, counts, CIs (both kinds), SEs, WV covariance (None with
        fewer than two draws); non-finite numbers are None."""
        est = self.estimate
        out: dict[str, Any] = {
            "model": est.model.spec, "method": est.method,
            "n_samples": int(est.wv.n_samples), "n_draws": self.n_draws,
            "n_converged": self.n_converged, "n_failed": self.n_failed,
            "settings": {"refit": self.refit, **self.settings.to_json_dict(),
                         "n_samples": int(est.wv.n_samples), "freq": est.wv.freq},
            "estimate": est.as_dict(), "sandwich_se": est.se_dict(),
            "wv_cov": self.wv_cov if self.n_draws >= 2 else None, "seconds": self.seconds,
            "failures": {str(k): v for k, v in self.messages.items()},
        }
        if self._usable():
            names = self.param_names
            pc, bc, se = self.percentile_ci(alpha), self.basic_ci(alpha), self.se
            out.update(level=1 - alpha,
                       percentile_ci={n: pc[i].tolist() for i, n in enumerate(names)},
                       basic_ci={n: bc[i].tolist() for i, n in enumerate(names)},
                       boot_se=dict(zip(names, se.tolist(), strict=True)))
        return json_safe(out)

    # -- chunks ----------------------------------------------------------------------------------
    @classmethod
    def combine(cls, parts: Sequence[BootstrapResult]) -> BootstrapResult:
        """Join chunks of one bootstrap (same estimate, seed and settings), sorted by draw."""
        if not parts:
            raise InputError("nothing to combine: no bootstrap chunks given")
        first = parts[0]
        for p in parts[1:]:
            same = (np.array_equal(p.estimate.params, first.estimate.params)
                    and p.estimate.model == first.estimate.model and repr(p.seed) == repr(first.seed)
                    and p.refit == first.refit and p.settings == first.settings)
            if not same:
                raise InputError("bootstrap chunks come from different estimates, seeds or settings")
        draws = np.concatenate([p.draws for p in parts])
        if np.unique(draws).size != draws.size:
            raise InputError("bootstrap chunks overlap (a draw index appears twice)")
        order = np.argsort(draws, kind="stable")
        cat = lambda name: np.concatenate([getattr(p, name) for p in parts])[order]
        messages = {k: v for p in parts for k, v in p.messages.items()}
        return cls(first.estimate, draws[order], cat("theta"), cat("converged"), cat("wv"),
                   first.seed, first.settings, messages, sum(p.seconds for p in parts),
                   first.refit)


def parametric_bootstrap(result: GMWMResult, B: int = 100, *, seed: SeedLike = 0,
                         refit: bool = True, n_starts: int | None = None,
                         weights: str | np.ndarray | None = None, reweight: int | None = None,
                         draws: Iterable[int] | None = None,
                         progress: Progress | None = None) -> BootstrapResult:
    """Parametric bootstrap of a GMWM fit (docs/METHODS.md §7).

    Each draw ``b`` simulates ``T = result.wv.n_samples`` samples from ``result.params`` (stream
    :func:`draw_seed` ``(seed, b)``), computes its WV on the same J levels and, if ``refit``,
    refits the same model with the estimate's settings (``result.settings``; ``weights``,
    ``reweight``, ``n_starts`` replace theirs if given) as an estimate-only fit
    (:func:`gmwm.fit` ``estimate_only=True``: the full fit's estimate, without its SEs,
    diagnostics or WV interval, which no bootstrap output reads). A
    refit that raises a :class:`GMWMError` or reports ``converged=False`` is kept in ``theta``
    but excluded from intervals and SEs (counted in ``n_failed``, message in ``messages``).
    ``draws`` restricts the run to those draw indices (chunks for a pipeline; join them with
    :meth:`BootstrapResult.combine`).
    """
    t0 = time.perf_counter()
    idx = _draw_list(draws, B)
    model, theta = result.model, np.asarray(result.params, dtype=float)
    wv0 = result.wv
    J, T = wv0.n_levels, int(wv0.n_samples)
    given = {"weights": weights, "reweight": reweight, "n_starts": n_starts}
    settings = result.settings.replace(se_cov="gaussian", levels=J,
                                       **{k: v for k, v in given.items() if v is not None})
    p = model.n_params
    th = np.full((idx.size, p), np.nan)
    ok = np.zeros(idx.size, dtype=bool)
    nus = np.empty((idx.size, J))
    messages: dict[int, str] = {}
    for i, b in enumerate(idx):
        ss = draw_seed(seed, int(b))
        x = simulate_draw(model, theta, T, np.random.default_rng(ss))
        if not refit:
            nus[i] = _wv_values(x, J)
        else:
            try:
                # estimate_only: the bootstrap reads the refit's params, convergence and WV
                # values, not its SEs, diagnostics or the WV's interval (same search and optimum)
                res = fit(x, model, settings=settings, freq=wv0.freq, seed=_fit_seed(ss),
                          estimate_only=True)
                nus[i] = res.wv.variance
                th[i] = res.params
                ok[i] = bool(res.converged) and bool(np.all(np.isfinite(res.params)))
                if not ok[i]:
                    messages[int(b)] = f"not converged: {res.message}"
            except GMWMError as err:
                nus[i] = _wv_values(x, J)
                messages[int(b)] = f"refit failed: {err}"
        del x
        if progress is not None:
            progress(i + 1, idx.size)
    return BootstrapResult(result, idx, th, ok, nus, seed, settings, messages,
                           time.perf_counter() - t0, bool(refit))


# -- coverage -------------------------------------------------------------------------------------
class Coverage(NamedTuple):
    """Per-parameter share of replicates covering the truth, its Monte Carlo SE, the number of
    replicates with a finite interval, and the Wilson score interval of the share (``lo``, ``hi``;
    95 %), which stays inside [0, 1] and is not empty at a share of 0 or 1."""

    share: np.ndarray
    mcse: np.ndarray
    n: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def covers(ci: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Boolean (..., p): ``ci[..., 0] <= truth <= ci[..., 1]`` (False where the CI is NaN)."""
    ci = np.asarray(ci, dtype=float)
    truth = np.asarray(truth, dtype=float)
    if ci.shape[-1] != 2 or ci.shape[-2] != truth.shape[-1]:
        raise InputError(f"intervals must have shape (..., p, 2) with p = {truth.shape[-1]}, "
                         f"got {ci.shape}")
    with np.errstate(invalid="ignore"):
        return (ci[..., 0] <= truth) & (truth <= ci[..., 1])


def coverage(cis: np.ndarray, truth: np.ndarray) -> Coverage:
    """Coverage of intervals ``cis`` (R, p, 2) for ``truth`` (p,).

    Replicates whose interval is NaN (e.g. no converged refits) are left out per parameter and
    ``n`` says how many were used. ``mcse = sqrt(c (1 - c) / n)`` (binomial Monte Carlo SE, 0 at a
    share of 0 or 1, so reports quote the Wilson interval ``lo``-``hi`` instead).
    """
    cis = np.asarray(cis, dtype=float)
    if cis.ndim != 3:
        raise InputError(f"intervals must have shape (R, p, 2), got {cis.shape}")
    hit = covers(cis, truth)
    finite = np.all(np.isfinite(cis), axis=-1)
    n = finite.sum(axis=0)
    from scipy.stats import binomtest

    k = (hit & finite).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(n > 0, k / np.maximum(n, 1), np.nan)
        mcse = np.sqrt(share * (1 - share) / n)
    lo, hi = np.full(len(n), np.nan), np.full(len(n), np.nan)
    for j in np.flatnonzero(n > 0):
        ci = binomtest(int(k[j]), int(n[j])).proportion_ci(confidence_level=0.95, method="wilson")
        lo[j], hi[j] = ci.low, ci.high
    return Coverage(share, mcse, n, lo, hi)
