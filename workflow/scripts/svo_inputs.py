"""Rule svo_inputs: [SVO] Fig. 1 (Case 1) / Fig. 6 (Case 2), the absolute correlation matrices
of the input innovation covariances (App. C), and their entries as a table."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies.montecarlo import format_markdown_table
from gmwm_studies.svo_study import figure_inputs, input_table

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
out, case = snakemake.output, snakemake.wildcards.svo_case
df = pd.DataFrame(input_table(case))
write_text_atomic(out.csv, df.to_csv(index=False))
title = (f"# {case}: input innovation covariances of [SVO] App. C (deg^2/s^2 per sample, "
         f"10 Hz) and their correlations, upper triangle\n\n")
write_text_atomic(out.md, title + format_markdown_table(df) + "\n")
written = save_figure(figure_inputs(case), Path(out[0]).with_suffix(""),
                      formats=snakemake.params.formats)
log.info("wrote %s, %s, %s", out.csv, out.md, ", ".join(map(str, written)))
