# Paper items checked by computation over committed tables (gmwm_studies.paper_items; issue 42):
#   paper_items   [GMWFM] Lemma 1's Jacobian determinant under both readings of its (1,1) entry,
#                 the Sec. IV sample-size cells of the GMWFM estimators, Corollary 1's RMSE
#                 ratios and Sec. III's bias comparison (STIM-300 tables and per-replicate
#                 tables), and [SVO] Theorems 1-2 as Case 1's tables show them
#                 -> reports/paper_items/paper_items.{json,md}, which REPRODUCTION.md links.
# Seconds of CPU. Requested by `rule all` only (like `design`), when both STIM-300 studies and SVO
# Case 1's coverage study are configured; not an input of the index or the archive.

PAPER_ITEMS_FILES = ["reports/paper_items/paper_items.json", "reports/paper_items/paper_items.md"]
PAPER_ITEMS_STIM = {"gyro": "stim300_gyro", "accel": "stim300_accel"}


def paper_items_enabled():
    return (all(name in STUDIES for name in PAPER_ITEMS_STIM.values())
            and "case1" in SVO_COV["cases"])


def paper_items_lengths():
    lengths = {tuple(sorted(int(T) for T in STUDIES[n]["n_samples"]))
               for n in PAPER_ITEMS_STIM.values()}
    return list(lengths.pop()) if len(lengths) == 1 else []


def paper_items_targets():
    return PAPER_ITEMS_FILES if paper_items_enabled() and len(paper_items_lengths()) == 2 else []


# Defined only when its inputs exist: with a STIM-300 study or SVO Case 1's coverage switched off
# (a restricted run, the kill test's), the inputs' replicate lists cannot be built.
if paper_items_enabled():

    localrules:
        paper_items,


    rule paper_items:
        input:
            tables=[f"reports/stim300/{n}_bias_sd_rmse.csv" for n in PAPER_ITEMS_STIM.values()],
            replicates=[f for n in PAPER_ITEMS_STIM.values() for f in replicates_files(n)],
            coverage="reports/svo/case1/coverage.csv",
            coefficients="reports/svo/case1/coefficients.csv",
        output:
            json=PAPER_ITEMS_FILES[0],
            md=PAPER_ITEMS_FILES[1],
        params:
            stim=PAPER_ITEMS_STIM,
            sensors={k: STUDIES[n]["sensor"] for k, n in PAPER_ITEMS_STIM.items()},
            lengths=paper_items_lengths(),
            arrays=int(SVO["train"]),
        log:
            "logs/paper_items.log",
        benchmark:
            f"{BENCH}/paper_items/paper_items/paper_items.tsv"
        resources:
            runtime=5,
            mem_mb=1000,
        script:
            "../scripts/paper_items.py"
