# Navigation emulation of the vibration-noise paper (config key `navigation`; [Vibration] sec. 5,
# Figs. 7-8; library code gmwm_studies.navigation and gmwm_studies.ekf):
#   misspec study's gathered Model 1 / Model 2 fits (steps (i)-(ii) of the paper's protocol:
#   iteration b uses replicate b, simulated from Table 5 at T = 2,879,999 and fitted by GMWM)
#   -> nav_chunk (per chunk of iterations: simulate the AR1+RW gyro errors and sensor noise, run
#      both EKFs on the same measurements, vectorised over the chunk)
#   -> nav_report (Fig. 7 trajectory, Fig. 8 ratio with 95 % CI, table of its maximum, and the
#      per-iteration table reports/navigation/replicates/iterations.csv that rule counts counts).
# Iteration b draws from SeedSequence(seed, spawn_key=(crc32(name), b)): chunking changes nothing.
# Variants (navigation.variants.<v>: the main study with gyro_axes / iterations / chunk_size
# overridden; gmwm_studies.navigation.variant_config) rerun the emulation on the same fits, seeds
# and trajectory: nav_variant_chunk (same script as nav_chunk) -> nav_variant_report
# (reports/navigation/<v>/: ratio_max.{csv,md}, ratio_series.csv, fig8_ratio). Their outputs are
# targets of the navigation section, so a disabled navigation plans none of them.
# Registered in the index and the archive with register_section (common.smk).

import gmwm_studies.montecarlo as _gs_nav
from gmwm.errors import InputError
from gmwm_studies.navigation import variant_config as _nav_variant_config

NAV = config["navigation"]  # defaults: config.schema.yaml; seed: common.smk
# the main study's params: without `variants`, so editing a variant does not rerun the main study
NAV_MAIN = {k: v for k, v in NAV.items() if k != "variants"}
NAV_VARIANTS = {}
_NAV_ON = NAV["enabled"] and NAV["estimates_from"] in STUDIES
if NAV["enabled"] and not _NAV_ON:
    raise WorkflowError(f"config: navigation.estimates_from {NAV['estimates_from']!r} is not an "
                        "enabled study (kind misspec); enable it or set navigation.enabled: false")
if _NAV_ON:
    _src = STUDIES[NAV["estimates_from"]]
    if _src["kind"] != "misspec" or any(m not in _src["fit_models"] for m in NAV["models"]):
        raise WorkflowError(f"config: navigation.models {NAV['models']} must be fit_models of the "
                            f"misspec study {NAV['estimates_from']!r}")
    if NAV["iterations"] > _src["replicates"]:
        raise WorkflowError(f"config: navigation.iterations ({NAV['iterations']}) exceeds the "
                            f"replicates of {NAV['estimates_from']!r} ({_src['replicates']})")
    for _v in NAV.get("variants") or {}:
        try:
            NAV_VARIANTS[_v] = _nav_variant_config(NAV, _v)
        except InputError as exc:
            raise WorkflowError(f"config: {exc}") from None
        if NAV_VARIANTS[_v]["iterations"] > _src["replicates"]:
            raise WorkflowError(f"config: navigation.variants.{_v}.iterations "
                                f"({NAV_VARIANTS[_v]['iterations']}) exceeds the replicates of "
                                f"{NAV['estimates_from']!r} ({_src['replicates']})")


def nav_n_chunks(cfg=NAV):
    return len(_gs_nav.chunk_bounds(cfg["iterations"], cfg["chunk_size"]))


def nav_variant_targets(v):
    return [f"reports/navigation/{v}/{name}" for name in
            ("ratio_max.csv", "ratio_max.md", "ratio_series.csv",
             *[f"fig8_ratio.{fmt}" for fmt in FIG_FORMATS])]


def nav_targets():
    if not _NAV_ON:
        return []
    return [
        "reports/navigation/ratio_max.csv",
        "reports/navigation/ratio_max.md",
        "reports/navigation/ratio_series.csv",
        "reports/navigation/replicates/iterations.csv",
        *[f"reports/navigation/fig7_trajectory.{fmt}" for fmt in FIG_FORMATS],
        *[f"reports/navigation/fig8_ratio.{fmt}" for fmt in FIG_FORMATS],
        *[t for v in NAV_VARIANTS for t in nav_variant_targets(v)],
    ]


def nav_benchmarks():
    if not _NAV_ON:
        return []
    return [*[f"{BENCH}/nav_chunk/navigation/c{c}.tsv" for c in range(nav_n_chunks())],
            f"{BENCH}/nav_report/navigation/report.tsv",
            *[f"{BENCH}/nav_variant_chunk/navigation/{v}_c{c}.tsv"
              for v, cfg in NAV_VARIANTS.items() for c in range(nav_n_chunks(cfg))],
            *[f"{BENCH}/nav_variant_report/navigation/{v}.tsv" for v in NAV_VARIANTS]]


if _NAV_ON:
    register_section("navigation", {
        "model": "EKF tuned with Model 1 vs Model 2 AR1+RW estimates",
        "description": ("Vibration-noise paper, navigation emulation (Figs. 7-8): 235 s flight, "
                        "IMU 100 Hz, GNSS 1 Hz with an outage "
                        f"{NAV['outage'][0]:g}-{NAV['outage'][1]:g} s, loosely coupled EKF; "
                        "ratio of mean position errors Model 1 / Model 2."),
        "n_samples": [int(round(NAV["duration"] * NAV["imu_rate"]))],
        "replicates": NAV["iterations"],
        "targets": nav_targets(),
        "benchmarks": nav_benchmarks(),
    })


def nav_inputs(wildcards):
    src = NAV["estimates_from"]
    return {m: misspec_estimates(src, m) for m in NAV["models"]}


localrules:
    nav_report,
    nav_variant_report,


wildcard_constraints:
    nav_variant="[a-z][a-z0-9_]*",


rule nav_chunk:
    input:
        unpack(nav_inputs),
    output:
        "results/navigation/chunks/c{chunk}.nc",
    params:
        nav=NAV_MAIN,
        iterations=lambda w: _gs_nav.chunk_replicates(int(w.chunk), NAV["iterations"],
                                                       NAV["chunk_size"]),
        truth=lambda w: STUDIES[NAV["estimates_from"]]["truth"],
    log:
        "logs/navigation/nav_chunk/c{chunk}.log",
    benchmark:
        f"{BENCH}/nav_chunk/navigation/c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=lambda w: max(10, int(NAV["chunk_size"] * NAV["duration"] / 235 * 2 / 60) + 5),
        mem_mb=lambda w: max(1000, int(NAV["chunk_size"] * NAV["duration"] * NAV["imu_rate"]
                                       * 2 * 3 * 8 * 3 / 1e6) + 500),
    script:
        "../scripts/nav_chunk.py"


rule nav_report:
    input:
        lambda w: [f"results/navigation/chunks/c{c}.nc" for c in range(nav_n_chunks())],
    output:
        report(
            "reports/navigation/fig7_trajectory.png",
            caption="../report/nav_fig7.rst",
            category="Navigation emulation",
            labels={"type": "Figure 7: trajectory and altitude"},
        ),
        report(
            "reports/navigation/fig8_ratio.png",
            caption="../report/nav_fig8.rst",
            category="Navigation emulation",
            labels={"type": "Figure 8: position error ratio"},
        ),
        *[f"reports/navigation/fig{k}.{fmt}" for k in ("7_trajectory", "8_ratio")
          for fmt in FIG_FORMATS if fmt != "png"],
        csv=report(
            "reports/navigation/ratio_max.csv",
            caption="../report/nav_table.rst",
            category="Navigation emulation",
            labels={"type": "table: maximum ratio and CI (CSV)"},
        ),
        md="reports/navigation/ratio_max.md",
        series="reports/navigation/ratio_series.csv",
        # per iteration and model: dropped?, filter parameters, errors (counts: rule counts)
        iterations="reports/navigation/replicates/iterations.csv",
    params:
        nav=NAV_MAIN,
        formats=FIG_FORMATS,
    log:
        "logs/navigation/nav_report.log",
    benchmark:
        f"{BENCH}/nav_report/navigation/report.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/nav_report.py"


# --- variants (config navigation.variants) ----------------------------------------------------


def nav_variant(wildcards):
    """The variant's config; an unconfigured name (a stray target) is an error naming the list."""
    if wildcards.nav_variant not in NAV_VARIANTS:
        raise WorkflowError(f"navigation: no variant {wildcards.nav_variant!r} configured "
                            f"(navigation.variants: {sorted(NAV_VARIANTS)})")
    return NAV_VARIANTS[wildcards.nav_variant]


rule nav_variant_chunk:
    input:
        unpack(nav_inputs),
    output:
        "results/navigation/{nav_variant}/chunks/c{chunk}.nc",
    params:
        nav=nav_variant,
        iterations=lambda w: _gs_nav.chunk_replicates(int(w.chunk), nav_variant(w)["iterations"],
                                                       nav_variant(w)["chunk_size"]),
        truth=lambda w: STUDIES[NAV["estimates_from"]]["truth"],
    log:
        "logs/navigation/nav_variant_chunk/{nav_variant}_c{chunk}.log",
    benchmark:
        f"{BENCH}/nav_variant_chunk/navigation/{{nav_variant}}_c{{chunk}}.tsv"
    threads: 1
    resources:
        runtime=lambda w: max(10, int(nav_variant(w)["chunk_size"] * NAV["duration"] / 235 * 2
                                      / 60) + 5),
        mem_mb=lambda w: max(1000, int(nav_variant(w)["chunk_size"] * NAV["duration"]
                                       * NAV["imu_rate"] * 2 * 3 * 8 * 3 / 1e6) + 500),
    script:
        "../scripts/nav_chunk.py"


rule nav_variant_report:
    input:
        lambda w: [f"results/navigation/{w.nav_variant}/chunks/c{c}.nc"
                   for c in range(nav_n_chunks(nav_variant(w)))],
    output:
        csv=report(
            "reports/navigation/{nav_variant}/ratio_max.csv",
            caption="../report/nav_variant_table.rst",
            category="Navigation emulation",
            labels={"type": "variant {nav_variant}: maximum ratio and CI (CSV)"},
        ),
        md="reports/navigation/{nav_variant}/ratio_max.md",
        series="reports/navigation/{nav_variant}/ratio_series.csv",
        fig="reports/navigation/{nav_variant}/fig8_ratio.png",
        other=[f"reports/navigation/{{nav_variant}}/fig8_ratio.{fmt}" for fmt in FIG_FORMATS
               if fmt != "png"],
    params:
        nav=nav_variant,
        formats=FIG_FORMATS,
    log:
        "logs/navigation/nav_variant_report/{nav_variant}.log",
    benchmark:
        f"{BENCH}/nav_variant_report/navigation/{{nav_variant}}.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/nav_variant_report.py"
