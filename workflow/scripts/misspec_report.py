"""Rule misspec_report: bias/SD/RMSE table of every fitted model and Fig. 6 (AR1, RW estimates)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from gmwm.atomic import save_figure
from gmwm_studies.misspec import BASIC_PARAMS, misspec_table, plot_fig6
from gmwm_studies.montecarlo import write_table
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
study = snakemake.wildcards.study
fits = {label: read_dataset(path) for label, path in snakemake.input.items()}
labels = snakemake.params.labels
table = misspec_table(fits, labels=labels)
n = next(iter(fits.values())).sizes["replicate"]
T = next(iter(fits.values())).attrs["n_samples"]
write_table(table, snakemake.output.csv, snakemake.output.md,
            title=f"{study}: estimates of each fitted model against Table 5 (T = {T}, {n} replicates)")
fig = plot_fig6(fits, BASIC_PARAMS, labels=labels,
                title=f"GMWM estimates, T = {T}, {n} replicates (dashed: truth)")
written = save_figure(fig, Path(snakemake.output[0]).with_suffix(""),
                      formats=snakemake.params.formats)
for label, ds in fits.items():
    log.info("%s (%s): %d/%d converged", label, ds.attrs["model"], int(ds["converged"].sum()),
             ds.sizes["replicate"])
log.info("wrote %s, %s", snakemake.output.csv, ", ".join(map(str, written)))
