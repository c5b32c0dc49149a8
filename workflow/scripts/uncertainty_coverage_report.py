"""Rule coverage_report: coverage per parameter and interval kind with its MC error, bootstrap vs
sandwich SE ratios (CSV + Markdown), and the coverage figure."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import xarray as xr

from gmwm.atomic import save_figure
from gmwm_studies.montecarlo import write_table
from gmwm_studies.store import read_dataset
from gmwm_studies.uncertainty import coverage_summary, plot_coverage

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
ds = xr.concat([read_dataset(f) for f in snakemake.input], dim="replicate",
               combine_attrs="override").sortby("replicate")
df = coverage_summary(ds)
a = df.attrs
name = snakemake.wildcards.study
n_conv = int(ds["converged"].sum())
write_table(df, snakemake.output.csv, snakemake.output.md,
            title=(f"{name}: coverage of {100 * a['level']:g} % intervals over R = {a['R']} "
                   f"replicates (T = {a['n_samples']}, B = {a['B']} bootstrap refits each; "
                   f"{n_conv}/{a['R']} replicate fits converged); mc_se = sqrt(c (1 - c) / n); "
                   "wilson_lo/hi = Wilson 95 % interval of the coverage (quoted instead of mc_se, "
                   "which is 0 at a coverage of 0 or 1); "
                   "mean/median_se_ratio = bootstrap SE / sandwich SE; sd_over_* = empirical SD "
                   "of the estimates / mean SE"))
fig = plot_coverage(df, level=a["level"])
fig.axes[0].set_title(f"{name}: T = {a['n_samples']}, R = {a['R']}, B = {a['B']}", fontsize=9)
for path in [snakemake.output.png, *snakemake.output.other]:
    save_figure(fig, path)
log.info("coverage:\n%s", df[["parameter", "interval", "coverage", "wilson_lo", "wilson_hi",
                                "mean_se_ratio"]]
         .to_string())
