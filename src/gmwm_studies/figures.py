"""Figures of the paper studies (replicate WVs, boxplots of standardised errors, RMSE and
run-time curves) in the style of :mod:`gmwm.plots`, which they share with the library's figures.

Every function takes ``ax=None`` (a new figure is made when None) and returns the Axes (or the
Figure for multi-panel plots); nothing here touches pyplot's global state.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure

from gmwm.plots import (
    PALETTE,
    draw_model,
    finish_loglog,
    model_theta,
    new_axes,
    param_label,
    positive,
    scale_label,
    style,
    variance_label,
)

__all__ = ["REPLICATE_COLOR", "boxplot_grouped", "boxplot_standardized", "plot_rmse_curves",
           "plot_runtime", "plot_wv_replicates"]

REPLICATE_COLOR = "#B0B0B0"


def plot_wv_replicates(
    scales: Sequence[float],
    variances: np.ndarray,
    model: Any,
    theta: Any,
    *,
    freq: float = 1.0,
    components: bool = True,
    ax: Axes | None = None,
    units: str = "",
) -> Axes:
    """Empirical WVs of many replicates (light grey, shape (R, J)) with the true model WV and its
    components ([Vibration] Figure 3 style); ``scales`` in samples."""
    model, theta = model_theta(model, theta, None)
    ax = new_axes(ax)
    scales = np.asarray(scales, dtype=float)
    v = np.atleast_2d(np.asarray(variances, dtype=float))
    if v.shape[1] != scales.size:
        raise ValueError(f"variances have {v.shape[1]} scales, expected {scales.size}")
    x = scales / freq
    with style():
        # one LineCollection instead of R Line2D objects: fast for hundreds of replicates
        segs = [np.column_stack([x, positive(row)]) for row in v]
        lc = LineCollection(segs, colors=REPLICATE_COLOR, linewidths=0.5, alpha=0.5, zorder=1,
                            label=f"Empirical WV ({v.shape[0]} replicates)", gid="replicates")
        ax.add_collection(lc)
        draw_model(ax, x, scales, model, theta, components, label="Model WV")
        ax.set_xlim(x.min() / 1.2, x.max() * 1.2)
        pos = v[v > 0]
        if pos.size:
            ax.set_ylim(pos.min() / 2, pos.max() * 2)
        finish_loglog(ax, scale_label(freq), variance_label("Wavelet variance", units))
    return ax


def _as_columns(
    data: Mapping[str, Any] | np.ndarray, labels: Sequence[str] | None
) -> tuple[list[str], list[np.ndarray]]:
    if isinstance(data, Mapping):
        names = [str(k) for k in data]
        cols = [np.asarray(v, dtype=float).ravel() for v in data.values()]
    else:
        a = np.atleast_2d(np.asarray(data, dtype=float))
        cols = [a[:, i] for i in range(a.shape[1])]
        names = [str(s) for s in labels] if labels is not None else [str(i) for i in range(len(cols))]
        if len(names) != len(cols):
            raise ValueError(f"{len(names)} labels for {len(cols)} columns")
    return names, [c[np.isfinite(c)] for c in cols]


def _box(ax: Axes, cols: list[np.ndarray], positions: Sequence[float], color: str, width: float):
    return ax.boxplot(
        cols,
        positions=positions,
        widths=width,
        patch_artist=True,
        showfliers=True,
        medianprops={"color": "black", "lw": 1.0},
        boxprops={"facecolor": color, "alpha": 0.55, "lw": 0.6},
        whiskerprops={"lw": 0.6},
        capprops={"lw": 0.6},
        flierprops={"marker": "o", "ms": 2, "mec": color, "alpha": 0.5},
    )


_MARKS = {"boundary": ("v", "#C0392B", "at a boundary (0, |φ| = 1, β = π)"),
          "switched": ("x", "#E67E22", "label-switched (components swapped)")}


def boxplot_standardized(
    data: Mapping[str, Any] | np.ndarray,
    *,
    labels: Sequence[str] | None = None,
    ax: Axes | None = None,
    title: str | None = None,
    ylabel: str = "Standardized error",
    math_labels: bool = True,
) -> Axes:
    """Boxplots of standardized errors ((estimate - truth) / SD), one box per parameter, with a zero
    line ([Vibration] Figures 4 and 9). ``data``: ``{param: values}``, or ``{param: {"z": values,
    "boundary": mask, "switched": mask}}`` (as the studies' ``standardized_errors`` gives with
    flags) to mark and count boundary and label-switched replicates, or a 2-D array (R, p) +
    ``labels``. ``math_labels``: tick labels in the papers' notation (:func:`param_label`)."""
    marks: dict[str, dict[str, np.ndarray]] = {}
    if isinstance(data, Mapping) and any(isinstance(v, Mapping) for v in data.values()):
        marks = {k: {m: np.asarray(v[m], bool) for m in _MARKS if m in v} for k, v in data.items()}
        data = {k: np.asarray(v["z"], float) for k, v in data.items()}
    names, cols = _as_columns(data, labels)
    ax = new_axes(ax)
    with style():
        ax.axhline(0.0, color=PALETTE[2], lw=0.8, zorder=0, gid="zero_line")
        _box(ax, cols, range(1, len(cols) + 1), PALETTE[1], 0.6)
        shown: set[str] = set()
        for i, name in enumerate(names, start=1):
            z = np.asarray(data[name], float) if marks else None
            counts = []
            for m, (marker, color, text) in _MARKS.items():
                mask = marks.get(name, {}).get(m)
                if mask is None or z is None or not mask.any():
                    continue
                pts = z[mask & np.isfinite(z)]
                jitter = np.linspace(-0.18, 0.18, len(pts)) if len(pts) > 1 else np.zeros(1)
                ax.plot(i + jitter, pts, marker, color=color, ms=3.5, alpha=0.8, ls="none",
                        label=text if m not in shown else None, gid=f"mark_{m}")
                shown.add(m)
                counts.append(f"{m[0]} {int(mask.sum())}")
            if counts:
                ax.text(i, 1.0, "\n".join(counts), transform=ax.get_xaxis_transform(),
                        ha="center", va="bottom", fontsize=7, gid="mark_counts")
        ticks = [param_label(n, names) for n in names] if math_labels else names
        ax.set_xticks(range(1, len(cols) + 1), ticks)
        ax.set_ylabel(ylabel)
        ax.grid(False, axis="x")
        if shown:
            ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.12), ncols=2, fontsize=7)
        if title:
            ax.set_title(title, pad=22 if shown else 6)
    return ax


def boxplot_grouped(
    values: Mapping[str, Mapping[str, Any]],
    *,
    ax: Axes | None = None,
    title: str | None = None,
    ylabel: str = "Standardized error",
    zero_line: bool = True,
) -> Axes:
    """Side-by-side boxplots of several groups (e.g. methods) per parameter:
    ``values[group][param] -> array``. Parameters are taken in first-seen order across groups."""
    groups = list(values)
    params: list[str] = []
    for g in groups:
        params += [p for p in values[g] if p not in params]
    ng = max(len(groups), 1)
    width = 0.8 / ng
    ax = new_axes(ax)
    with style():
        if zero_line:
            ax.axhline(0.0, color="#777777", lw=0.8, zorder=0, gid="zero_line")
        for gi, g in enumerate(groups):
            color = PALETTE[1 + gi % (len(PALETTE) - 1)]
            present = [i for i, p in enumerate(params) if p in values[g]]
            cols = [np.asarray(values[g][params[i]], float).ravel() for i in present]
            cols = [c[np.isfinite(c)] for c in cols]
            pos = [i + 1 - 0.4 + width * (gi + 0.5) for i in present]
            _box(ax, cols, pos, color, width * 0.85)
            ax.plot([], [], "s", color=color, alpha=0.55, label=g)  # legend proxy
        ax.set_xticks(range(1, len(params) + 1), params)
        ax.set_xlim(0.4, len(params) + 0.6)
        ax.set_ylabel(ylabel)
        ax.grid(False, axis="x")
        ax.legend(loc="best")
        if title:
            ax.set_title(title)
    return ax


def plot_rmse_curves(
    T: Sequence[float],
    rmse: Mapping[str, Mapping[str, Any]],
    *,
    ncols: int | None = None,
    xlabel: str = "Sample size T",
    ylabel: str = "RMSE",
    param_labels: Mapping[str, str] | None = None,
    fig: Figure | None = None,
) -> Figure:
    """RMSE against sample size, log-log, one panel per parameter and one line per method:
    ``rmse[method][param] -> array over T``."""
    methods = list(rmse)
    params: list[str] = []
    for m in methods:
        params += [p for p in rmse[m] if p not in params]
    n = len(params)
    ncols = ncols or min(n, 4)
    nrows = -(-n // ncols)
    T = np.asarray(T, dtype=float)
    with style():
        if fig is None:
            fig = Figure(figsize=(2.3 * ncols + 0.4, 2.1 * nrows + 0.3), layout="constrained")
        axes = fig.subplots(nrows, ncols, squeeze=False)
        for k, ax in enumerate(axes.ravel()):
            if k >= n:
                ax.set_visible(False)
                continue
            p = params[k]
            for i, m in enumerate(methods):
                if p in rmse[m]:
                    ax.plot(T, positive(rmse[m][p]), "o-", color=PALETTE[1 + i % 7], label=m)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_title((param_labels or {}).get(p, p))
            if k % ncols == 0:
                ax.set_ylabel(ylabel)
            if k // ncols == nrows - 1:
                ax.set_xlabel(xlabel)
        axes.ravel()[0].legend(loc="best")
    return fig


def plot_runtime(
    T: Sequence[float],
    times: Mapping[str, Any],
    *,
    ax: Axes | None = None,
    ratio: tuple[str, str] | None = None,
    xlabel: str = "Sample size T",
    ylabel: str = "Mean run time [s]",
) -> Axes:
    """Run time against sample size, log-log, one line per method, with the speed-up
    ``times[slow] / times[fast]`` annotated at each T (``ratio=(slow, fast)``; default: the slowest
    and the fastest method by overall mean, when there are at least two)."""
    T = np.asarray(T, dtype=float)
    ax = new_axes(ax)
    with style():
        for i, (m, t) in enumerate(times.items()):
            ax.plot(T, positive(t), "o-", color=PALETTE[1 + i % 7], label=m)
        if ratio is None and len(times) >= 2:
            order = sorted(times, key=lambda m: float(np.nanmean(np.asarray(times[m], float))))
            ratio = (order[-1], order[0])
        if ratio is not None:
            slow, fast = (np.asarray(times[r], float) for r in ratio)
            for t, s, f in zip(T, slow, fast, strict=True):
                if np.isfinite(s) and np.isfinite(f) and f > 0:
                    r = s / f
                    ax.annotate(f"×{r:.0f}" if r >= 10 else f"×{r:.2g}", (t, np.sqrt(s * f)), ha="center", va="center",
                                fontsize=7, color="#444444", gid="speedup")
            ax.plot([], [], " ", label=f"×: {ratio[0]} / {ratio[1]}")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.legend(loc="best")
    return ax
