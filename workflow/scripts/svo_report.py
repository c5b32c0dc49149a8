"""Rule svo_report: figures and tables of one SVO case from its training chunks."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import numpy as np
import pandas as pd

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies.montecarlo import format_markdown_table
from gmwm_studies.svo_study import (
    PER_REPLICATE_FORMAT,
    array_coef_table,
    coef_table,
    figure_coefs,
    figure_gmwm,
    figure_wv,
    gmwm_table,
    merge,
    virtual_fit_table,
    wv_table,
)

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, out, case = snakemake.params, snakemake.output, snakemake.wildcards.svo_case
res = merge([dict(np.load(f)) for f in snakemake.input.train])
for rows, csv, md in ((coef_table(res, case, p.levels), out.coefs_csv, out.coefs_md),
                      (wv_table(res, p.freq, case), out.wv_csv, out.wv_md),
                      (gmwm_table(res), out.gmwm_csv, out.gmwm_md)):
    df = pd.DataFrame(rows)
    write_text_atomic(csv, df.to_csv(index=False))  # atomic: a killed job leaves no half file
    write_text_atomic(md, format_markdown_table(df) + "\n")
for rows, csv in ((array_coef_table(res), out.array_coefs),
                  (virtual_fit_table(res), out.virtual_fits)):
    write_text_atomic(csv, pd.DataFrame(rows).to_csv(index=False,
                                                     float_format=PER_REPLICATE_FORMAT))
folder = Path(out[0]).parent
for fig, stem in ((figure_wv(res, p.freq, case), "fig_wv"),
                  (figure_coefs(res, case, p.levels), "fig_coefs"), (figure_gmwm(res), "fig_gmwm")):
    log.info("wrote %s", ", ".join(map(str, save_figure(fig, folder / stem, formats=p.formats))))
log.info("%s: %d training arrays, %.2f s per training replicate", case, res["coef"].shape[0],
         float(np.mean(res["seconds"])))
