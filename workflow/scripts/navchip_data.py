"""Rule navchip_data: obtain the Navchip WV file (local copy or public source).

When the file is neither in the configured directory nor downloadable, the job fails with one
line naming the file and its public source (no traceback); the rest of the workflow still runs.
"""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import sys
from pathlib import Path

from gmwm.errors import GMWMError
from gmwm_studies.navchip import obtain_navchip

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
try:
    path = obtain_navchip(Path(snakemake.output.csv).parent, p.dataset, p.data_dir,
                          p.allow_download)
except GMWMError as exc:
    log.error("Navchip data unavailable: %s", exc)
    sys.exit(f"navchip_data: {exc}")
log.info("obtained %s (data_dir %s, download allowed: %s)", path, p.data_dir, p.allow_download)
