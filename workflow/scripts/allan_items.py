"""Rule allan_items: [AV-chapter] Lemma 4.1 on sampled series, Corollary 4.1, Lemmas 4.3-4.4 with
the Sec. 4.3.3 interval, and Sec. 4.1's inconsistency of AV-based estimation
(gmwm_studies.allan_chapter); tables, per-replicate files and the key numbers (JSON)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm.atomic import write_json_atomic, write_text_atomic
from gmwm_studies import allan_chapter as ac
from gmwm_studies.montecarlo import write_table
from gmwm_studies.replicates import FLOAT_FORMAT

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, out = snakemake.params, snakemake.output
folder = Path(out.replicates_moav).parents[1]  # reports/allan


def table(df: pd.DataFrame, stem: str, title: str) -> None:
    write_table(df, folder / f"{stem}.csv", folder / f"{stem}.md", title)


lemma41 = ac.lemma41_study()
table(lemma41, "lemma41", "Lemma 4.1 on sampled series: the continuous-time kernel against the exact "
      "AV (Lemma 4.2) and the discrete kernel (innovation variance 1)")

c = p.cor41
cor41 = ac.additivity_study(int(c["n_samples"]), int(c["replicates"]), p.seed)
table(cor41, "cor41", f"Corollary 4.1: AV of WN + AR1 + RW against the sum of the parts' AVs "
      f"({c['replicates']} replicates, T = {c['n_samples']})")

c = p.moav
moav, moav_reps = ac.moav_asymptotics_study([int(t) for t in c["n_samples"]],
                                            [int(m) for m in c["clusters"]],
                                            int(c["replicates"]), p.seed)
table(moav, "moav", f"Lemmas 4.3-4.4 and the Sec. 4.3.3 interval: the MOAV of the Fig 4.2 model "
      f"as T grows ({c['replicates']} replicates)")
write_text_atomic(out.replicates_moav, moav_reps.to_csv(index=False, float_format=FLOAT_FORMAT))

c = p.consistency
cons, cons_reps = ac.avsm_consistency_study([int(t) for t in c["n_samples"]],
                                            int(c["replicates"]), p.seed,
                                            [int(t) for t in c["limit_n_samples"]])
table(cons, "consistency", f"Sec. 4.1: AVSM and GMWM on WN + RW as T grows ({c['replicates']} "
      "replicates; ratios to the truth)")
write_text_atomic(out.replicates_consistency,
                  cons_reps.to_csv(index=False, float_format=FLOAT_FORMAT))

numbers = ac.items_numbers(lemma41, cor41, moav, cons)
write_json_atomic(out.numbers, numbers)
log.info("Lemma 4.1: WN continuous-kernel rel. diff. at m = 1: %.4f; Cor 4.1 max |z| %.2f",
         numbers["lemma41"]["WN"]["rel_continuous_m1"], numbers["cor41"]["max_abs_z_cross"])
