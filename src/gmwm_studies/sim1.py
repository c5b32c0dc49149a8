"""Simulation 1 of the vibration-noise paper ([Vibration] Sec. 4, Figs 1, 2, 9): GMWM against
maximum likelihood (docs/METHODS.md §12.1-§12.2).

Per replicate one WN + RW + AR1 + SIN signal is simulated from
:func:`seeds.replicate_rng` ``(study, T, r, seed)`` (so results do not depend on chunking), the
GMWM is fitted to the signal and, for the first ``n_mle`` replicates of each sample size, the
project's Kalman-filter MLE (:func:`gmwm_studies.mle.fit_mle`, sinusoid frequency known) once per
configured *variant*, i.e. per starting rule:

* ``moment``: the MLE's own data-driven start (NNLS fit of the model to the empirical variogram
  on a grid of phi), no GMWM information: the MLE as a user would run it;
* ``default``: statsmodels' start values (``UnobservedComponents(...).start_params``), still the
  project's filter and optimiser;
* ``gmwm``: started at the GMWM estimate (labelled; not a like-for-like comparison).

The first variant is the headline. A variant other than the headline may run on fewer replicates
(``variant_replicates``: the first ones, a cost cap); its comparison and counts are over the
replicates where it ran. Separately (:func:`run_baseline_chunk`, its own pipeline rule,
on a smaller subset of the same signals because it is slow) the general-purpose baseline
``statsmodels``: statsmodels' own estimator (:func:`gmwm_studies.mle.fit_statsmodels`), merged
in by :func:`add_baseline`. Raw signals are never stored.

Two clocks per fit: ``seconds``, the point estimate alone (GMWM: its WV and search,
``GMWMResult.seconds_wv + seconds_fit``; MLE: the optimisation), and ``seconds_se``, the point
estimate with its standard errors (GMWM: the whole ``gmwm.fit`` call, which adds the sandwich SEs
under the model-based WV covariance and the fit diagnostics; Kalman MLE: plus the observed
information by a finite-difference Hessian; statsmodels: plus its default OPG covariance). Both
in wall time and (``cpu_seconds``, ``cpu_seconds_se``) in process CPU time, which other load on
the machine barely affects; the GMWM's point-estimate CPU time is its call's CPU time split in the
proportion of its wall-clock parts (``gmwm.fit`` times its parts by wall clock only).

Results are xarray Datasets with dims ``(estimator, replicate, parameter)``; ``estimator`` is
``['gmwm', <variant names>]``. The methods are compared on WN sigma2, AR1 phi, AR1 innovation
variance and RW gamma2 only (the MLE treats the sinusoid as deterministic, as the paper's Hector
MLE did). Following the paper, a replicate where a variant's MLE did not converge, or stopped at a
wrong optimum (log-likelihood more than ``wrong_optimum_ll`` below the best any variant reached on
that signal), is dropped from *both* methods in that variant's comparison, and counted. The best
is over the variants fitted to that signal, so a variant beyond its cap takes no part in it.
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import GMWMError, InputError
from gmwm_studies.seeds import replicate_rng, replicate_seed

__all__ = [
    "COMPARED",
    "DEFAULT_MLE",
    "PARAM_LABELS",
    "SHORT_NAMES",
    "START_RULES",
    "add_baseline",
    "comparison_table",
    "counts_text",
    "gmwm_text",
    "method_label",
    "paired_mask",
    "run_baseline_chunk",
    "run_chunk",
    "run_replicate",
    "standardized_by_method",
    "study_tables",
    "summarize_comparison",
    "variant_replicate_caps",
    "variants_of",
    "wrong_optimum",
]

COMPARED = ("WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2")
SHORT_NAMES = {"WN[1].sigma2": "sigma2", "AR1[1].phi": "phi", "AR1[1].sigma2": "ar1_sigma2",
               "RW[1].gamma2": "gamma2"}
#: Starting rules of the MLE variants and their display names; ``statsmodels`` is the baseline
#: estimator (statsmodels' own fit), run by :func:`run_baseline_chunk`, not a variant.
START_RULES = {"moment": "own moment start", "default": "statsmodels' start, own filter",
               "gmwm": "GMWM start", "statsmodels": "statsmodels' own fit"}
VARIANT_RULES = ("moment", "default", "gmwm")
#: Estimator name (and rule) of the statsmodels baseline in the results.
BASELINE = "statsmodels"
MLE_KEYS = ("backend", "maxiter", "wrong_optimum_ll", "variants")
BASELINE_KEYS = ("maxiter",)
#: Settings used when the config leaves them out.
DEFAULT_MLE: dict[str, Any] = {"backend": "kalman", "maxiter": 200, "wrong_optimum_ll": 1.0,
                               "variants": {"mle": "moment", "mle_gmwm": "gmwm"}}
_FAILURES = (GMWMError, np.linalg.LinAlgError, FloatingPointError)

Progress = Callable[[str], None]


def _noop(_: str) -> None:
    return None


def _mle_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """Settings with defaults filled in and checked (one-line errors)."""
    unknown = sorted(set(settings) - set(MLE_KEYS))
    if unknown:
        raise InputError(f"unknown MLE setting(s) {unknown}; allowed: {list(MLE_KEYS)}")
    out = {**DEFAULT_MLE, **dict(settings)}
    variants = dict(out["variants"])
    if not variants:
        raise InputError("the MLE needs at least one variant (name: start rule)")
    for name, rule in variants.items():
        if rule not in VARIANT_RULES:
            raise InputError(f"MLE variant {name!r}: unknown start rule {rule!r}; "
                             f"use one of {list(VARIANT_RULES)}")
        if name in ("gmwm", BASELINE):
            raise InputError(f"an MLE variant cannot be called {name!r}")
    out["variants"] = variants
    if not float(out["wrong_optimum_ll"]) > 0:
        raise InputError(f"wrong_optimum_ll must be > 0, got {out['wrong_optimum_ll']}")
    return out


def variants_of(ds: xr.Dataset) -> dict[str, str]:
    """{variant name: start rule} of a results Dataset, in configured order (first = headline)."""
    return json.loads(ds.attrs["variants"])


def method_label(name: str, rule: str | None = None) -> str:
    """Display name: ``'GMWM'`` or ``'MLE (<start>)'``."""
    return "GMWM" if name == "gmwm" else f"MLE ({START_RULES.get(rule or '', name)})"


# ---------------------------------------------------------------------------------------------
# one replicate, one chunk
# ---------------------------------------------------------------------------------------------


def _check_model(model: Any, truth: Mapping[str, float]) -> float:
    """The compared parameters must be in the model; returns the (known) sinusoid frequency."""
    missing = [p for p in (*COMPARED, "SIN[1].beta") if p not in model.param_names]
    if missing or model.count("SIN") != 1:
        raise InputError(
            f"the MLE comparison needs a WN + RW + AR1 + one SIN model, got {model.spec!r}"
        )
    return float(truth["SIN[1].beta"])


def _empty_fit(n: int, ran: bool = False, message: str = "") -> dict[str, Any]:
    return {"estimate": np.full(n, np.nan), "se": np.full(n, np.nan), "converged": False,
            "start": "", "loglike": np.nan, "seconds": np.nan, "seconds_se": np.nan,
            "cpu_seconds": np.nan, "cpu_seconds_se": np.nan, "ran": ran, "message": message}


def _mle_record(res: Any, names: Sequence[str]) -> dict[str, Any]:
    """Fit record of an :class:`~gmwm_studies.mle.MLEResult` (estimates and SEs by name)."""
    est, se = res.as_dict(), dict(zip(res.param_names, res.se, strict=True))
    return {"estimate": np.array([est.get(n, np.nan) for n in names]),
            "se": np.array([se.get(n, np.nan) for n in names]),
            "converged": bool(res.converged), "start": res.start, "loglike": float(res.loglike),
            "message": res.message, "seconds": float(res.seconds),
            "seconds_se": float(res.seconds + res.seconds_se),
            "cpu_seconds": float(res.cpu_seconds),
            "cpu_seconds_se": float(res.cpu_seconds + res.cpu_seconds_se)}


def _fit_variant(x: np.ndarray, beta: float, rule: str, gmwm_start: dict[str, float] | None,
                 settings: Mapping[str, Any], names: Sequence[str]) -> dict[str, Any]:
    from gmwm_studies.mle import fit_mle

    if rule == "gmwm" and gmwm_start is None:
        return _empty_fit(len(names), True, "not run: the GMWM fit failed")
    kw = {"maxiter": int(settings["maxiter"]), "backend": str(settings["backend"]), "n_starts": 1,
          "own_starts": "default" if rule == "default" else "variogram", "se": True}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        return {**_mle_record(fit_mle(x, beta, gmwm_start if rule == "gmwm" else None, **kw),
                              names), "ran": True}
    except _FAILURES as exc:
        return {**_empty_fit(len(names), True, f"{type(exc).__name__}: {exc}"),
                **_failed_clocks(t0, c0)}


def _failed_clocks(t0: float, c0: float) -> dict[str, float]:
    """Both clocks of a fit that raised: the time it cost, as point estimate and with SEs."""
    secs, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"seconds": secs, "seconds_se": secs, "cpu_seconds": cpu, "cpu_seconds_se": cpu}


def _signal(model: Any, theta: np.ndarray, n_samples: int, replicate: int, study: str,
            base_seed: int) -> np.ndarray:
    """Replicate ``replicate``'s signal (the same in every rule that fits it)."""
    return model.simulate(theta, int(n_samples),
                          replicate_rng(study, n_samples, replicate, base_seed))


def run_replicate(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicate: int,
    study: str,
    base_seed: int,
    gmwm_settings: Mapping[str, Any],
    mle_settings: Mapping[str, Any] | None,
    variants: Sequence[str] | None = None,
) -> dict[str, Any]:
    """Simulate replicate ``replicate``, fit the GMWM and (unless ``mle_settings`` is None) every
    MLE variant, or only those named in ``variants`` (the others are recorded as not run, beyond
    their replicate cap).

    Returns ``{'mle_ran': bool, 'fits': {estimator: {...}}}`` where each fit has ``estimate``
    and ``se`` (canonical parameter order of the model; the MLE's known frequency is NaN),
    ``converged``, ``seconds`` (wall time of the point estimate [s]; the GMWM's includes its WV),
    ``seconds_se`` (wall time with the standard errors [s]; the GMWM's whole ``fit`` call),
    ``message``, ``start`` (the MLE's start name), ``loglike`` (the MLE's exact log-likelihood)
    and ``ran``.
    """
    from gmwm import fit
    from gmwm.model import Model
    from gmwm_studies.montecarlo import check_truth, estimator_settings

    model = Model(model_spec)
    theta = check_truth(model_spec, truth)
    beta = _check_model(model, truth)
    gmwm_fit = estimator_settings(gmwm_settings)
    settings = None if mle_settings is None else _mle_settings(mle_settings)
    names = list(model.param_names)
    x = _signal(model, theta, n_samples, replicate, study, base_seed)
    g = _empty_fit(len(names), True)
    seed = replicate_seed(study, n_samples, replicate, base_seed, stream=1)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        res = fit(x, model, settings=gmwm_fit, seed=seed)
        g["seconds_se"] = time.perf_counter() - t0
        g["cpu_seconds_se"] = time.process_time() - c0
        # the point estimate's clock: the WV and the search, without the SEs and diagnostics;
        # its CPU time is the call's, split like its wall time
        g["seconds"] = float(res.seconds_wv + res.seconds_fit)
        g["cpu_seconds"] = g["cpu_seconds_se"] * min(1.0, g["seconds"] / g["seconds_se"])
        gmwm_theta = model.canonical(np.asarray(res.params, dtype=float))
        g.update(estimate=gmwm_theta, se=np.asarray(res.se, dtype=float),
                 converged=bool(res.converged), message=str(res.message))
    except _FAILURES as exc:
        g.update(_failed_clocks(t0, c0))
        gmwm_theta = None
        g["message"] = f"{type(exc).__name__}: {exc}"
    fits = {"gmwm": g}
    if settings is None:
        return {"mle_ran": False, "fits": fits}
    start = None if gmwm_theta is None else model.as_dict(gmwm_theta)
    for name, rule in settings["variants"].items():
        if variants is None or name in variants:
            fits[name] = _fit_variant(x, beta, rule, start, settings, names)
        else:
            fits[name] = _empty_fit(len(names), False, "not run (beyond this variant's replicate "
                                    "cap)")
    return {"mle_ran": True, "fits": fits}


def _warm_up(model_spec: str, backend: str | None, truth: Mapping[str, float] | None = None,
             gmwm_settings: Any = None) -> None:
    """Compile the WV, GMWM and filter kernels and load the libraries before timing anything, so
    that no replicate's clock includes a one-off cost (``backend`` None: the statsmodels baseline
    only; ``truth`` None: no GMWM fit)."""
    from gmwm import fit
    from gmwm.model import Model
    from gmwm_studies.mle import fit_mle, fit_statsmodels, mle_covariance

    rng = np.random.default_rng(0)
    model = Model(model_spec)
    x = np.cumsum(rng.normal(size=256)) * 0.1 + rng.normal(size=256)
    if backend is None:
        fit_statsmodels(x, 0.35, maxiter=2, se=True)
        return
    if truth is not None:
        theta = np.array([float(truth[n]) for n in model.param_names])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit(model.simulate(theta, 4096, rng), model, settings=gmwm_settings)
    fit_mle(x, 0.35, n_starts=1, maxiter=2, backend=backend)
    fit_mle(x, 0.35, n_starts=1, maxiter=2, backend=backend, own_starts="default")
    mle_covariance(x, 0.35, {"WN[1].sigma2": 1.0, "RW[1].gamma2": 0.01, "AR1[1].phi": 0.5,
                             "AR1[1].sigma2": 0.1})


def run_chunk(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicates: Sequence[int],
    study: str,
    base_seed: int,
    gmwm_settings: Mapping[str, Any],
    mle_settings: Mapping[str, Any],
    n_mle: int,
    progress: Progress | None = None,
    variant_replicates: Mapping[str, int] | None = None,
) -> xr.Dataset:
    """Run :func:`run_replicate` on every replicate id in ``replicates``; the MLE only on ids < ``n_mle``.

    ``variant_replicates``: ``{variant: cap}``, that variant only on ids < cap (<= ``n_mle``; not
    the headline, which runs wherever the MLE does); a variant not named runs on ids < ``n_mle``.
    One row per replicate, none dropped: failed fits have NaN estimates, ``converged = False`` and
    the reason in ``message``; fits not run have ``ran = False``. Timings exclude one-off start-up
    costs (numba compilation, imports).
    """
    from gmwm.model import Model
    from gmwm_studies.montecarlo import estimator_settings

    progress = progress or _noop
    reps = [int(r) for r in replicates]
    if not reps:
        raise InputError("a chunk needs at least one replicate")
    if n_mle < 0:
        raise InputError(f"the MLE replicate cap must be >= 0, got {n_mle}")
    settings = _mle_settings(mle_settings)
    caps = _variant_caps(variant_replicates, settings["variants"], n_mle)
    methods = ["gmwm", *settings["variants"]]
    model = Model(model_spec)
    names = list(model.param_names)
    _warm_up(model_spec, settings["backend"], truth, estimator_settings(gmwm_settings))
    rows = []
    for i, rep in enumerate(reps):
        row = run_replicate(model_spec, truth, n_samples, rep, study, base_seed, gmwm_settings,
                            settings if rep < n_mle else None,
                            [v for v in settings["variants"] if rep < caps[v]])
        rows.append(row)
        done = "; ".join(f"{m} {f['seconds']:.2f} s conv={f['converged']}"
                         for m, f in row["fits"].items() if f["ran"])
        progress(f"{study} T={n_samples}: replicate {i + 1}/{len(reps)} (id {rep}): {done}")
    not_run = _empty_fit(len(names), False, "not run (beyond the MLE replicate cap)")
    ds = _dataset(rows, methods, reps, names, truth, not_run)
    ds["mle_ran"] = ("replicate", np.array([r["mle_ran"] for r in rows], dtype=bool))
    ds.attrs.update({
        "study": study,
        "model": model_spec,
        "n_samples": int(n_samples),
        "base_seed": int(base_seed),
        "estimator": "+".join(methods),
        "n_mle": int(n_mle),
        "variants": json.dumps(settings["variants"]),
        "variant_replicates": json.dumps(dict(variant_replicates or {})),
        "wrong_optimum_ll": float(settings["wrong_optimum_ll"]),
        "gmwm_settings": json.dumps(dict(gmwm_settings), sort_keys=True),
        "mle_settings": json.dumps(settings, sort_keys=True),
    })
    return ds


def variant_replicate_caps(variant_replicates: Mapping[str, int | Sequence[int]] | None,
                           variants: Sequence[str],
                           mle_caps: Mapping[int, int]) -> dict[str, dict[int, int]]:
    """{variant: {T: replicates with its fit}} from a study's ``mle.variant_replicates`` (one int
    or one per sample size, in the order of ``mle_caps``, the MLE cap per T).

    A cap above the MLE cap at that T, a cap on the headline (``variants[0]``) or on a name that
    is not a variant is an error (one line); variants not named run on every MLE replicate.
    """
    sizes = list(mle_caps)
    out: dict[str, dict[int, int]] = {}
    for name, cap in (variant_replicates or {}).items():
        if name not in variants:
            raise InputError(f"mle.variant_replicates names {name!r}, not one of mle.variants "
                             f"{list(variants)}")
        if name == variants[0]:
            raise InputError(f"mle.variant_replicates caps the headline variant {name!r}; lower "
                             "mle.replicates instead")
        caps = list(cap) if isinstance(cap, (list, tuple)) else [cap] * len(sizes)
        if len(caps) != len(sizes):
            raise InputError(f"mle.variant_replicates.{name} has {len(caps)} entries for "
                             f"{len(sizes)} sample sizes")
        out[name] = {int(T): int(c) for T, c in zip(sizes, caps, strict=True)}
        for T, c in out[name].items():
            if not 0 <= c <= int(mle_caps[T]):
                raise InputError(f"mle.variant_replicates.{name} ({c}) is not between 0 and the "
                                 f"MLE cap ({mle_caps[T]}) at T = {T}")
    return out


def _variant_caps(caps: Mapping[str, int] | None, variants: Mapping[str, str],
                  n_mle: int) -> dict[str, int]:
    """{variant: replicate ids below which it runs} for every variant (checked, one-line errors)."""
    caps = dict(caps or {})
    head = next(iter(variants))
    for name, cap in caps.items():
        if name not in variants:
            raise InputError(f"variant_replicates names {name!r}, which is not an MLE variant "
                             f"({list(variants)})")
        if name == head:
            raise InputError(f"variant_replicates: the headline variant {head!r} runs on every "
                             "MLE replicate; lower the MLE cap instead")
        if not 0 <= int(cap) <= n_mle:
            raise InputError(f"variant_replicates: {name!r} cap {cap} must be between 0 and the "
                             f"MLE cap ({n_mle})")
    return {v: int(caps.get(v, n_mle)) for v in variants}


def _dataset(rows: Sequence[Mapping[str, Any]], methods: Sequence[str], reps: Sequence[int],
             names: Sequence[str], truth: Mapping[str, float],
             not_run: Mapping[str, Any]) -> xr.Dataset:
    """Stack per-replicate fit records into ``(estimator, replicate[, parameter])`` arrays."""

    def stack(key: str, dtype: Any = float) -> np.ndarray:
        return np.array([[r["fits"].get(m, not_run)[key] for r in rows] for m in methods],
                        dtype=dtype)

    per_fit = ("estimator", "replicate")
    return xr.Dataset(
        {
            "estimate": ((*per_fit, "parameter"), stack("estimate")),
            "se": ((*per_fit, "parameter"), stack("se")),
            "converged": (per_fit, stack("converged", bool)),
            "ran": (per_fit, stack("ran", bool)),
            "seconds": (per_fit, stack("seconds")),
            "seconds_se": (per_fit, stack("seconds_se")),
            "cpu_seconds": (per_fit, stack("cpu_seconds")),
            "cpu_seconds_se": (per_fit, stack("cpu_seconds_se")),
            "message": (per_fit, stack("message", object)),
            "start": (per_fit, stack("start", object)),
            "loglike": (per_fit, stack("loglike")),
        },
        coords={
            "estimator": np.array(methods, dtype=object),
            "replicate": np.asarray(reps, dtype=np.int64),
            "parameter": np.asarray(names, dtype=object),
            "truth": ("parameter", np.array([float(truth[n]) for n in names])),
        },
    )


def _baseline_settings(settings: Mapping[str, Any] | None) -> dict[str, Any]:
    out = {"maxiter": 50, **dict(settings or {})}  # 50: statsmodels' own default
    unknown = sorted(set(out) - set(BASELINE_KEYS))
    if unknown:
        raise InputError(f"unknown statsmodels baseline setting(s) {unknown}; "
                         f"allowed: {list(BASELINE_KEYS)}")
    if not int(out["maxiter"]) >= 1:
        raise InputError(f"statsmodels maxiter must be >= 1, got {out['maxiter']}")
    return out


def run_baseline_chunk(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicates: Sequence[int],
    study: str,
    base_seed: int,
    settings: Mapping[str, Any] | None = None,
    progress: Progress | None = None,
) -> xr.Dataset:
    """statsmodels' own MLE (:func:`gmwm_studies.mle.fit_statsmodels`, with its SEs) on the
    signals of ``replicates`` (the same signals as :func:`run_chunk`'s), estimator
    :data:`BASELINE`; merge into the study's results with :func:`add_baseline`.
    ``settings``: ``maxiter`` (default 50, statsmodels' own)."""
    from gmwm.model import Model
    from gmwm_studies.mle import fit_statsmodels
    from gmwm_studies.montecarlo import check_truth

    progress = progress or _noop
    reps = [int(r) for r in replicates]
    if not reps:
        raise InputError("a chunk needs at least one replicate")
    opts = _baseline_settings(settings)
    model = Model(model_spec)
    theta = check_truth(model_spec, truth)
    beta = _check_model(model, truth)
    names = list(model.param_names)
    _warm_up(model_spec, None)
    rows = []
    for i, rep in enumerate(reps):
        x = _signal(model, theta, n_samples, rep, study, base_seed)
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            rec = {**_mle_record(fit_statsmodels(x, beta, maxiter=int(opts["maxiter"]), se=True),
                                 names), "ran": True}
        except _FAILURES as exc:
            rec = {**_empty_fit(len(names), True, f"{type(exc).__name__}: {exc}"),
                   **_failed_clocks(t0, c0)}
        rows.append({"fits": {BASELINE: rec}})
        progress(f"{study} T={n_samples} statsmodels: replicate {i + 1}/{len(reps)} (id {rep}): "
                 f"{rec['seconds']:.2f} s (+SE {rec['seconds_se']:.2f} s) "
                 f"conv={rec['converged']}")
    ds = _dataset(rows, [BASELINE], reps, names, truth, {})
    ds.attrs.update({"study": study, "model": model_spec, "n_samples": int(n_samples),
                     "base_seed": int(base_seed), "estimator": BASELINE,
                     "baseline_settings": json.dumps(opts, sort_keys=True)})
    return ds


def add_baseline(ds: xr.Dataset, baseline: xr.Dataset) -> xr.Dataset:
    """``ds`` (:func:`run_chunk`'s, gathered) with the statsmodels baseline's fits as one more
    estimator, :data:`BASELINE`, appended to the variants (rule ``statsmodels``).

    The baseline must come from the same study, seed and T, and have run only on replicates where
    the Kalman-filter variants ran too (its wrong optima are judged against their
    log-likelihoods); its other replicates are marked not run.
    """
    for key in ("study", "n_samples", "base_seed", "model"):
        if ds.attrs.get(key) != baseline.attrs.get(key):
            raise InputError(f"statsmodels baseline and study results differ in {key}: "
                             f"{baseline.attrs.get(key)!r} vs {ds.attrs.get(key)!r}")
    if BASELINE in ds["estimator"].values:
        raise InputError("the results already hold the statsmodels baseline")
    b = baseline.sel(estimator=[BASELINE])
    reps = b["replicate"].values
    missing = np.setdiff1d(reps, ds["replicate"].values)
    if missing.size:
        raise InputError(f"statsmodels baseline replicates {missing.tolist()} are not in the "
                         "study results")
    no_mle = reps[~ds["mle_ran"].sel(replicate=reps).values]
    if no_mle.size:
        raise InputError(f"statsmodels baseline ran on replicates {no_mle.tolist()} where the "
                         "Kalman-filter MLE did not: raise the MLE cap or lower the baseline's")
    fill = {"estimate": np.nan, "se": np.nan, "converged": False, "ran": False,
            "seconds": np.nan, "seconds_se": np.nan, "cpu_seconds": np.nan,
            "cpu_seconds_se": np.nan, "message": "not run (beyond the "
            "statsmodels baseline's subset)", "start": "", "loglike": np.nan}
    b = b.reindex(replicate=ds["replicate"].values, fill_value=fill)
    for var in ("converged", "ran"):
        b[var] = b[var].astype(bool)
    out = xr.concat([ds, b[list(fill)]], dim="estimator", data_vars="minimal",
                    coords="minimal", compat="override", join="outer")
    out["mle_ran"] = ds["mle_ran"]
    out.attrs = dict(ds.attrs)
    out.attrs["variants"] = json.dumps({**variants_of(ds), BASELINE: BASELINE})
    out.attrs["estimator"] = "+".join(str(e) for e in out["estimator"].values)
    out.attrs["baseline_settings"] = baseline.attrs.get("baseline_settings", "{}")
    out.attrs["n_baseline"] = int(baseline.sizes["replicate"])
    return out


# ---------------------------------------------------------------------------------------------
# summaries
# ---------------------------------------------------------------------------------------------


def wrong_optimum(ds: xr.Dataset) -> xr.DataArray:
    """(estimator, replicate): a converged MLE whose log-likelihood is more than
    ``wrong_optimum_ll`` below the best log-likelihood any variant reached on the same signal
    (always False for the GMWM)."""
    ll = ds["loglike"]
    best = ll.max("estimator", skipna=True)
    tol = float(ds.attrs["wrong_optimum_ll"])
    wrong = ds["converged"] & (ll < best - tol)
    return wrong & (ds["estimator"] != "gmwm")


def _ran(ds: xr.Dataset, estimator: str) -> np.ndarray:
    """Replicates where ``estimator`` was run (results without a ``ran`` record: the MLE cap)."""
    if "ran" in ds:
        return ds["ran"].sel(estimator=estimator).values.astype(bool)
    return ds["mle_ran"].values.copy() if estimator != "gmwm" else np.ones(ds.sizes["replicate"],
                                                                           bool)


def _status(ds: xr.Dataset, variant: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ran and timed, not converged, wrong optimum) per replicate for one MLE variant."""
    attempted = _ran(ds, variant)
    ran = attempted & np.isfinite(ds["seconds"].sel(estimator=variant).values)
    failed = attempted & ~ds["converged"].sel(estimator=variant).values
    wrong = wrong_optimum(ds).sel(estimator=variant).values
    return ran, failed, wrong


def paired_mask(ds: xr.Dataset, variant: str | None = None) -> np.ndarray:
    """Replicates used to compare the GMWM with one MLE variant (default: the headline one): the
    MLE ran, converged and did not stop at a wrong optimum, and both methods gave finite estimates
    of the compared parameters (the paper's rule: MLE failures are dropped from both)."""
    variant = variant or next(iter(variants_of(ds)))
    est = ds["estimate"].sel(estimator=["gmwm", variant], parameter=list(COMPARED))
    finite = np.isfinite(est.values).all(axis=2).all(axis=0)
    ran, failed, wrong = _status(ds, variant)
    return ran & ~failed & ~wrong & finite


def _stats(x: np.ndarray, truth: float) -> dict[str, float]:
    n = len(x)
    mean = float(np.mean(x)) if n else np.nan
    sd = float(np.std(x, ddof=1)) if n > 1 else np.nan
    rmse = float(np.sqrt(np.mean((x - truth) ** 2))) if n else np.nan
    return {"n_used": n, "mean": mean, "bias": mean - truth, "sd": sd, "rmse": rmse,
            "rel_bias": (mean - truth) / abs(truth) if truth else np.nan,
            "rel_rmse": rmse / abs(truth) if truth else np.nan,
            "z_bias": (mean - truth) / (sd / np.sqrt(n)) if n > 1 and sd > 0 else np.nan}


def _times(secs: np.ndarray, suffix: str = "") -> dict[str, float]:
    secs = secs[np.isfinite(secs)]
    return {f"mean_seconds{suffix}": float(np.mean(secs)) if secs.size else np.nan,
            f"median_seconds{suffix}": float(np.median(secs)) if secs.size else np.nan}


def _mean_se(ds: xr.Dataset, method: str, param: str, subset: np.ndarray) -> float:
    if "se" not in ds:
        return np.nan
    se = ds["se"].sel(estimator=method, parameter=param).values[subset]
    se = se[np.isfinite(se)]
    return float(np.mean(se)) if se.size else np.nan


def summarize_comparison(ds: xr.Dataset) -> pd.DataFrame:
    """RMSE, bias, SD and run times per comparison, method and compared parameter at one T.

    ``set = 'paired'`` rows, one pair per MLE ``variant`` (methods ``gmwm`` and the variant): the
    replicates of :func:`paired_mask` for that variant, identical for both methods; run times are
    over every replicate where the MLE ran (converged or not: a failed fit costs time too), the
    same signals for both methods: ``mean_seconds`` / ``median_seconds`` of the point estimate,
    ``*_seconds_se`` with the standard errors, ``*_seconds_cpu`` / ``*_seconds_cpu_se`` the same
    in CPU time; the same with suffix ``_conv`` over the converged fits only (the paired
    replicates: the MLE converged to the best optimum; the paper timed only these). ``mean_se`` is the mean reported SE over the
    paired replicates (compare with ``sd``). ``n_mle_run``: replicates where that variant ran.
    ``set = 'all'`` rows (``gmwm`` only, variant ``''``): every replicate with a converged GMWM
    fit, including those beyond the MLE cap.
    """
    gmwm_ok = ds["converged"].sel(estimator="gmwm").values
    base = {"n_samples": int(ds.attrs["n_samples"]), "n_replicates": int(ds.sizes["replicate"])}
    rows = []
    jobs = []
    for variant, rule in variants_of(ds).items():
        ran, failed, wrong = _status(ds, variant)
        counts = {"n_mle_run": int(_ran(ds, variant).sum()), "variant": variant,
                  "start_rule": rule, "n_not_converged": int(failed.sum()),
                  "n_wrong_optimum": int(wrong.sum())}
        mask = paired_mask(ds, variant)
        jobs += [("paired", "gmwm", mask, ran, counts), ("paired", variant, mask, ran, counts)]
    jobs.append(("all", "gmwm", gmwm_ok, np.ones_like(gmwm_ok),
                 {"n_mle_run": int(ds["mle_ran"].values.sum()), "variant": "", "start_rule": "",
                  "n_not_converged": int((~gmwm_ok).sum()), "n_wrong_optimum": 0}))
    for set_name, method, subset, timed, counts in jobs:
        times: dict[str, float] = {}
        # all attempts (`timed`) and converged only (`subset`: the replicates the statistics use)
        for mask, conv in ((timed, ""), (subset, "_conv")):
            for var, suffix in (("seconds", ""), ("seconds_se", "_se"), ("cpu_seconds", "_cpu"),
                                ("cpu_seconds_se", "_cpu_se")):
                secs = (ds[var].sel(estimator=method).values[mask] if var in ds
                        else np.full(int(mask.sum()), np.nan))
                times.update(_times(secs, suffix + conv))
        for p in COMPARED:
            truth = float(ds["truth"].sel(parameter=p))
            x = ds["estimate"].sel(estimator=method, parameter=p).values[subset]
            x = x[np.isfinite(x)]
            rows.append({**base, **counts, "set": set_name, "method": method, "parameter": p,
                         "truth": truth, **_stats(x, truth),
                         "mean_se": _mean_se(ds, method, p, subset), **times})
    return pd.DataFrame(rows)


def comparison_table(summary: pd.DataFrame) -> pd.DataFrame:
    """One row per sample size and MLE variant: counts, mean and median times, speed-ups (MLE /
    GMWM time on the same signals, ratio of means and ratio of medians) of the point estimates
    and (``*_se``) of the fits with their standard errors, in wall time and (``*_cpu*``, ratio of
    means) CPU time, over every attempted fit (failed and capped ones included) and (``*_conv``)
    over the converged fits only (the ``n_used`` paired replicates), and the RMSE ratio MLE / GMWM
    per compared parameter (that variant's paired replicates)."""
    paired = summary[summary["set"] == "paired"]
    rows = []
    for (T, variant), g in paired.groupby(["n_samples", "variant"], sort=False):
        by = g.set_index(["method", "parameter"])
        gm, ml = by.loc[("gmwm", COMPARED[0])], by.loc[(variant, COMPARED[0])]
        first = g.iloc[0]
        row = {
            "n_samples": int(T),
            "variant": variant,
            "start_rule": first["start_rule"],
            "n_replicates": int(first["n_replicates"]),
            "n_mle": int(first["n_mle_run"]),
            "not_converged": int(first["n_not_converged"]),
            "wrong_optimum": int(first["n_wrong_optimum"]),
            "n_used": int(ml["n_used"]),
            "gmwm_mean_s": float(gm["mean_seconds"]),
            "mle_mean_s": float(ml["mean_seconds"]),
            "speedup_mean": _ratio(ml["mean_seconds"], gm["mean_seconds"]),
            "gmwm_median_s": float(gm["median_seconds"]),
            "mle_median_s": float(ml["median_seconds"]),
            "speedup_median": _ratio(ml["median_seconds"], gm["median_seconds"]),
            "gmwm_se_mean_s": float(gm["mean_seconds_se"]),
            "mle_se_mean_s": float(ml["mean_seconds_se"]),
            "speedup_se_mean": _ratio(ml["mean_seconds_se"], gm["mean_seconds_se"]),
            "speedup_se_median": _ratio(ml["median_seconds_se"], gm["median_seconds_se"]),
            "gmwm_cpu_mean_s": float(gm["mean_seconds_cpu"]),
            "mle_cpu_mean_s": float(ml["mean_seconds_cpu"]),
            "speedup_cpu_mean": _ratio(ml["mean_seconds_cpu"], gm["mean_seconds_cpu"]),
            "speedup_cpu_se_mean": _ratio(ml["mean_seconds_cpu_se"], gm["mean_seconds_cpu_se"]),
            # converged only: the n_used replicates (MLE converged to the best optimum)
            "gmwm_mean_s_conv": float(gm["mean_seconds_conv"]),
            "mle_mean_s_conv": float(ml["mean_seconds_conv"]),
            "speedup_mean_conv": _ratio(ml["mean_seconds_conv"], gm["mean_seconds_conv"]),
            "gmwm_cpu_mean_s_conv": float(gm["mean_seconds_cpu_conv"]),
            "mle_cpu_mean_s_conv": float(ml["mean_seconds_cpu_conv"]),
            "speedup_cpu_mean_conv": _ratio(ml["mean_seconds_cpu_conv"],
                                            gm["mean_seconds_cpu_conv"]),
        }
        for p in COMPARED:
            row[f"rmse_ratio_{SHORT_NAMES[p]}"] = _ratio(by.loc[(variant, p), "rmse"],
                                                         by.loc[("gmwm", p), "rmse"])
        rows.append(row)
    return pd.DataFrame(rows)  # in the summary's order: by T, then variants as configured


def _ratio(a: float, b: float) -> float:
    a, b = float(a), float(b)
    return a / b if b > 0 else np.nan


def standardized_by_method(ds: xr.Dataset, variant: str | None = None
                           ) -> dict[str, dict[str, np.ndarray]]:
    """(estimate - truth) / SD of the MLE, per method and compared parameter, on one variant's
    paired replicates (default: the headline variant).

    Both methods are divided by the same number, the MLE's empirical SD (ddof = 1), so that the
    boxes show relative efficiency as well as bias (MLE boxes have unit SD; a wider GMWM box means
    a larger variance). Keys: ``'GMWM'`` and the variant's label (:func:`method_label`).
    """
    variants = variants_of(ds)
    variant = variant or next(iter(variants))
    label = method_label(variant, variants[variant])
    paired = paired_mask(ds, variant)
    out: dict[str, dict[str, np.ndarray]] = {"GMWM": {}, label: {}}
    for p in COMPARED:
        truth = float(ds["truth"].sel(parameter=p))
        mle = ds["estimate"].sel(estimator=variant, parameter=p).values[paired]
        sd = float(np.std(mle, ddof=1)) if len(mle) > 1 else np.nan
        for key, method in (("GMWM", "gmwm"), (label, variant)):
            x = ds["estimate"].sel(estimator=method, parameter=p).values[paired]
            out[key][p] = (x - truth) / sd if sd > 0 else np.full(len(x), np.nan)
    return out


PARAM_LABELS = {"WN[1].sigma2": "WN $\\sigma^2$", "AR1[1].phi": "AR1 $\\phi$",
                "AR1[1].sigma2": "AR1 $\\varsigma^2$ (innovation)", "RW[1].gamma2": "RW $\\gamma^2$"}


def study_tables(datasets: Sequence[xr.Dataset]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(long table of :func:`summarize_comparison` over all T, per-T and variant
    :func:`comparison_table`), sorted by sample size."""
    parts = sorted(datasets, key=lambda d: int(d.attrs["n_samples"]))
    if not parts:
        raise InputError("no gathered Simulation 1 results given")
    long = pd.concat([summarize_comparison(d) for d in parts], ignore_index=True)
    return long, comparison_table(long)


def gmwm_text(gmwm_settings: Mapping[str, Any]) -> str:
    """One sentence naming the GMWM's search settings (single model or nested, starts, weights);
    a setting not given is ``gmwm.fit``'s default."""
    from gmwm_studies.montecarlo import estimator_settings

    s = estimator_settings(gmwm_settings)
    search = ("nested search: the model and each of its submodels" if s.nested else
              "single-model search, as in the paper (no nested submodel search)")
    return f"GMWM: {search}, {s.n_starts} starts, {s.weights_kind} weights."


def counts_text(comp: pd.DataFrame, mle_settings: Mapping[str, Any],
                gmwm_settings: Mapping[str, Any] | None = None,
                baseline_settings: Mapping[str, Any] | None = None) -> str:
    """Plain sentences (valid reStructuredText) with the GMWM's settings (if given), the MLE cap,
    the variants, the statsmodels baseline (if in ``comp``), the dropped replicates and the used
    counts per T, for the figure captions and the tables."""
    settings = _mle_settings(mle_settings)
    first = comp[comp["variant"] == comp["variant"].iloc[0]]
    base = comp[comp["variant"] == BASELINE]

    def per_t(df: pd.DataFrame, col: str) -> str:
        return "; ".join(f"T = {int(r.n_samples):,}: {getattr(r, col)}" for r in df.itertuples())

    lines = [] if gmwm_settings is None else [gmwm_text(gmwm_settings)]
    lines += [(
        f"GMWM replicates per sample size: {per_t(first, 'n_replicates')}. "
        f"MLE fitted on the first replicates only (cost cap): {per_t(first, 'n_mle')}. "
        f"MLE backend {settings['backend']!r} (exact likelihood, one start per variant). "
        f"A fit counts as a wrong optimum when its log-likelihood is more than "
        f"{float(settings['wrong_optimum_ll']):g} below the best any variant fitted to the same "
        f"signal reached. Replicates whose MLE did not converge or stopped at a wrong optimum are dropped "
        f"from both methods' statistics for that variant (as in the paper)."
    )]
    caps = (f"maxiter = {int(settings['maxiter'])} per BFGS run and per polish for the project's "
            "Kalman-filter MLE")
    if len(base):
        caps += (f", {int(_baseline_settings(baseline_settings)['maxiter'])} for statsmodels "
                 "(its default)")
    lines.append(
        f"Time means over all attempts (mean_s, cpu_mean_s: every fit where the MLE ran, failed "
        f"fits, fits stopped by the iteration cap ({caps}) and wrong optima included) and over "
        f"the converged fits only (*_conv: the n_used replicates where the MLE converged to the "
        f"best optimum, as the paper timed them; GMWM on the same signals). The paper's MLE "
        f"(Hector) is not run: the MLE times are the project's Kalman-filter MLE and "
        f"statsmodels', not the paper's.")
    lines.append(
        "Clocks (same signals for all methods): point estimate (GMWM: WV and search; "
        "MLE: the optimisation) and, separately, with standard errors (GMWM: the whole fit call, "
        "with its sandwich SEs and diagnostics; own-filter MLE: plus a finite-difference Hessian; "
        "statsmodels: plus its default OPG covariance); wall time, and CPU time of the process "
        "(cpu columns; the GMWM's point-estimate share of its call's CPU time taken in the "
        "proportion of the wall clock).")
    if len(base):
        opts = _baseline_settings(baseline_settings)
        lines.append(
            f"General-purpose baseline [{BASELINE}]: statsmodels' own estimator, "
            f"UnobservedComponents(level='llevel', autoregressive=1, exog=[cos, sin] at the "
            f"known frequency, exact diffuse start).fit(maxiter={int(opts['maxiter'])}) with its "
            f"start values and L-BFGS, on the first replicates only: {per_t(base, 'n_mle')}; "
            f"'not converged' is statsmodels' own verdict.")
    for variant, df in comp.groupby("variant", sort=False):
        rule = str(df["start_rule"].iloc[0])
        fewer = variant != BASELINE and (df["n_mle"].to_numpy()
                                         < first.set_index("n_samples")["n_mle"]
                                         .reindex(df["n_samples"]).to_numpy()).any()
        own_cap = (f", fitted on the first replicates only (its own cost cap, config "
                   f"mle.variant_replicates): {per_t(df, 'n_mle')};" if fewer else ":")
        dropped = "; ".join(
            f"T = {int(r.n_samples):,}: {int(r.not_converged)} + {int(r.wrong_optimum)} of "
            f"{int(r.n_mle)}" for r in df.itertuples())
        lines.append(f"{method_label(variant, rule)} [{variant}]{own_cap} not converged + wrong "
                     f"optimum: "
                     f"{dropped}; compared: {per_t(df, 'n_used')}.")
    return " ".join(lines) + "\n"
