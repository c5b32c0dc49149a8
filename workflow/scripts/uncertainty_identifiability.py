"""Rule uncertainty_identifiability(_navchip): pass/warn table with reasons, one row per fit."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import json

import pandas as pd

from gmwm_studies.montecarlo import write_table
from gmwm_studies.uncertainty import summary_row

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
rows = []
for fit, path in zip(snakemake.params.fits, snakemake.input, strict=True):
    with open(path, encoding="utf-8") as fh:
        rows.append(summary_row(snakemake.params.labels[fit], json.load(fh)))
df = pd.DataFrame(rows)
write_table(df, snakemake.output.csv, snakemake.output.md,
            title=("Identifiability of the fitted models: pass/warn with reasons (local: whitened "
                   "WV Jacobian; global: multi-start; posterior: emcee quasi-posterior)"))
log.info("wrote %s: %s", snakemake.output.csv, dict(df["status"].value_counts()))
