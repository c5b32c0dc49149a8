"""Rule counts_navchip: counts of the Navchip bootstrap draws -> reports/navchip/counts.{json,md}."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm_studies.counts import draw_counts, write_counts

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
draws = pd.read_csv(snakemake.input.draws)
estimates = pd.read_csv(snakemake.input.estimates).set_index("fit")
src = str(Path(snakemake.input.draws).relative_to(Path(snakemake.output.json).parent))
counts = [c for fit, row in estimates.iterrows()
          for c in draw_counts(f"navchip.{fit}", draws[draws["fit"] == fit], row.to_dict(), src)]
write_counts(counts, snakemake.output.json, snakemake.output.md,
             title="Counts of the Navchip bootstrap draws")
log.info("wrote %s: %d counts", snakemake.output.json, len(counts))
