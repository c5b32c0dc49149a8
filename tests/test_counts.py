"""Per-replicate tables, named counts and the checker of the counts quoted in REPRODUCTION.md."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from gmwm_studies.counts import (
    Count,
    check_markers,
    draw_counts,
    find_markers,
    quoted_matches,
    read_counts,
    study_counts,
    write_counts,
)
from gmwm_studies.replicates import dataset_table, read_replicates, study_table, write_replicates

REPO = Path(__file__).resolve().parents[1]
NAN = float("nan")
TRUTH = {"WN[1].sigma2": 1.0, "SIN[1].alpha": 1.0, "SIN[1].beta": 0.5,
         "SIN[2].alpha": 0.1, "SIN[2].beta": 0.01}
# J = 10: the ridge starts at period 2 pi / beta > 100 * 2**10, i.e. beta < 6.1e-5
ROWS = [  # replicate, WN, SIN1 alpha, beta, SIN2 alpha, beta, converged, at_boundary, switched
    (0, 1.0, 1.0, 0.5, 0.1, 0.01, 1, "", ""),         # the truth
    (1, 1.1, 1.0, 0.5, 0.25, 0.011, 1, "", ""),       # SIN2 alpha x2.5: miss; |beta rel| 0.1
    (2, 0.0, 1.0, 0.5, 0.1, 0.004, 1, "WN[1].sigma2", ""),  # beta x0.4: miss; 0.6
    (3, 1.0, 1.0, 0.5, 500.0, 1e-7, 1, "", ""),       # ridge, alpha 500: miss; 0.99999
    (4, NAN, NAN, NAN, NAN, NAN, 0, "", "SIN"),       # not converged: counted only there
    (5, 1.0, 1.0, 0.5, 50.0, 2e-6, 1, "", "SIN"),     # ridge, alpha 50, switched: miss; 0.9998
]


def toy_table() -> tuple[pd.DataFrame, dict]:
    cols = ["replicate", *TRUTH, "converged", "at_boundary", "label_switched"]
    df = pd.DataFrame([dict(zip(cols, r, strict=True)) for r in ROWS])
    df.insert(1, "estimator", "gmwm")
    df.insert(2, "T", 4096)
    df.insert(3, "J", 10)
    return df, {"model": "WN+2*SIN", "truth": TRUTH, "T": 4096, "J": 10}


def test_study_counts_hand_checked():
    df, rec = toy_table()
    c = {x.name: x.value for x in study_counts("toy", df, rec, "toy/replicates/estimates.csv")}
    assert c["toy.gmwm.n"] == 6
    assert c["toy.gmwm.not_converged"] == 1
    assert c["toy.gmwm.at_boundary.WN1.sigma2"] == 1
    assert c["toy.gmwm.at_boundary.SIN2.alpha"] == 0
    assert c["toy.gmwm.label_switched"] == 1  # replicate 4 is not converged
    assert c["toy.gmwm.label_switched.SIN"] == 1
    assert "toy.gmwm.label_switched.WN" not in c  # one WN: nothing to switch
    assert c["toy.gmwm.SIN1.factor2_miss"] == 0
    assert c["toy.gmwm.SIN2.factor2_miss"] == 4  # replicates 1, 2, 3, 5
    assert c["toy.gmwm.SIN2.beta_median_abs_rel_err"] == pytest.approx(0.6)
    assert c["toy.gmwm.SIN1.ridge"] == 0
    assert c["toy.gmwm.SIN2.ridge"] == 2
    assert c["toy.gmwm.SIN2.ridge1.replicate"] == 3  # larger alpha first
    assert c["toy.gmwm.SIN2.ridge2.replicate"] == 5
    assert c["toy.gmwm.SIN2.ridge1.alpha_beta"] == pytest.approx(5e-5)
    assert c["toy.gmwm.SIN2.ridge1.period"] == pytest.approx(2 * math.pi / 1e-7)
    assert c["toy.gmwm.SIN2.ridge2.period_over_longest_scale"] == pytest.approx(
        2 * math.pi / 2e-6 / 1024)
    # several sample sizes: T in the names
    assert "toy.T4096.gmwm.n" in {x.name for x in study_counts("toy", df, rec, "x", label_T=True)}


def test_a_sinusoid_the_fitted_model_lacks_has_no_counts():
    """A misspecified model without the true sinusoids (its SIN columns all NaN): no SIN counts
    and no ridge fits (a NaN beta is not an infinite period)."""
    df, rec = toy_table()
    for c in ("SIN[2].alpha", "SIN[2].beta"):
        df[c] = NAN
    names = {x.name for x in study_counts("toy", df, rec, "x")}
    assert "toy.gmwm.SIN1.factor2_miss" in names
    assert not any(n.startswith("toy.gmwm.SIN2.") for n in names), sorted(names)


def test_draw_counts_hand_checked():
    df = pd.DataFrame({"fit": "a", "draw": range(6), "converged": [1, 1, 1, 1, 1, 0],
                       "WN[1].sigma2": [0.0, 1.0, 2.0, 3.0, 4.0, NAN]})
    c = {x.name: x.value for x in draw_counts("nav.a", df, {"WN[1].sigma2": 2.0}, "d.csv")}
    assert c["nav.a.n"] == 6 and c["nav.a.n_failed"] == 1
    assert c["nav.a.WN1.sigma2.q10"] == pytest.approx(0.4)  # numpy linear: 0 + 0.4 * (1 - 0)
    assert c["nav.a.WN1.sigma2.q50"] == pytest.approx(2.0)
    assert c["nav.a.WN1.sigma2.at_boundary"] == 1
    assert c["nav.a.WN1.sigma2.max"] == 4.0


def estimates_dataset() -> xr.Dataset:
    """Five replicates of a WN + RW fit: RW at 0 in replicate 2, replicate 4 not converged."""
    est = np.array([[1.0, 1e-6], [1.1, 2e-6], [0.9, 0.0], [1.0, 1e-6], [NAN, NAN]])
    return xr.Dataset(
        {"estimate": (("replicate", "parameter"), est),
         "converged": ("replicate", np.array([1, 1, 1, 1, 0], dtype=bool)),
         "objective": ("replicate", np.arange(5.0))},
        coords={"replicate": np.arange(5), "parameter": ["WN[1].sigma2", "RW[1].gamma2"],
                "truth": ("parameter", [1.0, 1e-6])},
        attrs={"model": "WN+RW", "n_samples": 1024, "n_levels": 9, "estimator": "gmwm",
               "study": "toy"})


def test_dataset_table_flags_and_round_trip(tmp_path):
    from gmwm_studies.store import write_dataset

    ds = estimates_dataset()
    df = dataset_table(ds)
    assert list(df.columns) == ["replicate", "estimator", "T", "J", "WN[1].sigma2",
                                "RW[1].gamma2", "objective", "converged", "at_boundary"]
    assert df["at_boundary"].tolist() == ["", "", "RW[1].gamma2", "", ""]
    path = tmp_path / "gmwm_T1024.nc"
    write_dataset(ds, path)
    table, rec = study_table("wv_montecarlo", [path])
    assert rec["truth"] == {"WN[1].sigma2": 1.0, "RW[1].gamma2": 1e-6} and rec["J"] == 9
    out = tmp_path / "replicates"
    out.mkdir()
    write_replicates(table, rec, out / "estimates_T1024.csv", out / "truth_T1024.json")
    back, rec2 = read_replicates(out / "estimates_T1024.csv")
    assert rec2 == rec
    assert back["at_boundary"].tolist() == df["at_boundary"].tolist()
    np.testing.assert_array_equal(back["RW[1].gamma2"].to_numpy(), df["RW[1].gamma2"].to_numpy())
    c = {x.name: x.value for x in study_counts("toy", back, rec2, "x")}
    assert c["toy.gmwm.at_boundary.RW1.gamma2"] == 1 and c["toy.gmwm.not_converged"] == 1


def test_dataset_table_names_the_switched_type():
    truth = [0.5, 1.0, 0.05, 0.1]  # SIN[1] (alpha, beta) fast, SIN[2] slow
    est = np.array([truth, [0.1, 0.05, 0.5, 1.0]])  # replicate 1: the two swapped
    ds = xr.Dataset(
        {"estimate": (("replicate", "parameter"), est),
         "converged": ("replicate", np.array([True, True]))},
        coords={"replicate": [0, 1],
                "parameter": ["SIN[1].alpha", "SIN[1].beta", "SIN[2].alpha", "SIN[2].beta"],
                "truth": ("parameter", truth)},
        attrs={"model": "2*SIN", "n_samples": 4096, "estimator": "gmwm"})
    assert dataset_table(ds)["label_switched"].tolist() == ["", "SIN"]


def test_quoted_matches_uses_the_quoted_precision():
    assert quoted_matches("0.112", 0.11234)
    assert not quoted_matches("0.112", 0.1136)
    assert quoted_matches("37", 37) and not quoted_matches("37", 38)
    assert not quoted_matches("37", 370)
    assert quoted_matches("5.1e-13", 5.08e-13) and quoted_matches("1.2e13", 1.23e13)
    assert quoted_matches("1574", 1574.3) and quoted_matches("1290", 1290)
    assert not quoted_matches("1290", 1291)
    assert not quoted_matches("many", 3) and not quoted_matches("3", None)


SAMPLE = """# Status

Sim 2's slow sinusoid misses by a factor 2 in [37](counts.md#sim2.gmwm.SIN2.factor2_miss) /
[80](counts.md#sim2.gmwm_eff.SIN2.factor2_miss) of 500; median
[0.112](counts.md#sim2.gmwm.SIN2.beta_median_abs_rel_err). A plain link
[table](sim2/bias_sd_rmse.md) is no marker; Navchip: [0.43](navchip/counts.md#navchip.gx.q10).
An example in code, `[1](counts.md#no.such.count)`, is no marker either.
"""


def write_sample(root: Path, text: str, navchip: bool = True) -> Path:
    write_counts([Count("sim2.gmwm.SIN2.factor2_miss", 37, "d |x| > 2", "s.csv"),
                  Count("sim2.gmwm_eff.SIN2.factor2_miss", 80, "d", "s.csv"),
                  Count("sim2.gmwm.SIN2.beta_median_abs_rel_err", 0.11234, "d", "s.csv")],
                 root / "counts.json", root / "counts.md")
    if navchip:
        (root / "navchip").mkdir(exist_ok=True)
        write_counts([Count("navchip.gx.q10", 0.4321, "d", "b.csv")],
                     root / "navchip" / "counts.json", root / "navchip" / "counts.md")
    md = root / "REPRODUCTION.md"
    md.write_text(text, encoding="utf-8")
    return md


def test_checker_passes_and_fails(tmp_path):
    md = write_sample(tmp_path, SAMPLE)
    assert [m[3] for m in find_markers(SAMPLE)] == [
        "sim2.gmwm.SIN2.factor2_miss", "sim2.gmwm_eff.SIN2.factor2_miss",
        "sim2.gmwm.SIN2.beta_median_abs_rel_err", "navchip.gx.q10"]
    n, bad = check_markers(md)
    assert n == 4 and bad == []
    assert read_counts(tmp_path / "counts.json")["sim2.gmwm_eff.SIN2.factor2_miss"] == 80
    page = (tmp_path / "counts.md").read_text()
    assert 'id="sim2.gmwm.SIN2.factor2_miss"' in page
    assert all(line.count(" | ") == 3 for line in page.splitlines() if line.startswith("| <a"))
    # a wrong number, an unknown name and a counts file that does not exist all fail
    wrong = SAMPLE.replace("[80]", "[81]").replace("beta_median_abs_rel_err", "nope")
    n, bad = check_markers(write_sample(tmp_path, wrong))
    assert n == 4
    assert [(b.line, b.quote, b.value) for b in bad] == [(4, "81", 80), (5, "0.112", None)]
    n, bad = check_markers(write_sample(tmp_path / "navchip", SAMPLE, navchip=False))
    assert n == 4 and [b.name for b in bad] == ["navchip.gx.q10"]


def test_committed_reproduction_quotes_match_counts():
    """Every count marker of reports/REPRODUCTION.md equals its value in the committed counts.json
    (before a run has committed reports/counts.json there must be no markers: a marker whose
    counts file is missing fails)."""
    md = REPO / "reports" / "REPRODUCTION.md"
    n, bad = check_markers(md)
    if not (REPO / "reports" / "counts.json").is_file():
        assert n == 0, "count markers in REPRODUCTION.md but no reports/counts.json"
    assert bad == [], "\n".join(f"line {b.line}: [{b.quote}] {b.name} = {b.value} ({b.counts_file})"
                                for b in bad)


def test_cell_value_argmax_picks_the_row_where_another_column_peaks(tmp_path):
    from gmwm_studies.counts import cell_value

    f = tmp_path / "s.csv"
    pd.DataFrame({"time_s": [200.0, 210.0, 211.0, 212.9, 214.0],
                  "ratio": [1.3, 1.01, 1.05, 1.09, 1.02]}).to_csv(f, index=False)
    assert cell_value(f, "time_s>=210&col=time_s&argmax=ratio") == 212.9
    assert cell_value(f, "col=time_s&argmax=ratio") == 200.0
    assert cell_value(f, "time_s>=210&col=ratio&argmin=ratio") == 1.01
    with pytest.raises(Exception, match="no column"):
        cell_value(f, "col=time_s&argmax=nope")
