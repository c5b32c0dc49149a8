"""Rule navchip_fit: GMWM fit of the Navchip model to every axis; writes the fits file that the
report and the bootstrap step read (gmwm_studies.navchip.load_fits)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import json
from pathlib import Path

from gmwm.atomic import write_json_atomic
from gmwm_studies.navchip import fit_channels, fits_to_json

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
data = Path(snakemake.input[0])
log.info("model %s, sensors %s, fit settings %s", p.model, p.sensors, p.fit)
fits = fit_channels(data, p.model, p.sensors, fit_settings=p.fit, progress=log.info)
meta = data.with_suffix(".json")
source = json.loads(meta.read_text()).get("source", {}) if meta.is_file() else {}
write_json_atomic(snakemake.output[0], fits_to_json(fits, p.fit, source))
log.info("wrote %s (%d channels)", snakemake.output[0], len(fits))
