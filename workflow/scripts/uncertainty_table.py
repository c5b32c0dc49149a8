"""Rule uncertainty_table(_navchip): Table 1, estimates with 95 % parametric bootstrap CIs
(percentile and basic), bootstrap SE next to the sandwich SE, per fitted model (CSV + Markdown)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import pandas as pd

from gmwm.bootstrap import BootstrapResult
from gmwm.codec import read_result
from gmwm_studies.montecarlo import write_table
from gmwm_studies.store import read_dataset
from gmwm_studies.uncertainty import bootstrap_from_dataset, bootstrap_table

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
alpha = snakemake.params.alpha
frames = []
for fit, path in zip(snakemake.params.fits, snakemake.input.fits, strict=True):
    est = read_result(path)
    parts = [bootstrap_from_dataset(read_dataset(f), est) for f in snakemake.input.boot
             if f.split("/")[-1].rsplit("_d", 1)[0] == fit]
    boot = BootstrapResult.combine(parts)
    label = fit.replace("navchip_", "Navchip ").replace("_", " ")
    frames.append(bootstrap_table(boot, label, alpha))
    log.info("%s: %d draws, %d failed, %.0f s of draws\n%s", fit, boot.n_draws, boot.n_failed,
             boot.seconds, boot.summary(alpha))
df = pd.concat(frames, ignore_index=True)
lvl = f"{100 * (1 - alpha):g}"
write_table(df, snakemake.output.csv, snakemake.output.md,
            title=(f"Estimates with {lvl} % parametric bootstrap CIs (percentile pct_*, basic "
                   "basic_*), bootstrap SE (boot_se) and asymptotic sandwich SE; se_ratio = "
                   "boot_se / sandwich_se; n_used / n_failed refits of B draws"))
log.info("wrote %s (%d rows)", snakemake.output.csv, len(df))
