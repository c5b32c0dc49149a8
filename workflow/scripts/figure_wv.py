"""Rule figure_wv: replicate WVs, model WV and component WVs, log-log ([Vibration] Fig. 3 style)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from gmwm.atomic import save_figure
from gmwm.model import Model
from gmwm_studies.figures import plot_wv_replicates
from gmwm_studies.store import read_wv_chunks

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
chunk = read_wv_chunks(list(snakemake.input))
model = Model(chunk.model)
theta = model.theta(chunk.truth)
fig, ax = plt.subplots(figsize=(7.0, 5.0))
plot_wv_replicates(chunk.scales, chunk.variances, model, theta, ax=ax)
ax.set_title(f"{chunk.study}: {chunk.model}, T = {chunk.n_samples:.3g}, "
             f"{len(chunk.replicates)} replicates")
base = Path(snakemake.output[0]).with_suffix("")
written = save_figure(fig, base, formats=snakemake.params.formats)
plt.close(fig)
log.info("wrote %s", ", ".join(map(str, written)))
