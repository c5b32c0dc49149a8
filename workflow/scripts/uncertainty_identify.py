"""Rule uncertainty_identify: local, global and (if configured) emcee posterior identifiability
checks of one fitted model; report as JSON, posterior draws as .npz (empty if not run)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import numpy as np

from gmwm.atomic import atomic_path, write_json_atomic
from gmwm.codec import read_result
from gmwm.identify import check

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
est = read_result(snakemake.input[0])
rep = check(est, posterior=p.posterior, seed=p.seed, n_starts=p.n_starts, max_steps=p.max_steps)
log.info("%s\n%s", snakemake.wildcards.fit, rep.summary())
write_json_atomic(snakemake.output.json, rep.to_json_dict())
samples = rep.posterior.samples if rep.posterior is not None else np.zeros((0, est.model.n_params))
with atomic_path(snakemake.output.samples) as tmp, open(tmp, "wb") as fh:
    np.savez_compressed(fh, samples=samples, names=np.array(est.param_names))
