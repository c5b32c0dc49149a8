"""Rule sim1_table: RMSE, bias and run time per method and T; speed-up and RMSE ratios per T (the
statsmodels baseline merged in at the T where it ran)."""

from wflog import get_logger

from gmwm.atomic import write_text_atomic
from gmwm_studies.montecarlo import write_table
from gmwm_studies.sim1 import add_baseline, counts_text, study_tables
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
out, p = snakemake.output, snakemake.params
name = snakemake.wildcards.study
baselines = {int(T): f for T, f in zip(p.baseline_T, snakemake.input.baselines, strict=True)}
results = []
for f in snakemake.input.estimates:
    ds = read_dataset(f)
    T = int(ds.attrs["n_samples"])
    results.append(add_baseline(ds, read_dataset(baselines[T])) if T in baselines else ds)
long, comp = study_tables(results)
counts = counts_text(comp, p.mle, p.gmwm, p.baseline)
write_text_atomic(out.counts, counts)
write_table(comp, out.comparison, out.comparison_md,
            title=(f"{name}: GMWM vs MLE variants and statsmodels' own MLE; speed-up = MLE time / "
                   f"GMWM time on the same signals (ratio of means and ratio of medians), of the "
                   f"point estimates (speedup_*) and of the fits with standard errors "
                   f"(speedup_se_*); RMSE ratio MLE / GMWM per parameter\n\n{counts}"))
write_table(long, out.table, out.table_md,
            title=(f"{name}: RMSE, bias, SD, mean SE and mean run time (point estimate; "
                   f"*_seconds_se with standard errors) per method, sample size and parameter "
                   f"(set 'paired': per MLE variant, the replicates where it converged to the best "
                   f"optimum, both methods; set 'all': GMWM on every replicate)\n\n{counts}"))
log.info("speed-up and RMSE ratios:\n%s", comp.to_string())
