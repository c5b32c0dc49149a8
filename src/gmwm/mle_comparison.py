"""Simulation 1 of the vibration-noise paper: GMWM against the Kalman-filter MLE (SPEC 4.1, 5.7).

Per replicate one WN + RW + AR1 + SIN signal is simulated from
:func:`gmwm.seeds.replicate_rng` ``(study, T, r, seed)`` (so results do not depend on chunking), the
GMWM is fitted to the signal (timed as one call, WV computation included) and, for the first
``n_mle`` replicates of each sample size, the MLE of :func:`gmwm.mle.fit_mle` with the sinusoid's
frequency known, started from the GMWM estimate and then from its own start(s). Raw signals are
never stored.

Results are xarray Datasets with dims ``(estimator, replicate, parameter)``; ``estimator`` is
``['gmwm', 'mle']``. The two methods are compared on WN sigma2, AR1 phi, AR1 innovation variance
and RW gamma2 only (the MLE treats the sinusoid as deterministic, as the paper's Hector MLE did).
Following the paper, a replicate whose MLE did not converge is dropped from *both* methods'
statistics and counted; replicates beyond the MLE cap are used only in the GMWM-only rows.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import GMWMError, InputError
from gmwm.seeds import replicate_rng, replicate_seed

__all__ = [
    "COMPARED",
    "METHODS",
    "SHORT_NAMES",
    "comparison_table",
    "counts_text",
    "mle_start_counts",
    "paired_mask",
    "run_chunk",
    "run_replicate",
    "standardized_by_method",
    "study_tables",
    "summarize_comparison",
]

METHODS = ("gmwm", "mle")
COMPARED = ("WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2")
SHORT_NAMES = {"WN[1].sigma2": "sigma2", "AR1[1].phi": "phi", "AR1[1].sigma2": "ar1_sigma2",
               "RW[1].gamma2": "gamma2"}
MLE_KEYS = ("n_starts", "maxiter")
_FAILURES = (GMWMError, np.linalg.LinAlgError, FloatingPointError)

Progress = Callable[[str], None]


def _noop(_: str) -> None:
    return None


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


def run_replicate(
    model_spec: str,
    truth: Mapping[str, float],
    n_samples: int,
    replicate: int,
    study: str,
    base_seed: int,
    gmwm_settings: Mapping[str, Any],
    mle_settings: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """Simulate replicate ``replicate`` and fit it by GMWM and (unless ``mle_settings`` is None) MLE.

    Returns a dict with, per method ``m``: ``m_estimate`` (canonical parameter order of the model;
    the MLE's known frequency is NaN), ``m_converged``, ``m_seconds`` (wall time of the whole fit
    call [s]; the GMWM's includes its WV), ``m_message``; plus ``mle_ran``, ``mle_start`` (the
    winning start: ``'gmwm'`` = the GMWM estimate, else the MLE's own) and ``mle_loglike``.
    """
    from gmwm.fit import fit
    from gmwm.mle import fit_mle
    from gmwm.model import Model
    from gmwm.studies import check_truth, fit_settings_kwargs

    model = Model(model_spec)
    theta = check_truth(model_spec, truth)
    beta = _check_model(model, truth)
    gmwm_kwargs = fit_settings_kwargs(gmwm_settings)
    mle_kwargs = None if mle_settings is None else _mle_kwargs(mle_settings)
    names = list(model.param_names)
    x = model.simulate(theta, int(n_samples), replicate_rng(study, n_samples, replicate, base_seed))
    out: dict[str, Any] = {
        "gmwm_estimate": np.full(len(names), np.nan), "gmwm_converged": False,
        "mle_estimate": np.full(len(names), np.nan), "mle_converged": False,
        "mle_ran": mle_settings is not None, "mle_start": "", "mle_loglike": np.nan,
        "mle_seconds": np.nan, "mle_message": "not run (beyond the MLE replicate cap)",
    }
    seed = replicate_seed(study, n_samples, replicate, base_seed, stream=1)
    t0 = time.perf_counter()
    try:
        res = fit(x, model, seed=seed, **gmwm_kwargs)
        gmwm_theta = model.canonical(np.asarray(res.params, dtype=float))
        out.update(gmwm_estimate=gmwm_theta, gmwm_converged=bool(res.converged),
                   gmwm_message=str(res.message))
    except _FAILURES as exc:
        gmwm_theta = None
        out["gmwm_message"] = f"{type(exc).__name__}: {exc}"
    out["gmwm_seconds"] = time.perf_counter() - t0

    if mle_kwargs is None:
        return out
    start = None if gmwm_theta is None else model.as_dict(gmwm_theta)
    t0 = time.perf_counter()
    try:
        mres = fit_mle(x, beta, start, **mle_kwargs)
        est = np.array([mres.params.get(n, np.nan) for n in names])
        out.update(mle_estimate=est, mle_converged=bool(mres.converged), mle_start=mres.start,
                   mle_loglike=float(mres.loglike), mle_message=mres.message)
    except _FAILURES as exc:
        out["mle_message"] = f"{type(exc).__name__}: {exc}"
    out["mle_seconds"] = time.perf_counter() - t0
    return out


def _mle_kwargs(settings: Mapping[str, Any]) -> dict[str, Any]:
    unknown = sorted(set(settings) - set(MLE_KEYS))
    if unknown:
        raise InputError(f"unknown MLE setting(s) {unknown}; allowed: {list(MLE_KEYS)}")
    return dict(settings)


def _warm_up(model_spec: str) -> None:
    """Compile the WV kernels and load statsmodels before timing anything (first-call costs)."""
    from gmwm.mle import fit_mle
    from gmwm.model import Model
    from gmwm.wv import wvar

    rng = np.random.default_rng(0)
    wvar(rng.normal(size=1024))
    Model(model_spec)
    fit_mle(rng.normal(size=256), 0.35, n_starts=1, maxiter=2)


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
) -> xr.Dataset:
    """Run :func:`run_replicate` on every replicate id in ``replicates``; the MLE only on ids < ``n_mle``.

    One row per replicate, none dropped: failed fits have NaN estimates, ``converged = False`` and
    the reason in ``message``. Timings exclude one-off start-up costs (numba compilation, imports).
    """
    from gmwm.model import Model

    progress = progress or _noop
    reps = [int(r) for r in replicates]
    if not reps:
        raise InputError("a chunk needs at least one replicate")
    if n_mle < 0:
        raise InputError(f"the MLE replicate cap must be >= 0, got {n_mle}")
    _mle_kwargs(mle_settings)
    model = Model(model_spec)
    names = list(model.param_names)
    _warm_up(model_spec)
    rows = []
    for i, rep in enumerate(reps):
        row = run_replicate(model_spec, truth, n_samples, rep, study, base_seed, gmwm_settings,
                            mle_settings if rep < n_mle else None)
        rows.append(row)
        mle = (f"MLE {row['mle_seconds']:.2f} s converged={row['mle_converged']} "
               f"start={row['mle_start']}" if row["mle_ran"] else "MLE not run (cap)")
        progress(f"{study} T={n_samples}: replicate {i + 1}/{len(reps)} (id {rep}) "
                 f"GMWM {row['gmwm_seconds']:.2f} s converged={row['gmwm_converged']}; {mle}")
    truth_vec = np.array([float(truth[n]) for n in names])

    def stack(key: str, dtype: Any = float) -> np.ndarray:
        return np.array([[r[f"{m}_{key}"] for r in rows] for m in METHODS], dtype=dtype)

    return xr.Dataset(
        {
            "estimate": (("estimator", "replicate", "parameter"), stack("estimate")),
            "converged": (("estimator", "replicate"), stack("converged", bool)),
            "seconds": (("estimator", "replicate"), stack("seconds")),
            "message": (("estimator", "replicate"), stack("message", object)),
            "mle_ran": ("replicate", np.array([r["mle_ran"] for r in rows], dtype=bool)),
            "mle_start": ("replicate", np.array([r["mle_start"] for r in rows], dtype=object)),
            "mle_loglike": ("replicate", np.array([r["mle_loglike"] for r in rows], dtype=float)),
        },
        coords={
            "estimator": np.array(METHODS, dtype=object),
            "replicate": np.asarray(reps, dtype=np.int64),
            "parameter": np.asarray(names, dtype=object),
            "truth": ("parameter", truth_vec),
        },
        attrs={
            "study": study,
            "model": model_spec,
            "n_samples": int(n_samples),
            "base_seed": int(base_seed),
            "estimator": "gmwm+mle",
            "n_mle": int(n_mle),
            "gmwm_settings": json.dumps(dict(gmwm_settings), sort_keys=True),
            "mle_settings": json.dumps(dict(mle_settings), sort_keys=True),
        },
    )


# ---------------------------------------------------------------------------------------------
# summaries
# ---------------------------------------------------------------------------------------------


def paired_mask(ds: xr.Dataset) -> np.ndarray:
    """Replicates used for the comparison: the MLE ran and converged, and both methods gave finite
    estimates of the compared parameters (the paper's rule: MLE failures are dropped from both)."""
    est = ds["estimate"].sel(parameter=list(COMPARED))
    finite = np.isfinite(est.values).all(axis=2).all(axis=0)
    mle_ok = ds["mle_ran"].values & ds["converged"].sel(estimator="mle").values
    return mle_ok & finite


def _mle_failed(ds: xr.Dataset) -> np.ndarray:
    """The MLE ran but did not converge (or raised)."""
    return ds["mle_ran"].values & ~ds["converged"].sel(estimator="mle").values


def _stats(x: np.ndarray, truth: float) -> dict[str, float]:
    n = len(x)
    mean = float(np.mean(x)) if n else np.nan
    sd = float(np.std(x, ddof=1)) if n > 1 else np.nan
    return {"n_used": n, "mean": mean, "bias": mean - truth, "sd": sd,
            "rmse": float(np.sqrt(np.mean((x - truth) ** 2))) if n else np.nan,
            "rel_rmse": float(np.sqrt(np.mean((x - truth) ** 2))) / abs(truth) if n and truth
            else np.nan}


def summarize_comparison(ds: xr.Dataset) -> pd.DataFrame:
    """RMSE, bias, SD and mean run time per method and compared parameter at one sample size.

    ``set = 'paired'`` rows (methods ``gmwm`` and ``mle``): the replicates of :func:`paired_mask`,
    identical for both methods. ``set = 'all'`` rows (``gmwm`` only): every replicate except those
    whose MLE failed (so the paper's 500 replicates where the MLE was capped). ``mean_seconds`` of
    the paired rows is over every replicate where the MLE ran (converged or not: a failed fit
    costs time too), the same signals for both methods; of the ``all`` row over its replicates.
    """
    paired = paired_mask(ds)
    failed = _mle_failed(ds)
    ran = ds["mle_ran"].values
    gmwm_ok = ds["converged"].sel(estimator="gmwm").values
    common = {
        "n_samples": int(ds.attrs["n_samples"]),
        "n_replicates": int(ds.sizes["replicate"]),
        "n_mle_run": int(ran.sum()),
        "n_mle_not_converged": int(failed.sum()),
    }
    rows = []
    for method, subset, timed in (("gmwm", paired, ran), ("mle", paired, ran),
                                  ("gmwm", ~failed, np.ones_like(ran))):
        secs = ds["seconds"].sel(estimator=method).values[timed]
        for p in COMPARED:
            truth = float(ds["truth"].sel(parameter=p))
            x = ds["estimate"].sel(estimator=method, parameter=p).values[subset]
            x = x[np.isfinite(x)]
            rows.append({
                **common, "set": "paired" if subset is paired else "all", "method": method,
                "parameter": p, "truth": truth, **_stats(x, truth),
                "n_gmwm_not_converged": int((~gmwm_ok & subset).sum()),
                "mean_seconds": float(np.nanmean(secs)) if secs.size else np.nan,
            })
    return pd.DataFrame(rows)


def comparison_table(summary: pd.DataFrame) -> pd.DataFrame:
    """One row per sample size: counts, mean times, speed-up (MLE / GMWM mean time on the same
    signals) and the RMSE ratio MLE / GMWM per compared parameter (paired replicates)."""
    paired = summary[summary["set"] == "paired"]
    rows = []
    for T, g in paired.groupby("n_samples", sort=True):
        by = g.set_index(["method", "parameter"])
        t_g = float(by.loc[("gmwm", COMPARED[0]), "mean_seconds"])
        t_m = float(by.loc[("mle", COMPARED[0]), "mean_seconds"])
        first = g.iloc[0]
        row = {
            "n_samples": int(T),
            "n_replicates": int(first["n_replicates"]),
            "n_mle": int(first["n_mle_run"]),
            "mle_not_converged": int(first["n_mle_not_converged"]),
            "n_used": int(by.loc[("mle", COMPARED[0]), "n_used"]),
            "gmwm_seconds": t_g,
            "mle_seconds": t_m,
            "speedup": t_m / t_g if t_g > 0 else np.nan,
        }
        for p in COMPARED:
            r_g, r_m = float(by.loc[("gmwm", p), "rmse"]), float(by.loc[("mle", p), "rmse"])
            row[f"rmse_ratio_{SHORT_NAMES[p]}"] = r_m / r_g if r_g > 0 else np.nan
        rows.append(row)
    return pd.DataFrame(rows)


def mle_start_counts(ds: xr.Dataset) -> dict[str, int]:
    """How often each start won the MLE (replicates where the MLE ran)."""
    starts = ds["mle_start"].values[ds["mle_ran"].values]
    names, counts = np.unique(starts.astype(str), return_counts=True)
    return {str(n) if n else "(failed)": int(c) for n, c in zip(names, counts, strict=True)}


def standardized_by_method(ds: xr.Dataset) -> dict[str, dict[str, np.ndarray]]:
    """(estimate - truth) / SD of the MLE, per method and compared parameter, paired replicates.

    Both methods are divided by the same number, the MLE's empirical SD (ddof = 1), so that the
    boxes show relative efficiency as well as bias (MLE boxes have unit SD; a wider GMWM box means
    a larger variance). Keys: ``'GMWM'``, ``'MLE'``.
    """
    paired = paired_mask(ds)
    out: dict[str, dict[str, np.ndarray]] = {"GMWM": {}, "MLE": {}}
    for p in COMPARED:
        truth = float(ds["truth"].sel(parameter=p))
        mle = ds["estimate"].sel(estimator="mle", parameter=p).values[paired]
        sd = float(np.std(mle, ddof=1)) if len(mle) > 1 else np.nan
        for label, method in (("GMWM", "gmwm"), ("MLE", "mle")):
            x = ds["estimate"].sel(estimator=method, parameter=p).values[paired]
            out[label][p] = (x - truth) / sd if sd > 0 else np.full(len(x), np.nan)
    return out


PARAM_LABELS = {"WN[1].sigma2": "WN $\\sigma^2$", "AR1[1].phi": "AR1 $\\phi$",
                "AR1[1].sigma2": "AR1 $\\varsigma^2$ (innovation)", "RW[1].gamma2": "RW $\\gamma^2$"}


def study_tables(datasets: Sequence[xr.Dataset]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(long table of :func:`summarize_comparison` over all T, per-T :func:`comparison_table` with
    the winning MLE starts), sorted by sample size."""
    parts = sorted(datasets, key=lambda d: int(d.attrs["n_samples"]))
    if not parts:
        raise InputError("no gathered Simulation 1 results given")
    long = pd.concat([summarize_comparison(d) for d in parts], ignore_index=True)
    comp = comparison_table(long)
    comp["mle_winning_start"] = [
        ", ".join(f"{k} {v}" for k, v in mle_start_counts(d).items()) for d in parts
    ]
    return long, comp


def counts_text(comp: pd.DataFrame, mle_settings: Mapping[str, Any]) -> str:
    """Plain sentences (valid reStructuredText) with the MLE cap, the dropped replicates and the
    winning starts per T, for the figure captions and the tables."""
    def per_t(col: str) -> str:
        return "; ".join(f"T = {int(r.n_samples):,}: {getattr(r, col)}" for r in comp.itertuples())

    dropped = "; ".join(
        f"T = {int(r.n_samples):,}: {int(r.mle_not_converged)} of {int(r.n_mle)}"
        for r in comp.itertuples()
    )
    n_starts = mle_settings.get("n_starts", 2)
    return (
        f"GMWM replicates per sample size: {per_t('n_replicates')}. "
        f"MLE fitted on the first replicates only (cost cap): {per_t('n_mle')}. "
        f"MLE fits that did not converge, dropped from both methods' statistics (as in the "
        f"paper): {dropped}. Replicates compared: {per_t('n_used')}. "
        f"MLE starts: the GMWM estimate first, then the MLE's own data-driven start(s), "
        f"{n_starts} in all, highest likelihood kept; winning start: {per_t('mle_winning_start')}.\n"
    )
