# Shared helpers: which studies run, their chunks, file names, resource hints.
# Adding a study kind = a rule file that registers its targets with register_targets(kind, fn).

import os

import gmwm_studies.montecarlo as gs
import yaml
from gmwm_studies.archive import config_hash
from snakemake.exceptions import WorkflowError

# Every default lives in workflow/schemas/config.schema.yaml, filled by validate() in the Snakefile
# (sections navchip, navigation, svo, uncertainty and their sub-objects default to {}, so their
# keys are always present). The only defaults the schema cannot state depend on other keys; they
# are derived here, once:
#   studies.<name>.chunk_size / seed  -> the global chunk_size / seed (_study_with_defaults)
#   navigation.seed, svo.seed, uncertainty.seed -> the global seed
for _section in ("navigation", "svo", "uncertainty"):
    config[_section].setdefault("seed", config["seed"])


def _schema_order(section, props):
    """section's keys in the schema's order: dicts passed whole as params (nav=NAV) have a repr,
    hence a params-change trigger, that does not depend on the key order of the config files."""
    return {k: section[k] for k in props if k in section}


with open(os.path.join(workflow.basedir, "workflow/schemas/config.schema.yaml")) as _fh:
    _SCHEMA_PROPS = yaml.safe_load(_fh)["properties"]
for _section in ("navchip", "navigation", "svo", "uncertainty"):
    _props = _SCHEMA_PROPS[_section]["properties"]
    config[_section] = _schema_order(config[_section], _props)
    for _sub in ("coverage", "identifiability"):
        if _sub in config[_section]:
            config[_section][_sub] = _schema_order(config[_section][_sub], _props[_sub]["properties"])


def _study_with_defaults(name, raw):
    s = dict(raw)
    s.setdefault("chunk_size", config["chunk_size"])
    s.setdefault("seed", config["seed"])
    for est in s["estimators"]:
        if est not in config["estimators"]:
            raise WorkflowError(
                f"config: study {name!r} uses estimator {est!r}, which is not defined under "
                f"'estimators' ({sorted(config['estimators'])})"
            )
    try:
        gs.check_truth(s["model"], s["truth"])
    except ValueError as exc:
        raise WorkflowError(f"config: study {name!r}: {exc}") from exc
    return s


STUDIES = {
    name: _study_with_defaults(name, raw)
    for name, raw in config["studies"].items()
    if raw["enabled"]
}
FIG_FORMATS = config["figures"]["formats"]
CONFIG_ID = config_hash(config)
BENCH = "results/benchmarks"


wildcard_constraints:
    study="[A-Za-z][A-Za-z0-9_]*",
    estimator="[A-Za-z][A-Za-z0-9_]*",
    T="[0-9]+",
    chunk="[0-9]+",


def study(wildcards_or_name):
    name = getattr(wildcards_or_name, "study", wildcards_or_name)
    return STUDIES[name]


def studies_of_kind(kind):
    return [name for name, s in STUDIES.items() if s["kind"] == kind]


def n_chunks(name):
    s = STUDIES[name]
    return len(gs.chunk_bounds(s["replicates"], s["chunk_size"]))


def chunk_reps(name, chunk):
    s = STUDIES[name]
    return gs.chunk_replicates(int(chunk), s["replicates"], s["chunk_size"])


def max_T(name):
    return max(STUDIES[name]["n_samples"])


# --- targets: each rule file registers a function study name -> list of final files -------------
_TARGET_BUILDERS = {}
_BENCHMARK_BUILDERS = {}


INDEX_SECTIONS = {}
"""Analyses that are not studies (uncertainty, navigation, SVO): name -> {model, description,
n_samples, replicates, targets, benchmarks}, added with register_section; report.smk puts them in
the index and the archive."""


def register_section(name, section):
    """Add one index/archive section (see INDEX_SECTIONS); a name may be registered once."""
    if name in INDEX_SECTIONS:
        raise WorkflowError(f"index section {name!r} registered twice")
    INDEX_SECTIONS[name] = section


def register_targets(kind, targets, benchmarks):
    """targets(name) -> final files of a study; benchmarks(name) -> its jobs' benchmark files."""
    _TARGET_BUILDERS[kind] = targets
    _BENCHMARK_BUILDERS[kind] = benchmarks


def study_targets(name):
    kind = STUDIES[name]["kind"]
    if kind not in _TARGET_BUILDERS:
        raise WorkflowError(f"no rule file handles study kind {kind!r} (study {name!r})")
    return _TARGET_BUILDERS[kind](name)


def all_benchmarks():
    return [f for name, s in STUDIES.items() for f in _BENCHMARK_BUILDERS[s["kind"]](name)]


def all_study_targets():
    return [f for name in STUDIES for f in study_targets(name)]


def all_targets():
    return [*all_study_targets(), "reports/index.md", f"results/archive/{CONFIG_ID}.json"]


# --- resource hints (runtime in minutes, mem_mb), used locally and by the SLURM profile ----------
# Measured on the 2-core dev machine: simulate + WV ~ 1.5 s per 1e7 samples, fit ~1-3 s per replicate.
def simulate_runtime(wildcards):
    reps = len(chunk_reps(wildcards.study, wildcards.chunk))
    return max(10, int(3 * reps * int(wildcards.T) * 3e-7 / 60) + 5)


def simulate_mem(wildcards):
    # a few float64 copies of one signal (components + sum + WV pyramid)
    return max(1000, int(8 * int(wildcards.T) * 8 / 1e6) + 500)


def fit_runtime(wildcards):
    reps = len(chunk_reps(wildcards.study, wildcards.chunk))
    return max(10, int(reps * 10 / 60) + 5)
