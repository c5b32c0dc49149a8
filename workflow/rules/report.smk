# Cross-study outputs: the index page and the archive of the run.
# Small jobs run on the submitting host under a cluster executor.

localrules:
    gather,
    table,
    figure_wv,
    figure_boxplot,
    index,
    archive,


rule index:
    input:
        all_study_targets(),
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
        },
        config_id=CONFIG_ID,
        benchmarks=all_benchmarks(),
    log:
        "logs/index.log",
    script:
        "../scripts/index.py"


# The archive directory name carries a timestamp, unknown when the DAG is built, so the rule's
# output is a small JSON marker per config hash naming the archive it wrote. Same config and up
# to date outputs: nothing to do; any rerun of a study output or a new config: a new archive.
rule archive:
    input:
        files=[*all_study_targets(), "reports/index.md"],
    output:
        f"results/archive/{CONFIG_ID}.json",
    params:
        benchmarks=all_benchmarks(),
        archive_root="reports/archive",
    log:
        "logs/archive.log",
    script:
        "../scripts/archive.py"
