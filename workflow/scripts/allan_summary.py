"""Rule allan_summary: the key numbers of the Allan-variance chapter study (the index's table and
the JSON the reproduction table quotes)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import json

from gmwm.atomic import write_json_atomic
from gmwm_studies import allan_chapter as ac
from gmwm_studies.montecarlo import write_table

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
inp, out = snakemake.input, snakemake.output

with open(inp.chapter) as fh:
    numbers = json.load(fh)
with open(inp.mle) as fh:
    numbers["mle"] = json.load(fh)
with open(inp.added) as fh:
    numbers |= json.load(fh)  # lemma41, cor41, moav, consistency
write_json_atomic(out.json, numbers)
table = ac.summary_table(numbers)
write_table(table, out.csv, out.md, "Allan-variance chapter ([AV-chapter]): key numbers")
log.info("wrote %s (%d rows)", out.csv, len(table))
