# Design against estimator (gmwm_studies.design; docs/pipeline.md "Design against estimator"):
#   design   the asymptotic SE of each study's GMWM at its truth (gmwm.plan.predict) and the
#            design's probability of the boundary and factor-2 events the counts record, beside
#            the observed counts: Simulations 2 and 3 and STIM-300 (kinds wv_montecarlo, stim300:
#            their committed per-replicate tables) and the Navchip axes (their bootstrap draws)
#            -> reports/design/asymptotic.{csv,md} and reports/design/counts.{json,md} (the
#            numbers REPRODUCTION.md quotes through count markers), with the counts of the
#            committed audit of Simulation 2's slow-sinusoid misses (reports/design/sim2_audit.csv,
#            written by benchmarks/audit_sim2_misses.py) when it is there.
# Requested by `rule all` only, not by the index or the archive: its Navchip input needs the
# data file, whose absence must fail only the Navchip jobs (as navchip_draws / counts_navchip).

from gmwm_studies.data import dataset_entry

DESIGN_KINDS = ("wv_montecarlo", "stim300")
DESIGN_FILES = ["reports/design/asymptotic.csv", "reports/design/asymptotic.md",
                "reports/design/counts.json", "reports/design/counts.md"]


def design_tables():
    return [{"study": name, "csv": f"reports/{name}/replicates/estimates_T{T}.csv",
             "label_T": len(replicates_T(name)) > 1}
            for name, s in STUDIES.items() if s["kind"] in DESIGN_KINDS
            for T in replicates_T(name)]


def design_audits():
    """The committed multistart audits of a study's misses (benchmarks/audit_sim2_misses.py
    writes reports/design/<study>_audit.csv); counted when the file is there."""
    return [t for t in design_tables() if t["study"] == "sim2" and not t["label_T"]
            and os.path.exists(f"reports/design/{t['study']}_audit.csv")]


def design_estimators():
    """Settings of the estimators the design studies run (a change of another estimator's
    settings does not rerun the rule)."""
    names = {e for t in design_tables() for e in STUDIES[t["study"]]["estimators"]}
    return {e: dict(config["estimators"][e]) for e in sorted(names)}


def design_navchip():
    """The Navchip part's settings, or None when the Navchip bootstrap is not run."""
    if not unc_navchip_fits():
        return None
    entry = dataset_entry(config["navchip"]["dataset"])
    return {"model": config["navchip"]["model"], "fit": dict(config["navchip"]["fit"]),
            "n_samples": int(entry["n"]), "levels": int(entry["n_levels"]),
            "freq": float(entry["freq_hz"])}


def design_targets():
    return DESIGN_FILES if design_tables() or design_navchip() else []


localrules:
    design,


rule design:
    input:
        tables=[t["csv"] for t in design_tables()],
        truths=[t["csv"].replace("estimates_", "truth_").replace(".csv", ".json")
                for t in design_tables()],
        navchip_draws=NAVCHIP_DRAWS[0] if design_navchip() else [],
        navchip_estimates=NAVCHIP_DRAWS[1] if design_navchip() else [],
        audits=[f"reports/design/{t['study']}_audit.csv" for t in design_audits()],
    output:
        csv=DESIGN_FILES[0],
        md=DESIGN_FILES[1],
        json=DESIGN_FILES[2],
        counts_md=DESIGN_FILES[3],
    params:
        tables=design_tables(),
        estimators=design_estimators(),
        navchip=design_navchip(),
        audits=design_audits(),
        seed=config["seed"],
    log:
        "logs/design.log",
    benchmark:
        f"{BENCH}/design/design/design.tsv"
    resources:
        runtime=10,
        mem_mb=1000,
    script:
        "../scripts/design.py"
