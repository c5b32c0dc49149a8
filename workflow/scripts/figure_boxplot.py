"""Rule figure_boxplot: boxplots of (estimate - truth) / empirical SD per parameter (Fig. 4 style),
one panel per estimator, boundary and label-switched replicates marked and counted."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

from gmwm.atomic import save_figure
from gmwm.plots import subplots
from gmwm_studies.figures import boxplot_standardized
from gmwm_studies.montecarlo import standardized_errors
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
datasets = [read_dataset(f) for f in snakemake.input]
n_par = datasets[0].sizes["parameter"]
fig, axes = subplots(1, len(datasets), figsize=(1.6 + 0.75 * n_par * len(datasets), 4.6),
                     squeeze=False)
for ax, ds in zip(axes[0], datasets):
    data = standardized_errors(ds, with_flags=True)
    n_conv = int(ds["converged"].sum())
    boxplot_standardized(
        data, ax=ax,
        title=(f"{ds.attrs['estimator']}: {n_conv}/{ds.sizes['replicate']} converged\n"
               f"{ds.attrs['model']}, T = {ds.attrs['n_samples']:.3g}"),
    )
    for name, d in data.items():
        log.info("%s %s: %d at boundary, %d label-switched", ds.attrs["estimator"], name,
                 int(d["boundary"].sum()), int(d["switched"].sum()))
base = Path(snakemake.output[0]).with_suffix("")
written = save_figure(fig, base, formats=snakemake.params.formats)
log.info("wrote %s", ", ".join(map(str, written)))
