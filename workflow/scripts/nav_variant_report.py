"""Rule nav_variant_report: Fig. 8 ratio and the table of its maximum for one variant of the
navigation emulation (config navigation.variants.<name>; same functions as nav_report)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies.montecarlo import write_table
from gmwm_studies.navigation import concat_chunks, plot_fig8, ratio_series, ratio_summary
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
nav = snakemake.params.nav  # variant_config(): the main study's config with the overrides
out = snakemake.output
parts = [read_dataset(f) for f in snakemake.input]
ds, dropped = concat_chunks(parts)
outage = tuple(nav["outage"])
models = tuple(nav["models"])
level = float(nav["level"])
axes = "+".join(nav["gyro_axes"])

fig8 = plot_fig8(ds, outage, models, level=level)
fig8.axes[0].set_title(f"variant {nav['variant']} (error model on gyro {axes}): "
                       f"{ds.sizes['iteration']} iterations")
save_figure(fig8, Path(out.fig).with_suffix(""), formats=snakemake.params.formats)

table = ratio_summary(ds, models, outage, level=level, seed=int(nav["seed"]))
table.insert(1, "n_dropped", len(dropped))
# the artifact names what differs from the main study (reports/navigation/ratio_max.csv)
table.insert(0, "gyro_axes", axes)
table.insert(0, "variant", nav["variant"])
write_table(table, out.csv, out.md,
            title=(f"Navigation emulation, variant {nav['variant']}: calibrated error model on "
                   f"gyro {axes} only ({int(nav['iterations'])} iterations; main study: "
                   "reports/navigation/ratio_max.csv). Maximum of the mean position error ratio "
                   f"{models[0]} / {models[1]} (paper: 1.1789 in the outage)"))
write_text_atomic(out.series, ratio_series(ds, models, level).to_csv(index=False,
                                                                       float_format="%.8g"))
log.info("variant %s: %d iterations (%d dropped: %s); chunk seconds %s", nav["variant"],
         ds.sizes["iteration"], len(dropped), dropped,
         [round(float(p.attrs.get("seconds", 0)), 1) for p in parts])
log.info("\n%s", table.to_string())
