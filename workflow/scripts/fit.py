"""Rule fit: fit the study model to every cached WV of one chunk with one estimator."""

from wflog import get_logger

from gmwm_studies.montecarlo import fit_chunk
from gmwm_studies.store import read_wv_chunk, write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
chunk = read_wv_chunk(snakemake.input[0])
log.info("estimator %s, settings %s, %d replicates", snakemake.wildcards.estimator,
         snakemake.params.settings, len(chunk.replicates))
ds = fit_chunk(chunk, snakemake.params.settings, estimator=snakemake.wildcards.estimator,
               progress=log.info)
write_dataset(ds, snakemake.output[0])
log.info("wrote %s; %d/%d converged", snakemake.output[0], int(ds["converged"].sum()),
         ds.sizes["replicate"])
