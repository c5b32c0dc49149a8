"""Rule archive: copy this run's reports, config, versions, git commit and timings to a new
reports/archive/<timestamp>-<config hash>/ directory (never overwriting an earlier one)."""

from wflog import get_logger

from gmwm.atomic import write_json_atomic
from gmwm_studies.archive import config_hash, make_archive, read_benchmarks

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
bench = read_benchmarks(snakemake.params.benchmarks)
target = make_archive(snakemake.params.archive_root, snakemake.config, snakemake.input.files,
                      bench, repo=snakemake.scriptdir, produced=snakemake.params.produced)
write_json_atomic(snakemake.output[0], {"archive": str(target), "config_hash":
                                        config_hash(snakemake.config), "jobs": len(bench)})
log.info("archived %d files and %d job timings to %s", len(snakemake.input.files), len(bench),
         target)
