"""STIM-300 Monte Carlo of [GMWFM] (docs/METHODS.md §12.5): GMWM against the Allan-variance methods.

Per replicate the pipeline simulates the signal once, computes ONE wavelet variance (cached by
:func:`montecarlo.simulate_wv_chunk`) and fits it with three cheap estimators, each named in the
config (``estimators.<name>.method``):

* ``gmwm``: GMWM, closed form (non-negative weighted least squares, docs/METHODS.md §5.4) for these linear
  models, optionally re-weighted with the fitted model's WV (``reweight``, docs/METHODS.md §5.1);
* ``armav``: the GMWFM estimator with ``f = log10`` on the Allan variance (docs/METHODS.md §5.3), with the
  delta-method weights ("ARMAV (weighted)", asymptotically the GMWM) or, with
  ``weights: identity``, equal weights ("ARMAV (OLS)", least squares on log10 AV, the usual reading
  of Jurado et al.'s regression); both can run side by side as differently named estimators;
* ``avsm``: the automated Allan-variance slope method (:mod:`gmwm.avsm`, docs/METHODS.md §9.2).

Estimates are per-sample parameters (signal in deg/s for the gyroscope, m/s^2 for the
accelerometer); summaries and figures convert them to the paper's Table I units with
:func:`gmwm.units.to_table_units` (Q [deg | m/s], N [./sqrt(h)], K [./h/sqrt(h)], R [./h/h]).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import InputError
from gmwm.settings import METHODS
from gmwm_studies import sensors as units  # Table I and its units (formerly in gmwm.units)
from gmwm_studies.montecarlo import check_truth, estimator_settings, gather, summarize
from gmwm_studies.store import WVChunk

__all__ = [
    "ESTIMATOR_METHODS",
    "LABELS",
    "cost_summary",
    "estimator_label",
    "figure_boxplots",
    "figure_rmse",
    "fit_chunk",
    "fit_chunk_all",
    "fit_wv",
    "group_datasets",
    "ranking_table",
    "read_estimates",
    "summarize_table_units",
    "to_table_units",
    "write_estimates",
]

Progress = Callable[[str], None]
#: the estimators, in display order (those of :func:`gmwm.fit`)
ESTIMATOR_METHODS = METHODS
#: Display names of the estimator methods (figures, tables).
LABELS = {"gmwm": "GMWM", "armav": "ARMAV", "avsm": "AVSM"}


#: covariance behind the stored (unreported) SEs of the study's fits, see :func:`fit_wv`
SE_COV = "gaussian"


def _noop(_: str) -> None:
    return None


def estimator_label(settings: Mapping[str, Any]) -> str:
    """Display name of an estimator from its settings: GMWM, AVSM, and for ARMAV its weighting,
    "ARMAV (OLS)" (``weights: identity``) or "ARMAV (weighted)" (delta-method weights)."""
    s = estimator_settings(settings)
    if s.method == "armav":
        return "ARMAV (OLS)" if s.weights_kind == "identity" else "ARMAV (weighted)"
    return LABELS[s.method]


def _label(ds: xr.Dataset) -> str:
    """Display name stored with a Dataset (older files: from its method only)."""
    if "label" in ds.attrs:
        return str(ds.attrs["label"])
    return LABELS.get(str(ds.attrs.get("method", "")), str(ds.attrs.get("estimator", "")))


def fit_wv(wv: Any, model: Any, settings: Mapping[str, Any], seed: int = 0
           ) -> tuple[np.ndarray, np.ndarray, bool, float, str]:
    """Fit ``model`` to one WaveletVariance with one estimator.

    Returns (params, se, converged, objective, message); AVSM has no SE or objective (NaN).
    The study reports estimates, not SEs, so GMWM/ARMAV fits take the diagonal (Gaussian) SEs
    (``se_cov="gaussian"``): the model-based covariance of the WV was 60-90 % of their fit time,
    and the estimates do not depend on it (per-job times: timings.csv of the run's archive).
    """
    from gmwm import fit

    s = estimator_settings(settings)
    if s.method == "avsm":
        res = fit(wv, model, settings=s)
        return (np.asarray(res.params, float), np.asarray(res.se, float), bool(res.converged),
                np.nan, res.message)
    res = fit(wv, model, settings=s, seed=seed, se_cov=SE_COV)
    return (np.asarray(res.params, float), np.asarray(res.se, float), bool(res.converged),
            float(res.objective), str(res.message))


def fit_chunk(chunk: WVChunk, settings: Mapping[str, Any], estimator: str, freq: float,
              progress: Progress | None = None) -> xr.Dataset:
    """Fit every replicate's cached WV of ``chunk`` with one estimator; one row per replicate.

    :func:`montecarlo.fit_chunk` with this module's per-replicate fit (GMWM, ARMAV or AVSM), so
    :func:`montecarlo.gather` and :func:`montecarlo.summarize` apply; adds the ``method``
    and ``freq`` attributes. ``freq`` [Hz] matters for AVSM only (it reads the AD at cluster
    times in seconds).
    """
    from gmwm_studies.montecarlo import fit_chunk as fit_study_chunk

    method = estimator_settings(settings).method
    ds = fit_study_chunk(chunk, settings, estimator, progress, freq=freq,
                         fit_one=lambda wv, model, seed: fit_wv(wv, model, settings, seed))
    ds.attrs.update(method=method, freq=float(freq), label=estimator_label(settings), se_cov=SE_COV)
    return ds


def fit_chunk_all(chunk: WVChunk, estimators: Mapping[str, Mapping[str, Any]], freq: float,
                  progress: Progress | None = None) -> dict[str, xr.Dataset]:
    """:func:`fit_chunk` for every named estimator on the same cached WVs: {name: Dataset}."""
    return {name: fit_chunk(chunk, settings, name, freq, progress)
            for name, settings in estimators.items()}


def write_estimates(path: str | os.PathLike, datasets: Mapping[str, xr.Dataset]) -> None:
    """Write several estimators' Datasets to one NetCDF-4 file, one group per estimator (atomic)."""
    from gmwm.atomic import atomic_path

    if not datasets:
        raise InputError("no estimates to write")
    with atomic_path(path) as tmp:
        for i, (name, ds) in enumerate(datasets.items()):
            ds.to_netcdf(tmp, group=name, mode="w" if i == 0 else "a", engine="netcdf4")


def read_estimates(path: str | os.PathLike) -> dict[str, xr.Dataset]:
    """Read a file written by :func:`write_estimates`: {estimator: Dataset} (loaded, closed)."""
    import netCDF4

    if not os.path.isfile(path):
        raise InputError(f"estimates file not found: {path}")
    with netCDF4.Dataset(path) as nc:
        names = list(nc.groups)
    out = {}
    for name in names:
        with xr.open_dataset(path, group=name, engine="netcdf4") as ds:
            out[name] = ds.load()
    return out


def group_datasets(datasets: Iterable[xr.Dataset]) -> dict[tuple[str, int], xr.Dataset]:
    """Chunk Datasets -> one Dataset per (estimator, T), replicates joined and sorted; groups in
    the order GMWM, ARMAV, AVSM (then estimator name), then by T."""
    groups: dict[tuple[str, int], list[xr.Dataset]] = {}
    methods: dict[str, int] = {}
    for ds in datasets:
        est = str(ds.attrs["estimator"])
        method = str(ds.attrs.get("method", ""))
        methods[est] = ESTIMATOR_METHODS.index(method) if method in ESTIMATOR_METHODS else 99
        groups.setdefault((est, int(ds.attrs["n_samples"])), []).append(ds)
    if not groups:
        raise InputError("no estimates given")
    order = sorted(groups, key=lambda k: (methods[k[0]], k[0], k[1]))
    return {key: gather(groups[key]) for key in order}


def to_table_units(ds: xr.Dataset, sensor: str, freq: float) -> xr.Dataset:
    """Copy of ``ds`` with ``estimate`` and ``truth`` in [GMWFM] Table I units.

    Adds the ``unit`` (parameter) coordinate and the ``Table I`` symbol (Q, N, K, R) coordinate.
    """
    names = [str(n) for n in ds["parameter"].values]
    est = ds["estimate"].values.copy()
    truth = ds["truth"].values.astype(float).copy()
    for k, name in enumerate(names):
        est[:, k] = units.to_table_units(name, np.abs(est[:, k]), sensor, freq)
        truth[k] = units.to_table_units(name, abs(truth[k]), sensor, freq)
    out = ds.copy()
    out["estimate"] = (("replicate", "parameter"), est)
    return out.assign_coords(
        truth=("parameter", truth),
        unit=("parameter", [units.table_unit(n, sensor) for n in names]),
        symbol=("parameter", [_symbol(n) for n in names]),
    )


def _symbol(name: str) -> str:
    return {"QN": "Q", "WN": "N", "RW": "K", "DR": "R"}.get(name.split("[", 1)[0], name)


def summarize_table_units(groups: Mapping[tuple[str, int], xr.Dataset], sensor: str,
                          freq: float) -> pd.DataFrame:
    """Bias, SD, RMSE (and relative versions) in Table I units per estimator, T and parameter.

    Non-converged fits are excluded from the statistics and counted (``share_not_converged``).
    """
    frames = []
    for ds in groups.values():
        conv = to_table_units(ds, sensor, freq)
        df = summarize(conv)
        df.insert(1, "sensor", units.canonical_sensor(sensor))
        df.insert(3, "method", _label(ds))
        pos = df.columns.get_loc("parameter") + 1
        df.insert(pos, "symbol", [str(s) for s in conv["symbol"].values])
        df.insert(pos + 1, "unit", [str(u) for u in conv["unit"].values])
        frames.append(df)
    return pd.concat(frames, ignore_index=True)


def cost_summary(groups: Mapping[tuple[str, int], xr.Dataset], replicates: int,
                 cores: int = 2) -> pd.DataFrame:
    """Mean per-replicate cost [s] per T: simulation, WV and each estimator's fit, and the
    projected wall time [min] of ``replicates`` replicates on ``cores`` cores (compute only, no
    job start-up)."""
    rows: dict[int, dict[str, float]] = {}
    for (estimator, T), ds in groups.items():
        row = rows.setdefault(T, {"n_samples": T,
                                  "simulate_s": float(np.nanmean(ds["seconds_simulate"])),
                                  "wv_s": float(np.nanmean(ds["seconds_wv"]))})
        row[f"fit_{estimator}_s"] = float(np.nanmean(ds["seconds_fit"]))
    df = pd.DataFrame(list(rows.values())).sort_values("n_samples").reset_index(drop=True)
    per_rep = df.filter(regex=r"_s$").sum(axis=1)
    df["total_s"] = per_rep
    df["projected_min"] = per_rep * replicates / cores / 60.0
    return df


# ---------------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------------


def _length_label(T: int, freq: float) -> str:
    return f"T = {T:.2g}\n({T / freq / 3600:.2g} h)"


def _param_title(ds: xr.Dataset, k: int) -> str:
    return f"{ds['symbol'].values[k]} [{ds['unit'].values[k]}]"


def figure_boxplots(groups: Mapping[tuple[str, int], xr.Dataset], sensor: str, freq: float,
                    title: str = "") -> Any:
    """Figure 1 of [GMWFM]: per parameter one panel, boxes of the estimates (Table I units) per
    sample size and estimator (converged fits), the true value as a dashed line. A panel whose
    values span more than a factor 20 (none below truth / 1000) uses a log axis."""
    from gmwm.plots import PALETTE, subplots
    from gmwm_studies.figures import boxplot_grouped

    conv = {key: to_table_units(ds, sensor, freq) for key, ds in groups.items()}
    estimators = list(dict.fromkeys(e for e, _ in conv))
    lengths = lengths_of(conv)
    first = next(iter(conv.values()))
    n_par = first.sizes["parameter"]
    ncols = min(n_par, 2)
    nrows = -(-n_par // ncols)
    fig, axes = subplots(nrows, ncols, figsize=(3.6 * ncols, 2.9 * nrows), squeeze=False)
    for k, ax in enumerate(axes.ravel()):
        if k >= n_par:
            ax.set_visible(False)
            continue
        values: dict[str, dict[str, np.ndarray]] = {}
        for est in estimators:
            label = _label(conv[(est, lengths[0])])
            values[label] = {}
            for T in lengths:
                ds = conv[(est, T)]
                x = ds["estimate"].where(ds["converged"]).values[:, k]
                values[label][_length_label(T, freq)] = x[np.isfinite(x)]
        boxplot_grouped(values, ax=ax, zero_line=False, ylabel=_param_title(first, k),
                        title=f"{first['symbol'].values[k]}")
        truth = float(first["truth"].values[k])
        ax.axhline(truth, color=PALETTE[0], lw=0.9, ls="--", zorder=0, label="truth")
        allv = np.concatenate([v for d in values.values() for v in d.values()] + [[truth]])
        # log axis for a wide spread (AVSM's Q), not for estimates collapsing to the boundary 0
        if allv.min() > 1e-3 * truth and allv.max() / allv.min() > 20:
            ax.set_yscale("log")
        else:
            _clip_outliers(ax, allv, truth)
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    # one legend for all panels, below them: inside a panel it covered the outliers
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=len(labels), fontsize=7)
    if title:
        fig.suptitle(title)
    return fig


def _clip_outliers(ax: Any, values: np.ndarray, truth: float) -> None:
    """Zoom a linear panel onto the 0.5-99.5 % range of all its values (and the truth) when a few
    extreme estimates would otherwise squash every box; say how many points are off the axis."""
    lo, hi = np.percentile(values, [0.5, 99.5])
    lo, hi = min(lo, truth), max(hi, truth)
    if hi <= lo or values.max() - values.min() < 3 * (hi - lo):
        return
    pad = 0.08 * (hi - lo)
    ax.set_ylim(lo - pad, hi + pad)
    off = int(np.sum((values < lo - pad) | (values > hi + pad)))
    ax.annotate(f"{off} point(s) off the axis", (0.99, 0.01), xycoords="axes fraction",
                ha="right", va="bottom", fontsize=6, color="#555555")


def figure_rmse(table: pd.DataFrame, title: str = "") -> Any:
    """Figure 2 of [GMWFM]: RMSE (Table I units) against T, one panel per parameter, one line
    per estimator (log-log)."""
    from matplotlib.ticker import NullFormatter

    from gmwm_studies.figures import plot_rmse_curves

    lengths = sorted(table["n_samples"].unique())
    rmse: dict[str, dict[str, np.ndarray]] = {}
    labels: dict[str, str] = {}
    for (est, method), sub in table.groupby(["estimator", "method"], sort=False):
        name = method or est
        rmse[name] = {}
        for par, rows in sub.groupby("parameter", sort=False):
            rows = rows.set_index("n_samples").reindex(lengths)
            rmse[name][par] = rows["rmse"].to_numpy(float)
            labels[par] = f"RMSE of {rows['symbol'].iloc[0]} [{rows['unit'].iloc[0]}]"
    ncols = min(len(labels), 2)
    fig = plot_rmse_curves(lengths, rmse, ncols=ncols, param_labels=labels, ylabel="RMSE")
    for ax in fig.axes:
        if ax.get_visible():
            ax.set_xticks(lengths, [f"{T:.2g}" for T in lengths])
            ax.xaxis.set_minor_formatter(NullFormatter())
    if title:
        fig.suptitle(title)
    return fig


def check_table_i_truth(model_spec: str, truth: Mapping[str, float], sensor: str,
                        freq: float) -> dict[str, float]:
    """Relative difference of a study's truth from Table I (:func:`gmwm.units.stim300_truth`),
    per parameter (0 = the paper's values; the quick profile rescales RW and DR on purpose)."""
    ref = units.stim300_truth(sensor, freq)
    check_truth(model_spec, truth)
    missing = sorted(set(ref) - set(truth))
    if missing:
        raise InputError(f"truth lacks Table I parameter(s) {missing} for the {sensor}")
    return {k: float(truth[k]) / ref[k] - 1.0 for k in ref}


def lengths_of(groups: Mapping[tuple[str, int], xr.Dataset]) -> Sequence[int]:
    """Sample sizes present in ``groups``, increasing."""
    return sorted({T for _, T in groups})


def ranking_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per sample size and parameter: each estimator's RMSE relative to the GMWM's (columns named
    by display name, in table order), the estimator with the lowest RMSE and the full ranking
    (lowest RMSE first), for the paper's claim "GMWM has the lowest RMSE for every parameter"."""
    labels = list(dict.fromkeys(table["method"]))
    ref = "GMWM" if "GMWM" in labels else labels[0]
    rows = []
    for (T, symbol), g in table.groupby(["n_samples", "symbol"], sort=False):
        rmse = g.set_index("method")["rmse"]
        row: dict[str, Any] = {"n_samples": int(T), "symbol": symbol, "unit": g["unit"].iloc[0]}
        for lab in labels:
            row[f"rmse/{ref}: {lab}"] = float(rmse.get(lab, np.nan)) / float(rmse[ref])
        order = rmse.sort_values(kind="stable")
        row["best"] = order.index[0]
        row["ranking"] = " < ".join(order.index)
        rows.append(row)
    return pd.DataFrame(rows)


TABLE_COLUMNS = ["study", "sensor", "estimator", "method", "n_samples", "parameter", "symbol",
                 "unit", "truth", "mean", "bias", "sd", "rmse", "rel_bias", "rel_sd", "std_bias",
                 "mc_se_bias", "n_used", "n_replicates", "share_not_converged"]


def report_markdown(table: pd.DataFrame, cost: pd.DataFrame, *, title: str, model: str,
                    estimators: Mapping[str, Mapping[str, Any]],
                    truth_vs_table_i: Mapping[str, float], cores: int) -> str:
    """Markdown report: settings, truth vs Table I, bias/SD/RMSE table, per-replicate cost."""
    from gmwm_studies.montecarlo import format_markdown_table

    lines = [f"# {title}", "", (f"Model `{model}`; values in [GMWFM] Table I units. "
             "Statistics over the converged fits (non-converged ones are counted in "
             "`share_not_converged`); `mc_se_bias` = SD / sqrt(n_used)."), ""]
    lines += ["Estimators: " + "; ".join(f"`{k}` {json.dumps(dict(v), sort_keys=True)}"
                                          for k, v in estimators.items()), ""]
    off = {k: v for k, v in truth_vs_table_i.items() if abs(v) > 1e-9}
    if off:
        lines += ["**Truth differs from Table I** (relative difference): "
                  + ", ".join(f"{k} {v:+.4g}" for k, v in off.items())
                  + " (quick profile: slow terms raised so that they show at the shorter lengths).",
                  ""]
    else:
        lines += ["Truth = Table I converted to discrete time (`gmwm.units.stim300_truth`).", ""]
    cols = ["method", "n_samples", "symbol", "unit", "truth", "mean", "bias", "sd", "rmse",
            "rel_bias", "rel_sd", "share_not_converged"]
    lines += [format_markdown_table(table[cols], digits=4), ""]
    lines += [("RMSE relative to the GMWM's and ranking by RMSE (lowest first) per length and "
               "parameter:"), "", format_markdown_table(ranking_table(table), digits=3), ""]
    lines += [(f"Mean cost per replicate [s] and projected wall time [min] of "
              f"{int(table['n_replicates'].max()) if len(table) else 0} replicates "
              f"(this run's count) on {cores} cores, compute only:"), "",
              format_markdown_table(cost, digits=3)]
    if len(cost) and "wv_s" in cost and bool((cost["wv_s"] == 0).all()):
        lines += ["", ("The signals were simulated by the fused simulator (`simulator: fused`): "
                       "each replicate's WV is computed in the simulation's own pass, so "
                       "`simulate_s` includes the WV and `wv_s` is 0.")]
    return "\n".join(lines) + "\n"
