"""Rule sim1_chunk: simulate one chunk of Simulation 1 replicates, fit GMWM and (under the cap) MLE."""

from wflog import get_logger

from gmwm_studies.sim1 import run_chunk
from gmwm_studies.store import write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
reps = p.replicates
# replicates with an MLE fit are the lowest ids (the cap keeps ids < n_mle), contiguous in a chunk
n_mle = max(p.mle_replicates) + 1 if p.mle_replicates else 0
# likewise per capped variant: its replicates in this chunk are the lowest MLE ones
variant_caps = {v: max(r) + 1 if r else 0 for v, r in p.variant_replicates.items()}
log.info("study %s, model %s, T=%d, replicates %d..%d (MLE on %d of them; capped variants %s), "
         "seed %d, GMWM %s, MLE %s", snakemake.wildcards.study, p.model, p.n_samples, reps[0],
         reps[-1], len(p.mle_replicates), {v: len(r) for v, r in p.variant_replicates.items()},
         p.seed, p.gmwm, p.mle)
ds = run_chunk(p.model, p.truth, p.n_samples, reps, study=snakemake.wildcards.study,
               base_seed=p.seed, gmwm_settings=p.gmwm, mle_settings=p.mle, n_mle=n_mle,
               progress=log.info, variant_replicates=variant_caps)
write_dataset(ds, snakemake.output[0])
for est in ds["estimator"].values[1:]:
    ran = ds["ran"].sel(estimator=est)
    log.info("%s: converged %d/%d", est, int((ds["converged"].sel(estimator=est) & ran).sum()),
             int(ran.sum()))
log.info("wrote %s", snakemake.output[0])
