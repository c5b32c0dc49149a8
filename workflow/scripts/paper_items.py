"""Rule paper_items: Lemma 1, sample size, Corollary 1, bias ([GMWFM]) and Theorems 1-2 ([SVO])
-> reports/paper_items/paper_items.{json,md} (gmwm_studies.paper_items)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from gmwm_studies.paper_items import compute_items, write_items

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p = snakemake.params
lengths = [int(T) for T in p.lengths]
tables = {k: f"reports/stim300/{name}_bias_sd_rmse.csv" for k, name in p.stim.items()}
replicates = {(p.sensors[k], T): f"reports/{name}/replicates/estimates_T{T}.csv"
              for k, name in p.stim.items() for T in lengths}
items = compute_items(tables, replicates, snakemake.input.coverage, snakemake.input.coefficients,
                      int(p.arrays), lengths)
write_items(items, snakemake.output.json, snakemake.output.md)
log.info("wrote %s and %s", snakemake.output.json, snakemake.output.md)
