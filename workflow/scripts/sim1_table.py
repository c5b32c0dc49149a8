"""Rule sim1_table: RMSE, bias and run time per method and T; speed-up and RMSE ratios per T."""

from wflog import get_logger

from gmwm.atomic import write_text_atomic
from gmwm_studies.montecarlo import write_table
from gmwm_studies.sim1 import counts_text, study_tables
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
out = snakemake.output
name = snakemake.wildcards.study
long, comp = study_tables([read_dataset(f) for f in snakemake.input])
counts = counts_text(comp, snakemake.params.mle, snakemake.params.gmwm)
write_text_atomic(out.counts, counts)
write_table(comp, out.comparison, out.comparison_md,
            title=(f"{name}: GMWM vs MLE variants, speed-up (MLE time / GMWM time on the same "
                   f"signals; ratio of means and ratio of medians) and RMSE ratio MLE / GMWM per "
                   f"parameter\n\n{counts}"))
write_table(long, out.table, out.table_md,
            title=(f"{name}: RMSE, bias, SD and mean run time per method, sample size and "
                   f"parameter (set 'paired': per MLE variant, the replicates where it converged to "
                   f"the best optimum, both methods; set 'all': GMWM on every replicate)\n\n{counts}"))
log.info("speed-up and RMSE ratios:\n%s", comp.to_string())
