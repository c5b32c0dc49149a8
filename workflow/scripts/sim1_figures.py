"""Rule sim1_figures: Figures 1 (RMSE vs T), 2 (mean run time vs T) and 9 (standardized errors at
the largest T) of the vibration-noise paper's Simulation 1, GMWM against the MLE."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd
from wflog import get_logger

from gmwm.io import save_figure
from gmwm.mle_comparison import COMPARED, PARAM_LABELS, standardized_by_method
from gmwm.plots import boxplot_grouped, plot_rmse_curves, plot_runtime, style
from gmwm.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
name = snakemake.wildcards.study
formats = snakemake.params.formats
outdir = Path(snakemake.output[0]).parent
long = pd.read_csv(snakemake.input.table)
comp = pd.read_csv(snakemake.input.comparison)
paired = long[long["set"] == "paired"]
T = comp["n_samples"].to_numpy()


def per_t(col):
    return "/".join(str(int(v)) for v in comp[col])


sizes = ", ".join(f"{t / 1e4:g}" for t in T)
note = (f"T = ({sizes}) x 1e4; MLE on {per_t('n_mle')} of {per_t('n_replicates')} replicates; "
        f"MLE not converged (dropped from both): {per_t('mle_not_converged')}")


def save(fig, stem):
    written = save_figure(fig, outdir / stem, formats=formats)
    log.info("wrote %s", ", ".join(map(str, written)))


# Figure 1: RMSE against T, one panel per parameter, both methods on the same replicates
rmse = {label: {p: paired[(paired.method == m) & (paired.parameter == p)]
                .sort_values("n_samples")["rmse"].to_numpy() for p in COMPARED}
        for label, m in (("GMWM", "gmwm"), ("MLE", "mle"))}
fig = plot_rmse_curves(T, rmse, ncols=2, param_labels=PARAM_LABELS)
fig.set_size_inches(7.0, 5.6)
fig.suptitle(f"{name}: RMSE against T (replicates with a converged MLE)\n{note}", fontsize=8)
save(fig, "fig1_rmse")

# Figure 2: mean run time against T with the speed-up annotated
with style():  # the package style for the whole figure, as in Figure 1
    fig, ax = plt.subplots(figsize=(6.0, 4.5), layout="constrained")
    plot_runtime(T, {"GMWM": comp["gmwm_seconds"].to_numpy(),
                     "MLE": comp["mle_seconds"].to_numpy()},
                 ax=ax, ratio=("MLE", "GMWM"), ylabel="Mean run time per replicate [s]")
    ax.set_title(f"{name}: mean run time (GMWM incl. its WV; same signals)\n{note}", fontsize=8)
    save(fig, "fig2_runtime")
plt.close(fig)

# Figure 9: standardized errors of both estimators at the largest T
ds = read_dataset(snakemake.input.estimates[-1])
big = int(ds.attrs["n_samples"])
std = standardized_by_method(ds)
std = {m: {PARAM_LABELS[p]: v for p, v in d.items()} for m, d in std.items()}
n_used = len(next(iter(std["MLE"].values())))
with style():
    fig, ax = plt.subplots(figsize=(7.0, 4.5), layout="constrained")
    boxplot_grouped(std, ax=ax, ylabel="(estimate - truth) / SD of the MLE",
                    title=(f"{name}: T = {big:,}, {n_used} replicates with a converged MLE "
                           f"({int(comp['mle_not_converged'].iloc[-1])} dropped)"))
    save(fig, "fig9_boxplot")
plt.close(fig)
