"""Rule figure_boxplot: boxplots of (estimate - truth) / empirical SD per parameter (Fig. 4 style)."""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from wflog import get_logger

from gmwm.io import save_figure
from gmwm.plots import boxplot_standardized
from gmwm_studies.montecarlo import standardized_errors
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
ds = read_dataset(snakemake.input[0])
data = standardized_errors(ds)
n_conv = int(ds["converged"].sum())
fig, ax = plt.subplots(figsize=(2.0 + 1.0 * len(data), 4.5))
boxplot_standardized(
    data, ax=ax,
    title=(f"{ds.attrs['study']}: {ds.attrs['model']}, T = {ds.attrs['n_samples']:.3g}, "
           f"{n_conv}/{ds.sizes['replicate']} converged fits ({ds.attrs['estimator']})"),
)
for label in ax.get_xticklabels():  # long parameter names such as 'AR1[1].sigma2'
    label.set_rotation(30)
    label.set_horizontalalignment("right")
fig.tight_layout()
base = Path(snakemake.output[0]).with_suffix("")
written = save_figure(fig, base, formats=snakemake.params.formats)
plt.close(fig)
log.info("wrote %s", ", ".join(map(str, written)))
