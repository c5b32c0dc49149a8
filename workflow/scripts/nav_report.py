"""Rule nav_report: Fig. 7 (trajectory), Fig. 8 (position error ratio with CI), table of its maximum."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from gmwm.atomic import save_figure, write_text_atomic
from gmwm_studies.montecarlo import write_table
from gmwm_studies.navigation import (
    concat_chunks,
    gnss_schedule,
    iteration_table,
    make_trajectory,
    plot_fig7,
    plot_fig8,
    ratio_series,
    ratio_summary,
)
from gmwm_studies.store import read_dataset

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
nav = snakemake.params.nav
fmt = snakemake.params.formats
out = snakemake.output
parts = [read_dataset(f) for f in snakemake.input]
ds, dropped = concat_chunks(parts)
outage = tuple(nav["outage"])
models = tuple(nav["models"])

traj = make_trajectory(duration=float(nav["duration"]), rate=float(nav["imu_rate"]))
fig7 = plot_fig7(traj, gnss_schedule(traj, float(nav["gnss_rate"]), outage), outage)
save_figure(fig7, Path(out[0]).with_suffix(""), formats=fmt)
fig8 = plot_fig8(ds, outage, models, level=float(nav["level"]))
save_figure(fig8, Path(out[1]).with_suffix(""), formats=fmt)

table = ratio_summary(ds, models, outage, level=float(nav["level"]), seed=int(nav["seed"]))
table.insert(1, "n_dropped", len(dropped))
write_table(table, out.csv, out.md,
            title=(f"Navigation emulation: maximum of the mean position error ratio "
                   f"{models[0]} / {models[1]} (paper: 1.1789 in the outage)"))
series = ratio_series(ds, models, float(nav["level"]))
write_text_atomic(out.series, series.to_csv(index=False, float_format="%.8g"))
per_it = iteration_table(ds, dropped, range(int(nav["iterations"])),
                         float(table["time_s"].iloc[0]), outage)
write_text_atomic(out.iterations, per_it.to_csv(index=False, float_format="%.10g"))
log.info("%d iterations (%d dropped: %s); chunk seconds %s", ds.sizes["iteration"], len(dropped),
         dropped, [round(float(p.attrs.get("seconds", 0)), 1) for p in parts])
log.info("\n%s", table.to_string())
