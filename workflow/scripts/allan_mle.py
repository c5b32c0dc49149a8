"""Rule allan_mle: [AV-chapter] Example 4.1, exact MLE of WN + AR1 beside the GMWM
(gmwm_studies.allan_chapter.mle_study) and the cost of the chapter's dense likelihood."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm_studies import allan_chapter as ac
from gmwm_studies.montecarlo import write_table

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, out = snakemake.params, snakemake.output

settings = {k: ac.MLE_SETTINGS[k] for k in p.settings}
per, summary = ac.mle_study(p.n_samples, p.replicates, settings, p.seed, p.maxiter,
                            p.wrong_optimum_ll)
write_text_atomic(out.replicates, per.to_csv(index=False, float_format="%.10g"))
write_table(summary, out.mle_csv, out.mle_md,
            f"Example 4.1: MLE of WN + AR1 vs GMWM ({p.replicates} replicates per T)")
dense = ac.dense_cost(settings[p.settings[0]], p.dense_sizes, p.seed)
write_table(dense, out.dense_csv, out.dense_md,
            "Example 4.1: seconds per log-likelihood evaluation, dense T x T vs Kalman filter")
numbers = ac.mle_numbers(summary, dense) | {"settings": settings, "replicates": p.replicates}
write_json_atomic(out.numbers, numbers)
log.info("wrote %s (%d fits)", Path(out.mle_csv).parent, len(per))
