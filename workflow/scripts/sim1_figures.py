"""Rule sim1_figures: Figures 1 (RMSE vs T), 2 (mean run time vs T) and 9 (standardized errors at
the largest T) of the vibration-noise paper's Simulation 1, GMWM against the MLE."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from gmwm.atomic import save_figure
from gmwm.plots import style
from gmwm_studies.figures import boxplot_grouped, plot_rmse_curves, plot_runtime
from gmwm_studies.sim1 import (
    BASELINE,
    COMPARED,
    PARAM_LABELS,
    method_label,
    standardized_by_method,
)
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
name = snakemake.wildcards.study
formats = snakemake.params.formats
outdir = Path(snakemake.output[0]).parent
long = pd.read_csv(snakemake.input.table)
comp = pd.read_csv(snakemake.input.comparison)
paired = long[long["set"] == "paired"]
variants = dict(zip(comp["variant"], comp["start_rule"], strict=False))  # configured order
head = next(iter(variants))
by_variant = {v: comp[comp["variant"] == v].sort_values("n_samples") for v in variants}
T = by_variant[head]["n_samples"].to_numpy()


def per_t(df, col):
    return "/".join(str(int(v)) for v in df[col])


def fewer(v):
    """Whether variant ``v`` ran on fewer replicates than the headline at some T (its own cap, or
    the statsmodels baseline's subset): its label and the note say on how many."""
    own = by_variant[v].set_index("n_samples")["n_mle"]
    return bool((own < by_variant[head].set_index("n_samples")["n_mle"].reindex(own.index)).any())


label = {v: method_label(v, r) + (f", {per_t(by_variant[v], 'n_mle')} reps" if fewer(v) else "")
         for v, r in variants.items()}


sizes = ", ".join(f"{t / 1e4:g}" for t in T)
note = (f"T = ({sizes}) x 1e4; MLE on {per_t(by_variant[head], 'n_mle')} of "
        f"{per_t(by_variant[head], 'n_replicates')} replicates; dropped from both (not converged "
        f"+ wrong optimum): " + "; ".join(
            f"{method_label(v, variants[v])} " + "/".join(f"{int(a)}+{int(b)}" for a, b in
                                     zip(df["not_converged"], df["wrong_optimum"], strict=True))
            + (f" of {per_t(df, 'n_mle')}" if fewer(v) else "")
            for v, df in by_variant.items()))


def save(fig, stem):
    written = save_figure(fig, outdir / stem, formats=formats)
    log.info("wrote %s", ", ".join(map(str, written)))


# Figure 1: RMSE against T, one panel per parameter. GMWM and the headline MLE on the same
# replicates; every other MLE variant on its own paired replicates.


def rmse_of(variant, method):
    """RMSE per compared parameter at every T (NaN where the variant did not run)."""
    sub = paired[(paired.variant == variant) & (paired.method == method)]
    return {p: sub[sub.parameter == p].set_index("n_samples")["rmse"].reindex(T)
            .to_numpy(dtype=float) for p in COMPARED}


def restyle(fig):
    """Variants after the headline dashed with open markers (the GMWM-started MLE usually reaches
    the headline's optimum, so its line lies on top), one legend below the panels."""
    handles = {}
    for ax in fig.axes:
        for line in ax.get_lines():
            if line.get_label() in [label[v] for v in list(variants)[1:]]:
                line.set_linestyle("--")
                line.set_markerfacecolor("none")
            handles.setdefault(line.get_label(), line)
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    shown = {k: h for k, h in handles.items() if not k.startswith("_")}
    fig.legend(shown.values(), shown.keys(), loc="outside lower center", ncol=2, fontsize=7,
               frameon=False)


rmse = {"GMWM": rmse_of(head, "gmwm"), **{label[v]: rmse_of(v, v) for v in variants}}
fig = plot_rmse_curves(T, rmse, ncols=2, param_labels=PARAM_LABELS)
fig.set_size_inches(7.0, 6.2)
restyle(fig)
fig.suptitle(f"{name}: RMSE against T (GMWM on the replicates of {label[head]})\n"
             + textwrap.fill(note, 140), fontsize=7)
save(fig, "fig1_rmse")

# Figure 2: mean run time against T; left the point estimates, right with standard errors. The
# headline MLE / GMWM speed-up is annotated by plot_runtime; statsmodels / GMWM above its points.
# Every MLE line is over the replicates where that MLE ran (statsmodels: its subset), the GMWM's
# over the headline's replicates (its mean over the statsmodels subset is in the table).
base = BASELINE if BASELINE in by_variant else None


def series(df, col):
    """``col`` of one variant's rows at every T of the headline (NaN where it did not run)."""
    return df.set_index("n_samples")[col].reindex(T).to_numpy(dtype=float)


with style():  # the package style for the whole figure, as in Figure 1
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 5.4), layout="constrained", sharey=True)
    for ax, (gcol, mcol, what) in zip(axes, (("gmwm_mean_s", "mle_mean_s", "point estimates"),
                                            ("gmwm_se_mean_s", "mle_se_mean_s",
                                             "with standard errors")), strict=True):
        times = {"GMWM": series(by_variant[head], gcol),
                 **{label[v]: series(df, mcol) for v, df in by_variant.items()}}
        plot_runtime(T, times, ax=ax, ratio=(label[head], "GMWM"),
                     ylabel="Mean run time per replicate [s]")
        if base is not None:
            sm, gm = series(by_variant[base], mcol), series(by_variant[base], gcol)
            for t, a, g in zip(T, sm, gm, strict=True):
                if np.isfinite(a) and np.isfinite(g) and g > 0:
                    ax.annotate(f"×{a / g:,.0f}", (t, a), textcoords="offset points",
                                xytext=(0, 6), ha="center", fontsize=7, color="#444444")
            ax.plot([], [], " ", label=f"× above: {label[base]} / GMWM (same replicates)")
        ax.get_legend().remove()
        ax.set_title(what, fontsize=8)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=3,
               fontsize=7, frameon=False)
    fig.suptitle(f"{name}: mean run time (same signals for all methods)\n"
                 + textwrap.fill(note, 150), fontsize=7)
    save(fig, "fig2_runtime")
plt.close(fig)

# Figure 9: standardized errors of the GMWM and the headline MLE at the largest T
ds = read_dataset(snakemake.input.estimates[-1])
big = int(ds.attrs["n_samples"])
std = standardized_by_method(ds, head)
std = {m: {PARAM_LABELS[p]: v for p, v in d.items()} for m, d in std.items()}
n_used = len(next(iter(std[label[head]].values())))
last = by_variant[head].iloc[-1]
with style():
    fig, ax = plt.subplots(figsize=(7.0, 4.5), layout="constrained")
    boxplot_grouped(std, ax=ax, ylabel="(estimate - truth) / SD of the MLE",
                    title=(f"{name}: T = {big:,}, {n_used} replicates compared "
                           f"({int(last['not_converged'])} not converged, "
                           f"{int(last['wrong_optimum'])} wrong optima dropped)"))
    save(fig, "fig9_boxplot")
plt.close(fig)
