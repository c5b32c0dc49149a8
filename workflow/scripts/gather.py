"""Rules gather and sim1_gather: join one study's chunk estimates at one sample size."""

from wflog import get_logger

from gmwm_studies.montecarlo import gather
from gmwm_studies.store import read_dataset, write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
ds = gather(read_dataset(f) for f in snakemake.input)
write_dataset(ds, snakemake.output[0])
log.info("gathered %d chunks, %d replicates -> %s", len(snakemake.input), ds.sizes["replicate"],
         snakemake.output[0])
