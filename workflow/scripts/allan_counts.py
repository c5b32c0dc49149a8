"""Rule allan_counts: the counts the Allan-chapter rows of REPRODUCTION.md quote, recomputed from
the committed per-replicate files (gmwm_studies.allan_chapter.allan_counts) and written in
gmwm_studies.counts' format (counts.json / counts.md beside the files)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import os

import pandas as pd

from gmwm_studies.allan_chapter import allan_counts
from gmwm_studies.counts import write_counts

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
inp, out = snakemake.input, snakemake.output
base = os.path.dirname(out.json)
tables = {k: pd.read_csv(inp[k]) for k in ("readings", "intervals", "moav", "consistency")}
sources = {k: os.path.relpath(inp[k], base) for k in tables}
counts = allan_counts(tables["readings"], tables["intervals"], tables["moav"], sources,
                      tables["consistency"])
write_counts(counts, out.json, out.md, title="Counts quoted in the Allan-chapter rows")
log.info("wrote %d counts to %s", len(counts), out.json)
