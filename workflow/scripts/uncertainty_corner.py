"""Rule uncertainty_corner: corner plot of the emcee quasi-posterior of one fitted model, with the
GMWM estimate marked."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import numpy as np

from gmwm.atomic import save_figure
from gmwm.codec import read_result
from gmwm.identify import corner_plot

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
est = read_result(snakemake.input.fit)
z = np.load(snakemake.input.samples)
samples, names = z["samples"], [str(n) for n in z["names"]]
if not len(samples):
    raise SystemExit("no posterior draws: enable the posterior check for this fit")
keep = np.ptp(samples, axis=0) > 0  # parameters held fixed at the boundary carry no information
fig = corner_plot(samples[:, keep], [n for n, k in zip(names, keep, strict=True) if k],
                  truths=est.params[keep])
fig.suptitle(f"{est.model.spec}: quasi-posterior (red: GMWM estimate)", fontsize=10, y=0.995)
fig.subplots_adjust(top=0.965, left=0.09, bottom=0.08, right=0.99)
save_figure(fig, snakemake.output[0])
log.info("wrote %s (%d draws)", snakemake.output[0], len(samples))
