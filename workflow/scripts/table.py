"""Rule table: bias, SD, RMSE and non-convergence per parameter (CSV + Markdown)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import pandas as pd

from gmwm_studies.montecarlo import summarize, write_table
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
df = pd.concat([summarize(read_dataset(f)) for f in snakemake.input], ignore_index=True)
title = f"{snakemake.wildcards.study}: bias, SD and RMSE of the estimates"
write_table(df, snakemake.output.csv, snakemake.output.md, title=title)
log.info("wrote %s and %s (%d rows)", snakemake.output.csv, snakemake.output.md, len(df))
