"""Rule misspec_fit: fit one model (possibly misspecified) to every cached WV of one chunk."""

from wflog import get_logger

from gmwm_studies.misspec import fit_model_chunk
from gmwm_studies.store import read_wv_chunk, write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
w, p = snakemake.wildcards, snakemake.params
chunk = read_wv_chunk(snakemake.input[0])
log.info("simulated %s; fitting %s (%s) with %s %s to %d replicates", chunk.model, w.fitmodel,
         p.spec, w.estimator, p.settings, len(chunk.replicates))
ds = fit_model_chunk(chunk, p.spec, w.fitmodel, p.settings, estimator=w.estimator,
                     progress=log.info)
write_dataset(ds, snakemake.output[0])
log.info("wrote %s; %d/%d converged", snakemake.output[0], int(ds["converged"].sum()),
         ds.sizes["replicate"])
