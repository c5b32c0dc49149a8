"""Rule uncertainty_boot: parametric bootstrap draws [a, b) of one fitted model (NetCDF chunk)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import numpy as np

from gmwm.bootstrap import parametric_bootstrap
from gmwm.codec import read_result
from gmwm_studies.store import write_dataset
from gmwm_studies.uncertainty import bootstrap_to_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
est = read_result(snakemake.input[0])
a, b = snakemake.params.draws
entropy, key = snakemake.params.seed
seed = np.random.SeedSequence(entropy, spawn_key=(key,))
log.info("%s: draws %d..%d of T = %d, seed %s", snakemake.wildcards.fit, a, b - 1,
         est.wv.n_samples, seed)
boot = parametric_bootstrap(est, seed=seed, draws=range(a, b),  # refits repeat est.settings
                            progress=lambda i, n: log.info("draw %d/%d", i, n))
write_dataset(bootstrap_to_dataset(boot), snakemake.output[0])
log.info("wrote %s: %d/%d refits used, %.1f s (%.2f s per draw)", snakemake.output[0],
         boot.n_converged, boot.n_draws, boot.seconds, boot.seconds / boot.n_draws)
