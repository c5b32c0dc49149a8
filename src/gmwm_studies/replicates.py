"""Per-replicate estimate tables of the Monte Carlo studies (one CSV per study and sample size).

Every count a report quotes about individual replicates (boundary estimates, label switches,
replicates far from the truth, ...) must be traceable to a committed file; the studies' gathered
NetCDF estimates live under the untracked ``results/``. These functions turn them into small CSV
tables under ``reports/<study>/replicates/``, one row per (replicate, estimator):

``replicate, estimator[, fit_model], T, J, <one column per model parameter>, objective,
converged, at_boundary[, label_switched]``

* parameters in the canonical order and per-sample units of the fitted model (as in the NetCDF
  estimates), ``%.10g``;
* ``converged`` 1/0 (a non-converged fit keeps its row; its estimates may be empty);
* ``at_boundary``: the parameters flagged by :func:`montecarlo.replicate_flags` (the rule of the
  tables' ``n_boundary``), joined by ``;``, empty if none. For STIM-300 the flags are computed in
  Table I units, as its report does;
* ``label_switched``: the process types (``AR1``, ``SIN``) with a true component estimated in
  another component's column, ``;``-joined, empty if none; only for models with two components of
  one type (the rule of the tables' ``n_switched``).

Simulation 1 (kind ``mle_comparison``) has rows for the GMWM, every MLE variant and the
statsmodels baseline, each where it ran, and per fit the columns of :data:`SIM1_COLUMNS`
(log-likelihood, wrong optimum, iterations, both clocks); its ``objective`` is minus the
log-likelihood for the MLEs, empty for the GMWM.

A ``truth_T<T>.json`` beside each CSV holds what the counts need besides the estimates: the model,
the true values, the number of WV levels J and, for STIM-300, the sensor and sampling rate.
"""

from __future__ import annotations

import json
import os
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm.errors import InputError

__all__ = [
    "FLOAT_FORMAT",
    "SIM1_COLUMNS",
    "bootstrap_draw_table",
    "dataset_table",
    "read_replicates",
    "study_table",
    "write_replicates",
]

FLOAT_FORMAT = "%.10g"
"""Ten significant digits: exact enough to recount every flag, a third of float64 repr's size."""


def _has_switch_check(model_spec: str) -> bool:
    from gmwm.model import Model

    kinds = [c.process.name for c in Model(model_spec).components]
    return len(kinds) != len(set(kinds))


def dataset_table(ds: xr.Dataset, *, estimator: str | None = None,
                  flags_ds: xr.Dataset | None = None) -> pd.DataFrame:
    """Rows of one estimates Dataset (dims replicate, parameter; :mod:`montecarlo` layout).

    ``flags_ds``: the Dataset the boundary/switch flags are computed on (default ``ds``; STIM-300
    passes its Table-I-unit copy so the flags are its report's).
    """
    from gmwm_studies.montecarlo import replicate_flags

    names = [str(n) for n in ds["parameter"].values]
    est = np.asarray(ds["estimate"].values, dtype=float)
    df = pd.DataFrame({
        "replicate": ds["replicate"].values.astype(np.int64),
        "estimator": estimator or str(ds.attrs.get("estimator", "")),
        "T": int(ds.attrs["n_samples"]),
        "J": int(ds.attrs.get("n_levels", 0)) or pd.NA,
    })
    for k, name in enumerate(names):
        df[name] = est[:, k]
    obj = ds["objective"].values if "objective" in ds else np.full(len(df), np.nan)
    df["objective"] = np.asarray(obj, dtype=float)
    df["converged"] = np.asarray(ds["converged"].values).astype(bool).astype(np.int8)
    flags = replicate_flags(flags_ds if flags_ds is not None else ds)
    bnd = flags["boundary"].values
    df["at_boundary"] = [";".join(n for n, b in zip(names, row, strict=True) if b) for row in bnd]
    if _has_switch_check(str(ds.attrs["model"])):
        sw = flags["switched"].values
        df["label_switched"] = [";".join(dict.fromkeys(n.split("[", 1)[0]
                                                       for n, s in zip(names, row, strict=True)
                                                       if s))
                                for row in sw]
    return df


def _truth_of(ds: xr.Dataset) -> dict[str, float]:
    return {str(n): float(v) for n, v in zip(ds["parameter"].values, ds["truth"].values,
                                             strict=True)}


#: Simulation 1's per-fit columns beside the estimates (kind ``mle_comparison``), and their meaning.
SIM1_COLUMNS = {
    "loglike": "exact Gaussian log-likelihood of the MLE fit (empty for the GMWM)",
    "wrong_optimum": "1: converged, but the log-likelihood is more than wrong_optimum_ll below the "
                     "best any MLE (variant or statsmodels) reached on the same signal "
                     "(sim1.wrong_optimum)",
    "iterations": "optimiser iterations as its message reports them (BFGS: first run + polish; "
                  "statsmodels: L-BFGS), empty if not reported",
    "seconds": "wall time of the point estimate [s] (GMWM: WV + search)",
    "cpu_seconds": "process CPU time of the point estimate [s]",
    "seconds_se": "wall time with the standard errors [s]",
    "cpu_seconds_se": "process CPU time with the standard errors [s]",
}
_ITERATIONS = re.compile(r"(\d+)(?:\+(\d+))?\s+(?:BFGS\s+)?iterations")


def _iterations(message: str) -> float:
    """Iterations named in an MLE message ("12+3 BFGS iterations", "statsmodels lbfgs, 50
    iterations"), NaN when it names none."""
    m = _ITERATIONS.search(str(message))
    return float(int(m.group(1)) + int(m.group(2) or 0)) if m else np.nan


def _mle_comparison_rows(ds: xr.Dataset, method: str) -> pd.DataFrame:
    """Rows of one Simulation 1 method: the replicates where it ran, with :data:`SIM1_COLUMNS`."""
    from gmwm_studies.sim1 import wrong_optimum

    wrong = wrong_optimum(ds).sel(estimator=method).values
    sub = ds.sel(estimator=method)
    keep = np.flatnonzero(np.asarray(sub["ran"].values, dtype=bool))
    sub, wrong = sub.isel(replicate=keep), wrong[keep]
    part = sub.drop_vars(["objective"], errors="ignore")
    # the GMWM's objective is not stored by this study; the MLE's is -log-likelihood
    part["objective"] = np.nan * sub["loglike"] if str(method) == "gmwm" else -sub["loglike"]
    part.attrs = dict(ds.attrs)
    df = dataset_table(part, estimator=str(method))
    df["loglike"] = np.asarray(sub["loglike"].values, dtype=float)
    df["wrong_optimum"] = wrong.astype(np.int8)
    df["iterations"] = pd.array([_iterations(m) for m in sub["message"].values], dtype="Int64") \
        if str(method) != "gmwm" else pd.array([pd.NA] * len(df), dtype="Int64")
    for col in ("seconds", "cpu_seconds", "seconds_se", "cpu_seconds_se"):
        df[col] = np.asarray(sub[col].values, dtype=float)
    return df


def study_table(kind: str, paths: Sequence[str | os.PathLike], *,
                extra: Mapping[str, Any] | None = None) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Per-replicate table and truth record of one study at one sample size.

    ``kind``: the study kind of config/config.yaml; ``paths``: its gathered estimates at that T
    (wv_montecarlo: one file per estimator; misspec: one per fitted model, in
    ``extra["fit_models"]`` order; stim300 and bootstrap_coverage: its chunk files;
    mle_comparison: the gathered GMWM + MLE file and, where it ran at that T, the gathered
    statsmodels baseline, rows only where a method ran, with :data:`SIM1_COLUMNS`). ``extra``: kind-specific settings (stim300: ``sensor``, ``freq``;
    misspec: ``fit_models`` labels and the study ``truth``).
    """
    from gmwm_studies.montecarlo import gather
    from gmwm_studies.store import read_dataset

    extra = dict(extra or {})
    if not paths:
        raise InputError("no estimates files given")
    frames: list[pd.DataFrame] = []
    if kind == "wv_montecarlo":
        sets = [read_dataset(p) for p in paths]
        frames = [dataset_table(ds) for ds in sets]
        record = {"model": sets[0].attrs["model"], "truth": _truth_of(sets[0])}
    elif kind == "misspec":
        labels = list(extra["fit_models"])
        if len(labels) != len(paths):
            raise InputError(f"{len(paths)} estimates files for {len(labels)} fitted models")
        sets = [read_dataset(p) for p in paths]
        for label, ds in zip(labels, sets, strict=True):
            df = dataset_table(ds)
            df.insert(2, "fit_model", label)
            frames.append(df)
        record = {"model": extra.get("model", sets[-1].attrs["model"]),
                  "truth": dict(extra.get("truth") or _truth_of(sets[-1])),
                  "fit_models": {lab: str(ds.attrs["model"]) for lab, ds in zip(labels, sets,
                                                                                 strict=True)}}
    elif kind == "stim300":
        from gmwm_studies import stim300

        sensor, freq = str(extra["sensor"]), float(extra["freq"])
        groups = stim300.group_datasets(ds for p in paths
                                        for ds in stim300.read_estimates(p).values())
        for (name, _T), ds in groups.items():
            frames.append(dataset_table(ds, estimator=name,
                                        flags_ds=stim300.to_table_units(ds, sensor, freq)))
        first = next(iter(groups.values()))
        record = {"model": first.attrs["model"], "truth": _truth_of(first), "sensor": sensor,
                  "freq": freq}
    elif kind == "bootstrap_coverage":
        ds = gather(read_dataset(p) for p in paths)
        frames = [dataset_table(ds, estimator=str(extra.get("estimator", "gmwm")))]
        record = {"model": ds.attrs["model"], "truth": _truth_of(ds)}
    elif kind == "mle_comparison":
        from gmwm_studies.sim1 import add_baseline

        ds = read_dataset(paths[0])
        if len(paths) > 2:
            raise InputError(f"mle_comparison: the gathered results and at most one statsmodels "
                             f"baseline file, got {len(paths)} files")
        if len(paths) == 2:
            ds = add_baseline(ds, read_dataset(paths[1]))
        frames = [_mle_comparison_rows(ds, method) for method in ds["estimator"].values]
        record = {"model": ds.attrs["model"], "truth": _truth_of(ds),
                  "objective": "GMWM: not stored; MLE variants and statsmodels: minus the "
                               "log-likelihood (loglike)",
                  "wrong_optimum_ll": float(ds.attrs["wrong_optimum_ll"]),
                  "mle_settings": json.loads(ds.attrs.get("mle_settings", "{}")),
                  "baseline_settings": json.loads(ds.attrs.get("baseline_settings", "{}")),
                  "columns": SIM1_COLUMNS}
    else:
        raise InputError(f"no per-replicate table for study kind {kind!r}")
    df = pd.concat(frames, ignore_index=True)
    # misspec: the fitted models' parameter columns in the truth's order, flags last
    params = [c for c in df.columns if "[" in c]
    params.sort(key=lambda n: list(record["truth"]).index(n) if n in record["truth"] else 1 << 30)
    ids = [c for c in ("replicate", "estimator", "fit_model", "T", "J") if c in df.columns]
    tail = [c for c in ("objective", "converged", *SIM1_COLUMNS, "at_boundary", "label_switched")
            if c in df.columns]
    df = df[[*ids, *params, *tail]]
    T = int(df["T"].iloc[0])
    if (df["T"] != T).any():
        raise InputError(f"estimates of several sample sizes given: {sorted(set(df['T']))}")
    J = None if df["J"].isna().all() else int(df["J"].max())
    record.update({"kind": kind, "T": T, "J": J,
                   "columns": {**record.get("columns", {}),
                               "at_boundary": "parameters at the boundary (montecarlo."
                               "replicate_flags, the tables' n_boundary rule)"}})
    return df, record


def write_replicates(df: pd.DataFrame, record: Mapping[str, Any], csv_path: str | os.PathLike,
                     json_path: str | os.PathLike) -> None:
    """Write the table (CSV, ``FLOAT_FORMAT``) and its truth record (JSON), atomically."""
    write_text_atomic(csv_path, df.to_csv(index=False, float_format=FLOAT_FORMAT))
    write_json_atomic(json_path, dict(record))


def read_replicates(csv_path: str | os.PathLike) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a table written by :func:`write_replicates` and its ``truth_T<T>.json`` beside it."""
    csv_path = os.fspath(csv_path)
    if not os.path.isfile(csv_path):
        raise InputError(f"per-replicate table not found: {csv_path}")
    df = pd.read_csv(csv_path, keep_default_na=False, na_values=[""],
                     dtype={"at_boundary": str, "label_switched": str, "estimator": str,
                            "fit_model": str})
    for col in ("at_boundary", "label_switched"):
        if col in df:
            df[col] = df[col].fillna("")
    head, tail = os.path.split(csv_path)
    json_path = os.path.join(head, tail.replace("estimates_", "truth_").replace(".csv", ".json"))
    if not os.path.isfile(json_path):
        raise InputError(f"truth record not found beside {csv_path}: {json_path}")
    with open(json_path, encoding="utf-8") as fh:
        return df, json.load(fh)


def bootstrap_draw_table(boot: Any, fit: str) -> pd.DataFrame:
    """One row per bootstrap draw of a fit: draw, converged, the label-aligned refit (the draws
    the percentile intervals use; empty for a failed refit)."""
    names = list(boot.param_names)
    aligned = np.full((boot.n_draws, len(names)), np.nan)
    conv = np.asarray(boot.converged, dtype=bool)
    if boot.n_converged >= 2:
        aligned[conv] = boot.aligned()
    df = pd.DataFrame({"fit": fit, "draw": np.asarray(boot.draws, dtype=np.int64),
                       "converged": conv.astype(np.int8)})
    for k, name in enumerate(names):
        df[name] = aligned[:, k]
    return df
