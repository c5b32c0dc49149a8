"""Rule replicates: one study's per-replicate estimate table at one T (CSV + truth JSON)."""

from wflog import get_logger

from gmwm_studies.replicates import study_table, write_replicates

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
df, record = study_table(snakemake.params.kind, list(snakemake.input),
                         extra=dict(snakemake.params.extra))
record["study"] = snakemake.wildcards.study
write_replicates(df, record, snakemake.output.csv, snakemake.output.truth)
log.info("wrote %s: %d rows (%d converged), %d with a boundary parameter", snakemake.output.csv,
         len(df), int(df["converged"].sum()), int((df["at_boundary"] != "").sum()))
