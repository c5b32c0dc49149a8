"""Rule svo_coverage_report: coverage table (Wilson MC intervals) and figure of one SVO case."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import numpy as np
import pandas as pd

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies.montecarlo import format_markdown_table
from gmwm_studies.svo_study import (
    PER_REPLICATE_FORMAT,
    coverage_replicate_table,
    coverage_table,
    figure_coverage,
    merge,
)

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
out = snakemake.output
res = merge([dict(np.load(f)) for f in snakemake.input])
rows = coverage_table(res, 1.0 - snakemake.params.alpha)
df = pd.DataFrame(rows)
write_text_atomic(out.csv, df.to_csv(index=False))  # atomic: a killed job leaves no half file
write_text_atomic(out.md, format_markdown_table(df) + "\n")
per_rep = pd.DataFrame(coverage_replicate_table(res, snakemake.params.alpha))
write_text_atomic(out.replicates, per_rep.to_csv(index=False, float_format=PER_REPLICATE_FORMAT))
written = save_figure(figure_coverage(rows, 1.0 - snakemake.params.alpha),
                      Path(out.fig).with_suffix(""), formats=snakemake.params.formats)
log.info("wrote %s; %d replicates, block %d, %.2f s per replicate", ", ".join(map(str, written)),
         len(res["coef"]), int(res["block"]), float(np.mean(res["seconds"])))
