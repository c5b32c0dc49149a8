"""Rule allan_chapter: [AV-chapter] Figs 4.1-4.2, Example 4.2, Lemma 4.2, Sec. 4.2.2 and Remark 4.3
(gmwm_studies.allan_chapter); tables, figures and the key numbers (JSON)."""

from wflog import get_logger  # first: it sets the thread limits before numpy/numba load

from pathlib import Path

import pandas as pd

from gmwm.atomic import save_figure, write_json_atomic, write_text_atomic
from gmwm_studies import allan_chapter as ac
from gmwm_studies.montecarlo import write_table
from gmwm_studies.replicates import FLOAT_FORMAT

snakemake = globals()["snakemake"]  # injected by Snakemake
log = get_logger(snakemake)
p, out = snakemake.params, snakemake.output
folder = Path(out.fig41).parent


def table(df: pd.DataFrame, stem: str, title: str) -> None:
    write_table(df, folder / f"{stem}.csv", folder / f"{stem}.md", title)


def figure(fig, stem: str) -> None:
    log.info("wrote %s", ", ".join(map(str, save_figure(fig, folder / stem, formats=p.formats))))


numbers = {}
adev = {w: ac.adev_study(w, p.n_samples, p.replicates, p.seed) for w in ("fig41", "fig42")}
for w, res in adev.items():
    figure(ac.figure_adev(res), f"{w}_adev")
    numbers[w] = ac.adev_numbers(res)
table(pd.concat([r.summary for r in adev.values()], ignore_index=True), "adev",
      f"Figs 4.1-4.2: readings, slopes and GMWM over {p.replicates} replicates (T = {p.n_samples})")
readings = pd.concat([ac.readings_table(r) for r in adev.values()], ignore_index=True)
table(readings, "readings", "Figs 4.1-4.2: IEEE 952 readings of replicate 0")
numbers["readings"] = readings.to_dict(orient="records")
write_text_atomic(out.replicates_readings, ac.adev_replicates(list(adev.values())).to_csv(
    index=False, float_format=FLOAT_FORMAT))

ma1 = ac.ma1_study(p.ma1_thetas, 1.0, p.ma1_n_samples, p.ma1_replicates, p.seed)
table(ma1, "ma1", f"Example 4.2: AV of an MA(1), sigma2 = 1 ({p.ma1_replicates} replicates, "
      f"T = {p.ma1_n_samples})")
figure(ac.figure_ma1(ma1), "fig_ma1")
numbers["ma1"] = ac.ma1_numbers(ma1) | {"replicates": p.ma1_replicates,
                                        "n_samples": p.ma1_n_samples}

lemma = ac.lemma42_study()
table(lemma, "lemma42", "Lemma 4.2 against the exact AV of ARMA(1,1), sigma2 = 1")
numbers["lemma42"] = ac.lemma42_numbers(lemma)

amb = ac.ambiguity_study(n_samples=p.ambiguity_n_samples, replicates=p.ambiguity_replicates,
                         seed=p.seed)
table(amb.table, "ambiguity", "Sec. 4.2.2: Allan variances of two processes with different spectra")
figure(ac.figure_ambiguity(amb), "fig_ambiguity")
numbers["ambiguity"] = amb.summary

intervals, first = ac.interval_study(p.n_samples, p.replicates, p.seed)
table(intervals, "intervals", f"Remark 4.3: 95 % AV intervals on WN + RW ({p.replicates} "
      f"replicates, T = {p.n_samples})")
figure(ac.figure_intervals(intervals, first), "fig_intervals")
numbers["intervals"] = ac.interval_numbers(intervals)
write_text_atomic(out.replicates_intervals, first["replicates"].to_csv(
    index=False, float_format=FLOAT_FORMAT))
numbers["interval_kinds"] = list(ac.interval_kinds())

write_json_atomic(out.numbers, numbers)
log.info("max rel. diff.: Lemma 4.2 vs spectral %.2e; equal-AV pair (dyadic) %.2e / %.2e",
         numbers["lemma42"]["max_rel_spectral"],
         amb.summary["chapter_2phi2f_max_rel_diff_dyadic"],
         amb.summary["discrete_max_rel_diff_dyadic"])
