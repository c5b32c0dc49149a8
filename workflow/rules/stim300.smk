# STIM-300 Monte Carlo of [GMWFM] (kind: stim300): GMWM, ARMAV and AVSM fitted to the SAME
# simulated wavelet variances. One study per sensor (its model, Table I truth, sensor, freq):
#   simulate_wv (montecarlo.smk: per chunk, simulate + one WV pass, HDF5 cache, raw signals never
#   stored) -> stim300_fit (per chunk: all of the study's estimators on the same WVs, one NetCDF
#   group per estimator) -> stim300_report (table, Figures 1 and 2).
# The four estimators together cost tens of ms of CPU per replicate (with the diagonal SEs the
# study stores, see gmwm_studies.stim300.fit_wv; per-job times in the run archive's
# timings.csv), seconds per 500-replicate chunk against ~1-2 s of job start, hence one fit job
# per chunk rather than per estimator; the estimator settings are its params, so changing them
# refits
# (cheaply) and reuses the WV cache.

STIM300_DEFAULT_FREQ = 250.0

for _name in studies_of_kind("stim300"):
    if "sensor" not in STUDIES[_name]:
        raise WorkflowError(f"config: study {_name!r} (kind stim300) needs 'sensor' "
                            "(gyroscope or accelerometer)")


def stim300_freq(name):
    return float(STUDIES[name].get("freq", STIM300_DEFAULT_FREQ))


def stim300_fit_files(name):
    s = STUDIES[name]
    chunks = range(n_chunks(name))
    return [f"results/{name}/allan/T{T}_c{c}.nc" for T in s["n_samples"] for c in chunks]


def stim300_targets(name):
    base = f"reports/stim300/{name}"
    return [
        f"{base}_bias_sd_rmse.csv",
        f"{base}_bias_sd_rmse.md",
        *[f"{base}_fig1_boxplot.{fmt}" for fmt in FIG_FORMATS],
        *[f"{base}_fig2_rmse.{fmt}" for fmt in FIG_FORMATS],
    ]


def stim300_benchmarks(name):
    s = STUDIES[name]
    chunks = range(n_chunks(name))
    return [
        *[f"{BENCH}/simulate_wv/{name}/T{T}_c{c}.tsv" for T in s["n_samples"] for c in chunks],
        *[f"{BENCH}/stim300_fit/{name}/T{T}_c{c}.tsv" for T in s["n_samples"] for c in chunks],
        f"{BENCH}/stim300_report/{name}/report.tsv",
    ]


register_targets("stim300", stim300_targets, stim300_benchmarks)


localrules:
    stim300_report,


rule stim300_fit:
    input:
        "results/{study}/wv/T{T}_c{chunk}.h5",
    output:
        "results/{study}/allan/T{T}_c{chunk}.nc",
    params:
        estimators=lambda w: {e: config["estimators"][e] for e in study(w)["estimators"]},
        freq=lambda w: stim300_freq(w.study),
    log:
        "logs/{study}/stim300_fit/T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/stim300_fit/{{study}}/T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/stim300_fit.py"


rule stim300_report:
    input:
        lambda w: stim300_fit_files(w.study),
    output:
        report(
            "reports/stim300/{study}_fig1_boxplot.png",
            caption="../report/stim300_fig1.rst",
            category="STIM-300",
            labels={"study": "{study}", "type": "Figure 1: estimates (Table I units)"},
        ),
        report(
            "reports/stim300/{study}_fig2_rmse.png",
            caption="../report/stim300_fig2.rst",
            category="STIM-300",
            labels={"study": "{study}", "type": "Figure 2: RMSE"},
        ),
        *[f"reports/stim300/{{study}}_fig{k}.{fmt}" for k in ("1_boxplot", "2_rmse")
          for fmt in FIG_FORMATS if fmt != "png"],
        csv=report(
            "reports/stim300/{study}_bias_sd_rmse.csv",
            caption="../report/stim300_table.rst",
            category="STIM-300",
            labels={"study": "{study}", "type": "table: bias, SD, RMSE (CSV)"},
        ),
        md="reports/stim300/{study}_bias_sd_rmse.md",
    params:
        sensor=lambda w: study(w)["sensor"],
        freq=lambda w: stim300_freq(w.study),
        model=lambda w: study(w)["model"],
        replicates=lambda w: study(w)["replicates"],
        estimators=lambda w: {e: config["estimators"][e] for e in study(w)["estimators"]},
        formats=FIG_FORMATS,
        cores=2,
    log:
        "logs/{study}/stim300_report.log",
    benchmark:
        f"{BENCH}/stim300_report/{{study}}/report.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/stim300_report.py"
