# Allan-variance chapter ([AV-chapter], [AV-chapter]; config key `allan`; library code
# gmwm_studies.allan_chapter). Not a Monte Carlo study of the usual kind: three small jobs.
#
#   allan_chapter  Figs 4.1 / 4.2 (AD of WN and WN + RW, theoretical lines, IEEE 952 readings,
#                  GMWM), Example 4.2 (MA(1) AV), Lemma 4.2 (ARMA(1,1)), Sec. 4.2.2 (equal AV,
#                  different spectra), Remark 4.3 (Gaussian AV intervals below 0): seconds
#   allan_mle      Example 4.1: exact MLE of WN + AR1 (Kalman filter; the dense T x T route timed)
#                  beside the GMWM on the same signals: about a minute on an idle core
#   allan_items    Lemma 4.1 (continuous-time kernel vs exact AV of sampled series), Cor 4.1
#                  (additivity), Lemmas 4.3-4.4 and the Sec. 4.3.3 interval (MOAV as T grows),
#                  Sec. 4.1 (AVSM vs GMWM as T grows): about 20 s
#   allan_counts   the counts the rows quote, from the per-replicate files (replicates/*.csv)
#                  -> counts.json / counts.md (gmwm_studies.counts' format)
#   allan_summary  the key numbers of all (summary.csv / .md / .json), the index's table
# Every signal has its own SeedSequence keyed by ("allan/<item>", T, replicate) under `seed`.
# Paths are relative to the workdir (config `outdir`), like every other rule file.

ALLAN = config["allan"]  # defaults: config.schema.yaml
ALLAN.setdefault("seed", config["seed"])
ALLAN_DIR = "reports/allan"
ALLAN_FIGS = ("fig41_adev", "fig42_adev", "fig_ma1", "fig_ambiguity", "fig_intervals")
ALLAN_TABLES = ("adev", "readings", "ma1", "lemma42", "ambiguity", "intervals")
ALLAN_ITEM_TABLES = ("lemma41", "cor41", "moav", "consistency")
# per-replicate files (what the rows quote as counts): readings and intervals from allan_chapter,
# moav and consistency from allan_items
ALLAN_REPLICATES = {k: f"{ALLAN_DIR}/replicates/{k}.csv"
                    for k in ("readings", "intervals", "moav", "consistency")}
ALLAN_COUNTS = [f"{ALLAN_DIR}/counts.json", f"{ALLAN_DIR}/counts.md"]


def allan_targets():
    if not ALLAN["enabled"]:
        return []
    return [
        # first CSV: the index's key table
        *[f"{ALLAN_DIR}/summary.{ext}" for ext in ("csv", "md", "json")],
        *[f"{ALLAN_DIR}/{t}.{ext}" for t in ALLAN_TABLES for ext in ("csv", "md")],
        *[f"{ALLAN_DIR}/{t}.{ext}" for t in ("mle", "dense_cost") for ext in ("csv", "md")],
        f"{ALLAN_DIR}/mle_replicates.csv",
        *[f"{ALLAN_DIR}/{t}.{ext}" for t in ALLAN_ITEM_TABLES for ext in ("csv", "md")],
        *ALLAN_REPLICATES.values(),
        *ALLAN_COUNTS,
        *[f"{ALLAN_DIR}/{f}.{fmt}" for f in ALLAN_FIGS for fmt in FIG_FORMATS],
    ]


def allan_benchmarks():
    if not ALLAN["enabled"]:
        return []
    return [f"{BENCH}/allan/{rule}.tsv"
            for rule in ("chapter", "mle", "items", "counts", "summary")]


if ALLAN["enabled"]:
    _mle = ALLAN["mle"]
    register_section("allan", {
        "model": "WN, WN+RW, MA(1), ARMA(1,1), MA(4) pair, WN+AR1",
        "description": (
            "Allan-variance chapter ([AV-chapter]): AD of WN and WN + RW with the theoretical lines, "
            "IEEE 952 readings and GMWM (Figs 4.1-4.2); MA(1) AV (Example 4.2); Lemma 4.2 against "
            "the exact AV of ARMA(1,1); equal AV with different spectra (Sec. 4.2.2); Gaussian AV "
            "intervals below 0 (Remark 4.3); Lemma 4.1's kernel on sampled series, additivity "
            "(Cor 4.1), MOAV consistency, normality and the Sec. 4.3.3 interval (Lemmas 4.3-4.4), "
            "AVSM vs GMWM as T grows (Sec. 4.1); MLE of WN + AR1 vs GMWM at T = "
            + ", ".join(f"{t:g}" for t in _mle["n_samples"])
            + f" ({_mle['replicates']} replicates, Example 4.1). [summary](allan/summary.md)"
        ),
        "n_samples": [int(ALLAN["n_samples"])],
        "replicates": int(ALLAN["replicates"]),
        "targets": allan_targets(),
        "benchmarks": allan_benchmarks(),
    })


localrules:
    allan_counts,
    allan_summary,


rule allan_chapter:
    output:
        fig41=report(
            f"{ALLAN_DIR}/fig41_adev.png",
            caption="../report/allan_fig41.rst",
            category="Allan-variance chapter",
            labels={"figure": "Fig 4.1: AD of white noise"},
        ),
        fig42=report(
            f"{ALLAN_DIR}/fig42_adev.png",
            caption="../report/allan_fig42.rst",
            category="Allan-variance chapter",
            labels={"figure": "Fig 4.2: AD of WN + RW"},
        ),
        ma1=report(
            f"{ALLAN_DIR}/fig_ma1.png",
            caption="../report/allan_ma1.rst",
            category="Allan-variance chapter",
            labels={"figure": "Example 4.2: AV of an MA(1)"},
        ),
        ambiguity=report(
            f"{ALLAN_DIR}/fig_ambiguity.png",
            caption="../report/allan_ambiguity.rst",
            category="Allan-variance chapter",
            labels={"figure": "Sec 4.2.2: equal AV, different spectra"},
        ),
        intervals=report(
            f"{ALLAN_DIR}/fig_intervals.png",
            caption="../report/allan_intervals.rst",
            category="Allan-variance chapter",
            labels={"figure": "Remark 4.3: Gaussian AV intervals below 0"},
        ),
        other_formats=[f"{ALLAN_DIR}/{f}.{fmt}" for f in ALLAN_FIGS for fmt in FIG_FORMATS
                       if fmt != "png"],
        tables=[f"{ALLAN_DIR}/{t}.{ext}" for t in ALLAN_TABLES for ext in ("csv", "md")],
        replicates_readings=ALLAN_REPLICATES["readings"],
        replicates_intervals=ALLAN_REPLICATES["intervals"],
        numbers="results/allan/chapter.json",
    params:
        n_samples=int(ALLAN["n_samples"]),
        replicates=int(ALLAN["replicates"]),
        ma1_thetas=[float(t) for t in ALLAN["ma1"]["thetas"]],
        ma1_n_samples=int(ALLAN["ma1"]["n_samples"]),
        ma1_replicates=int(ALLAN["ma1"]["replicates"]),
        ambiguity_n_samples=int(ALLAN["ambiguity"]["n_samples"]),
        ambiguity_replicates=int(ALLAN["ambiguity"]["replicates"]),
        seed=int(ALLAN["seed"]),
        formats=FIG_FORMATS,
    log:
        "logs/allan/chapter.log",
    benchmark:
        f"{BENCH}/allan/chapter.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=2000,
    script:
        "../scripts/allan_chapter.py"


rule allan_mle:
    output:
        mle_csv=f"{ALLAN_DIR}/mle.csv",
        mle_md=f"{ALLAN_DIR}/mle.md",
        replicates=f"{ALLAN_DIR}/mle_replicates.csv",
        dense_csv=f"{ALLAN_DIR}/dense_cost.csv",
        dense_md=f"{ALLAN_DIR}/dense_cost.md",
        numbers="results/allan/mle.json",
    params:
        n_samples=[int(t) for t in ALLAN["mle"]["n_samples"]],
        replicates=int(ALLAN["mle"]["replicates"]),
        settings=list(ALLAN["mle"]["settings"]),
        dense_sizes=[int(t) for t in ALLAN["mle"]["dense_sizes"]],
        maxiter=int(ALLAN["mle"]["maxiter"]),
        wrong_optimum_ll=float(ALLAN["mle"]["wrong_optimum_ll"]),
        seed=int(ALLAN["seed"]),
    log:
        "logs/allan/mle.log",
    benchmark:
        f"{BENCH}/allan/mle.tsv"
    threads: 1
    resources:
        # per replicate: 3 MLE runs + 1 GMWM, ~0.1-0.3 s at T = 1e5 on one idle core
        runtime=lambda wc: max(10, int(len(ALLAN["mle"]["settings"]) * int(
            ALLAN["mle"]["replicates"]) * sum(ALLAN["mle"]["n_samples"]) * 2e-6 / 60) + 10),
        mem_mb=lambda wc: max(1000, int(8 * max(ALLAN["mle"]["dense_sizes"]) ** 2 * 3 / 1e6)
                              + 500),
    script:
        "../scripts/allan_mle.py"


rule allan_items:
    output:
        tables=[f"{ALLAN_DIR}/{t}.{ext}" for t in ALLAN_ITEM_TABLES for ext in ("csv", "md")],
        replicates_moav=ALLAN_REPLICATES["moav"],
        replicates_consistency=ALLAN_REPLICATES["consistency"],
        numbers="results/allan/items.json",
    params:
        cor41=dict(ALLAN["items"]["cor41"]),
        moav=dict(ALLAN["items"]["moav"]),
        consistency=dict(ALLAN["items"]["consistency"]),
        seed=int(ALLAN["seed"]),
    log:
        "logs/allan/items.log",
    benchmark:
        f"{BENCH}/allan/items.tsv"
    threads: 1
    resources:
        runtime=20,
        mem_mb=2000,
    script:
        "../scripts/allan_items.py"


rule allan_counts:
    input:
        **ALLAN_REPLICATES,
    output:
        json=ALLAN_COUNTS[0],
        md=ALLAN_COUNTS[1],
    log:
        "logs/allan/counts.log",
    benchmark:
        f"{BENCH}/allan/counts.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/allan_counts.py"


rule allan_summary:
    input:
        chapter="results/allan/chapter.json",
        mle="results/allan/mle.json",
        added="results/allan/items.json",
    output:
        csv=report(
            f"{ALLAN_DIR}/summary.csv",
            caption="../report/allan_summary.rst",
            category="Allan-variance chapter",
            labels={"figure": "key numbers of every item (CSV)"},
        ),
        md=f"{ALLAN_DIR}/summary.md",
        json=f"{ALLAN_DIR}/summary.json",
    log:
        "logs/allan/summary.log",
    benchmark:
        f"{BENCH}/allan/summary.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/allan_summary.py"


rule allan_all:
    input:
        allan_targets(),
