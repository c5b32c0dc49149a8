"""Per-replicate files of Simulation 1 (per-fit rows with the statsmodels baseline, converged-only
times), the SVO study (per array, per virtual signal, per coverage replication) and the navigation
emulation (per iteration), and the counts computed from them."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from gmwm.errors import InputError
from gmwm_studies.counts import navigation_counts, study_counts, svo_counts
from gmwm_studies.navigation import iteration_table
from gmwm_studies.replicates import SIM1_COLUMNS, read_replicates, study_table, write_replicates
from gmwm_studies.sim1 import comparison_table, summarize_comparison
from gmwm_studies.store import write_dataset
from gmwm_studies.svo_study import (
    METHODS,
    coverage_replicate_table,
    gmwm_table,
    virtual_fit_table,
)

MODEL = "WN+RW+AR1+SIN"
NAMES = ["WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "SIN[1].alpha", "SIN[1].beta",
         "RW[1].gamma2"]
TRUTH = np.array([1.0, 0.975, 0.03, 0.85, 0.35, 4e-4])


def sim1_results(methods, loglike, converged, cpu, messages, ran, T=1000):
    """A gathered Simulation 1 Dataset (sim1._dataset layout) with the given per-fit records."""
    n_m, n_r = loglike.shape
    est = np.tile(TRUTH, (n_m, n_r, 1))
    per_fit = ("estimator", "replicate")
    return xr.Dataset(
        {"estimate": ((*per_fit, "parameter"), est), "se": ((*per_fit, "parameter"), est * 0.1),
         "converged": (per_fit, converged), "ran": (per_fit, ran),
         "seconds": (per_fit, cpu * 1.5), "seconds_se": (per_fit, cpu * 2.0),
         "cpu_seconds": (per_fit, cpu), "cpu_seconds_se": (per_fit, cpu * 1.2),
         "message": (per_fit, np.array(messages, dtype=object)),
         "start": (per_fit, np.full((n_m, n_r), "", dtype=object)),
         "loglike": (per_fit, loglike),
         "mle_ran": ("replicate", ran[1])},
        coords={"estimator": np.array(methods, dtype=object), "replicate": np.arange(n_r),
                "parameter": np.array(NAMES, dtype=object), "truth": ("parameter", TRUTH)},
        attrs={"study": "syn", "model": MODEL, "n_samples": T, "base_seed": 1,
               "estimator": "+".join(methods), "variants": json.dumps({"mle": "moment"}),
               "wrong_optimum_ll": 1.0, "mle_settings": json.dumps({"maxiter": 200})},
    )


def three_replicates():
    """GMWM on 0..2; 'mle' on 0..2: converged, not converged (capped), wrong optimum (ll 5 below
    the best: the GMWM start variant is not needed, the best is its own on 0 and 1 and
    statsmodels' on 2); 'statsmodels' on 0 and 2 only."""
    methods = ["gmwm", "mle", "statsmodels"]
    loglike = np.array([[np.nan] * 3, [-10.0, -11.0, -15.0], [-10.2, np.nan, -10.0]])
    converged = np.array([[True] * 3, [True, False, True], [True, False, False]])
    ran = np.array([[True] * 3, [True] * 3, [True, False, True]])
    cpu = np.array([[0.1, 0.2, 0.3], [1.0, 4.0, 2.0], [10.0, np.nan, 30.0]])
    msgs = [[""] * 3,
            ["4 BFGS iterations; gradient < tol", "200+3 BFGS iterations; capped",
             "7 BFGS iterations; gradient < tol"],
            ["converged (statsmodels lbfgs, 13 iterations)", "not run",
             "not converged (statsmodels lbfgs, 50 iterations)"]]
    return sim1_results(methods, loglike, converged, cpu, msgs, ran)


def test_sim1_per_fit_rows_and_their_counts(tmp_path):
    ds = three_replicates()
    path = tmp_path / "all.nc"
    write_dataset(ds, path)
    df, rec = study_table("mle_comparison", [path])
    # rows only where a method ran; statsmodels' are in the table
    assert df.groupby("estimator").size().to_dict() == {"gmwm": 3, "mle": 3, "statsmodels": 2}
    assert set(SIM1_COLUMNS) <= set(df.columns)
    mle = df[df.estimator == "mle"].set_index("replicate")
    assert mle["wrong_optimum"].tolist() == [0, 0, 1]
    assert mle["iterations"].tolist() == [4, 203, 7]
    np.testing.assert_allclose(mle["objective"], -mle["loglike"])
    sm = df[df.estimator == "statsmodels"].set_index("replicate")
    assert sm["iterations"].tolist() == [13, 50] and sm["converged"].tolist() == [1, 0]
    assert df[df.estimator == "gmwm"]["iterations"].isna().all()
    write_replicates(df, rec, tmp_path / "estimates_T1000.csv", tmp_path / "truth_T1000.json")
    back, rec2 = read_replicates(tmp_path / "estimates_T1000.csv")
    counts = {c.name: c.value for c in study_counts("sim1", back, rec2, "x.csv")}
    assert counts["sim1.mle.wrong_optimum"] == 1 and counts["sim1.mle.n_ok"] == 1
    assert counts["sim1.mle.not_converged"] == 1
    assert counts["sim1.mle.mean_cpu_seconds"] == pytest.approx(7.0 / 3)
    assert counts["sim1.mle.mean_cpu_seconds_conv"] == pytest.approx(1.0)
    assert counts["sim1.mle.iterations_max"] == 203
    assert counts["sim1.statsmodels.mean_cpu_seconds"] == pytest.approx(20.0)
    assert counts["sim1.statsmodels.mean_cpu_seconds_conv"] == pytest.approx(10.0)
    assert counts["sim1.statsmodels.n"] == 2 and counts["sim1.statsmodels.not_converged"] == 1


def test_sim1_converged_only_times_beside_all_attempt_times():
    ds = three_replicates()
    ds.attrs["variants"] = json.dumps({"mle": "moment", "statsmodels": "statsmodels"})
    comp = comparison_table(summarize_comparison(ds)).set_index("variant")
    # 'mle': all attempts (1 + 4 + 2) / 3; converged only: replicate 0 (1.0); GMWM on the same
    assert comp.loc["mle", "mle_cpu_mean_s"] == pytest.approx(7.0 / 3)
    assert comp.loc["mle", "mle_cpu_mean_s_conv"] == pytest.approx(1.0)
    assert comp.loc["mle", "gmwm_cpu_mean_s_conv"] == pytest.approx(0.1)
    assert comp.loc["mle", "speedup_cpu_mean_conv"] == pytest.approx(10.0)
    assert comp.loc["mle", "mle_mean_s_conv"] == pytest.approx(1.5)
    # statsmodels: attempted on 0 and 2 (mean 20), converged to the best optimum on 0 only
    assert comp.loc["statsmodels", "mle_cpu_mean_s"] == pytest.approx(20.0)
    assert comp.loc["statsmodels", "mle_cpu_mean_s_conv"] == pytest.approx(10.0)
    assert comp.loc["statsmodels", "n_used"] == 1


def svo_results(R=3, n_test=2, p=6, seed=3):
    rng = np.random.default_rng(seed)
    return {"replicates": np.arange(10, 10 + R), "coef": rng.dirichlet(np.ones(p), (R, 4)),
            "gmwm": rng.gamma(2.0, 1.0, (R, n_test, len(METHODS), 2))}


def test_svo_virtual_fits_recount_the_share_lowest():
    res = svo_results()
    fits = pd.DataFrame(virtual_fit_table(res))
    assert len(fits) == 3 * 2 * len(METHODS)
    cov = {"replicates": np.arange(5), "coef": np.full((5, 6), 0.2), "se": np.full((1, 5, 6), 0.01),
           "hit": np.zeros((1, 5, 6), dtype=bool), "schemes": np.array(["paper"])}
    cov["hit"][0, :3, 0] = True  # gyro 1 covered in 3 of 5, the others never
    rows = pd.DataFrame(coverage_replicate_table(cov, 0.05))
    assert len(rows) == 30
    np.testing.assert_allclose(rows["ci_high"] - rows["ci_low"], 2 * 1.959964 * 0.01, rtol=1e-6)
    counts = {c.name: c.value for c in svo_counts("case1", fits, rows,
                                                  {"fits": "f.csv", "coverage": "c.csv"})}
    table = pd.DataFrame(gmwm_table(res)).set_index(["method", "parameter"])
    for m in METHODS:
        for prm in ("sigma2", "gamma2"):
            assert counts[f"svo.case1.{m}.{prm}.lowest"] / 6 == pytest.approx(
                table.loc[(m, prm), "share_lowest"])
            assert counts[f"svo.case1.{m}.{prm}.lowest_pct"] == pytest.approx(
                100 * table.loc[(m, prm), "share_lowest"])
    assert counts["svo.case1.n_signals"] == 6
    assert counts["svo.case1.coverage.paper.n"] == 5
    assert counts["svo.case1.coverage.paper.gyro1.covered"] == 3
    assert counts["svo.case1.coverage.paper.max"] == pytest.approx(0.6)
    assert counts["svo.case1.coverage.paper.min"] == 0.0


def nav_results():
    """Iterations 0, 2, 3 emulated (1 dropped); errors at 3 epochs, model1 = 1.2 x model2 at
    170 s."""
    e2 = np.array([[1.0, 2.0, 3.0], [1.0, 4.0, 2.0], [2.0, 6.0, 1.0]])
    e1 = e2 * np.array([1.0, 1.2, 1.0])
    fp = np.tile([0.9, 1e-6, 1e-9], (3, 2, 1))
    return xr.Dataset(
        {"pos_err_norm": (("iteration", "model", "time"), np.stack([e1, e2], axis=1)),
         "filter_params": (("iteration", "model", "parameter"), fp)},
        coords={"iteration": [0, 2, 3], "model": np.array(["model1", "model2"], dtype=object),
                "time": [100.0, 170.0, 220.0],
                "parameter": ["AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2"]})


def test_navigation_iteration_rows_and_counts():
    ds = nav_results()
    df = iteration_table(ds, {1: "model1 fit did not converge"}, range(4), 170.0)
    assert len(df) == 8 and df.groupby("iteration")["dropped"].max().tolist() == [0, 1, 0, 0]
    drop = df[df.iteration == 1]
    assert drop["reason"].eq("model1 fit did not converge").all()
    assert drop["err_at_peak_m"].isna().all()
    kept = df[(df.iteration == 2) & (df.model == "model2")].iloc[0]
    assert kept["err_at_peak_m"] == 4.0 and kept["max_err_m"] == 4.0
    assert kept["mean_err_outage_m"] == 4.0  # the outage 160-210 s holds the 170 s epoch only
    counts = {c.name: c.value for c in navigation_counts(df, "it.csv", ["model1", "model2"])}
    assert counts["navigation.n_iterations"] == 4 and counts["navigation.n_dropped"] == 1
    assert counts["navigation.n_used"] == 3
    assert counts["navigation.ratio_at_peak"] == pytest.approx(1.2)
    with pytest.raises(InputError, match="neither"):
        iteration_table(ds, {}, range(4), 170.0)
