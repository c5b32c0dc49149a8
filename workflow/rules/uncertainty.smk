# Uncertainty and trust of the pipeline's fits (config key `uncertainty`, study kind
# `bootstrap_coverage`). Statistics live in gmwm_studies.uncertainty (built on gmwm.bootstrap) and
# gmwm.identify; scripts only wire.
#
#   uncertainty_estimate   one fitted model per "fit": replicate 0 at the largest T of every study
#                          (simulated with the study's stream and fitted with its first GMWM
#                          estimator), or one Navchip axis (from results/navchip/fits.json)
#   -> uncertainty_boot    parametric bootstrap draws [a, b) of a fit (draw b always uses stream
#                          (seed, stable_int(fit), b): chunking does not change any draw)
#   -> uncertainty_table   Table 1: estimates, 95 % percentile and basic CIs, bootstrap vs sandwich SE
#   -> uncertainty_identify (local + global + emcee posterior checks) -> uncertainty_corner,
#      uncertainty_identifiability (pass/warn table with reasons)
#   coverage_chunk -> coverage_report   the coverage study (kind bootstrap_coverage)
#
# Outputs that need the Navchip data go to reports/navchip/ and are requested by `rule all` only
# (not index/archive inputs), like navchip.smk's, so a missing data file fails only those jobs.

from gmwm_studies.seeds import stable_int

UNC = config["uncertainty"]  # defaults: config.schema.yaml; seed: common.smk
UNC_ID = UNC["identifiability"]
_NAVCHIP_ON = UNC["enabled"] and config["navchip"]["enabled"]


def unc_navchip_fits():
    if not _NAVCHIP_ON:
        return []
    return [f"navchip_{s}_{a}" for s in UNC["navchip_sensors"] for a in UNC["navchip_axes"]]


def unc_study_fits():
    """Studies whose replicate-0 fit is checked (identifiability.studies; null = all)."""
    if not UNC["enabled"]:
        return []
    chosen = UNC_ID["studies"] or list(STUDIES)
    return [n for n in chosen if n in STUDIES]


def unc_table_studies():
    return [n for n in UNC["table_studies"] if n in STUDIES] if UNC["enabled"] else []


def unc_estimator(name):
    """Settings of the study's first GMWM/ARMAV estimator (AVSM is not a GMWM fit)."""
    for e in STUDIES[name]["estimators"]:
        if config["estimators"][e].get("method", "gmwm") in ("gmwm", "armav"):
            return config["estimators"][e]
    return {}


def unc_fit_spec(fit):
    """What uncertainty_estimate fits: a study's replicate 0 or a Navchip axis."""
    if fit.startswith("navchip_"):
        _, sensor, axis = fit.split("_")
        return {"source": "navchip", "sensor": sensor, "axis": axis}
    s = STUDIES[fit]
    return {"source": "study", "study": fit, "model": s["model"], "truth": s["truth"],
            "n_samples": max(s["n_samples"]), "replicate": 0, "seed": s["seed"],
            "levels": s["levels"], "settings": unc_estimator(fit),
            "freq": float(s.get("freq", 1.0)), "simulator": s["simulator"]}


def unc_posterior(fit):
    """emcee check for the Table-1 fits always, for the other studies' fits if configured."""
    return (fit.startswith("navchip_") or fit in unc_table_studies()
            or bool(UNC_ID["posterior_studies"]))


def unc_chunks(fit):
    B, k = int(UNC["B"]), int(UNC["draws_per_job"])
    return [(a, min(a + k, B)) for a in range(0, B, k)]


def unc_boot_files(fits):
    return [f"results/uncertainty/boot/{f}_d{a}-{b}.nc" for f in fits for a, b in unc_chunks(f)]


def unc_report_dir(fit):
    return "reports/navchip" if fit.startswith("navchip_") else "reports/uncertainty"


def unc_corner(fit):
    return f"{unc_report_dir(fit)}/corner_{fit.removeprefix('navchip_')}.png"


def unc_section_targets():
    """Index inputs: everything that does not need the Navchip data."""
    if not UNC["enabled"]:
        return []
    table = unc_table_studies()
    return [
        "reports/uncertainty/identifiability.csv",
        "reports/uncertainty/identifiability.md",
        *(["reports/uncertainty/bootstrap_ci.csv", "reports/uncertainty/bootstrap_ci.md"]
          if table else []),
        *[unc_corner(f) for f in table],
    ]


def uncertainty_navchip_targets():
    """Requested by rule all only (need the Navchip data file)."""
    fits = unc_navchip_fits()
    if not fits:
        return []
    return [
        "reports/navchip/bootstrap_ci.csv",
        "reports/navchip/bootstrap_ci.md",
        "reports/navchip/identifiability.csv",
        "reports/navchip/identifiability.md",
        *[unc_corner(f) for f in fits],
        *NAVCHIP_DRAWS,  # per-draw table and its counts (replicates.smk)
        *NAVCHIP_COUNTS,
    ]


def unc_navchip_benchmarks():
    """Benchmark files of the jobs behind uncertainty_navchip_targets."""
    fits = unc_navchip_fits()
    if not fits:
        return []
    return [
        *[f"{BENCH}/uncertainty_{r}/uncertainty/{f}.tsv" for f in fits for r in ("estimate", "identify")],
        *[f"{BENCH}/uncertainty_boot/uncertainty/{f}_d{a}-{b}.tsv" for f in fits for a, b in unc_chunks(f)],
        *[f"{BENCH}/uncertainty_corner/navchip/{f.removeprefix('navchip_')}.tsv" for f in fits],
        f"{BENCH}/uncertainty_table/navchip/navchip.tsv",
        f"{BENCH}/uncertainty_identifiability/navchip/navchip.tsv",
    ]


def unc_section_benchmarks():
    fits = unc_study_fits()
    table = unc_table_studies()
    return [
        *[f"{BENCH}/uncertainty_estimate/uncertainty/{f}.tsv" for f in fits],
        *[f"{BENCH}/uncertainty_identify/uncertainty/{f}.tsv" for f in fits],
        *[f"{BENCH}/uncertainty_boot/uncertainty/{f}_d{a}-{b}.tsv"
          for f in table for a, b in unc_chunks(f)],
        *[f"{BENCH}/uncertainty_corner/uncertainty/{f}.tsv" for f in table],
        f"{BENCH}/uncertainty_identifiability/uncertainty/uncertainty.tsv",
        *([f"{BENCH}/uncertainty_table/uncertainty/uncertainty.tsv"] if table else []),
    ]


# the index shows this section next to the studies (register_section, common.smk)
if UNC["enabled"]:
    register_section("uncertainty", {
        "model": "fits of every study" + (" (Navchip: see below)" if _NAVCHIP_ON else ""),
        "description": (
            "Parametric bootstrap (Table 1: estimates, 95 % percentile and basic CIs, bootstrap vs "
            f"sandwich SE, B = {UNC['B']}) of replicate 0 of "
            + ", ".join(unc_table_studies() or ["(none)"])
            + "; identifiability (local, global, emcee posterior) of replicate 0 of every study."
            + (" Navchip axes: [bootstrap CIs](navchip/bootstrap_ci.md), "
               "[identifiability](navchip/identifiability.md)." if _NAVCHIP_ON else "")
        ),
        "n_samples": sorted({max(STUDIES[n]["n_samples"]) for n in unc_table_studies()}) or ["-"],
        "replicates": 1,
        "targets": unc_section_targets(),
        "benchmarks": unc_section_benchmarks(),
    })


# --- coverage study (kind bootstrap_coverage) ----------------------------------------------------
def cov_B(name):
    return int(STUDIES[name].get("bootstrap", {}).get("B", 100))


def cov_alpha(name):
    return float(STUDIES[name].get("bootstrap", {}).get("alpha", 0.05))


def coverage_targets(name):
    return [
        f"reports/{name}/coverage.csv",
        f"reports/{name}/coverage.md",
        *[f"reports/{name}/fig_coverage.{fmt}" for fmt in FIG_FORMATS],
    ]


def coverage_benchmarks(name):
    T = max_T(name)
    return [
        *[f"{BENCH}/coverage_chunk/{name}/T{T}_c{c}.tsv" for c in range(n_chunks(name))],
        f"{BENCH}/coverage_report/{name}/report.tsv",
    ]


register_targets("bootstrap_coverage", coverage_targets, coverage_benchmarks)


wildcard_constraints:
    fit="[A-Za-z][A-Za-z0-9_]*",
    a="[0-9]+",
    b="[0-9]+",


localrules:
    uncertainty_table,
    uncertainty_table_navchip,
    uncertainty_corner,
    uncertainty_identifiability,
    uncertainty_identifiability_navchip,
    coverage_report,


rule uncertainty_estimate:
    input:
        lambda w: (
            ["results/navchip/data/navchip_wv.csv", "results/navchip/fits.json"]
            if w.fit.startswith("navchip_")
            else []
        ),
    output:
        "results/uncertainty/fits/{fit}.json",
    params:
        spec=lambda w: unc_fit_spec(w.fit),
    log:
        "logs/uncertainty/estimate/{fit}.log",
    benchmark:
        f"{BENCH}/uncertainty_estimate/uncertainty/{{fit}}.tsv"
    resources:
        runtime=15,
        # the study fits simulate one signal: a few float64 copies of it
        mem_mb=lambda w: 1000 if w.fit.startswith("navchip_") else max(
            1000, int(64 * unc_fit_spec(w.fit)["n_samples"] / 1e6) + 500
        ),
    script:
        "../scripts/uncertainty_estimate.py"


rule uncertainty_boot:
    input:
        "results/uncertainty/fits/{fit}.json",
    output:
        "results/uncertainty/boot/{fit}_d{a}-{b}.nc",
    params:
        draws=lambda w: [int(w.a), int(w.b)],
        seed=lambda w: [int(UNC["seed"]), stable_int(w.fit)],
    log:
        "logs/uncertainty/boot/{fit}_d{a}-{b}.log",
    benchmark:
        f"{BENCH}/uncertainty_boot/uncertainty/{{fit}}_d{{a}}-{{b}}.tsv"
    threads: 1
    resources:
        # measured: ~0.7 s per draw at the Navchip length, ~3 s at T = 1e7 (x4 margin)
        runtime=lambda w: max(10, int((int(w.b) - int(w.a)) * 12 / 60) + 5),
        mem_mb=1500,
    script:
        "../scripts/uncertainty_boot.py"


def _unc_table_outputs(d, caption, what):
    csv = report(
        f"{d}/bootstrap_ci.csv",
        caption=f"../report/{caption}",
        category="Uncertainty",
        labels={"table": what},
    )
    return csv


rule uncertainty_table:
    input:
        fits=lambda w: [f"results/uncertainty/fits/{f}.json" for f in unc_table_studies()],
        boot=lambda w: unc_boot_files(unc_table_studies()),
    output:
        csv=_unc_table_outputs("reports/uncertainty", "uncertainty_table.rst", "Table 1 (simulated)"),
        md="reports/uncertainty/bootstrap_ci.md",
    params:
        fits=unc_table_studies(),
        alpha=UNC["alpha"],
    log:
        "logs/uncertainty/table.log",
    benchmark:
        f"{BENCH}/uncertainty_table/uncertainty/uncertainty.tsv"
    script:
        "../scripts/uncertainty_table.py"


rule uncertainty_table_navchip:
    input:
        fits=lambda w: [f"results/uncertainty/fits/{f}.json" for f in unc_navchip_fits()],
        boot=lambda w: unc_boot_files(unc_navchip_fits()),
    output:
        csv=_unc_table_outputs("reports/navchip", "uncertainty_table.rst", "Table 1 (Navchip)"),
        md="reports/navchip/bootstrap_ci.md",
    params:
        fits=unc_navchip_fits(),
        alpha=UNC["alpha"],
    log:
        "logs/uncertainty/table_navchip.log",
    benchmark:
        f"{BENCH}/uncertainty_table/navchip/navchip.tsv"
    script:
        "../scripts/uncertainty_table.py"


rule uncertainty_identify:
    input:
        "results/uncertainty/fits/{fit}.json",
    output:
        json="results/uncertainty/identify/{fit}.json",
        samples="results/uncertainty/identify/{fit}_posterior.npz",
    params:
        posterior=lambda w: unc_posterior(w.fit),
        n_starts=UNC_ID["n_starts"],
        max_steps=UNC_ID["max_steps"],
        seed=lambda w: stable_int(w.fit),
    log:
        "logs/uncertainty/identify/{fit}.log",
    benchmark:
        f"{BENCH}/uncertainty_identify/uncertainty/{{fit}}.tsv"
    threads: 1
    resources:
        runtime=30,
        mem_mb=2000,
    script:
        "../scripts/uncertainty_identify.py"


def _corner_fit(w):
    return w.name if w.dir == "uncertainty" else f"navchip_{w.name}"


rule uncertainty_corner:
    input:
        json=lambda w: f"results/uncertainty/identify/{_corner_fit(w)}.json",
        samples=lambda w: f"results/uncertainty/identify/{_corner_fit(w)}_posterior.npz",
        fit=lambda w: f"results/uncertainty/fits/{_corner_fit(w)}.json",
    output:
        "reports/{dir}/corner_{name}.png",
    wildcard_constraints:
        dir="uncertainty|navchip",
    log:
        "logs/uncertainty/corner/{dir}_{name}.log",
    benchmark:
        f"{BENCH}/uncertainty_corner/{{dir}}/{{name}}.tsv"
    script:
        "../scripts/uncertainty_corner.py"


rule uncertainty_identifiability:
    input:
        lambda w: [f"results/uncertainty/identify/{f}.json" for f in unc_study_fits()],
    output:
        csv=report(
            "reports/uncertainty/identifiability.csv",
            caption="../report/uncertainty_identifiability.rst",
            category="Uncertainty",
            labels={"table": "identifiability (studies)"},
        ),
        md="reports/uncertainty/identifiability.md",
    params:
        fits=unc_study_fits(),
        labels={f: f"{f}: replicate 0, T = {unc_fit_spec(f)['n_samples']}" for f in unc_study_fits()},
    log:
        "logs/uncertainty/identifiability.log",
    benchmark:
        f"{BENCH}/uncertainty_identifiability/uncertainty/uncertainty.tsv"
    script:
        "../scripts/uncertainty_identifiability.py"


rule uncertainty_identifiability_navchip:
    input:
        lambda w: [f"results/uncertainty/identify/{f}.json" for f in unc_navchip_fits()],
    output:
        csv=report(
            "reports/navchip/identifiability.csv",
            caption="../report/uncertainty_identifiability.rst",
            category="Uncertainty",
            labels={"table": "identifiability (Navchip)"},
        ),
        md="reports/navchip/identifiability.md",
    params:
        fits=unc_navchip_fits(),
        labels={f: f"Navchip {f.split('_')[1]} {f.split('_')[2]}" for f in unc_navchip_fits()},
    log:
        "logs/uncertainty/identifiability_navchip.log",
    benchmark:
        f"{BENCH}/uncertainty_identifiability/navchip/navchip.tsv"
    script:
        "../scripts/uncertainty_identifiability.py"


rule coverage_chunk:
    output:
        "results/{study}/coverage/T{T}_c{chunk}.nc",
    params:
        model=lambda w: study(w)["model"],
        truth=lambda w: study(w)["truth"],
        n_samples=lambda w: int(w.T),
        replicates=lambda w: chunk_reps(w.study, w.chunk),
        seed=lambda w: study(w)["seed"],
        levels=lambda w: study(w)["levels"],
        settings=lambda w: unc_estimator(w.study),
        simulator=lambda w: study(w)["simulator"],
        B=lambda w: cov_B(w.study),
        alpha=lambda w: cov_alpha(w.study),
    log:
        "logs/{study}/coverage_chunk/T{T}_c{chunk}.log",
    benchmark:
        f"{BENCH}/coverage_chunk/{{study}}/T{{T}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        # measured: ~0.12 s per refit at T = 2^18 (x4 margin)
        runtime=lambda w: max(10, int(len(chunk_reps(w.study, w.chunk)) * cov_B(w.study)
                                      * 0.5e-6 * int(w.T) / 60) + 5),
        mem_mb=1000,
    script:
        "../scripts/uncertainty_coverage_chunk.py"


rule coverage_report:
    input:
        lambda w: [
            f"results/{w.study}/coverage/T{max_T(w.study)}_c{c}.nc" for c in range(n_chunks(w.study))
        ],
    output:
        csv=report(
            "reports/{study}/coverage.csv",
            caption="../report/uncertainty_coverage.rst",
            category="{study}",
            labels={"study": "{study}", "type": "table: coverage and SE ratios"},
        ),
        md="reports/{study}/coverage.md",
        png=report(
            "reports/{study}/fig_coverage.png",
            caption="../report/uncertainty_coverage_fig.rst",
            category="{study}",
            labels={"study": "{study}", "type": "figure: coverage"},
        ),
        other=[f"reports/{{study}}/fig_coverage.{fmt}" for fmt in FIG_FORMATS if fmt != "png"],
    params:
        formats=FIG_FORMATS,
        # named in the captions
        replicates=lambda w: int(study(w)["replicates"]),
        B=lambda w: cov_B(w.study),
    log:
        "logs/{study}/coverage_report.log",
    benchmark:
        f"{BENCH}/coverage_report/{{study}}/report.tsv"
    script:
        "../scripts/uncertainty_coverage_report.py"
