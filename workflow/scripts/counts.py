"""Rule counts: the named counts of every per-replicate table -> reports/counts.json, counts.md."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

from gmwm_studies.counts import collect, write_counts
from gmwm_studies.replicates import read_replicates

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
base = Path(snakemake.output.json).parent
tables = []
for t in snakemake.params.tables:
    df, record = read_replicates(t["csv"])
    tables.append((t["study"], df, record, str(Path(t["csv"]).relative_to(base)), t["label_T"]))
counts = collect(tables)
write_counts(counts, snakemake.output.json, snakemake.output.md)
log.info("wrote %s and %s: %d counts from %d tables", snakemake.output.json, snakemake.output.md,
         len(counts), len(tables))
