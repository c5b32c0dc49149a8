"""Rule nav_chunk: emulate one chunk of navigation iterations (both filters on the same data)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import time

from gmwm_studies.navigation import run_chunk
from gmwm_studies.store import read_dataset, write_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
fits = {m: read_dataset(path) for m, path in snakemake.input.items()}
log.info("iterations %d..%d, models %s, gyro error on %s", p.iterations[0], p.iterations[-1],
         list(fits), p.nav["gyro_axes"])
t0 = time.perf_counter()
ds = run_chunk(p.nav, fits, p.truth, p.iterations)
ds.attrs["seconds"] = time.perf_counter() - t0
write_dataset(ds, snakemake.output[0])
log.info("wrote %s: %d iterations (dropped: %s) in %.1f s", snakemake.output[0],
         ds.sizes["iteration"], ds.attrs["dropped"], ds.attrs["seconds"])
