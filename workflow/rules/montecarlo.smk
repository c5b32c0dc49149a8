# Monte Carlo studies on the wavelet variance (kind: wv_montecarlo), e.g. Simulations 2 and 3:
# simulate + WV (cached, per chunk) -> fit (per chunk, per estimator) -> gather -> tables, figures.
# params carry exactly what should trigger a rerun: the study design on simulate_wv, the
# estimator settings on fit. Changing an estimator setting therefore reuses the WV cache.


def mc_wv_chunks(wildcards, T=None):
    T = T if T is not None else wildcards.T
    return [
        f"results/{wildcards.study}/wv/T{T}_c{c}.h5" for c in range(n_chunks(wildcards.study))
    ]


def mc_estimates(name):
    s = STUDIES[name]
    return [
        f"results/{name}/estimates/{est}_T{T}.nc" for est in s["estimators"] for T in s["n_samples"]
    ]


def mc_targets(name):
    return [
        f"reports/{name}/bias_sd_rmse.csv",
        f"reports/{name}/bias_sd_rmse.md",
        *[f"reports/{name}/fig_wv.{fmt}" for fmt in FIG_FORMATS],
        *[f"reports/{name}/fig_boxplot.{fmt}" for fmt in FIG_FORMATS],
    ]


def mc_benchmarks(name):
    s = STUDIES[name]
    chunks = range(n_chunks(name))
    return [
        *[f"{BENCH}/simulate_wv/{name}/T{T}_c{c}.tsv" for T in s["n_samples"] for c in chunks],
        *[
            f"{BENCH}/fit/{name}/{e}_T{T}_c{c}.tsv"
            for e in s["estimators"]
            for T in s["n_samples"]
            for c in chunks
        ],
        *[f"{BENCH}/gather/{name}/{e}_T{T}.tsv" for e in s["estimators"] for T in s["n_samples"]],
        f"{BENCH}/table/{name}/table.tsv",
        f"{BENCH}/figure_wv/{name}/figure_wv.tsv",
        f"{BENCH}/figure_boxplot/{name}/figure_boxplot.tsv",
    ]


register_targets("wv_montecarlo", mc_targets, mc_benchmarks)


rule simulate_wv:
    output:
        "results/{study}/wv/T{T}_c{chunk}.h5",
    params:
        model=lambda w: study(w)["model"],
        truth=lambda w: study(w)["truth"],
        n_samples=lambda w: int(w.T),
        replicates=lambda w: chunk_reps(w.study, w.chunk),
        seed=lambda w: study(w)["seed"],
        levels=lambda w: study(w)["levels"],
        simulator=lambda w: study(w)["simulator"],
    log:
        "logs/{study}/simulate_wv/T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/simulate_wv/{{study}}/T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=simulate_runtime,
        mem_mb=simulate_mem,
    script:
        "../scripts/simulate_wv.py"


rule fit:
    input:
        "results/{study}/wv/T{T}_c{chunk}.h5",
    output:
        "results/{study}/fit/{estimator}/T{T}_c{chunk}.nc",
    params:
        settings=lambda w: config["estimators"][w.estimator],
    log:
        "logs/{study}/fit/{estimator}_T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/fit/{{study}}/{{estimator}}_T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=fit_runtime,
        mem_mb=1000,
    script:
        "../scripts/fit.py"


rule gather:
    input:
        lambda w: [
            f"results/{w.study}/fit/{w.estimator}/T{w.T}_c{c}.nc" for c in range(n_chunks(w.study))
        ],
    output:
        "results/{study}/estimates/{estimator}_T{T}.nc",
    log:
        "logs/{study}/gather/{estimator}_T{T}.log",
    benchmark:
        f"{BENCH}/gather/{{study}}/{{estimator}}_T{{T}}.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/gather.py"


rule table:
    input:
        lambda w: mc_estimates(w.study),
    output:
        csv=report(
            "reports/{study}/bias_sd_rmse.csv",
            caption="../report/table.rst",
            category="{study}",
            labels={"study": "{study}", "type": "table (CSV)"},
        ),
        md="reports/{study}/bias_sd_rmse.md",
    log:
        "logs/{study}/table.log",
    benchmark:
        f"{BENCH}/table/{{study}}/table.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/table.py"


rule figure_wv:
    input:
        lambda w: mc_wv_chunks(w, T=max_T(w.study)),
    output:
        report(
            "reports/{study}/fig_wv.png",
            caption="../report/fig_wv.rst",
            category="{study}",
            labels={"study": "{study}", "type": "figure: wavelet variance"},
        ),
        *[f"reports/{{study}}/fig_wv.{fmt}" for fmt in FIG_FORMATS if fmt != "png"],
    params:
        formats=FIG_FORMATS,
    log:
        "logs/{study}/figure_wv.log",
    benchmark:
        f"{BENCH}/figure_wv/{{study}}/figure_wv.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/figure_wv.py"


rule figure_boxplot:
    input:
        lambda w: [
            f"results/{w.study}/estimates/{e}_T{max_T(w.study)}.nc" for e in study(w)["estimators"]
        ],
    output:
        report(
            "reports/{study}/fig_boxplot.png",
            caption="../report/fig_boxplot.rst",
            category="{study}",
            labels={"study": "{study}", "type": "figure: standardized estimates"},
        ),
        *[f"reports/{{study}}/fig_boxplot.{fmt}" for fmt in FIG_FORMATS if fmt != "png"],
    params:
        formats=FIG_FORMATS,
    log:
        "logs/{study}/figure_boxplot.log",
    benchmark:
        f"{BENCH}/figure_boxplot/{{study}}/figure_boxplot.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/figure_boxplot.py"
