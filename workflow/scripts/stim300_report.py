"""Rule stim300_report: bias/SD/RMSE table in Table I units (CSV + Markdown with the per-replicate
cost), Figure 1 (boxplots per parameter, length and estimator) and Figure 2 (RMSE vs length)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies import stim300 as ac

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
study = snakemake.wildcards.study
groups = ac.group_datasets(ds for f in snakemake.input for ds in ac.read_estimates(f).values())
first = next(iter(groups.values()))
truth = {str(n): float(v) for n, v in zip(first["parameter"].values, first["truth"].values,
                                          strict=True)}
diff = ac.check_table_i_truth(p.model, truth, p.sensor, p.freq)
log.info("truth vs Table I (relative difference): %s", diff)

table = ac.summarize_table_units(groups, p.sensor, p.freq)[ac.TABLE_COLUMNS]
cost = ac.cost_summary(groups, p.replicates, cores=p.cores)
labels = list(dict.fromkeys(ac.estimator_label(v) for v in p.estimators.values()))
title = f"{study}: STIM-300 {p.sensor}, " + " vs ".join(labels)
write_text_atomic(snakemake.output.csv, table.to_csv(index=False))
write_text_atomic(snakemake.output.md, ac.report_markdown(
    table, cost, title=title, model=p.model, estimators=p.estimators, truth_vs_table_i=diff,
    cores=p.cores))
for _, row in cost.iterrows():
    log.info("T=%d: %.4f s per replicate, projected %.1f min", row["n_samples"], row["total_s"],
             row["projected_min"])

for fig, stem in ((ac.figure_boxplots(groups, p.sensor, p.freq, title=title), "fig1_boxplot"),
                  (ac.figure_rmse(table, title=title), "fig2_rmse")):
    base = Path(snakemake.output[0]).parent / f"{study}_{stem}"
    written = save_figure(fig, base, formats=p.formats)
    log.info("wrote %s", ", ".join(map(str, written)))
