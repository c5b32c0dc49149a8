"""gmwm_studies.lemmas000: paper 000's Lemma 1 / Lemma 2 / Remark A checks on small inputs."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gmwm_studies import lemmas000 as L


def test_lemma1_exact_matches_closed_form_and_filter():
    df = L.lemma1_exact({"a": (0.85, 0.35), "slow": (0.0015, 8e-6)}, levels=12, filter_levels=10)
    assert df["rel_err_closed_form"].max() < 1e-13
    assert df["rel_err_filter"].dropna().max() < 1e-10
    assert df["filter"].isna().sum() == 2 * 2  # levels 11-12 of both cases: not summed


def test_lemma1_rate_bound_and_slope():
    detail, slopes = L.lemma1_rate({"a": (0.85, 0.35)}, [8, 9, 10, 11], levels=3, replicates=64,
                                   seed=1, n_boot=50)
    # the deterministic bound |nu_hat - nu| <= nu / (M |sin beta|) holds for every phase
    assert detail["max_err_over_bound"].max() <= 1 + 1e-9
    # the error is O(1/M): the normalized slope is -T/M ~ -1
    assert np.allclose(slopes["slope_normalized"], -1, atol=0.1)
    assert (slopes["slope_normalized_ci_low"] <= slopes["slope_normalized_ci_high"]).all()


def test_lemma1_rate_rejects_too_many_levels():
    with pytest.raises(Exception, match="levels"):
        L.lemma1_rate({"a": (0.85, 0.35)}, [5, 6], levels=6, replicates=2, seed=1)


def test_lemma2_jacobian_rank_drops_on_the_ridge():
    df = L.lemma2_jacobian("SIN", {"truth": {"SIN[1].alpha": 0.0015, "SIN[1].beta": 8e-6},
                                   "ridge": {"SIN[1].alpha": 1574.0, "SIN[1].beta": 5e-13}}, 22)
    v = df.set_index(["point", "quantity"])["value"]
    assert v["truth", "rank"] == 2
    assert v["truth", "SIN[1].cos_alpha_beta"] < 0.5
    assert v["ridge", "rank"] == 1  # only alpha * beta acts on the WV
    assert v["ridge", "SIN[1].cos_alpha_beta"] > 1 - 1e-12


def _table(rng: np.random.Generator, n: int = 200) -> tuple[pd.DataFrame, dict[str, float]]:
    truth = {"X": 1.0, "SIN[1].alpha": 1.0, "SIN[1].beta": 0.1}
    rows = []
    for est, sd in (("a", 0.2), ("b", 0.1)):
        for r in range(n):
            rows.append({"replicate": r, "estimator": est, "converged": 1,
                         "X": 1 + sd * rng.standard_normal(),
                         "SIN[1].alpha": 1 + 0.01 * rng.standard_normal(),
                         "SIN[1].beta": (0.1 + 1e-3 * rng.standard_normal()
                                         if (est == "a" or r >= 5) else 1e-9)})
    return pd.DataFrame(rows), truth


def test_efficiency_ratios_and_misses():
    df, truth = _table(np.random.default_rng(3))
    e = L.efficiency(df, truth, "a", "b", seed=1, n_boot=200).set_index("parameter")
    assert 0.4 < e.loc["X", "sd_ratio"] < 0.6  # b has half a's SD
    assert e.loc["X", "sd_ratio_ci_low"] < e.loc["X", "sd_ratio"] < e.loc["X", "sd_ratio_ci_high"]
    assert e.loc["SIN[1] (alpha or beta)", "factor2_b"] == 5
    assert e.loc["SIN[1] (alpha or beta)", "factor2_a"] == 0
    assert e.loc["X", "n_no_miss"] == 195


def test_sd_gap_bootstrap_reference_is_zero_and_gap_sign():
    df, _ = _table(np.random.default_rng(4))
    df["Y"] = df["X"] * 2
    g = L.sd_gap_bootstrap(df, ["X", "Y"], "a", "b", "X", seed=1, n_boot=200).set_index("parameter")
    assert g.loc["X", "gap_pct"] > 30  # SD halved: a gap near 50 %
    assert g.loc["Y", "diff_vs_reference_pp"] == pytest.approx(0, abs=1e-9)  # same ratio
    assert g.loc["X", "diff_ci_low"] == g.loc["X", "diff_ci_high"] == 0


def test_ridge_rows_selects_long_periods():
    df, _ = _table(np.random.default_rng(5), n=20)
    r = L.ridge_rows(df, J=10, estimators=["a", "b"])
    assert sorted(r["replicate"]) == [0, 1, 2, 3, 4]
    assert set(r["estimator"]) == {"b"} and set(r["sin"]) == {1}


@pytest.mark.slow  # a real simulation and GMWM fit (~3 s with the JIT loads)
def test_ridge_study_refits_and_flags_a_table_it_does_not_reproduce():
    truth = {"WN[1].sigma2": 1.0, "SIN[1].alpha": 0.5, "SIN[1].beta": 0.3}
    table = pd.DataFrame([{"replicate": 3, "estimator": "g", "converged": 1, "WN[1].sigma2": 1.0,
                           "SIN[1].alpha": 1e3, "SIN[1].beta": 1e-9, "objective": 1.0}])
    record = {"truth": truth, "J": 10, "T": 4096, "model": "WN+SIN"}
    settings = {"g": {"method": "gmwm", "weights": "ci-eta3", "n_starts": 1, "reweight": 0}}
    betas = np.array([1e-12, 1e-10])
    prof, points = L.ridge_study(table, record, settings, "t", 7, "fast", betas, max_fits=1)
    assert list(prof.columns) == L.RIDGE_COLUMNS
    assert list(prof["point"]) == ["ridge", "ridge", "fit", "truth_sin", "truth"]
    assert not prof["matches_table"].any()  # the table's objective 1.0 is not the refit's
    fit = prof[prof["point"] == "fit"].iloc[0]
    assert fit["rel_increase"] == 0 and fit["objective"] == pytest.approx(fit["refit_objective"])
    assert list(points) == ["rep3_g"]
