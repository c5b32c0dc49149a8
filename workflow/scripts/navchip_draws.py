"""Rule navchip_draws: one row per Navchip bootstrap draw (label-aligned refit) and the estimates."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

import pandas as pd

from gmwm.atomic import write_text_atomic
from gmwm.bootstrap import BootstrapResult
from gmwm.codec import read_result
from gmwm_studies.replicates import FLOAT_FORMAT, bootstrap_draw_table
from gmwm_studies.store import read_dataset
from gmwm_studies.uncertainty import bootstrap_from_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
draws, estimates = [], []
for fit, path in zip(snakemake.params.fits, snakemake.input.fits, strict=True):
    est = read_result(path)
    parts = [bootstrap_from_dataset(read_dataset(f), est) for f in snakemake.input.boot
             if f.split("/")[-1].rsplit("_d", 1)[0] == fit]
    label = fit.removeprefix("navchip_")
    draws.append(bootstrap_draw_table(BootstrapResult.combine(parts), label))
    estimates.append(pd.DataFrame([{"fit": label, **dict(zip(est.param_names, est.params,
                                                               strict=True))}]))
for out, frames in ((snakemake.output.draws, draws), (snakemake.output.estimates, estimates)):
    write_text_atomic(out, pd.concat(frames, ignore_index=True).to_csv(
        index=False, float_format=FLOAT_FORMAT))
log.info("wrote %s (%d draws of %d fits)", snakemake.output.draws, sum(map(len, draws)), len(draws))
