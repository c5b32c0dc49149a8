# Virtual gyroscope by Scale-wise Variance Optimisation ([SVO], docs/METHODS.md §11; config key `svo`).
# Statistics live in gmwm.virtual (library) and gmwm_studies.svo_study (protocol, tables, figures).
#
#   svo_train     training replicates [a, b) of a case: the 4 coefficient vectors (SVO omega_1,
#                 SVO omega_2, RDVG, equal) of array r, applied to its `test_per_train` fresh
#                 arrays (WV of every virtual signal, WN+RW GMWM fit)
#   svo_coverage  coverage replicates [a, b): c_hat(omega_2) with MBB 95 % CIs against c0
#   svo_report    per case: Fig. 2/7 (mean WV + ratio), Fig. 4/8 (coefficient boxplots), Fig. 3
#                 (GMWM WN+RW of the virtual signals) and their tables (coefficients, WV, GMWM
#                 estimates); svo_coverage_report: coverage table and figure (Wilson MC intervals);
#                 both also write the per-replicate files under reports/svo/<case>/replicates/
#                 (coefficient vectors per array, GMWM fits per virtual signal, intervals per
#                 coverage replication) that rule counts counts
#   svo_inputs    per case: Fig. 1 (Case 1: |corr| of Q) / Fig. 6 (Case 2: |corr| of P_1..P_3),
#                 drawn from the App. C matrices the simulations use, and their table
# Every array has its own SeedSequence keyed by (svo, case, role, replicate[, k]) under `seed`.
# Paths are relative to the workdir (config `outdir`), like every other rule file.

SVO = config["svo"]  # defaults: config.schema.yaml; seed: common.smk
SVO_COV = SVO["coverage"]
from gmwm.errors import InputError
from gmwm_studies.svo_study import scheme_caps

try:  # names among `schemes`, positive ints (the schema checks the types, not the names)
    SVO_CAPS = scheme_caps(SVO_COV["scheme_replicates"], SVO_COV["schemes"])
except InputError as exc:
    raise WorkflowError(f"config: svo.coverage.{exc}") from None


def _svo_chunks(n, size):
    return [(a, min(n, a + size)) for a in range(0, n, size)]


def svo_train_files(case):
    return [f"results/svo/{case}/train_{a}_{b}.npz"
            for a, b in _svo_chunks(int(SVO["train"]), int(SVO["chunk_size"]))]


def svo_coverage_files(case):
    if case not in SVO_COV["cases"]:
        return []
    return [f"results/svo/{case}/coverage_{a}_{b}.npz"
            for a, b in _svo_chunks(int(SVO_COV["replicates"]), int(SVO_COV["chunk_size"]))]


def svo_report_files(case):
    files = [f"reports/svo/{case}/{stem}.{fmt}" for stem in ("fig_wv", "fig_coefs", "fig_gmwm")
             for fmt in FIG_FORMATS]
    files += [f"reports/svo/{case}/{t}.{ext}" for t in ("coefficients", "wv", "gmwm_estimates")
              for ext in ("csv", "md")]
    files += [f"reports/svo/{case}/replicates/{t}.csv" for t in ("coefficients", "virtual_fits")]
    files += [f"reports/svo/{case}/fig_input_correlation.{fmt}" for fmt in FIG_FORMATS]
    files += [f"reports/svo/{case}/input_correlation.{ext}" for ext in ("csv", "md")]
    if case in SVO_COV["cases"]:
        files += [f"reports/svo/{case}/coverage.{ext}" for ext in ("csv", "md")]
        files += [f"reports/svo/{case}/fig_coverage.{fmt}" for fmt in FIG_FORMATS]
        files.append(f"reports/svo/{case}/replicates/coverage.csv")
    return files


def svo_targets():
    if not SVO["enabled"]:
        return []
    return [f for case in SVO["cases"] for f in svo_report_files(case)]


def svo_benchmarks():
    if not SVO["enabled"]:
        return []
    out = []
    for case in SVO["cases"]:
        out += [f.replace("results/svo/", f"{BENCH}/svo_train/").replace(".npz", ".tsv")
                for f in svo_train_files(case)]
        out += [f.replace("results/svo/", f"{BENCH}/svo_coverage/").replace(".npz", ".tsv")
                for f in svo_coverage_files(case)]
    return out


if SVO["enabled"]:
    register_section("svo", {
        "model": "6-gyro arrays: " + ", ".join(SVO["cases"]) + " (docs/METHODS.md §11.6)",
        "description": (
            f"Virtual gyroscope ([SVO]): {SVO['train']} training arrays x "
            f"{SVO['test_per_train']} test arrays per case, SVO omega_1/omega_2, RDVG, equal "
            f"weights; coverage of MBB CIs ({SVO_COV['replicates']} replicates, "
            f"{SVO_COV['n_boot']} draws, l = {SVO_COV['block_const']:g} T^(1/3), schemes "
            f"{'/'.join(SVO_COV['schemes'])}"
            + "".join(f", {k} on the first {v}" for k, v in SVO_CAPS.items()) + ") for "
            + ", ".join(SVO_COV["cases"]) + ". [case1](svo/case1/wv.md)"
        ),
        "n_samples": [int(SVO["n_samples"])],
        "replicates": int(SVO["train"]),
        "targets": svo_targets(),
        "benchmarks": svo_benchmarks(),
    })


wildcard_constraints:
    svo_case="case[0-9]+",
    a="[0-9]+",
    b="[0-9]+",


rule svo_train:
    output:
        "results/svo/{svo_case}/train_{a}_{b}.npz",
    params:
        n_samples=int(SVO["n_samples"]),
        levels=int(SVO["levels"]),
        n_test=int(SVO["test_per_train"]),
        seed=int(SVO["seed"]),
    log:
        "logs/svo/{svo_case}/train_{a}_{b}.log",
    benchmark:
        f"{BENCH}/svo_train/{{svo_case}}/train_{{a}}_{{b}}.tsv"
    threads: 1
    resources:
        # measured: ~1.5 s per 1e6-sample 6-gyro array (simulate + WCCV + 4 GMWM fits), 2 cores
        runtime=lambda wc: max(10, int((int(wc.b) - int(wc.a)) * (1 + int(SVO["test_per_train"]))
                                      * 3.0 * int(SVO["n_samples"]) / 1e6 / 60) + 5),
        mem_mb=lambda wc: max(1000, int(6 * 8 * int(SVO["n_samples"]) * 6 / 1e6) + 500),
    script:
        "../scripts/svo_train.py"


rule svo_coverage:
    output:
        "results/svo/{svo_case}/coverage_{a}_{b}.npz",
    params:
        n_samples=int(SVO["n_samples"]),
        levels=int(SVO["levels"]),
        n_boot=int(SVO_COV["n_boot"]),
        block_const=float(SVO_COV["block_const"]),
        alpha=float(SVO_COV["alpha"]),
        schemes=list(SVO_COV["schemes"]),
        # a scheme named here runs on replications r < cap only; in params so a change reruns
        scheme_replicates=SVO_CAPS,
        seed=int(SVO["seed"]),
    log:
        "logs/svo/{svo_case}/coverage_{a}_{b}.log",
    benchmark:
        f"{BENCH}/svo_coverage/{{svo_case}}/coverage_{{a}}_{{b}}.tsv"
    threads: 1
    resources:
        runtime=lambda wc: max(10, int((int(wc.b) - int(wc.a)) * 5.0 * int(SVO["n_samples"]) / 1e6
                                      / 60) + 5),
        mem_mb=lambda wc: max(1000, int(12 * 8 * int(SVO["n_samples"]) * 6 / 1e6) + 500),
    script:
        "../scripts/svo_coverage.py"


rule svo_report:
    input:
        train=lambda wc: svo_train_files(wc.svo_case),
    output:
        report(
            "reports/svo/{svo_case}/fig_wv.png",
            caption="../report/svo_wv.rst",
            category="Virtual gyroscope (SVO)",
            subcategory="{svo_case}",
            labels={"figure": "WV of the virtual signals and ratio to equal weights"},
        ),
        report(
            "reports/svo/{svo_case}/fig_coefs.png",
            caption="../report/svo_coefs.rst",
            category="Virtual gyroscope (SVO)",
            subcategory="{svo_case}",
            labels={"figure": "estimated coefficients vs c0"},
        ),
        report(
            "reports/svo/{svo_case}/fig_gmwm.png",
            caption="../report/svo_gmwm.rst",
            category="Virtual gyroscope (SVO)",
            subcategory="{svo_case}",
            labels={"figure": "GMWM WN+RW estimates of the virtual signals"},
        ),
        *[f"reports/svo/{{svo_case}}/{stem}.{fmt}" for stem in ("fig_wv", "fig_coefs", "fig_gmwm")
          for fmt in FIG_FORMATS if fmt != "png"],
        coefs_csv="reports/svo/{svo_case}/coefficients.csv",
        coefs_md="reports/svo/{svo_case}/coefficients.md",
        wv_csv="reports/svo/{svo_case}/wv.csv",
        wv_md="reports/svo/{svo_case}/wv.md",
        gmwm_csv="reports/svo/{svo_case}/gmwm_estimates.csv",
        gmwm_md="reports/svo/{svo_case}/gmwm_estimates.md",
        # per-replicate files (counts: rule counts): coefficient vectors per training array,
        # GMWM estimates per virtual signal
        array_coefs="reports/svo/{svo_case}/replicates/coefficients.csv",
        virtual_fits="reports/svo/{svo_case}/replicates/virtual_fits.csv",
    params:
        levels=int(SVO["levels"]),
        freq=float(SVO["freq"]),
        formats=FIG_FORMATS,
    log:
        "logs/svo/{svo_case}/report.log",
    resources:
        runtime=10,
        mem_mb=2000,
    script:
        "../scripts/svo_report.py"


rule svo_coverage_report:
    input:
        lambda wc: svo_coverage_files(wc.svo_case),
    output:
        csv="reports/svo/{svo_case}/coverage.csv",
        md="reports/svo/{svo_case}/coverage.md",
        fig=report(
            "reports/svo/{svo_case}/fig_coverage.png",
            caption="../report/svo_coverage.rst",
            category="Virtual gyroscope (SVO)",
            subcategory="{svo_case}",
            labels={"figure": "coverage of the MBB confidence intervals"},
        ),
        *[f"reports/svo/{{svo_case}}/fig_coverage.{fmt}" for fmt in FIG_FORMATS if fmt != "png"],
        replicates="reports/svo/{svo_case}/replicates/coverage.csv",  # per replication and gyro
    params:
        formats=FIG_FORMATS,
        alpha=float(SVO_COV["alpha"]),
        schemes=list(SVO_COV["schemes"]),  # named in the caption
        scheme_replicates=SVO_CAPS,  # named in the caption
        replicates=int(SVO_COV["replicates"]),
    log:
        "logs/svo/{svo_case}/coverage_report.log",
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/svo_coverage_report.py"


rule svo_inputs:
    output:
        report(
            "reports/svo/{svo_case}/fig_input_correlation.png",
            caption="../report/svo_inputs.rst",
            category="Virtual gyroscope (SVO)",
            subcategory="{svo_case}",
            labels={"figure": "absolute correlation of the input covariances"},
        ),
        *[f"reports/svo/{{svo_case}}/fig_input_correlation.{fmt}" for fmt in FIG_FORMATS
          if fmt != "png"],
        csv="reports/svo/{svo_case}/input_correlation.csv",
        md="reports/svo/{svo_case}/input_correlation.md",
    params:
        formats=FIG_FORMATS,
    log:
        "logs/svo/{svo_case}/inputs.log",
    resources:
        runtime=5,
        mem_mb=500,
    script:
        "../scripts/svo_inputs.py"


localrules:
    svo_report,
    svo_coverage_report,
    svo_inputs,


rule svo_all:
    input:
        svo_targets(),
