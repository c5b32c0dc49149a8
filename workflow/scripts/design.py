"""Rule design: asymptotic SEs at the truth and design probabilities beside the observed counts
-> reports/design/asymptotic.{csv,md}, reports/design/counts.{json,md}."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import os

import pandas as pd

from gmwm_studies.design import audit_counts, navchip_design, study_design, write_design
from gmwm_studies.replicates import read_replicates

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
rows = []
for t in p.tables:
    df, record = read_replicates(t["csv"])
    rows += study_design(t["study"], df, record, p.estimators, label_T=t["label_T"], seed=p.seed)
    log.info("%s T = %s: %d rows", t["study"], record["T"], len(rows))
if p.navchip:
    nav = p.navchip
    est = pd.read_csv(snakemake.input.navchip_estimates)
    draws = pd.read_csv(snakemake.input.navchip_draws)
    rows += navchip_design(est, draws, nav["model"], nav["fit"], nav["n_samples"], nav["levels"],
                           nav["freq"], seed=p.seed)
    log.info("navchip: %d axes", len(est))
extra = []
for t, path in zip(p.audits, snakemake.input.audits, strict=True):
    df, record = read_replicates(t["csv"])
    src = os.path.relpath(path, os.path.dirname(snakemake.output.counts_md))
    extra += audit_counts(t["study"], df, record["truth"], pd.read_csv(path), src)
    log.info("%s: audit %s", t["study"], path)
write_design(rows, snakemake.output.csv, snakemake.output.md, snakemake.output.json,
             snakemake.output.counts_md, extra)
log.info("wrote %s (%d rows) and %s", snakemake.output.csv, len(rows), snakemake.output.json)
