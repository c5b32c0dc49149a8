# Per-replicate estimate tables and the named counts quoted in the reports
# (gmwm_studies.replicates, gmwm_studies.counts; docs/pipeline.md "Per-replicate tables"):
#   replicates  one study at one T: its gathered estimates -> reports/<study>/replicates/
#               estimates_T<T>.csv (one row per replicate and estimator) + truth_T<T>.json
#   counts      every table, and the SVO (reports/svo/<case>/replicates/) and navigation
#               (reports/navigation/replicates/) per-replicate files -> reports/counts.json and
#               reports/counts.md (an input of the index, so every run that rebuilds the index
#               recounts)
#   navchip_draws, counts_navchip   the Navchip bootstrap draws (label-aligned refits, one row per
#               fit and draw) -> reports/navchip/replicates/, reports/navchip/counts.{json,md}.
#               Requested with uncertainty_navchip_targets (rule all only, not the index): they
#               need the Navchip data, whose absence must fail only the navchip jobs.


def replicates_T(name):
    """Sample sizes with a per-replicate table (the coverage study: its largest T, as its report)."""
    s = STUDIES[name]
    return [max_T(name)] if s["kind"] == "bootstrap_coverage" else list(s["n_samples"])


def replicates_files(name):
    return [f"reports/{name}/replicates/{stem}_T{T}.{ext}" for T in replicates_T(name)
            for stem, ext in (("estimates", "csv"), ("truth", "json"))]


def replicates_inputs(w):
    name, T = w.study, w.T
    s = STUDIES[name]
    kind = s["kind"]
    chunks = range(n_chunks(name))
    if kind == "wv_montecarlo":
        return [f"results/{name}/estimates/{e}_T{T}.nc" for e in s["estimators"]]
    if kind == "misspec":
        return [f"results/{name}/misspec/{m}/{s['estimators'][0]}_T{T}.nc" for m in s["fit_models"]]
    if kind == "stim300":
        return [f"results/{name}/allan/T{T}_c{c}.nc" for c in chunks]
    if kind == "bootstrap_coverage":
        return [f"results/{name}/coverage/T{T}_c{c}.nc" for c in chunks]
    if kind == "mle_comparison":  # + the statsmodels baseline where it ran at this T
        base = sim1_baselines(name).get(int(T))
        return [f"results/{name}/gmwm_mle/all_T{T}.nc", *([base] if base else [])]
    raise WorkflowError(f"no per-replicate table for study kind {kind!r} (study {name!r})")


def replicates_extra(w):
    s = STUDIES[w.study]
    if s["kind"] == "stim300":
        return {"sensor": s["sensor"], "freq": stim300_freq(w.study)}
    if s["kind"] == "misspec":
        return {"fit_models": list(s["fit_models"]), "model": s["model"], "truth": s["truth"]}
    if s["kind"] == "bootstrap_coverage":
        return {"estimator": s["estimators"][0]}
    return {}


COUNTS_FILES = ["reports/counts.json", "reports/counts.md"]
NAVCHIP_DRAWS = ["reports/navchip/replicates/bootstrap_draws.csv",
                 "reports/navchip/replicates/bootstrap_estimates.csv"]
NAVCHIP_COUNTS = ["reports/navchip/counts.json", "reports/navchip/counts.md"]

# the per-replicate files of the SVO and navigation studies (written by svo_report,
# svo_coverage_report and nav_report), counted beside the estimate tables
COUNTS_SVO = [
    {"case": case, "fits": f"reports/svo/{case}/replicates/virtual_fits.csv",
     "coverage": (f"reports/svo/{case}/replicates/coverage.csv"
                  if case in SVO_COV["cases"] else None)}
    for case in (SVO["cases"] if SVO["enabled"] else [])
]
COUNTS_NAV = ({"csv": "reports/navigation/replicates/iterations.csv", "models": list(NAV["models"])}
              if _NAV_ON else None)

COUNTS_TABLES = [
    {"study": name, "csv": f"reports/{name}/replicates/estimates_T{T}.csv",
     "label_T": len(replicates_T(name)) > 1}
    for name in STUDIES for T in replicates_T(name)
]


localrules:
    replicates,
    counts,
    navchip_draws,
    counts_navchip,


rule replicates:
    input:
        replicates_inputs,
    output:
        csv="reports/{study}/replicates/estimates_T{T}.csv",
        truth="reports/{study}/replicates/truth_T{T}.json",
    params:
        kind=lambda w: study(w)["kind"],
        extra=replicates_extra,
    log:
        "logs/{study}/replicates/T{T}.log",
    benchmark:
        f"{BENCH}/replicates/{{study}}/T{{T}}.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/replicates.py"


rule counts:
    input:
        [f for name in STUDIES for f in replicates_files(name)],
        [f for c in COUNTS_SVO for f in (c["fits"], c["coverage"]) if f],
        [COUNTS_NAV["csv"]] if COUNTS_NAV else [],
    output:
        json=COUNTS_FILES[0],
        md=COUNTS_FILES[1],
    params:
        tables=COUNTS_TABLES,
        svo=COUNTS_SVO,
        navigation=COUNTS_NAV,
    log:
        "logs/counts.log",
    benchmark:
        f"{BENCH}/counts/counts/counts.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/counts.py"


rule navchip_draws:
    input:
        fits=lambda w: [f"results/uncertainty/fits/{f}.json" for f in unc_navchip_fits()],
        boot=lambda w: unc_boot_files(unc_navchip_fits()),
    output:
        draws=NAVCHIP_DRAWS[0],
        estimates=NAVCHIP_DRAWS[1],
    params:
        fits=unc_navchip_fits(),
    log:
        "logs/uncertainty/navchip_draws.log",
    benchmark:
        f"{BENCH}/navchip_draws/navchip/navchip.tsv"
    script:
        "../scripts/navchip_draws.py"


rule counts_navchip:
    input:
        draws=NAVCHIP_DRAWS[0],
        estimates=NAVCHIP_DRAWS[1],
    output:
        json=NAVCHIP_COUNTS[0],
        md=NAVCHIP_COUNTS[1],
    log:
        "logs/uncertainty/counts_navchip.log",
    benchmark:
        f"{BENCH}/counts_navchip/navchip/navchip.tsv"
    script:
        "../scripts/counts_navchip.py"
