"""Rule lemmas000: paper 000's Lemma 1, Lemma 2, Remark A and the Fig 9 gap bootstrap
(gmwm_studies.lemmas000) -> reports/lemmas000/*.{csv,md}."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import os

import numpy as np
import pandas as pd

from gmwm_studies import lemmas000 as L
from gmwm_studies.replicates import read_replicates

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
cfg = p.cfg
out_dir = os.path.dirname(snakemake.output.tables[0])
tables: dict[str, pd.DataFrame] = {}

cases = {name: tuple(ab) for name, ab in cfg["sinusoids"].items()}
tables["lemma1_exact"] = L.lemma1_exact(cases, int(cfg["exact_levels"]))
detail, slopes = L.lemma1_rate(cases, list(cfg["log2_T"]), int(cfg["rate_levels"]),
                               int(cfg["replicates"]), int(cfg["seed"]),
                               n_boot=int(cfg["n_boot"]))
tables["lemma1_rate"], tables["lemma1_rate_detail"] = slopes, detail
log.info("lemma 1: %d cases", len(cases))

points: dict[str, dict[str, float]] = {}
ridge = None
jac_model, jac_levels = None, None
if p.sim2:
    s2 = p.sim2
    df, record = read_replicates(snakemake.input.sim2)
    jac_model, jac_levels = record["model"], int(record["J"])
    points["truth"] = dict(record["truth"])
    betas = 10.0 ** np.arange(cfg["ridge_log10_beta"][0], cfg["ridge_log10_beta"][1] + 1e-9, 0.5)
    ridge, fits = L.ridge_study(df, record, s2["estimators"], s2["study"], s2["seed"],
                                s2["simulator"], betas, int(cfg["ridge_max_fits"]),
                                levels=s2["levels"], log=log)
    points.update(fits)
    tables["remarkA_efficiency"] = L.efficiency(df, record["truth"], s2["base"], s2["efficient"],
                                                int(cfg["seed"]), n_boot=int(cfg["n_boot"]))
if jac_model is None:  # no Simulation 2: the Jacobian at a one-sinusoid model of the first case
    jac_model, jac_levels = "SIN", int(cfg["exact_levels"])
    a, b = next(iter(cases.values()))
    points["truth"] = {"SIN[1].alpha": a, "SIN[1].beta": b}
tables["lemma2_jacobian"] = L.lemma2_jacobian(jac_model, points, jac_levels)
tables["lemma2_ridge"] = ridge if ridge is not None else pd.DataFrame(columns=L.RIDGE_COLUMNS)
if "remarkA_efficiency" not in tables:
    tables["remarkA_efficiency"] = pd.DataFrame(columns=["parameter"])
if p.sim1:
    df1, _ = read_replicates(snakemake.input.sim1)
    tables["fig9_sd_gap"] = L.sd_gap_bootstrap(df1, p.sim1["parameters"], "gmwm", p.sim1["mle"],
                                               p.sim1["parameters"][0], int(cfg["seed"]),
                                               n_boot=int(cfg["n_boot"]))
else:
    tables["fig9_sd_gap"] = pd.DataFrame(columns=["parameter"])
written = L.write_tables(tables, out_dir, p.titles)
log.info("wrote %d files to %s", len(written), out_dir)
