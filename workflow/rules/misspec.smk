# Model misspecification study of the vibration-noise paper (kind: misspec; [Vibration] Table 5,
# Fig. 6; library code gmwm_studies.misspec):
#   simulate_wv (montecarlo.smk: per chunk, simulate the study model + one WV pass, HDF5 cache)
#   -> misspec_fit (per chunk and fitted model: gmwm_studies.montecarlo.fit_chunk on the cached WVs)
#   -> misspec_gather (shared gather script) -> misspec_report (table, Fig. 6).
# The study's `fit_models` maps labels to the fitted models (model1 = AR1+RW, the misspecified
# static model; model2 = AR1+RW+2*SIN, the true one); each must be nested in the study model.
# navigation.smk reuses these fits: iteration b of the emulation uses replicate b's estimates.

MISSPEC_LABELS = {"model1": "Model 1", "model2": "Model 2"}

for _name in studies_of_kind("misspec"):
    if len(STUDIES[_name].get("fit_models", {})) < 1:
        raise WorkflowError(f"config: study {_name!r} (kind misspec) needs 'fit_models' "
                            "(label -> model string)")


def misspec_estimates(name, label, T=None):
    s = STUDIES[name]
    T = T if T is not None else max(s["n_samples"])
    return f"results/{name}/misspec/{label}/{s['estimators'][0]}_T{T}.nc"


def misspec_targets(name):
    base = f"reports/misspec/{name}"
    return [
        f"{base}_bias_sd_rmse.csv",
        f"{base}_bias_sd_rmse.md",
        *[f"{base}_fig6_boxplot.{fmt}" for fmt in FIG_FORMATS],
    ]


def misspec_benchmarks(name):
    s = STUDIES[name]
    chunks = range(n_chunks(name))
    est = s["estimators"][0]
    return [
        *[f"{BENCH}/simulate_wv/{name}/T{T}_c{c}.tsv" for T in s["n_samples"] for c in chunks],
        *[
            f"{BENCH}/misspec_fit/{name}/{m}_{est}_T{T}_c{c}.tsv"
            for m in s["fit_models"]
            for T in s["n_samples"]
            for c in chunks
        ],
        *[f"{BENCH}/misspec_gather/{name}/{m}_{est}_T{T}.tsv" for m in s["fit_models"]
          for T in s["n_samples"]],
        f"{BENCH}/misspec_report/{name}/report.tsv",
    ]


register_targets("misspec", misspec_targets, misspec_benchmarks)


localrules:
    misspec_gather,
    misspec_report,


rule misspec_fit:
    input:
        "results/{study}/wv/T{T}_c{chunk}.h5",
    output:
        "results/{study}/misspec/{fitmodel}/{estimator}_T{T}_c{chunk}.nc",
    params:
        spec=lambda w: study(w)["fit_models"][w.fitmodel],
        settings=lambda w: config["estimators"][w.estimator],
    log:
        "logs/{study}/misspec_fit/{fitmodel}_{estimator}_T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/misspec_fit/{{study}}/{{fitmodel}}_{{estimator}}_T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=fit_runtime,
        mem_mb=1000,
    script:
        "../scripts/misspec_fit.py"


rule misspec_gather:
    input:
        lambda w: [
            f"results/{w.study}/misspec/{w.fitmodel}/{w.estimator}_T{w.T}_c{c}.nc"
            for c in range(n_chunks(w.study))
        ],
    output:
        "results/{study}/misspec/{fitmodel}/{estimator}_T{T}.nc",
    log:
        "logs/{study}/misspec_gather/{fitmodel}_{estimator}_T{T}.log",
    benchmark:
        f"{BENCH}/misspec_gather/{{study}}/{{fitmodel}}_{{estimator}}_T{{T}}.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/gather.py"


rule misspec_report:
    input:
        unpack(lambda w: {m: misspec_estimates(w.study, m) for m in study(w)["fit_models"]}),
    output:
        report(
            "reports/misspec/{study}_fig6_boxplot.png",
            caption="../report/misspec_fig6.rst",
            category="Misspecification",
            labels={"study": "{study}", "type": "Figure 6: AR1 and RW estimates"},
        ),
        *[f"reports/misspec/{{study}}_fig6_boxplot.{fmt}" for fmt in FIG_FORMATS if fmt != "png"],
        csv=report(
            "reports/misspec/{study}_bias_sd_rmse.csv",
            caption="../report/misspec_table.rst",
            category="Misspecification",
            labels={"study": "{study}", "type": "table: bias, SD, RMSE (CSV)"},
        ),
        md="reports/misspec/{study}_bias_sd_rmse.md",
    params:
        labels=MISSPEC_LABELS,
        formats=FIG_FORMATS,
    log:
        "logs/{study}/misspec_report.log",
    benchmark:
        f"{BENCH}/misspec_report/{{study}}/report.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/misspec_report.py"
