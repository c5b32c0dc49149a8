"""STIM-300 study library (gmwm_studies.stim300): fits, units, summaries, storage, figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from gmwm.errors import InputError
from gmwm.model import Model
from gmwm.wv import WaveletVariance
from gmwm_studies import stim300 as ac
from gmwm_studies.montecarlo import simulate_wv_chunk
from gmwm_studies.sensors import stim300_truth

REPO = Path(__file__).resolve().parents[1]
FREQ = 250.0
ESTIMATORS = {
    "gmwm_cf": {"method": "gmwm", "weights": "ci", "n_starts": 1, "reweight": 2},
    "armav": {"method": "armav", "n_starts": 1},
    "armav_ols": {"method": "armav", "weights": "identity", "n_starts": 1},
    "avsm": {"method": "avsm", "min_edof": 2, "slope_tol": 0.1},
}
GYRO, ACCEL = "WN+RW", "QN+WN+RW+DR"


def _theoretical(spec: str, truth: dict, T: int) -> WaveletVariance:
    scales = 2.0 ** np.arange(1, int(np.log2(T)))
    m = Model(spec, freq=FREQ)
    return WaveletVariance.from_table(scales, m.wv(m.theta(truth), scales), n_samples=T, freq=FREQ)


@pytest.fixture(scope="module")
def accel_chunk():
    # quick-profile-like truth (RW, DR raised so they show at T = 2**15)
    truth = dict(stim300_truth("accel"))
    truth["RW[1].gamma2"] *= 1024
    truth["DR[1].omega"] *= 181
    return simulate_wv_chunk(ACCEL, truth, 2**15, range(6), study="t_accel", base_seed=7)


@pytest.fixture(scope="module")
def accel_fits(accel_chunk):
    return ac.fit_chunk_all(accel_chunk, ESTIMATORS, FREQ)


def test_gmwm_and_armav_recover_a_noise_free_wv_exactly():
    truth = stim300_truth("gyro")
    wv = _theoretical(GYRO, truth, 2_500_000)
    theta = Model(GYRO).theta(truth)
    for name in ("gmwm_cf", "armav", "armav_ols"):
        params, se, conv, _, _ = ac.fit_wv(wv, GYRO, ESTIMATORS[name])
        assert conv and np.all(np.isfinite(se))
        np.testing.assert_allclose(params, theta, rtol=1e-6, err_msg=name)
    # AVSM reads N off the -1/2 line: +0.5 % on the noise-free WV (docs/METHODS.md §9.2 / gmwm.avsm docstring)
    params, se, conv, obj, _ = ac.fit_wv(wv, GYRO, ESTIMATORS["avsm"])
    assert conv and np.isnan(obj) and np.all(np.isnan(se))
    n_rel = np.sqrt(params[0] / theta[0]) - 1
    assert 0.0 < n_rel < 0.01


def test_bad_estimator_settings_are_rejected():
    wv = _theoretical(GYRO, stim300_truth("gyro"), 2**16)
    with pytest.raises(InputError, match="unknown method"):
        ac.fit_wv(wv, GYRO, {"method": "mle"})
    with pytest.raises(InputError, match="do not apply"):
        ac.fit_wv(wv, GYRO, {"method": "avsm", "n_starts": 3})


def test_fit_chunk_layout_and_chunk_independence(accel_chunk, accel_fits):
    ds = accel_fits["avsm"]
    assert ds.sizes == {"replicate": 6, "parameter": 4}
    assert list(ds["parameter"].values) == Model(ACCEL).param_names
    assert ds.attrs["method"] == "avsm" and ds.attrs["freq"] == FREQ
    assert all(bool(d["converged"].all()) for d in accel_fits.values())
    # a sub-chunk gives the same rows: fits depend on the replicate only
    sub = simulate_wv_chunk(ACCEL, accel_chunk.truth, 2**15, [3, 4], study="t_accel", base_seed=7)
    part = ac.fit_chunk(sub, ESTIMATORS["armav"], "armav", FREQ)
    np.testing.assert_array_equal(part["estimate"].values,
                                  accel_fits["armav"]["estimate"].sel(replicate=[3, 4]).values)


def test_estimates_file_round_trip(tmp_path, accel_fits):
    path = tmp_path / "T32768_c0.nc"
    ac.write_estimates(path, accel_fits)
    back = ac.read_estimates(path)
    assert list(back) == list(accel_fits)
    for name, ds in accel_fits.items():
        np.testing.assert_array_equal(back[name]["estimate"].values, ds["estimate"].values)
        assert back[name].attrs["estimator"] == name
    assert [p.name for p in tmp_path.iterdir()] == ["T32768_c0.nc"]  # no temporary left
    with pytest.raises(InputError, match="not found"):
        ac.read_estimates(tmp_path / "missing.nc")


def test_table_units_and_summary(accel_fits):
    groups = ac.group_datasets(accel_fits.values())
    # GMWM, ARMAV (both weightings, by estimator name), AVSM order
    assert [k[0] for k in groups] == ["gmwm_cf", "armav", "armav_ols", "avsm"]
    conv = ac.to_table_units(groups[("gmwm_cf", 2**15)], "accel", FREQ)
    assert list(conv["symbol"].values) == ["Q", "N", "K", "R"]
    np.testing.assert_allclose(conv["truth"].values[:2], [1.79e-6, 4.70e-2], rtol=1e-12)
    table = ac.summarize_table_units(groups, "accel", FREQ)
    assert len(table) == 16
    assert list(dict.fromkeys(table["method"])) == ["GMWM", "ARMAV (weighted)", "ARMAV (OLS)",
                                                     "AVSM"]
    assert (table["unit"][table["symbol"] == "R"] == "m/s/h/h").all()
    # RMSE^2 = bias^2 + (n-1)/n SD^2 (exact identity of the sample moments)
    n = table["n_used"]
    np.testing.assert_allclose(table["rmse"] ** 2,
                               table["bias"] ** 2 + (n - 1) / n * table["sd"] ** 2, rtol=1e-9)
    # AVSM reads Q off white-noise scales: about x16 (docs/METHODS.md §9.2). GMWM's relative SD of Q is
    # ~0.9 here, so the MC SE of its relative bias over 6 replicates is ~0.37: |.| < 2 is ~5 SE.
    q = table[table["symbol"] == "Q"].set_index("method")["rel_bias"]
    assert q["AVSM"] > 5 and abs(q["GMWM"]) < 2


def test_cost_summary_projection(accel_fits):
    cost = ac.cost_summary(ac.group_datasets(accel_fits.values()), replicates=3000, cores=2)
    row = cost.iloc[0]
    parts = ["simulate_s", "wv_s", "fit_gmwm_cf_s", "fit_armav_s", "fit_armav_ols_s", "fit_avsm_s"]
    assert row["total_s"] == pytest.approx(sum(row[p] for p in parts))
    assert row["projected_min"] == pytest.approx(row["total_s"] * 3000 / 2 / 60)


def test_figures_have_one_panel_per_parameter(accel_fits):
    groups = ac.group_datasets(accel_fits.values())
    fig1 = ac.figure_boxplots(groups, "accel", FREQ, title="t")
    assert sum(ax.get_visible() for ax in fig1.axes) == 4
    assert fig1.axes[0].get_title() == "Q"
    # one figure legend (estimators + truth) outside the panels, none inside a panel
    assert len(fig1.legends) == 1 and all(ax.get_legend() is None for ax in fig1.axes)
    assert [t.get_text() for t in fig1.legends[0].get_texts()] == [
        "GMWM", "ARMAV (weighted)", "ARMAV (OLS)", "AVSM", "truth"]
    table = ac.summarize_table_units(groups, "accel", FREQ)
    fig2 = ac.figure_rmse(table)
    assert sum(ax.get_visible() for ax in fig2.axes) == 4
    assert {ln.get_label() for ln in fig2.axes[0].lines} == {"GMWM", "ARMAV (weighted)",
                                                             "ARMAV (OLS)", "AVSM"}


def test_full_config_truth_is_table_i():
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    for name, sensor in (("stim300_gyro", "gyroscope"), ("stim300_accel", "accelerometer")):
        s = cfg["studies"][name]
        assert s["sensor"] == sensor and s["n_samples"] == [2500000, 6300000]
        diff = ac.check_table_i_truth(s["model"], s["truth"], sensor, s["freq"])
        assert max(abs(v) for v in diff.values()) < 1e-12, (name, diff)


def test_armav_weightings_are_labelled_and_differ(accel_fits):
    assert accel_fits["armav"].attrs["label"] == "ARMAV (weighted)"
    assert accel_fits["armav_ols"].attrs["label"] == "ARMAV (OLS)"
    assert ac.estimator_label({"method": "armav", "weights": "ci"}) == "ARMAV (weighted)"
    assert ac.estimator_label({"method": "gmwm", "weights": "identity"}) == "GMWM"
    # equal weights on log10 AV are a different estimator on noisy WVs
    a, b = (accel_fits[k]["estimate"].values for k in ("armav", "armav_ols"))
    assert np.max(np.abs(a - b) / np.abs(a).max(axis=0)) > 1e-3


def test_ranking_table_orders_by_rmse():
    import pandas as pd

    table = pd.DataFrame({
        "n_samples": [10] * 3 + [20] * 3, "symbol": ["N"] * 6, "unit": ["u"] * 6,
        "method": ["GMWM", "ARMAV (OLS)", "AVSM"] * 2, "rmse": [1.0, 0.5, 2.0, 1.0, 3.0, 2.0]})
    rk = ac.ranking_table(table)
    assert list(rk["best"]) == ["ARMAV (OLS)", "GMWM"]
    assert rk["ranking"].iloc[1] == "GMWM < AVSM < ARMAV (OLS)"
    assert rk["rmse/GMWM: ARMAV (OLS)"].tolist() == [0.5, 3.0]
