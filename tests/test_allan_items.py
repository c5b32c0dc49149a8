"""The Allan-chapter items added for issue 42: Lemma 4.1 on sampled series, Corollary 4.1,
Lemmas 4.3-4.4 with the Sec. 4.3.3 interval, Sec. 4.1 (AVSM vs GMWM), and the counts the rows
quote from the per-replicate files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.integrate import quad

from gmwm.wv import wvar
from gmwm_studies import allan_chapter as ac


def test_lemma41_continuous_kernel_is_inexact_for_sampled_white_noise():
    t = ac.lemma41_study(levels=6)
    wn = t[t.process == "WN"].reset_index(drop=True)
    # exact AV of unit WN is 1/m; the printed kernel integrated independently by quad at m = 1, 2
    for k, m in enumerate((1, 2)):
        val = quad(lambda f, m=m: 4 * np.sin(np.pi * f * m) ** 4 / (np.pi * f * m) ** 2, 0, 0.5,
                   limit=200)[0]
        assert math.isclose(wn.continuous[k], val, rel_tol=1e-10)
        assert math.isclose(wn.exact[k], 1.0 / m, rel_tol=1e-14)
    assert wn.rel_continuous.iloc[0] < -0.3  # 35 % low at m = 1
    assert np.all(np.diff(np.abs(wn.rel_continuous)) < 0)  # shrinking like 1/m
    assert t.rel_discrete.max() < 1e-10  # the discrete kernel is exact


def test_cor41_additivity_exact_and_simulated():
    t = ac.additivity_study(n_samples=4096, replicates=6, seed=3, levels=8)
    assert t.rel_exact.max() < 1e-12
    assert np.all(np.isfinite(t.z_cross)) and t.replicates.iloc[0] == 6


def test_moav_at_is_twice_the_haar_wv():
    x = np.random.default_rng(5).standard_normal(3000).cumsum() * 0.1 + \
        np.random.default_rng(6).standard_normal(3000)
    wv = wvar(x, 6)
    for j, m in enumerate((1, 2, 4, 8, 16, 32)):
        assert math.isclose(ac.moav_at(x, m).mean(), 2 * wv.variance[j], rel_tol=1e-10)


def test_moav_study_and_printed_interval_is_too_narrow():
    s, per = ac.moav_asymptotics_study((2000,), (1, 16), replicates=8, seed=2)
    assert len(per) == 16 and set(s.m) == {1, 16}
    # the printed half-width sigma_T / T is 2 sqrt(M) / T ~ 2 / sqrt(T) of the consistent one
    ratio = per.half_printed / per.half_lrv
    m = per.m.to_numpy()
    assert np.allclose(ratio, 2 * np.sqrt(2000 - 2 * m + 1) / 2000)


def test_avsm_noise_free_limit_is_off_and_does_not_move_with_T():
    s, per = ac.avsm_consistency_study((4096,), replicates=2, seed=1,
                                       limit_n_samples=(2**20,))
    lim = s[(s.method == "avsm") & (s.parameter == "WN[1].sigma2")].set_index("n_samples")
    assert abs(lim.noise_free_ratio.loc[4096] - lim.noise_free_ratio.loc[2**20]) < 1e-9
    assert lim.noise_free_ratio.loc[2**20] > 1.02  # biased for every T
    assert len(per) == 4 and set(per.method) == {"avsm", "gmwm"}


def test_allan_counts_hand_checked():
    readings = pd.DataFrame({
        "figure": ["fig42"] * 3, "replicate": [0, 1, 2], "N": [10.0, 10.1, 9.0],
        "N_ci_low": [9.9, 10.05, 8.5], "N_ci_high": [10.1, 10.2, 9.5],
        "K": [np.nan, 0.03, 0.05], "K_ci_low": [np.nan, 0.02, 0.04],
        "K_ci_high": [np.nan, 0.04, 0.06]})
    intervals = pd.DataFrame({"replicate": [0, 1, 0, 1], "m": [1, 1, 2, 2],
                              "true_av": [1.0, 1.0, 0.5, 0.5],
                              "g_low": [0.9, -0.1, 0.6, 0.0], "g_high": [1.1, 0.5, 0.7, 0.6]})
    tv = float(ac.model_av("WN+RW", ac.FIG42, 1)[0])
    moav = pd.DataFrame({"replicate": [0, 1], "n_samples": [1000, 1000], "m": [1, 1],
                         "av_hat": [tv + 1.0, tv - 3.0], "half_exact": [2.0, 2.0],
                         "half_lrv": [0.5, 4.0], "half_printed": [0.0, 0.0]})
    c = {x.name: x.value for x in ac.allan_counts(readings, intervals, moav, {
        "readings": "r.csv", "intervals": "i.csv", "moav": "m.csv"})}
    assert c["allan.fig42.n"] == 3
    assert c["allan.fig42.K.n_read"] == 2 and c["allan.fig42.K.missing"] == 1
    assert c["allan.fig42.K.ci_covers"] == 1  # 0.03 in [0.02, 0.04]; 0.05's interval misses
    assert c["allan.fig42.N.ci_covers"] == 1  # only replicate 0 holds 10
    assert c["allan.intervals.n"] == 2
    assert c["allan.intervals.g.m1.low_le_0"] == 1 and c["allan.intervals.g.m1.covered"] == 1
    assert c["allan.intervals.g.m2.low_le_0"] == 1 and c["allan.intervals.g.m2.covered"] == 1
    assert c["allan.moav.T1000.m1.exact.covered"] == 1
    assert c["allan.moav.T1000.m1.lrv.covered"] == 1
    assert c["allan.moav.T1000.m1.printed.covered"] == 0


def test_allan_counts_consistency_hand_checked():
    cons = pd.DataFrame({"replicate": [0, 1, 2, 0], "n_samples": [100] * 4,
                         "method": ["avsm", "avsm", "avsm", "gmwm"],
                         "WN[1].sigma2": [1.005, 1.02, 1.5, 1.0],
                         "RW[1].gamma2": [1e-4, 1.2e-4, 1e-4, 0.5e-4]})
    empty = pd.DataFrame(columns=["figure", "replicate", "n_samples", "m", "av_hat"])
    c = {x.name: x.value for x in ac.allan_counts(
        empty, pd.DataFrame({"replicate": [], "m": [], "true_av": []}), empty,
        {"readings": "r", "intervals": "i", "moav": "m", "consistency": "c"}, cons)}
    assert c["allan.consistency.T100.avsm.WN1.sigma2.n"] == 3
    assert c["allan.consistency.T100.avsm.WN1.sigma2.within1pct"] == 1
    assert c["allan.consistency.T100.avsm.WN1.sigma2.off10pct"] == 1
    assert c["allan.consistency.T100.avsm.RW1.gamma2.off10pct"] == 1
    assert c["allan.consistency.T100.gmwm.RW1.gamma2.within1pct"] == 0


def test_committed_allan_counts_are_recomputed_from_the_committed_replicate_files():
    """reports/allan/counts.json (what the Allan rows quote) follows from the committed
    per-replicate files by the same function the rule allan_counts runs."""
    import pytest

    from gmwm_studies.counts import read_counts

    base = Path(__file__).resolve().parents[1] / "reports" / "allan"
    files = {k: base / "replicates" / f"{k}.csv"
             for k in ("readings", "intervals", "moav", "consistency")}
    if not (base / "counts.json").is_file() or not all(f.is_file() for f in files.values()):
        pytest.skip("no committed Allan counts or replicate files")
    t = {k: pd.read_csv(f) for k, f in files.items()}
    got = {c.name: c.value for c in ac.allan_counts(
        t["readings"], t["intervals"], t["moav"],
        {k: f"replicates/{k}.csv" for k in files}, t["consistency"])}
    assert got == read_counts(base / "counts.json")
