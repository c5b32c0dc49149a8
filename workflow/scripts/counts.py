"""Rule counts: the named counts of every per-replicate table (the studies' estimate tables, the
SVO and navigation per-replicate files) -> reports/counts.json, counts.md."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm_studies.counts import collect, navigation_counts, svo_counts, write_counts
from gmwm_studies.replicates import read_replicates

snakemake = globals()["snakemake"]  # injected by Snakemake


def read_table(path: str) -> pd.DataFrame:
    return pd.read_csv(path, keep_default_na=False, na_values=[""], dtype={"reason": str})


log = get_logger(snakemake)
base = Path(snakemake.output.json).parent
tables = []
for t in snakemake.params.tables:
    df, record = read_replicates(t["csv"])
    tables.append((t["study"], df, record, str(Path(t["csv"]).relative_to(base)), t["label_T"]))
counts = collect(tables)
for c in snakemake.params.svo:  # SVO: per virtual signal and per coverage replication
    fits = read_table(c["fits"])
    coverage = read_table(c["coverage"]) if c["coverage"] else None
    counts += svo_counts(c["case"], fits, coverage,
                         {"fits": str(Path(c["fits"]).relative_to(base)),
                          "coverage": str(Path(c["coverage"] or c["fits"]).relative_to(base))})
nav = snakemake.params.navigation
if nav:  # navigation: per iteration and model
    counts += navigation_counts(read_table(nav["csv"]), str(Path(nav["csv"]).relative_to(base)),
                                nav["models"])
write_counts(counts, snakemake.output.json, snakemake.output.md)
log.info("wrote %s and %s: %d counts from %d tables", snakemake.output.json, snakemake.output.md,
         len(counts), len(tables))
