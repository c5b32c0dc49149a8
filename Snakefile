# gmwm reproducible pipeline. Run from the repository root:
#   snakemake -j2                                  # full scale (config/config.yaml) -> reports/
#   snakemake -j2 --configfile config/quick.yaml   # quick profile (CI) -> results/quick/ (untracked)
#   snakemake --profile profiles/slurm             # full scale on a SLURM cluster
# The same command resumes a killed run (workflow/rules/runlock.smk). See docs/pipeline.md.
# This file only validates the config, moves to the output directory and includes the rule files.

from snakemake.utils import min_version, validate

min_version("8.0")


import os
import sys

# Jobs import this checkout's library, whichever copy of gmwm is installed (or none): the archive
# names this checkout's commit, so its code is what must run. Script jobs inherit PYTHONPATH.
_SRC = os.path.join(workflow.basedir, "src")
sys.path.insert(0, _SRC)
os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (_SRC, os.environ.get("PYTHONPATH")) if p)

# Paths from the Snakefile's directory: cluster jobs re-read this file from another directory.
configfile: os.path.join(workflow.basedir, "config/config.yaml")


validate(config, "workflow/schemas/config.schema.yaml")


# Every relative path below (results/, reports/, logs/, .snakemake/) lives under `outdir`:
# "." for the full run (the tracked reports/), results/quick for the quick profile, so a quick run
# never touches a tracked file and has its own Snakemake metadata and locks.
workdir: os.path.join(workflow.basedir, config["outdir"])


report: "workflow/report/workflow.rst"


include: "workflow/rules/runlock.smk"
include: "workflow/rules/common.smk"
include: "workflow/rules/montecarlo.smk"
include: "workflow/rules/sim1.smk"
include: "workflow/rules/stim300.smk"
include: "workflow/rules/navchip.smk"
include: "workflow/rules/uncertainty.smk"
include: "workflow/rules/misspec.smk"
include: "workflow/rules/navigation.smk"
include: "workflow/rules/svo.smk"
include: "workflow/rules/allan.smk"
include: "workflow/rules/replicates.smk"
include: "workflow/rules/design.smk"
include: "workflow/rules/paper_items.smk"
include: "workflow/rules/lemmas000.smk"
include: "workflow/rules/report.smk"


# Each job writes its exact CPU time (getrusage) beside its benchmark file
# (workflow/scripts/wflog.py); it finds the file from its rule's pattern and its wildcards.
import json as _json
from snakemake.io import strip_wildcard_constraints as _strip

os.environ["GMWM_BENCHMARK_PATTERNS"] = _json.dumps(
    {r.name: _strip(str(r.benchmark)) for r in workflow.rules if r.benchmark}
)


rule all:
    default_target: True
    input:
        all_targets(),
        navchip_targets(),  # not index/archive inputs: missing data fails only navchip
        uncertainty_navchip_targets(),  # likewise (bootstrap/identifiability of Navchip fits)
        design_targets(),  # archived where the Navchip data is on disk (report.smk)
        paper_items_targets(),  # seconds; archived, not an index input
