# Navchip real-data analysis ([GMWFM] Sec. V; config key `navchip`): not a Monte Carlo study.
#   navchip_data   (obtain the WV file: local copy or public source; fails cleanly, naming the file
#                   and its source, when neither is available)
#   -> navchip_fit (GMWM per axis; results/navchip/fits.json is the hook for the bootstrap step)
#   -> navchip_report (Figures 3 and 4, estimates table, goodness-of-fit table).
# Its targets are requested by `rule all` but are NOT inputs of the index and archive, so that a
# missing data file stops only these rules (keep-going): every study, the index and the archive
# are still produced.

import os

from gmwm_studies.data import local_copy

NAVCHIP = dict(config["navchip"])  # a copy: data_dir is made absolute below
if NAVCHIP["data_dir"] is not None:  # relative to the repository root, not to `outdir`
    _repo_root = os.path.dirname(os.path.dirname(workflow.current_basedir.get_path_or_uri(secret_free=True)))
    NAVCHIP["data_dir"] = os.path.join(_repo_root, NAVCHIP["data_dir"])


def navchip_local_copy():
    """Whether the Navchip file is already on disk (the configured data_dir, else the registry's
    local_dir). Then its reports are archive inputs too (report.smk): nothing can fail for want of
    the data. Without a local copy they stay outside the archive, so that a failed download stops
    only the navchip rules."""
    return NAVCHIP["enabled"] and local_copy(NAVCHIP["dataset"], NAVCHIP["data_dir"]) is not None


def navchip_benchmarks():
    """Benchmark files of the navchip rules (with navchip_targets)."""
    if not NAVCHIP["enabled"]:
        return []
    return [f"{BENCH}/navchip_{r}/navchip/{r}.tsv" for r in ("data", "fit", "report")]


def navchip_targets():
    if not NAVCHIP["enabled"]:
        return []
    return [
        "results/navchip/fits.json",
        "reports/navchip/estimates.csv",
        "reports/navchip/estimates.md",
        "reports/navchip/gof.csv",
        "reports/navchip/gof.md",
        *[f"reports/navchip/fig3_wv_datasheet.{fmt}" for fmt in FIG_FORMATS],
        *[f"reports/navchip/fig4_decomposition.{fmt}" for fmt in FIG_FORMATS],
    ]


localrules:
    navchip_data,
    navchip_report,


rule navchip_data:
    output:
        csv="results/navchip/data/navchip_wv.csv",
        meta="results/navchip/data/navchip_wv.json",
    params:
        dataset=NAVCHIP["dataset"],
        data_dir=NAVCHIP["data_dir"],
        allow_download=NAVCHIP["allow_download"],
    log:
        "logs/navchip/navchip_data.log",
    benchmark:
        f"{BENCH}/navchip_data/navchip/data.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/navchip_data.py"


rule navchip_fit:
    input:
        "results/navchip/data/navchip_wv.csv",
    output:
        "results/navchip/fits.json",
    params:
        model=NAVCHIP["model"],
        sensors=NAVCHIP["sensors"],
        fit=NAVCHIP["fit"],
    log:
        "logs/navchip/navchip_fit.log",
    benchmark:
        f"{BENCH}/navchip_fit/navchip/fit.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=1000,
    script:
        "../scripts/navchip_fit.py"


rule navchip_report:
    input:
        data="results/navchip/data/navchip_wv.csv",
        fits="results/navchip/fits.json",
    output:
        report(
            "reports/navchip/fig3_wv_datasheet.png",
            caption="../report/navchip_fig3.rst",
            category="Navchip",
            labels={"figure": "Figure 3: WV, GMWM model, datasheet model"},
        ),
        report(
            "reports/navchip/fig4_decomposition.png",
            caption="../report/navchip_fig4.rst",
            category="Navchip",
            labels={"figure": "Figure 4: decomposition of the GMWM model"},
        ),
        *[f"reports/navchip/fig{k}.{fmt}" for k in ("3_wv_datasheet", "4_decomposition")
          for fmt in FIG_FORMATS if fmt != "png"],
        estimates=report(
            "reports/navchip/estimates.csv",
            caption="../report/navchip_estimates.rst",
            category="Navchip",
            labels={"figure": "table: estimates and SEs (CSV)"},
        ),
        estimates_md="reports/navchip/estimates.md",
        gof=report(
            "reports/navchip/gof.csv",
            caption="../report/navchip_gof.rst",
            category="Navchip",
            labels={"figure": "table: goodness of fit (CSV)"},
        ),
        gof_md="reports/navchip/gof.md",
    params:
        model=NAVCHIP["model"],
        threshold=NAVCHIP["gof_threshold"],
        formats=FIG_FORMATS,
    log:
        "logs/navchip/navchip_report.log",
    benchmark:
        f"{BENCH}/navchip_report/navchip/report.tsv"
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/navchip_report.py"
