# Cross-study outputs: the index page and the archive of the run.
# Small jobs run on the submitting host under a cluster executor.

localrules:
    gather,
    table,
    figure_wv,
    figure_boxplot,
    index,
    archive,

# Analyses that are not studies (uncertainty, navigation, SVO) register their section with
# register_section (common.smk, included first); the index and the archive include them.
SECTION_TARGETS = [t for s in INDEX_SECTIONS.values() for t in s["targets"]]
SECTION_BENCHMARKS = [b for s in INDEX_SECTIONS.values() for b in s["benchmarks"]]
# the real-data reports join the archive when their data file is on disk (navchip.smk)
ARCHIVE_NAVCHIP = navchip_local_copy()
NAVCHIP_REPORTS = [t for t in [*navchip_targets(), *uncertainty_navchip_targets()]
                   if t.startswith("reports/")] if ARCHIVE_NAVCHIP else []
NAVCHIP_BENCHMARKS = [*navchip_benchmarks(), *unc_navchip_benchmarks()] if ARCHIVE_NAVCHIP else []
# the design and paper-item tables join it too (REPRODUCTION.md quotes them), the design table
# only where its inputs can be made (its Navchip part reads the Navchip bootstrap draws)
ARCHIVE_DERIVED = [*paper_items_targets(),
                   *(design_targets() if ARCHIVE_NAVCHIP or not design_navchip() else [])]


rule index:
    input:
        all_study_targets(),
        SECTION_TARGETS,
        COUNTS_FILES,  # reports/counts.{json,md} (replicates.smk): recounted with every index
    output:
        report("reports/index.md", caption="../report/index.rst", category="Overview"),
    params:
        studies={
            name: {
                "model": s["model"],
                "description": s["description"],
                "n_samples": s["n_samples"],
                "replicates": s["replicates"],
                "targets": study_targets(name),
            }
            for name, s in STUDIES.items()
        }
        | {name: {k: v for k, v in s.items() if k != "benchmarks"} for name, s in INDEX_SECTIONS.items()},
        config_id=CONFIG_ID,
        benchmarks=all_benchmarks() + SECTION_BENCHMARKS,
        archive_root="reports/archive",
        # real-data reports linked, not read: they are not inputs, so that a missing data file
        # stops only their own jobs (navchip.smk)
        linked={"navchip": {
            "model": "QN+WN+2*GM+RW+DR per axis",
            "description": ("Navchip IMU ([Vibration] Table 1 layout, Figs 3-4): GMWM fits of the "
                            "six axes, datasheet comparison and goodness of fit; bootstrap CIs "
                            "and identifiability in the uncertainty section. Built by the "
                            "navchip rules when the data file is available."),
            "targets": [t for t in navchip_targets() if t.startswith("reports/")],
        }} if navchip_targets() else {},
        # directory names of each section's benchmark files (the study column of its timings)
        study_dirs={name: sorted({os.path.basename(os.path.dirname(b)) for b in s["benchmarks"]})
                    for name, s in INDEX_SECTIONS.items()},
    log:
        "logs/index.log",
    script:
        "../scripts/index.py"


# The archive directory name carries a timestamp, unknown when the DAG is built, so the rule's
# output is a small JSON marker per config hash naming the archive it wrote. Same config and up
# to date outputs: nothing to do; any rerun of a study output or a new config: a new archive.
rule archive:
    input:
        files=[*all_study_targets(), *SECTION_TARGETS, *NAVCHIP_REPORTS, *COUNTS_FILES,
               *[f for name in STUDIES for f in replicates_files(name)], *ARCHIVE_DERIVED,
               "reports/index.md"],
    output:
        f"results/archive/{CONFIG_ID}.json",
    params:
        benchmarks=all_benchmarks() + SECTION_BENCHMARKS + NAVCHIP_BENCHMARKS,
        archive_root="reports/archive",
        # the run's tracked outputs that rule all requests after (or beside) the archive: not
        # archived (they need the Navchip data), but rewriting them does not make git.txt dirty
        produced=[f for f in [*design_targets(), *paper_items_targets(), *NAVCHIP_DRAWS,
                              *NAVCHIP_COUNTS] if f not in ARCHIVE_DERIVED],
    log:
        "logs/archive.log",
    script:
        "../scripts/archive.py"
