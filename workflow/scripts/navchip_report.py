"""Rule navchip_report: Figures 3 and 4 of [GMWFM] per axis, the estimates table (with SEs) and
the goodness-of-fit table, from the data file and the fits file."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

from gmwm.atomic import save_figure
from gmwm_studies.navchip import (
    channels_from_fits,
    estimates_table,
    figure_decomposition,
    figure_wv_datasheet,
    gof_table,
    write_tables,
)

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
fits = channels_from_fits(snakemake.input.data, snakemake.input.fits)
write_tables(estimates_table(fits), gof_table(fits, p.threshold), p.threshold, p.model,
             snakemake.output.estimates, snakemake.output.estimates_md, snakemake.output.gof,
             snakemake.output.gof_md)
out = Path(snakemake.output[0]).parent
for fig, stem in ((figure_wv_datasheet(fits, p.threshold), "fig3_wv_datasheet"),
                  (figure_decomposition(fits), "fig4_decomposition")):
    written = save_figure(fig, out / stem, formats=p.formats)
    log.info("wrote %s", ", ".join(map(str, written)))
