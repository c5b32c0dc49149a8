"""Tests for the Simulation 1 study library (gmwm.mle_comparison): runner, chunking, summaries."""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from gmwm.errors import InputError
from gmwm.mle_comparison import (
    COMPARED,
    comparison_table,
    counts_text,
    paired_mask,
    run_chunk,
    run_replicate,
    standardized_by_method,
    study_tables,
    summarize_comparison,
)
from gmwm.studies import gather

MODEL = "WN+RW+AR1+SIN"
TRUTH = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
         "SIN[1].beta": 0.35, "RW[1].gamma2": 4e-4}
GMWM = {"n_starts": 2}
MLE = {"n_starts": 2, "maxiter": 100}
T_TINY = 2048
NAMES = ["WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "SIN[1].alpha", "SIN[1].beta", "RW[1].gamma2"]


def chunk(reps, n_mle, study="t_sim1"):
    return run_chunk(MODEL, TRUTH, T_TINY, reps, study=study, base_seed=11, gmwm_settings=GMWM,
                     mle_settings=MLE, n_mle=n_mle)


@pytest.fixture(scope="module")
def whole():
    return chunk([0, 1, 2], n_mle=2)


def test_runner_records_both_methods_and_the_cap(whole):
    ds = whole
    assert list(ds["estimator"].values) == ["gmwm", "mle"]
    assert list(ds["parameter"].values) == NAMES
    assert ds["truth"].sel(parameter="AR1[1].phi") == 0.975
    assert list(ds["mle_ran"].values) == [True, True, False]
    assert np.isfinite(ds["estimate"].sel(estimator="gmwm").values).all()
    mle = ds["estimate"].sel(estimator="mle")
    # the MLE's frequency is known, not estimated; replicate 2 is beyond the cap
    assert np.isnan(mle.sel(parameter="SIN[1].beta")).all()
    assert np.isnan(mle.sel(replicate=2)).all() and "cap" in str(ds["message"].values[1, 2])
    assert np.isfinite(mle.sel(replicate=[0, 1], parameter=list(COMPARED))).all()
    secs = ds["seconds"].values
    assert (secs[0] > 0).all() and (secs[1, :2] > 0).all() and np.isnan(secs[1, 2])
    assert set(ds["mle_start"].values[:2]) <= {"gmwm", "variogram"}
    assert ds.attrs["n_samples"] == T_TINY and ds.attrs["n_mle"] == 2


def test_estimates_do_not_depend_on_chunking(whole):
    parts = gather([chunk([2], n_mle=2), chunk([0, 1], n_mle=2)])
    for var in ("estimate", "converged", "mle_ran", "mle_start"):
        np.testing.assert_array_equal(parts[var].values, whole[var].values)


def test_replicates_differ_and_depend_on_study_name(whole):
    est = whole["estimate"].sel(estimator="gmwm").values
    assert not np.array_equal(est[0], est[1])
    other = run_replicate(MODEL, TRUTH, T_TINY, 0, "another", 11, GMWM, None)
    assert not np.array_equal(other["gmwm_estimate"], est[0])
    assert not other["mle_ran"] and np.isnan(other["mle_seconds"])


def test_input_errors():
    with pytest.raises(InputError, match="WN \\+ RW \\+ AR1 \\+ one SIN"):
        run_replicate("WN+RW+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1,
                                    "RW[1].gamma2": 1e-4}, 1000, 0, "s", 0, GMWM, None)
    with pytest.raises(InputError, match="unknown MLE setting"):
        run_replicate(MODEL, TRUTH, 1000, 0, "s", 0, GMWM, {"tol": 1.0})
    with pytest.raises(InputError, match="cap"):
        run_chunk(MODEL, TRUTH, 1000, [0], "s", 0, GMWM, MLE, n_mle=-1)


# ---------------------------------------------------------------------------------------------
# summaries on synthetic results (known numbers)


def synthetic(T=1000):
    """5 replicates; the MLE ran on 0..3 and failed on 1; GMWM estimates truth + e, MLE truth + e/2.

    Errors e = (1, 2, -3, 4, -5) x unit per parameter (unit = 1e-3 x truth), so the paired set is
    {0, 2, 3} and every number below can be checked by hand.
    """
    p = len(NAMES)
    truth = np.array([TRUTH[n] for n in NAMES])
    e = np.array([1.0, 2.0, -3.0, 4.0, -5.0])[:, None] * (1e-3 * truth)[None, :]
    est = np.stack([truth + e, truth + e / 2])
    est[1, 4] = np.nan  # not run
    converged = np.array([[True] * 5, [True, False, True, True, False]])
    seconds = np.array([[0.1, 0.1, 0.1, 0.1, 0.3], [1.0, 2.0, 3.0, 2.0, np.nan]])
    return xr.Dataset(
        {
            "estimate": (("estimator", "replicate", "parameter"), est),
            "converged": (("estimator", "replicate"), converged),
            "seconds": (("estimator", "replicate"), seconds),
            "mle_ran": ("replicate", np.array([True, True, True, True, False])),
            "mle_start": ("replicate", np.array(["gmwm", "variogram", "gmwm", "gmwm", ""], object)),
        },
        coords={"estimator": ["gmwm", "mle"], "replicate": np.arange(5), "parameter": NAMES,
                "truth": ("parameter", truth)},
        attrs={"n_samples": T, "study": "syn", "model": MODEL, "estimator": "gmwm+mle"},
    ), p


def test_mle_failures_are_dropped_from_both_and_counted():
    ds, _ = synthetic()
    assert list(paired_mask(ds)) == [True, False, True, True, False]
    s = summarize_comparison(ds)
    assert set(s["set"]) == {"paired", "all"} and len(s) == 3 * len(COMPARED)
    assert (s.n_mle_run == 4).all() and (s.n_mle_not_converged == 1).all()
    for p in COMPARED:
        unit = 1e-3 * TRUTH[p]
        row = s[(s.parameter == p) & (s.set == "paired")].set_index("method")
        assert (row.n_used == 3).all()
        # paired errors (1, -3, 4) unit: RMSE sqrt(26/3) unit for GMWM, half that for the MLE
        np.testing.assert_allclose(row.loc["gmwm", "rmse"], np.sqrt(26 / 3) * unit, rtol=1e-9)
        np.testing.assert_allclose(row.loc["mle", "rmse"], np.sqrt(26 / 3) * unit / 2, rtol=1e-9)
        np.testing.assert_allclose(row.loc["gmwm", "bias"], 2 / 3 * unit, rtol=1e-9)
        # 'all': every replicate but the failed one (1, -3, 4, -5 unit; replicate 4 is beyond the cap)
        alls = s[(s.parameter == p) & (s.set == "all")].iloc[0]
        assert alls.method == "gmwm" and alls.n_used == 4
        np.testing.assert_allclose(alls.rmse, np.sqrt(51 / 4) * unit, rtol=1e-9)
    # times over the replicates where the MLE ran (failed fits cost time too)
    paired = s[s.set == "paired"].set_index("method")
    np.testing.assert_allclose(paired.loc["gmwm", "mean_seconds"].iloc[0], 0.1)
    np.testing.assert_allclose(paired.loc["mle", "mean_seconds"].iloc[0], 2.0)


def test_comparison_table_ratios_and_speedup():
    ds1, _ = synthetic(1000)
    ds2, _ = synthetic(2000)
    long, comp = study_tables([ds2, ds1])
    assert list(comp.n_samples) == [1000, 2000]
    np.testing.assert_allclose(comp.speedup, 20.0)
    for col in ("rmse_ratio_sigma2", "rmse_ratio_phi", "rmse_ratio_ar1_sigma2", "rmse_ratio_gamma2"):
        np.testing.assert_allclose(comp[col], 0.5)
    assert list(comp.mle_not_converged) == [1, 1] and list(comp.n_used) == [3, 3]
    assert comp.mle_winning_start.iloc[0] == "gmwm 3, variogram 1"
    assert comparison_table(long).shape[0] == 2
    text = counts_text(comp, {"n_starts": 2})
    assert "T = 1,000: 1 of 4" in text and "T = 2,000: 4" in text


def test_standardized_boxplot_data_share_the_mle_scale():
    ds, _ = synthetic()
    std = standardized_by_method(ds)
    for p in COMPARED:
        assert len(std["MLE"][p]) == 3
        np.testing.assert_allclose(np.std(std["MLE"][p], ddof=1), 1.0)
        # GMWM errors are twice the MLE's on every replicate, so on the common scale twice as wide
        np.testing.assert_allclose(std["GMWM"][p], 2 * std["MLE"][p])
