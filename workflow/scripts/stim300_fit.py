"""Rule stim300_fit: fit every cached WV of one chunk with each of the study's estimators
(GMWM, ARMAV, AVSM); one NetCDF group per estimator."""

from wflog import get_logger

from gmwm_studies.stim300 import fit_chunk_all, write_estimates
from gmwm_studies.store import read_wv_chunk

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
chunk = read_wv_chunk(snakemake.input[0])
log.info("estimators %s, %d replicates, freq %g Hz", snakemake.params.estimators,
         len(chunk.replicates), snakemake.params.freq)
fits = fit_chunk_all(chunk, snakemake.params.estimators, snakemake.params.freq, progress=log.info)
write_estimates(snakemake.output[0], fits)
for name, ds in fits.items():
    log.info("%s: %d/%d converged, mean fit %.4f s", name, int(ds["converged"].sum()),
             ds.sizes["replicate"], float(ds["seconds_fit"].mean()))
