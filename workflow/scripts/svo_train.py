"""Rule svo_train: training replicates [a, b) of one SVO case (gmwm_studies.svo_study.train_chunk)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import numpy as np

from gmwm.atomic import atomic_path
from gmwm_studies.svo_study import train_chunk

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, wc = snakemake.params, snakemake.wildcards
reps = list(range(int(wc.a), int(wc.b)))
res = train_chunk(wc.svo_case, reps, p.n_samples, p.levels, p.n_test, p.seed)
with atomic_path(snakemake.output[0]) as tmp, open(tmp, "wb") as fh:
    np.savez(fh, **res)
log.info("%s replicates %s: %.2f s per training replicate (%d test arrays each)", wc.svo_case,
         reps, float(np.mean(res["seconds"])), p.n_test)
