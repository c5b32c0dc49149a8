"""Rule svo_coverage: coverage replicates [a, b) of one SVO case (svo_study.coverage_chunk)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import numpy as np

from gmwm.atomic import atomic_path
from gmwm_studies.svo_study import coverage_chunk

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, wc = snakemake.params, snakemake.wildcards
reps = list(range(int(wc.a), int(wc.b)))
res = coverage_chunk(wc.svo_case, reps, p.n_samples, p.levels, p.n_boot, p.block_const, p.alpha,
                     p.seed, p.schemes, dict(p.scheme_replicates))
with atomic_path(snakemake.output[0]) as tmp, open(tmp, "wb") as fh:
    np.savez(fh, **res)
log.info("%s replicates %s: %.2f s per replicate, block %d", wc.svo_case, reps,
         float(np.mean(res["seconds"])), int(res["block"]))
