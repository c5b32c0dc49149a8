"""Rule simulate_wv: simulate one chunk of replicates and cache their wavelet variances."""

from wflog import get_logger

from gmwm_studies.montecarlo import simulate_wv_chunk
from gmwm_studies.store import write_wv_chunk

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
log.info("study %s, model %s, T=%d, replicates %d..%d, seed %d, simulator %s",
         snakemake.wildcards.study, p.model, p.n_samples, p.replicates[0], p.replicates[-1], p.seed,
         p.simulator)
chunk = simulate_wv_chunk(p.model, p.truth, p.n_samples, p.replicates,
                          study=snakemake.wildcards.study, base_seed=p.seed, levels=p.levels,
                          progress=log.info, simulator=p.simulator)
write_wv_chunk(snakemake.output[0], chunk)
log.info("wrote %s (%d replicates x %d scales)", snakemake.output[0], *chunk.variances.shape)
