"""Rule uncertainty_estimate: the fitted model that the bootstrap and the identifiability checks
use (replicate 0 of a study, or one Navchip axis from the navchip rule's fits file), as a lossless
JSON result (gmwm.codec.write_result; the consumers rebuild it with gmwm.codec.read_result)."""

from wflog import get_logger

from gmwm.codec import write_result
from gmwm_studies.montecarlo import replicate_fit
from gmwm_studies.uncertainty import navchip_result

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
spec = snakemake.params.spec
if spec["source"] == "navchip":
    data, fits = snakemake.input
    res = navchip_result(data, fits, spec["sensor"], spec["axis"])
    if res.diagnostics.get("navchip_refit_differs"):
        log.warning("refit differs from the recorded Navchip estimate; using the recorded one")
else:
    res = replicate_fit(spec["model"], spec["truth"], spec["n_samples"], spec["replicate"],
                        study=spec["study"], base_seed=spec["seed"], settings=spec["settings"],
                        levels=spec["levels"], freq=spec["freq"], simulator=spec["simulator"])
log.info("%s: %s\n%s", snakemake.wildcards.fit, spec, res.summary())
write_result(snakemake.output[0], res)
