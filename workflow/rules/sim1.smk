# Simulation 1 of the vibration-noise paper (kind: mle_comparison): GMWM against the Kalman-filter
# MLE on WN + RW + AR1 + SIN signals. Per chunk of replicates: simulate, fit GMWM (always) and each
# MLE variant (own start, statsmodels' start, GMWM start; only replicates below the study's MLE cap
# at that T, and below a variant's own cap, mle.variant_replicates, where it has one) -> gather per T -> tables -> figures. Beside it, on the first `statsmodels.replicates`
# of the same signals (slow: ~1e-3 T s per fit), statsmodels' own estimator as the general-purpose
# baseline (sim1_baseline_chunk -> sim1_baseline_gather), merged into the tables.
# The statistics live in gmwm_studies.sim1; raw signals are never stored.


def sim1_mle_caps(name):
    """{T: number of replicates with an MLE fit}; `mle.replicates` is one int or one per T."""
    s = STUDIES[name]
    cap = s.get("mle", {}).get("replicates", s["replicates"])
    caps = cap if isinstance(cap, list) else [cap] * len(s["n_samples"])
    if len(caps) != len(s["n_samples"]):
        raise WorkflowError(
            f"config: study {name!r}: mle.replicates has {len(caps)} entries for "
            f"{len(s['n_samples'])} sample sizes"
        )
    return {int(T): min(int(c), s["replicates"]) for T, c in zip(s["n_samples"], caps)}


def sim1_mle_settings(name):
    return {k: v for k, v in STUDIES[name].get("mle", {}).items()
            if k not in ("replicates", "variant_replicates")}


def sim1_variant_caps(name):
    """{variant: {T: replicates with its fit}} for the variants with their own cap (config
    `mle.variant_replicates`; gmwm_studies.sim1.variant_replicate_caps checks it); every other
    variant runs on all the MLE's replicates (`sim1_mle_caps`)."""
    from gmwm.errors import InputError
    from gmwm_studies.sim1 import DEFAULT_MLE, variant_replicate_caps

    mle = STUDIES[name].get("mle", {})
    try:
        return variant_replicate_caps(mle.get("variant_replicates"),
                                      list(mle.get("variants") or DEFAULT_MLE["variants"]),
                                      sim1_mle_caps(name))
    except InputError as exc:
        raise WorkflowError(f"config: study {name!r}: {exc}") from None


def sim1_baseline_caps(name):
    """{T: replicates with the statsmodels baseline}; at most the MLE cap at that T, since its
    wrong optima are judged against the Kalman-filter variants' log-likelihoods."""
    s = STUDIES[name]
    cap = s.get("statsmodels", {}).get("replicates", 0)
    caps = cap if isinstance(cap, list) else [cap] * len(s["n_samples"])
    if len(caps) != len(s["n_samples"]):
        raise WorkflowError(
            f"config: study {name!r}: statsmodels.replicates has {len(caps)} entries for "
            f"{len(s['n_samples'])} sample sizes"
        )
    mle = sim1_mle_caps(name)
    out = {int(T): int(c) for T, c in zip(s["n_samples"], caps)}
    for T, c in out.items():
        if c > mle[T]:
            raise WorkflowError(
                f"config: study {name!r}: statsmodels.replicates ({c}) exceeds the MLE cap "
                f"({mle[T]}) at T = {T}"
            )
    return out


def sim1_baseline_settings(name):
    return {k: v for k, v in STUDIES[name].get("statsmodels", {}).items()
            if k not in ("replicates", "chunk_size")}


def sim1_baseline_chunks(name, T):
    n = sim1_baseline_caps(name)[int(T)]
    size = int(STUDIES[name].get("statsmodels", {}).get("chunk_size", 5))
    return [(a, min(n, a + size)) for a in range(0, n, size)]


def sim1_baselines(name):
    """Gathered baseline results, one per T where it runs ({T: path})."""
    return {T: f"results/{name}/statsmodels/all_T{T}.nc"
            for T, n in sim1_baseline_caps(name).items() if n > 0}


def sim1_gmwm_settings(name):
    return config["estimators"][STUDIES[name]["estimators"][0]]


def sim1_estimates(name):
    return [f"results/{name}/gmwm_mle/all_T{T}.nc" for T in STUDIES[name]["n_samples"]]


SIM1_FIGURES = ("fig1_rmse", "fig2_runtime", "fig9_boxplot")


def sim1_targets(name):
    sim1_variant_caps(name)  # a wrong cap stops the run before any job starts
    # the first CSV/MD are what the index shows: the per-T speed-up and RMSE ratios
    return [
        f"reports/{name}/comparison.csv",
        f"reports/{name}/comparison.md",
        f"reports/{name}/rmse_bias_time.csv",
        f"reports/{name}/rmse_bias_time.md",
        f"reports/{name}/counts.rst",
        *[f"reports/{name}/{fig}.{fmt}" for fig in SIM1_FIGURES for fmt in FIG_FORMATS],
    ]


def sim1_benchmarks(name):
    s = STUDIES[name]
    return [
        *[
            f"{BENCH}/sim1_chunk/{name}/T{T}_c{c}.tsv"
            for T in s["n_samples"]
            for c in range(n_chunks(name))
        ],
        *[f"{BENCH}/sim1_gather/{name}/T{T}.tsv" for T in s["n_samples"]],
        *[
            f"{BENCH}/sim1_baseline_chunk/{name}/T{T}_r{a}_{b}.tsv"
            for T in sim1_baselines(name)
            for a, b in sim1_baseline_chunks(name, T)
        ],
        f"{BENCH}/sim1_table/{name}/table.tsv",
        f"{BENCH}/sim1_figures/{name}/figures.tsv",
    ]


register_targets("mle_comparison", sim1_targets, sim1_benchmarks)


def sim1_chunk_n_mle(w):
    return sim1_mle_caps(w.study)[int(w.T)]


def sim1_chunk_runtime(w):
    # measured (benchmarks/bench_mle.py, Kalman backend): an MLE fit costs at most ~1.5 s at
    # T = 1.6e5 (statsmodels' start, idle core), the GMWM ~0.1 s; about x4 margin for load
    reps = chunk_reps(w.study, w.chunk)
    n_mle = sum(r < sim1_chunk_n_mle(w) for r in reps)
    n_var = len(STUDIES[w.study].get("mle", {}).get("variants", {})) or 2
    capped = sim1_variant_caps(w.study)
    fits = n_mle * (n_var - len(capped)) + sum(
        sum(r < min(c[int(w.T)], sim1_chunk_n_mle(w)) for r in reps) for c in capped.values())
    return max(10, int((fits * 4e-5 * int(w.T) + len(reps) * 1.0) / 60) + 5)


rule sim1_chunk:
    output:
        "results/{study}/gmwm_mle/T{T}_c{chunk}.nc",
    params:
        model=lambda w: study(w)["model"],
        truth=lambda w: study(w)["truth"],
        n_samples=lambda w: int(w.T),
        replicates=lambda w: chunk_reps(w.study, w.chunk),
        seed=lambda w: study(w)["seed"],
        gmwm=lambda w: sim1_gmwm_settings(w.study),
        mle=lambda w: sim1_mle_settings(w.study),
        # only the cap's effect on this chunk, so raising the cap at one T reruns only the chunks
        # it reaches
        mle_replicates=lambda w: [r for r in chunk_reps(w.study, w.chunk) if r < sim1_chunk_n_mle(w)],
        # the same per capped variant
        variant_replicates=lambda w: {
            v: [r for r in chunk_reps(w.study, w.chunk) if r < caps[int(w.T)]]
            for v, caps in sim1_variant_caps(w.study).items()
        },
    log:
        "logs/{study}/sim1_chunk/T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/sim1_chunk/{{study}}/T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=sim1_chunk_runtime,
        mem_mb=1000,
    script:
        "../scripts/sim1_chunk.py"


def sim1_baseline_runtime(w):
    # measured (statsmodels 0.15, one core): 2.4 s CPU at T = 1e4 (13 L-BFGS iterations, wrong
    # optimum), 137 s at T = 1.6e5 (50 iterations, the cap); ~1e-3 T s per fit, x3 margin
    return max(10, int((int(w.b) - int(w.a)) * 3e-3 * int(w.T) / 60) + 5)


rule sim1_baseline_chunk:
    output:
        "results/{study}/statsmodels/T{T}_r{a}_{b}.nc",
    params:
        model=lambda w: study(w)["model"],
        truth=lambda w: study(w)["truth"],
        n_samples=lambda w: int(w.T),
        replicates=lambda w: list(range(int(w.a), int(w.b))),
        seed=lambda w: study(w)["seed"],
        settings=lambda w: sim1_baseline_settings(w.study),
    log:
        "logs/{study}/sim1_baseline_chunk/T{T}_r{a}_{b}.log",
    benchmark:
        f"{BENCH}/sim1_baseline_chunk/{{study}}/T{{T}}_r{{a}}_{{b}}.tsv"
    wildcard_constraints:
        a="[0-9]+",
        b="[0-9]+",
    threads: 1
    resources:
        runtime=sim1_baseline_runtime,
        mem_mb=1500,
    script:
        "../scripts/sim1_baseline_chunk.py"


rule sim1_baseline_gather:
    input:
        lambda w: [
            f"results/{w.study}/statsmodels/T{w.T}_r{a}_{b}.nc"
            for a, b in sim1_baseline_chunks(w.study, w.T)
        ],
    output:
        "results/{study}/statsmodels/all_T{T}.nc",
    log:
        "logs/{study}/sim1_baseline_gather/T{T}.log",
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/gather.py"


rule sim1_gather:
    input:
        lambda w: [
            f"results/{w.study}/gmwm_mle/T{w.T}_c{c}.nc" for c in range(n_chunks(w.study))
        ],
    output:
        "results/{study}/gmwm_mle/all_T{T}.nc",
    log:
        "logs/{study}/sim1_gather/T{T}.log",
    benchmark:
        f"{BENCH}/sim1_gather/{{study}}/T{{T}}.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/gather.py"


rule sim1_table:
    input:
        estimates=lambda w: sim1_estimates(w.study),
        baselines=lambda w: list(sim1_baselines(w.study).values()),
    output:
        comparison=report(
            "reports/{study}/comparison.csv",
            caption="../report/sim1_comparison.rst",
            category="{study}",
            labels={"study": "{study}", "type": "table: speed-up and RMSE ratios"},
        ),
        comparison_md="reports/{study}/comparison.md",
        table=report(
            "reports/{study}/rmse_bias_time.csv",
            caption="../report/sim1_table.rst",
            category="{study}",
            labels={"study": "{study}", "type": "table: RMSE, bias, time"},
        ),
        table_md="reports/{study}/rmse_bias_time.md",
        counts="reports/{study}/counts.rst",
    params:
        mle_caps=lambda w: sim1_mle_caps(w.study),
        mle=lambda w: sim1_mle_settings(w.study),
        gmwm=lambda w: sim1_gmwm_settings(w.study),
        baseline=lambda w: sim1_baseline_settings(w.study),
        baseline_T=lambda w: list(sim1_baselines(w.study)),
    log:
        "logs/{study}/sim1_table.log",
    benchmark:
        f"{BENCH}/sim1_table/{{study}}/table.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/sim1_table.py"


def _sim1_figure_outputs(fig, caption, label):
    # (a line starting with `report(` would be read as the `report:` keyword)
    png = report(
        f"reports/{{study}}/{fig}.png",
        caption=f"../report/{caption}",
        category="{study}",
        labels={"study": "{study}", "type": label},
    )
    return [png, *[f"reports/{{study}}/{fig}.{fmt}" for fmt in FIG_FORMATS if fmt != "png"]]


rule sim1_figures:
    input:
        estimates=lambda w: sim1_estimates(w.study),
        table="reports/{study}/rmse_bias_time.csv",
        comparison="reports/{study}/comparison.csv",
    output:
        *_sim1_figure_outputs("fig1_rmse", "sim1_fig1.rst", "figure 1: RMSE vs T"),
        *_sim1_figure_outputs("fig2_runtime", "sim1_fig2.rst", "figure 2: run time vs T"),
        *_sim1_figure_outputs("fig9_boxplot", "sim1_fig9.rst", "figure 9: standardized errors"),
    params:
        formats=FIG_FORMATS,
        mle_caps=lambda w: sim1_mle_caps(w.study),
        variant_caps=lambda w: sim1_variant_caps(w.study),
    log:
        "logs/{study}/sim1_figures.log",
    benchmark:
        f"{BENCH}/sim1_figures/{{study}}/figures.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/sim1_figures.py"


localrules:
    sim1_gather,
    sim1_baseline_gather,
    sim1_table,
    sim1_figures,
