"""Rule index: one Markdown page listing every study with its figures, key numbers and run time."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm.atomic import write_text_atomic
from gmwm_studies.archive import archived_summary, read_benchmarks, render_index, run_summary

KEY_COLUMNS = ["method",  # STIM-300: GMWM / ARMAV / AVSM rows of one table
               "estimator",  # Simulations 2 and 3: CI and efficient weights (when no "method")
               "n_samples", "variant", "parameter", "truth", "rel_bias", "rel_sd", "std_bias",
               "share_not_converged",
               # Simulation 1 (GMWM vs MLE variants): per T, MLE replicates, failures and wrong
               # optima, speed-ups (MLE time / GMWM time), RMSE ratios
               "n_mle", "not_converged", "wrong_optimum", "speedup_mean", "speedup_median",
               "rmse_ratio_sigma2", "rmse_ratio_phi", "rmse_ratio_ar1_sigma2", "rmse_ratio_gamma2",
               # uncertainty: identifiability status per fit; coverage study: coverage, MC SE
               "fit", "status", "interval", "coverage", "wilson_lo", "wilson_hi", "mean_se_ratio",
               # navigation emulation: maximum of the position error ratio, its epoch and CI
               "window", "time_s", "max_ratio", "ci_lo", "ci_hi",
               # Allan-variance chapter: one row per checked quantity, with its reference value
               "item", "quantity", "value", "reference"]

LABELS = {"method", "estimator", "n_samples", "variant", "parameter", "fit", "status", "interval",
          "window", "item", "quantity"}

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
out = Path(snakemake.output[0])


def relative(targets):
    """Target paths relative to the index's directory (the links on the page)."""
    paths = [Path(t) for t in targets]
    return [p.relative_to(out.parent) if p.is_relative_to(out.parent) else p for p in paths]


entries = []
for name, s in snakemake.params.studies.items():
    targets = [Path(t) for t in s["targets"]]
    rel = relative(targets)
    csv = next((t for t in targets if t.suffix == ".csv"), None)
    key = None
    if csv is not None:
        table = pd.read_csv(csv)
        labelled = "method" in table.columns  # "method" already names the estimator
        key = table[[c for c in KEY_COLUMNS
                     if c in table.columns and not (labelled and c == "estimator")]]
        if not any(c not in LABELS and pd.api.types.is_numeric_dtype(key[c]) for c in key):
            key = None  # labels only (e.g. the SVO table): nothing worth a glance
    entries.append({
        "name": name, "model": s["model"], "description": s["description"],
        "n_samples": s["n_samples"], "replicates": s["replicates"],
        "figures": [str(r) for r in rel if r.suffix == ".png"],
        "table": next((str(r) for r in rel if r.suffix == ".md"), ""),
        "key": key,
    })
for name, s in snakemake.params.linked.items():
    rel = relative(s["targets"])
    entries.append({
        "name": name, "model": s["model"], "description": s["description"],
        "figures": [str(r) for r in rel if r.suffix == ".png"],
        "table": next((str(r) for r in rel if r.suffix == ".md"), ""), "key": None,
    })
# a section's jobs may sit under other directory names (SVO: case1, case2)
aliases = {d: name for name, dirs in snakemake.params.study_dirs.items() for d in dirs if d != name}
bench = read_benchmarks(snakemake.params.benchmarks)
bench["study"] = bench["study"].replace(aliases)
summary = run_summary(bench)
# studies that did not run here (a partial rerun) keep the timings of their archived run
ran = set(summary["study"]) if len(summary) else set()
older, sources = archived_summary(snakemake.params.archive_root,
                                  [e["name"] for e in entries if e["name"] not in ran], aliases)
summary = pd.concat([summary, older], ignore_index=True) if len(older) else summary
write_text_atomic(out, render_index(entries, summary, snakemake.params.config_id, sources))
log.info("wrote %s (%d studies)", out, len(entries))
