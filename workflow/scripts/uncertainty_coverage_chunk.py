"""Rule coverage_chunk: for each replicate of one chunk, fit, bootstrap (B refits) and keep the
percentile, basic and Wald intervals (gmwm_studies.uncertainty.coverage_chunk)."""

from wflog import get_logger

from gmwm_studies.store import write_dataset
from gmwm_studies.uncertainty import coverage_chunk

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
log.info("study %s, model %s, T=%d, replicates %d..%d, B=%d, settings %s", snakemake.wildcards.study,
         p.model, p.n_samples, p.replicates[0], p.replicates[-1], p.B, p.settings)
ds = coverage_chunk(p.model, p.truth, p.n_samples, p.replicates, study=snakemake.wildcards.study,
                    base_seed=p.seed, B=p.B, settings=p.settings, levels=p.levels, alpha=p.alpha,
                    progress=log.info, simulator=p.simulator)
write_dataset(ds, snakemake.output[0])
log.info("wrote %s", snakemake.output[0])
