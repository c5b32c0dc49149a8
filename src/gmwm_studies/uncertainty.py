"""Uncertainty study of the GMWM papers (docs/METHODS.md §7): Table 1 bootstrap CIs and the coverage study.

Built on the core method :mod:`gmwm.bootstrap`; the Snakemake rules of
``workflow/rules/uncertainty.smk`` only wire these:
``navchip_result`` (the Navchip fit of one axis, from the navchip rule's fits file),
``bootstrap_to_dataset`` / ``bootstrap_from_dataset`` (chunks on disk), ``bootstrap_table``
(Table-1 rows: estimate, percentile and basic CIs, bootstrap and sandwich SEs),
``coverage_chunk`` / ``coverage_summary`` / ``plot_coverage`` (coverage study), ``summary_row``
(one row of the identifiability table of the fits). The fit of one
Monte Carlo replicate is :func:`montecarlo.replicate_fit`, the studies' own.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from gmwm.bootstrap import BootstrapResult, coverage, parametric_bootstrap
from gmwm.errors import GMWMError, InputError
from gmwm.estimator import GMWMResult, fit
from gmwm.identify import IdentifiabilityReport
from gmwm.model import Model
from gmwm.settings import FitSettings
from gmwm_studies.montecarlo import replicate_fit

__all__ = ["CI_KINDS", "bootstrap_from_dataset", "bootstrap_table", "bootstrap_to_dataset",
           "coverage_chunk", "coverage_summary", "navchip_result", "plot_coverage", "summary_row"]

CI_KINDS = ("percentile", "basic", "wald")


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

    from gmwm_studies.data import load_navchip_wv

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
    # the recorded SEs (sandwich in the free log coordinates, delta method) are the reported ones;
    # the library's theta-coordinate sandwich is kept in diagnostics (ill-conditioned for GM beta)
    se = np.array([rec["se"].get(n, np.nan) for n in model.param_names], dtype=float)
    diagnostics = {**res.diagnostics, "navchip_refit_differs": bool(differs),
                   "se_library": res.se.tolist()}
    res = dataclasses.replace(res, params=stored if differs else res.params, se=se,
                              diagnostics=diagnostics)
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
               "settings": json.dumps({"refit": boot.refit, **boot.settings.to_tree()},
                                      default=np.ndarray.tolist),
               "seconds": boot.seconds})


def bootstrap_from_dataset(ds, estimate: GMWMResult) -> BootstrapResult:
    """Inverse of :func:`bootstrap_to_dataset` given the estimate the chunk was drawn from
    (raises InputError if the stored estimate differs: the chunk is stale)."""
    import json

    stored = np.asarray(json.loads(ds.attrs["estimate"]), dtype=float)
    if not np.allclose(stored, estimate.params, rtol=1e-9, atol=0):
        raise InputError("bootstrap chunk was drawn from a different estimate; rerun its job")
    msgs = {int(b): str(m) for b, m in zip(ds["draw"].values, ds["message"].values, strict=True)
            if str(m)}
    settings = json.loads(ds.attrs["settings"])
    refit = bool(settings.pop("refit", True))
    return BootstrapResult(estimate, ds["draw"].values.astype(np.int64),
                           np.asarray(ds["theta"].values, dtype=float),
                           np.asarray(ds["converged"].values, dtype=bool),
                           np.asarray(ds["wv"].values, dtype=float), ds.attrs["seed"],
                           FitSettings.from_tree(settings), msgs, float(ds.attrs["seconds"]),
                           refit)


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
    # ndtri is scipy.stats.norm.ppf's own kernel (the same z), without the ~0.6 s import of
    # scipy.stats that a coverage job otherwise pays for this one number
    from scipy.special import ndtri

    z = ndtri(1 - alpha / 2)
    return np.stack([est - z * se, est + z * se], axis=-1)


def coverage_chunk(model_spec: str, truth: dict[str, float], n_samples: int,
                   replicates: Sequence[int], *, study: str, base_seed: int, B: int,
                   settings: dict[str, Any] | None = None, levels: int | None = None,
                   alpha: float = 0.05, progress: Callable[[str], None] | None = None,
                   simulator: str = "fast"):
    """Coverage study, one chunk of replicates: fit each replicate (:func:`replicate_fit`), run a
    parametric bootstrap of B refits from its estimate (draw streams extend the replicate's stream
    2, so results do not depend on chunking) and keep the percentile, basic and Wald (sandwich SE)
    intervals.

    Returns an xarray Dataset over (replicate, parameter): estimate, sandwich_se, boot_se,
    converged, n_used, seconds, and ci (replicate, kind, parameter, bound) with kind in
    :data:`CI_KINDS`; ``truth`` coordinate. NaN where a fit or all refits failed.
    """
    import xarray as xr

    from gmwm_studies.seeds import replicate_seed_sequence

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
                                base_seed=base_seed, settings=settings, levels=levels,
                                simulator=simulator)
        except GMWMError as err:
            if progress:
                progress(f"replicate {rep}: fit failed: {err}")
            continue
        conv[i] = bool(res.converged)
        est[i], sand[i] = res.params, res.se
        ci[i, 2] = _wald(res.params, res.se, alpha)
        ss = replicate_seed_sequence(study, n_samples, int(rep), base_seed, stream=2)
        boot = parametric_bootstrap(res, B, seed=ss)  # the refits repeat res.settings
        n_used[i] = boot.n_converged
        if boot.n_converged >= 2:
            bse[i] = boot.se
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


def summary_row(label: str, report: IdentifiabilityReport | dict[str, Any]) -> dict[str, Any]:
    """One row of a pass/warn table from a report or its ``to_json_dict()``: fit label, model,
    status, local rank and condition number, distinct and near-equal optima, posterior modality,
    longest autocorrelation time and chain length, range of posterior SD / Laplace SE, and the
    reasons joined by '; '."""
    d = report.to_json_dict() if isinstance(report, IdentifiabilityReport) else report
    loc, glob, post = d["local"], d.get("global"), d.get("posterior")
    row: dict[str, Any] = {
        "fit": label, "model": d["model"], "status": d["status"],
        "rank": f"{loc['rank']}/{loc['n_active']}",
        "condition_number": np.nan if loc["condition_number"] is None else loc["condition_number"],
        "optima": np.nan if glob is None else len(glob["optima"]),
        "near_equal_optima": np.nan if glob is None else len(glob["alternatives"]),
        "posterior": "not run", "tau_max": np.nan, "n_steps": np.nan,
        "sd_ratio_min": np.nan, "sd_ratio_max": np.nan}
    if post is not None:
        tau = [t for t in post["tau"].values() if t is not None]
        ratio = [r for n, r in post["sd_ratio"].items() if r is not None and post["tau"][n] is not None]
        row.update(posterior="unimodal" if post["unimodal"] else "multimodal",
                   tau_max=max(tau) if tau else np.nan, n_steps=post["n_steps"])
        if ratio:
            row.update(sd_ratio_min=min(ratio), sd_ratio_max=max(ratio))
    row["reasons"] = "; ".join(d["reasons"])
    return row
