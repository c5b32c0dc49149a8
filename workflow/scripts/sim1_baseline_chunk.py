"""Rule sim1_baseline_chunk: statsmodels' own MLE (the general-purpose baseline) on replicates
[a, b) of one Simulation 1 sample size, the same signals as sim1_chunk's."""

from wflog import get_logger

from gmwm_studies.sim1 import run_baseline_chunk
from gmwm_studies.store import write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
log.info("study %s, model %s, T=%d, replicates %d..%d, seed %d, statsmodels %s",
         snakemake.wildcards.study, p.model, p.n_samples, p.replicates[0], p.replicates[-1],
         p.seed, p.settings)
ds = run_baseline_chunk(p.model, p.truth, p.n_samples, p.replicates,
                        study=snakemake.wildcards.study, base_seed=p.seed, settings=p.settings,
                        progress=log.info)
write_dataset(ds, snakemake.output[0])
log.info("statsmodels: converged %d/%d; wrote %s", int(ds["converged"].sum()),
         ds.sizes["replicate"], snakemake.output[0])
