"""Parametric bootstrap of a GMWM fit (SPEC 5.6): WV covariance, refits, confidence intervals.

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
  ``theta*`` (canonical component order), bootstrap SEs. Refits that fail or do not converge are
  excluded from CIs and SEs and counted (``n_failed``).
* ``coverage``: share of Monte Carlo replicates whose interval covers the truth, with its
  Monte Carlo SE ``sqrt(c (1 - c) / R)``.

Pipeline runners (the Snakemake rules of ``workflow/rules/uncertainty.smk`` only wire these):
``replicate_fit`` (the fit of one Monte Carlo replicate, as the studies do it),
``bootstrap_to_dataset`` / ``bootstrap_from_dataset`` (chunks on disk), ``bootstrap_table``
(Table-1 rows: estimate, percentile and basic CIs, bootstrap and sandwich SEs),
``coverage_chunk`` / ``coverage_summary`` / ``plot_coverage`` (coverage study).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from itertools import permutations
from typing import Any, NamedTuple

import numpy as np

from .errors import GMWMError, InputError
from .estimator import GMWMResult, fit
from .model import Model
from .wv import wvar

__all__ = ["CI_KINDS", "BootstrapResult", "Coverage", "bootstrap_cov", "bootstrap_from_dataset",
           "bootstrap_table", "bootstrap_to_dataset", "coverage", "coverage_chunk",
           "coverage_summary", "covers", "draw_seed", "navchip_result", "parametric_bootstrap",
           "plot_coverage", "replicate_fit", "simulate_draw", "wv_bootstrap"]

Progress = Callable[[int, int], None]


def _free(model: Model, theta: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        eta = model.to_free(np.asarray(theta, dtype=float))
    return np.nan_to_num(eta, nan=0.0, posinf=50.0, neginf=-50.0)


def _positive_params(model: Model) -> np.ndarray:
    """Per parameter: its domain is (0, inf) (every parameter but AR1 phi, DR omega, SIN beta)."""
    out = []
    for c in model.components:
        for n in c.process.param_names:
            out.append(not ((c.process.name == "AR1" and n == "phi") or c.process.name == "DR"
                            or (c.process.name == "SIN" and n == "beta")))
    return np.array(out, dtype=bool)
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
    """One signal of ``n_samples`` from ``model`` at ``theta``, components in canonical order.

    Same stream use as :meth:`Model.simulate`, except that a linear component estimated at the
    boundary 0 (closed-form NNLS) is skipped instead of rejected: it contributes nothing.
    """
    theta = np.asarray(theta, dtype=float)
    if theta.shape != (model.n_params,):
        raise InputError(f"model {model.spec} has {model.n_params} parameters, got {theta.size}")
    x = np.zeros(int(n_samples))
    for c in model.components:
        p = theta[c.slice]
        if c.process.linear and p[0] == 0:
            continue
        msg = c.process.check(p)
        if msg:
            raise InputError(f"cannot simulate from the estimate: {c.name}: {msg}")
        x += c.process.simulate(p, x.size, rng, model.freq)
    return x


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
        out.append(wvar(x, levels=levels).variance)
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
@dataclass
class BootstrapResult:
    """Draws of a parametric bootstrap of ``estimate``; rows follow ``draws``.

    ``theta`` (n, p) holds the refits in canonical order (NaN where a refit raised),
    ``converged`` (n,) marks refits used for CIs/SEs, ``wv`` (n, J) the simulated WVs.
    """

    estimate: GMWMResult
    draws: np.ndarray
    theta: np.ndarray
    converged: np.ndarray
    wv: np.ndarray
    seed: Any = 0
    settings: dict[str, Any] = field(default_factory=dict)
    messages: dict[int, str] = field(default_factory=dict)
    seconds: float = 0.0

    # -- sizes -----------------------------------------------------------------------------------
    @property
    def param_names(self) -> list[str]:
        return self.estimate.param_names

    @property
    def n_draws(self) -> int:
        return int(self.draws.size)

    @property
    def refit(self) -> bool:
        return bool(self.settings.get("refit", True))

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
        opts: dict[str, Any] = {"method": est.method, "seed": 0}
        if "n_starts" in self.settings:
            opts["n_starts"] = self.settings["n_starts"]
        opts.update(kwargs)
        res = fit(est.wv, est.model, weights=self.wv_cov, **opts)
        for c in est.model.components:
            if c.process.name == "DR" and est.params[c.start] < 0:
                res.params[c.start] = -res.params[c.start]
        return res

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

    def se(self) -> np.ndarray:
        """Bootstrap standard errors: SD (ddof = 1) of the converged, label-aligned refits."""
        return np.std(self.aligned(), axis=0, ddof=1)

    def aligned(self) -> np.ndarray:
        """Converged refits with same-type components relabelled to match the estimate (the
        permutation closest to it in free coordinates), so quantiles do not mix label-switched
        draws."""
        used = self._need_refits().copy()
        model = self.estimate.model
        est_eta = _free(model, self.estimate.params)
        for name in ("AR1", "GM", "SIN"):
            comps = [c for c in model.components if c.process.name == name]
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
        _check_alpha(alpha)
        q = np.quantile(self.aligned(), [alpha / 2, 1 - alpha / 2], axis=0,
                        method="weibull")
        return q.T

    def percentile_ci(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) percentile intervals ``[q(alpha/2), q(1 - alpha/2)]``."""
        return self.quantiles(alpha)

    def basic_ci(self, alpha: float = 0.05) -> np.ndarray:
        """(p, 2) basic intervals ``[2 theta_hat - q(1-alpha/2), 2 theta_hat - q(alpha/2)]``,
        formed on the log scale for positive parameters (variances, amplitudes, GM beta) so that
        they never leave the domain: ``[theta_hat^2 / q_hi, theta_hat^2 / q_lo]``."""
        q = self.quantiles(alpha)
        th = self.estimate.params
        out = np.column_stack([2 * th - q[:, 1], 2 * th - q[:, 0]])
        pos = _positive_params(self.estimate.model)
        with np.errstate(all="ignore"):
            logci = np.column_stack([th**2 / q[:, 1], th**2 / q[:, 0]])
        ok = pos & (th > 0) & np.all(q > 0, axis=1)
        out[ok] = logci[ok]
        return out

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
        boot = self.se()
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

    def summary(self, alpha: float = 0.05, kind: str = "percentile") -> str:
        """Plain-text table: parameter, estimate, CI low, CI high, boot SE, sandwich SE."""
        est = self.estimate
        head = (f"parametric bootstrap of {est.model.spec} ({est.method}), T = "
                f"{est.wv.n_samples}: {self.n_draws} draws, {self.n_converged} refits used, "
                f"{self.n_failed} failed/not converged; {100 * (1 - alpha):g}% {kind} CIs")
        ci, boot = self.ci(alpha, kind), self.se()
        lines = [head, (f"{'parameter':<16}{'estimate':>13}{'CI low':>13}{'CI high':>13}"
                       f"{'boot SE':>12}{'sandwich SE':>13}"), "-" * 80]
        for i, name in enumerate(self.param_names):
            lines.append(f"{name:<16}{est.params[i]:>13.5g}{ci[i, 0]:>13.5g}{ci[i, 1]:>13.5g}"
                         f"{boot[i]:>12.4g}{est.se[i]:>13.4g}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.summary() if self.refit and self.n_converged >= 2 else repr(self)

    def to_json_dict(self, alpha: float = 0.05) -> dict[str, Any]:
        """JSON-able summary: settings, counts, CIs (both kinds), SEs, WV covariance."""
        out: dict[str, Any] = {
            "model": self.estimate.model.spec, "method": self.estimate.method,
            "n_samples": int(self.estimate.wv.n_samples), "n_draws": self.n_draws,
            "n_converged": self.n_converged, "n_failed": self.n_failed,
            "settings": {k: v for k, v in self.settings.items() if k != "weights_matrix"},
            "estimate": self.estimate.as_dict(), "sandwich_se": self.estimate.se_dict(),
            "wv_cov": self.wv_cov.tolist(), "seconds": self.seconds,
            "failures": {str(k): v for k, v in self.messages.items()},
        }
        if self.refit and self.n_converged >= 2:
            names = self.param_names
            pc, bc, se = self.percentile_ci(alpha), self.basic_ci(alpha), self.se()
            out.update(level=1 - alpha,
                       percentile_ci={n: pc[i].tolist() for i, n in enumerate(names)},
                       basic_ci={n: bc[i].tolist() for i, n in enumerate(names)},
                       boot_se=dict(zip(names, se.tolist(), strict=True)))
        return out

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
                    and p.settings.get("refit") == first.settings.get("refit"))
            if not same:
                raise InputError("bootstrap chunks come from different estimates, seeds or settings")
        draws = np.concatenate([p.draws for p in parts])
        if np.unique(draws).size != draws.size:
            raise InputError("bootstrap chunks overlap (a draw index appears twice)")
        order = np.argsort(draws, kind="stable")
        cat = lambda name: np.concatenate([getattr(p, name) for p in parts])[order]
        messages = {k: v for p in parts for k, v in p.messages.items()}
        return cls(first.estimate, draws[order], cat("theta"), cat("converged"), cat("wv"),
                   first.seed, dict(first.settings), messages, sum(p.seconds for p in parts))


def _check_alpha(alpha: float) -> None:
    if not 0 < alpha < 1:
        raise InputError(f"alpha must lie in (0, 1), got {alpha}")


def parametric_bootstrap(result: GMWMResult, B: int = 100, *, seed: SeedLike = 0,
                         refit: bool = True, n_starts: int | None = None,
                         weights: str | np.ndarray | None = None, reweight: int | None = None,
                         draws: Iterable[int] | None = None,
                         progress: Progress | None = None) -> BootstrapResult:
    """Parametric bootstrap of a GMWM fit (SPEC 5.6).

    Each draw ``b`` simulates ``T = result.wv.n_samples`` samples from ``result.params`` (stream
    :func:`draw_seed` ``(seed, b)``), computes its WV on the same J levels and, if ``refit``,
    refits the same model with the same method, weights, reweighting and ``n_starts`` as the
    estimate (its ``settings``, unless ``weights``/``reweight``/``n_starts`` are given). A
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
    recorded = result.fit_kwargs()
    if weights is None:
        weights = recorded["weights"]
    if reweight is None:
        reweight = recorded["reweight"]
    reweight = int(reweight)
    if n_starts is None:
        n_starts = recorded["n_starts"]
    kind = weights if isinstance(weights, str) else "covariance"
    settings = {"refit": bool(refit), "weights": kind, "reweight": reweight, "n_starts": n_starts,
                "method": result.method, "levels": J, "n_samples": T, "freq": wv0.freq}
    p = model.n_params
    th = np.full((idx.size, p), np.nan)
    ok = np.zeros(idx.size, dtype=bool)
    nus = np.empty((idx.size, J))
    messages: dict[int, str] = {}
    for i, b in enumerate(idx):
        ss = draw_seed(seed, int(b))
        x = simulate_draw(model, theta, T, np.random.default_rng(ss))
        if not refit:
            nus[i] = wvar(x, levels=J).variance
        else:
            try:
                res = fit(x, model, levels=J, freq=wv0.freq, weights=weights, method=result.method,
                          n_starts=n_starts, seed=_fit_seed(ss), reweight=reweight,
                          se_cov="gaussian", nested=recorded["nested"])
                nus[i] = res.wv.variance
                th[i] = res.params
                ok[i] = bool(res.converged) and bool(np.all(np.isfinite(res.params)))
                if not ok[i]:
                    messages[int(b)] = f"not converged: {res.message}"
            except GMWMError as err:
                nus[i] = wvar(x, levels=J).variance
                messages[int(b)] = f"refit failed: {err}"
        del x
        if progress is not None:
            progress(i + 1, idx.size)
    return BootstrapResult(result, idx, th, ok, nus, seed, settings, messages,
                           time.perf_counter() - t0)


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


# -- pipeline runners -----------------------------------------------------------------------------
CI_KINDS = ("percentile", "basic", "wald")
_FIT_KEYS = ("weights", "n_starts", "reweight", "method", "max_nfev")


def fit_kwargs(settings: dict[str, Any] | None) -> dict[str, Any]:
    """The ``gmwm.fit`` keywords among an estimator's settings (others, e.g. AVSM's, dropped)."""
    return {k: v for k, v in (settings or {}).items() if k in _FIT_KEYS}


def replicate_fit(model_spec: str, truth: dict[str, float], n_samples: int, replicate: int, *,
                  study: str, base_seed: int, settings: dict[str, Any] | None = None,
                  levels: int | None = None, freq: float = 1.0) -> GMWMResult:
    """GMWM fit of replicate ``replicate`` of a Monte Carlo study, as ``gmwm.studies`` does it.

    The signal uses the replicate's stream (``gmwm.seeds.replicate_rng``), the WV is rebuilt from
    its variances (CIs from the eta_3 rule) and the fit's starts use stream 1, so the result equals
    the study's own fit of that replicate.
    """
    from .seeds import replicate_rng, replicate_seed
    from .wv import WaveletVariance

    model = Model(model_spec, freq=freq)
    theta = model.theta(dict(truth))
    x = model.simulate(theta, int(n_samples), replicate_rng(study, n_samples, replicate, base_seed))
    wv = wvar(x, levels=levels, freq=freq)
    del x
    wv = WaveletVariance.from_table(wv.scales, wv.variance, n_samples=int(n_samples), freq=freq)
    seed = replicate_seed(study, n_samples, replicate, base_seed, stream=1)
    return fit(wv, model, seed=seed, **fit_kwargs(settings))


def navchip_result(data_path: str, fits_path: str, sensor: str, axis: str) -> GMWMResult:
    """The Navchip fit of one axis as a :class:`GMWMResult`, from the navchip rule's fits file.

    The fit is redone on the channel's WV with the settings recorded in the fits file (the fit is
    deterministic given its seed) to recover the weights; if the estimate differs from the recorded
    one (e.g. another library version), the recorded estimate is used
    (``diagnostics['navchip_refit_differs']``). ``se`` is the recorded sandwich SE (NaN at the
    boundary), ``cov`` stays the refit's.
    """
    import dataclasses
    import json

    from .data import load_navchip_wv

    with open(fits_path, encoding="utf-8") as fh:
        data = json.load(fh)
    recs = [c for c in data["channels"] if c["sensor"] == sensor and c["axis"] == axis]
    if not recs:
        raise InputError(f"{fits_path} has no fit for Navchip {sensor} {axis}")
    rec = recs[0]
    wv = load_navchip_wv(data_path, sensor, axis)
    model = Model(rec["model"], freq=float(rec["freq"]))
    res = fit(wv, model, freq=wv.freq, **dict(data.get("fit_settings", {})))
    stored = model.theta(rec["params"], estimate=True)
    differs = not np.allclose(res.params, stored, rtol=1e-6, atol=0)
    res.diagnostics["navchip_refit_differs"] = bool(differs)
    # the recorded SEs (sandwich in the free log coordinates, delta method) are the reported ones;
    # the library's theta-coordinate sandwich is kept in diagnostics (ill-conditioned for GM beta)
    se = np.array([rec["se"].get(n, np.nan) for n in model.param_names], dtype=float)
    res.diagnostics["se_library"] = res.se.tolist()
    res = dataclasses.replace(res, params=stored if differs else res.params, se=se)
    return res


def bootstrap_to_dataset(boot: BootstrapResult):
    """xarray Dataset of a bootstrap chunk: theta (draw, parameter), converged, wv (draw, level);
    the estimate, seed, settings and failure messages in attributes (JSON)."""
    import json

    import xarray as xr

    est = boot.estimate
    msgs = [boot.messages.get(int(b), "") for b in boot.draws]
    return xr.Dataset(
        {"theta": (("draw", "parameter"), boot.theta),
         "converged": ("draw", boot.converged.astype(np.int8)),
         "wv": (("draw", "level"), boot.wv),
         "message": ("draw", np.asarray(msgs, dtype=object))},
        coords={"draw": boot.draws.astype(np.int64),
                "parameter": np.asarray(est.param_names, dtype=object),
                "level": np.asarray(est.wv.levels, dtype=np.int64)},
        attrs={"model": est.model.spec, "n_samples": int(est.wv.n_samples),
               "estimate": json.dumps(est.params.tolist()), "seed": repr(boot.seed),
               "settings": json.dumps(boot.settings, default=str), "seconds": boot.seconds})


def bootstrap_from_dataset(ds, estimate: GMWMResult) -> BootstrapResult:
    """Inverse of :func:`bootstrap_to_dataset` given the estimate the chunk was drawn from
    (raises InputError if the stored estimate differs: the chunk is stale)."""
    import json

    stored = np.asarray(json.loads(ds.attrs["estimate"]), dtype=float)
    if not np.allclose(stored, estimate.params, rtol=1e-9, atol=0):
        raise InputError("bootstrap chunk was drawn from a different estimate; rerun its job")
    msgs = {int(b): str(m) for b, m in zip(ds["draw"].values, ds["message"].values, strict=True)
            if str(m)}
    return BootstrapResult(estimate, ds["draw"].values.astype(np.int64),
                           np.asarray(ds["theta"].values, dtype=float),
                           np.asarray(ds["converged"].values, dtype=bool),
                           np.asarray(ds["wv"].values, dtype=float), ds.attrs["seed"],
                           json.loads(ds.attrs["settings"]), msgs, float(ds.attrs["seconds"]))


def bootstrap_table(boot: BootstrapResult, label: str, alpha: float = 0.05):
    """Table-1 rows of one fitted model: label, parameter, estimate, percentile and basic CIs,
    bootstrap SE, sandwich SE, their ratio, refits used/failed, T, B."""
    pct, bas = boot.percentile_ci(alpha), boot.basic_ci(alpha)
    df = boot.to_frame(alpha, "percentile").rename(columns={"ci_low": "pct_low",
                                                            "ci_high": "pct_high"})
    df.insert(4, "basic_low", bas[:, 0])
    df.insert(5, "basic_high", bas[:, 1])
    df["pct_low"], df["pct_high"] = pct[:, 0], pct[:, 1]
    df.insert(0, "model", boot.estimate.model.spec)
    df.insert(0, "fit", label)
    df["n_samples"] = int(boot.estimate.wv.n_samples)
    df["B"] = boot.n_draws
    return df


def _wald(est: np.ndarray, se: np.ndarray, alpha: float) -> np.ndarray:
    from scipy.stats import norm

    z = norm.ppf(1 - alpha / 2)
    return np.stack([est - z * se, est + z * se], axis=-1)


def coverage_chunk(model_spec: str, truth: dict[str, float], n_samples: int,
                   replicates: Sequence[int], *, study: str, base_seed: int, B: int,
                   settings: dict[str, Any] | None = None, levels: int | None = None,
                   alpha: float = 0.05, progress: Callable[[str], None] | None = None):
    """Coverage study, one chunk of replicates: fit each replicate (:func:`replicate_fit`), run a
    parametric bootstrap of B refits from its estimate (draw streams extend the replicate's stream
    2, so results do not depend on chunking) and keep the percentile, basic and Wald (sandwich SE)
    intervals.

    Returns an xarray Dataset over (replicate, parameter): estimate, sandwich_se, boot_se,
    converged, n_used, seconds, and ci (replicate, kind, parameter, bound) with kind in
    :data:`CI_KINDS`; ``truth`` coordinate. NaN where a fit or all refits failed.
    """
    import xarray as xr

    from .seeds import replicate_seed_sequence

    model = Model(model_spec)
    theta0 = model.theta(dict(truth))
    names = model.param_names
    R, p = len(replicates), model.n_params
    est, sand, bse = (np.full((R, p), np.nan) for _ in range(3))
    ci = np.full((R, len(CI_KINDS), p, 2), np.nan)
    conv = np.zeros(R, dtype=bool)
    n_used = np.zeros(R, dtype=np.int64)
    secs = np.full(R, np.nan)
    for i, rep in enumerate(replicates):
        t0 = time.perf_counter()
        try:
            res = replicate_fit(model_spec, truth, n_samples, int(rep), study=study,
                                base_seed=base_seed, settings=settings, levels=levels)
        except GMWMError as err:
            if progress:
                progress(f"replicate {rep}: fit failed: {err}")
            continue
        conv[i] = bool(res.converged)
        est[i], sand[i] = res.params, res.se
        ci[i, 2] = _wald(res.params, res.se, alpha)
        ss = replicate_seed_sequence(study, n_samples, int(rep), base_seed, stream=2)
        kw = fit_kwargs(settings)
        boot = parametric_bootstrap(res, B, seed=ss, n_starts=kw.get("n_starts"))
        n_used[i] = boot.n_converged
        if boot.n_converged >= 2:
            bse[i] = boot.se()
            ci[i, 0], ci[i, 1] = boot.percentile_ci(alpha), boot.basic_ci(alpha)
        secs[i] = time.perf_counter() - t0
        if progress:
            progress(f"replicate {i + 1}/{R} (id {rep}): {boot.n_converged}/{B} refits used, "
                     f"{secs[i]:.1f} s")
    return xr.Dataset(
        {"estimate": (("replicate", "parameter"), est),
         "sandwich_se": (("replicate", "parameter"), sand),
         "boot_se": (("replicate", "parameter"), bse),
         "ci": (("replicate", "kind", "parameter", "bound"), ci),
         "converged": ("replicate", conv.astype(np.int8)),
         "n_used": ("replicate", n_used), "seconds": ("replicate", secs)},
        coords={"replicate": np.asarray(replicates, dtype=np.int64),
                "parameter": np.asarray(names, dtype=object),
                "kind": np.asarray(CI_KINDS, dtype=object),
                "bound": np.asarray(["low", "high"], dtype=object),
                "truth": ("parameter", theta0)},
        attrs={"study": study, "model": model_spec, "n_samples": int(n_samples), "B": int(B),
               "alpha": float(alpha), "base_seed": int(base_seed)})


def coverage_summary(ds):
    """Per parameter and interval kind: coverage share, its MC SE sqrt(c (1-c) / n), n used,
    mean CI width; plus per parameter the mean and median of boot SE / sandwich SE and the
    empirical SD of the estimates over the mean sandwich and mean bootstrap SEs."""
    import pandas as pd

    truth = ds["truth"].values
    names = [str(n) for n in ds["parameter"].values]
    ci = ds["ci"].values  # (R, kind, p, 2)
    est = ds["estimate"].values
    sand, bse = ds["sandwich_se"].values, ds["boot_se"].values
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = bse / sand
        emp_sd = np.nanstd(est, axis=0, ddof=1)
        sd_sand = emp_sd / np.nanmean(sand, axis=0)
        sd_boot = emp_sd / np.nanmean(bse, axis=0)
    rows = []
    for k, kind in enumerate(ds["kind"].values):
        cov = coverage(ci[:, k], truth)
        width = np.nanmean(ci[:, k, :, 1] - ci[:, k, :, 0], axis=0)
        for j, name in enumerate(names):
            rows.append({"parameter": name, "truth": truth[j], "interval": str(kind),
                         "coverage": cov.share[j], "mc_se": cov.mcse[j],
                         "wilson_lo": cov.lo[j], "wilson_hi": cov.hi[j], "n": int(cov.n[j]),
                         "mean_width": width[j],
                         "mean_se_ratio": np.nanmean(ratio[:, j]),
                         "median_se_ratio": np.nanmedian(ratio[:, j]),
                         "sd_over_sandwich": sd_sand[j], "sd_over_boot": sd_boot[j]})
    df = pd.DataFrame(rows)
    df.attrs.update(level=1 - float(ds.attrs["alpha"]), n_samples=int(ds.attrs["n_samples"]),
                    B=int(ds.attrs["B"]), R=int(ds.sizes["replicate"]))
    return df


def plot_coverage(summary, level: float = 0.95, ax=None):
    """Coverage per parameter (x, in the papers' notation) and interval kind (markers) with the
    Wilson 95 % interval of each coverage as bars (inside [0, 1]) and the nominal line. Returns
    the matplotlib Figure."""
    import matplotlib.pyplot as plt

    if ax is None:
        fig, ax = plt.subplots(figsize=(7.5, 3.8))
    else:
        fig = ax.figure
    names = list(dict.fromkeys(summary["parameter"]))
    kinds = list(dict.fromkeys(summary["interval"]))
    x = np.arange(len(names))
    for k, (kind, mk) in enumerate(zip(kinds, "osd^v", strict=False)):
        sub = summary[summary["interval"] == kind].set_index("parameter").loc[names]
        off = (k - (len(kinds) - 1) / 2) * 0.18
        c = sub["coverage"].to_numpy(float)
        yerr = np.clip(np.vstack([c - sub["wilson_lo"].to_numpy(float),
                                  sub["wilson_hi"].to_numpy(float) - c]), 0.0, None)
        ax.errorbar(x + off, c, yerr=yerr, fmt=mk, ms=5, capsize=3, label=kind)
    ax.axhline(level, color="0.3", ls="--", lw=1, label=f"nominal {level:g}")
    from gmwm.plots import param_label

    ax.set_xticks(x, [param_label(n, names) for n in names], fontsize=9)
    ax.set_ylabel("coverage (Wilson 95 % interval)")
    lo = float(np.nanmin(summary["wilson_lo"]))
    ax.set_ylim(max(0.0, min(lo, level - 0.1) - 0.02), 1.01)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    return fig
