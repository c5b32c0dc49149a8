"""Model misspecification study of the vibration-noise paper (000, Table 5, Fig. 6).

Signals are simulated from the rotating-gyroscope model (AR1 + RW + 2 SIN, Table 5, per-sample
values at 200 Hz, signal in deg/s) with the common Monte Carlo runner (:func:`montecarlo.
simulate_wv_chunk`, WV cached per chunk). Each cached WV is then fitted with every model of
``fit_models`` (Model 1 = AR1 + RW, misspecified; Model 2 = AR1 + RW + 2 SIN, true) by the common
:func:`montecarlo.fit_chunk`; only the parameters a model shares with the truth are scored.

Conventions: estimates are xarray Datasets as in :mod:`montecarlo` (dims replicate, parameter)
with the attribute ``fit_label`` naming the fitted model; the "basic" parameters are those of
AR1[1] and RW[1].
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd
import xarray as xr

from gmwm.errors import InputError, ModelError
from gmwm_studies.store import WVChunk

__all__ = [
    "BASIC_PARAMS",
    "PARAM_LABELS",
    "TABLE5",
    "fit_model_chunk",
    "misspec_table",
    "plot_fig6",
    "restrict_truth",
]

#: Table 5 of [Vibration] (canonical names; SIN[1] is the fast sinusoid). alpha2 is the OCR reading
#: 1.359012e-1 (docs/METHODS.md §13).
TABLE5: dict[str, float] = {
    "AR1[1].phi": 1.851173e-1,
    "AR1[1].sigma2": 3.559081e-2,
    "RW[1].gamma2": 8.692479e-10,
    "SIN[1].alpha": 3.235864e-1,
    "SIN[1].beta": 1.199147,
    "SIN[2].alpha": 1.359012e-1,
    "SIN[2].beta": 1.357501e-1,
}
BASIC_PARAMS: tuple[str, ...] = ("AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2")
#: Paper notation (mathtext) of the parameters.
PARAM_LABELS: dict[str, str] = {
    "AR1[1].phi": r"$\phi$",
    "AR1[1].sigma2": r"$\varsigma^2$",
    "RW[1].gamma2": r"$\gamma^2$",
    "SIN[1].alpha": r"$\alpha_1$",
    "SIN[1].beta": r"$\beta_1$",
    "SIN[2].alpha": r"$\alpha_2$",
    "SIN[2].beta": r"$\beta_2$",
}


def restrict_truth(truth: Mapping[str, float], model_spec: str) -> dict[str, float]:
    """The entries of ``truth`` that ``model_spec`` parametrises (its shared parameters).

    Raises ModelError if the fitted model has a parameter the truth lacks (it must be nested)."""
    from gmwm.model import Model

    names = Model(model_spec).param_names
    missing = [n for n in names if n not in truth]
    if missing:
        raise ModelError(
            f"fitted model {model_spec!r} has parameter(s) {missing} that the simulated model lacks"
        )
    return {n: float(truth[n]) for n in names}


def fit_model_chunk(chunk: WVChunk, model_spec: str, label: str, fit_settings: Mapping[str, Any],
                    estimator: str = "gmwm", progress: Any = None) -> xr.Dataset:
    """Fit ``model_spec`` to every WV of ``chunk`` (simulated from ``chunk.model``).

    Wraps :func:`montecarlo.fit_chunk` with the chunk's model replaced by the fitted one and the
    truth restricted to its parameters; the random starts use the replicate's stream 1 as in every
    study. Attributes ``fit_label`` and ``simulated_model`` are added."""
    from gmwm_studies.montecarlo import fit_chunk

    sub = dataclasses.replace(chunk, model=model_spec,
                              truth=restrict_truth(chunk.truth, model_spec))
    ds = fit_chunk(sub, fit_settings, estimator=estimator, progress=progress)
    ds.attrs["fit_label"] = label
    ds.attrs["simulated_model"] = chunk.model
    return ds


def misspec_table(fits: Mapping[str, xr.Dataset], parameters: Sequence[str] | None = None,
                  labels: Mapping[str, str] | None = None) -> pd.DataFrame:
    """Bias, SD and RMSE per fitted model and parameter (converged replicates).

    ``fits`` maps a model label (e.g. "model1") to its gathered Dataset. ``parameters`` limits the
    rows (default: every parameter of each model); ``labels`` gives display names ("Model 1").
    Columns: method ("Model 1 (AR1+RW)"), model (label), then those of
    :func:`montecarlo.summarize`, plus ``rmse_ratio`` = RMSE / RMSE of the last model (the true
    one) and ``sd_ratio`` = SD / SD of the last model for shared parameters ([Vibration] Fig. 6
    compares both bias and variability)."""
    from gmwm_studies.montecarlo import summarize

    if not fits:
        raise InputError("misspec_table needs at least one fitted model")
    parts = []
    for label, ds in fits.items():
        df = summarize(ds)
        if parameters is not None:
            df = df[df["parameter"].isin(list(parameters))]
        name = (labels or {}).get(label, label)
        df.insert(0, "model", label)
        df.insert(0, "method", f"{name} ({ds.attrs.get('model', '')})")
        parts.append(df)
    out = pd.concat(parts, ignore_index=True)
    last = parts[-1].set_index("parameter")
    for col in ("rmse", "sd"):
        ref = last[col]
        out[f"{col}_ratio"] = [v / ref[p] if p in ref.index and ref[p] > 0 else np.nan
                               for p, v in zip(out["parameter"], out[col], strict=True)]
    return out


def plot_fig6(fits: Mapping[str, xr.Dataset], parameters: Sequence[str] = BASIC_PARAMS,
              labels: Mapping[str, str] | None = None, title: str | None = None) -> Any:
    """Fig. 6: one panel per basic parameter, a boxplot of each model's estimates, truth dashed.

    Converged replicates only. ``labels`` maps model labels to legend text. Returns the Figure."""
    from gmwm.plots import PALETTE, style, subplots

    labels = dict(labels or {})
    fig, axes = subplots(1, len(parameters), figsize=(2.3 * len(parameters) + 0.6, 3.2),
                         squeeze=False)
    for ax, name in zip(axes[0], parameters, strict=True):
        cols, ticks, truth = [], [], np.nan
        for label, ds in fits.items():
            x = ds["estimate"].where(ds["converged"]).sel(parameter=name).values
            cols.append(x[np.isfinite(x)])
            ticks.append(labels.get(label, label))
            truth = float(ds["truth"].sel(parameter=name))
        bp = ax.boxplot(cols, widths=0.55, patch_artist=True, showfliers=True,
                        flierprops={"markersize": 2, "alpha": 0.6})
        for patch, color in zip(bp["boxes"], PALETTE[2:], strict=False):
            patch.set_facecolor(color)
            patch.set_alpha(0.55)
        for med in bp["medians"]:
            med.set_color("black")
        ax.axhline(truth, color="black", linestyle="--", linewidth=0.9, label="truth")
        ax.set_xticks(range(1, len(ticks) + 1), ticks)
        ax.set_title(PARAM_LABELS.get(name, name))
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
    axes[0][0].legend(loc="best")
    if title:
        with style():
            fig.suptitle(title)
    return fig
