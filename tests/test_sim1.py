"""Tests for the Simulation 1 study library (gmwm_studies.sim1): runner, chunking, summaries."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import xarray as xr

from gmwm.errors import InputError
from gmwm_studies.mle import fit_mle, fit_statsmodels, kalman_loglike, mle_covariance
from gmwm_studies.montecarlo import gather
from gmwm_studies.sim1 import (
    BASELINE,
    COMPARED,
    add_baseline,
    comparison_table,
    counts_text,
    gmwm_text,
    paired_mask,
    run_baseline_chunk,
    run_chunk,
    run_replicate,
    standardized_by_method,
    study_tables,
    summarize_comparison,
    variant_replicate_caps,
    wrong_optimum,
)

MODEL = "WN+RW+AR1+SIN"
TRUTH = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.975, "AR1[1].sigma2": 0.03, "SIN[1].alpha": 0.85,
         "SIN[1].beta": 0.35, "RW[1].gamma2": 4e-4}
GMWM = {"n_starts": 2}
VARIANTS = {"mle": "moment", "mle_default": "default", "mle_gmwm": "gmwm"}
MLE = {"maxiter": 100, "variants": VARIANTS}
T_TINY = 2048
NAMES = ["WN[1].sigma2", "AR1[1].phi", "AR1[1].sigma2", "SIN[1].alpha", "SIN[1].beta", "RW[1].gamma2"]


def chunk(reps, n_mle, study="t_sim1"):
    return run_chunk(MODEL, TRUTH, T_TINY, reps, study=study, base_seed=11, gmwm_settings=GMWM,
                     mle_settings=MLE, n_mle=n_mle)


@pytest.fixture(scope="module")
def whole():
    return chunk([0, 1, 2], n_mle=2)


def test_runner_records_every_method_and_the_cap(whole):
    ds = whole
    assert list(ds["estimator"].values) == ["gmwm", *VARIANTS]
    assert json.loads(ds.attrs["variants"]) == VARIANTS
    assert list(ds["parameter"].values) == NAMES
    assert ds["truth"].sel(parameter="AR1[1].phi") == 0.975
    assert list(ds["mle_ran"].values) == [True, True, False]
    assert np.isfinite(ds["estimate"].sel(estimator="gmwm").values).all()
    for v in VARIANTS:
        mle = ds["estimate"].sel(estimator=v)
        # the MLE's frequency is known, not estimated; replicate 2 is beyond the cap
        assert np.isnan(mle.sel(parameter="SIN[1].beta")).all()
        assert np.isnan(mle.sel(replicate=2)).all()
        assert "cap" in str(ds["message"].sel(estimator=v, replicate=2).values)
        assert np.isfinite(mle.sel(replicate=[0, 1], parameter=list(COMPARED))).all()
        assert np.isfinite(ds["loglike"].sel(estimator=v, replicate=[0, 1])).all()
    secs = ds["seconds"].values
    assert (secs[0] > 0).all() and (secs[1:, :2] > 0).all() and np.isnan(secs[1:, 2]).all()
    starts = ds["start"].sel(replicate=0).values
    assert list(starts) == ["", "variogram", "default", "gmwm"]
    assert ds.attrs["n_samples"] == T_TINY and ds.attrs["n_mle"] == 2
    assert ds["ran"].sel(estimator="gmwm").values.all()
    assert (ds["ran"].sel(estimator="mle").values == ds["mle_ran"].values).all()


def test_two_clocks_point_estimate_and_with_standard_errors(whole):
    ds = whole
    point, full = ds["seconds"].values, ds["seconds_se"].values
    ran = ds["ran"].values
    assert (point[ran] > 0).all() and np.isnan(point[~ran]).all()
    # the SEs come on top of the point estimate, for every method (GMWM: the whole fit call)
    assert (full[ran] >= point[ran]).all()
    cpu, cpu_full = ds["cpu_seconds"].values, ds["cpu_seconds_se"].values
    assert (cpu[ran] > 0).all() and (cpu_full[ran] >= cpu[ran]).all()
    assert np.isnan(cpu[~ran]).all()
    # the GMWM's point-estimate CPU time is its call's split like the wall clock
    g = ds.sel(estimator="gmwm")
    np.testing.assert_allclose(g["cpu_seconds"] / g["cpu_seconds_se"],
                               g["seconds"] / g["seconds_se"], rtol=1e-12)
    se = ds["se"].sel(parameter=list(COMPARED))
    # (the weakly identified RW may sit at the boundary at this T, and then has no SE)
    assert np.isfinite(se.sel(estimator="gmwm", parameter=list(COMPARED[:3]))).all()
    for v in VARIANTS:
        conv = ds["converged"].sel(estimator=v).values & ds["mle_ran"].values
        assert (se.sel(estimator=v).values[conv] > 0).all()
        assert np.isnan(se.sel(estimator=v, replicate=2)).all()


def test_estimates_do_not_depend_on_chunking(whole):
    parts = gather([chunk([2], n_mle=2), chunk([0, 1], n_mle=2)])
    for var in ("estimate", "se", "converged", "ran", "mle_ran", "start", "loglike"):
        np.testing.assert_array_equal(parts[var].values, whole[var].values)


def test_replicates_differ_and_depend_on_study_name(whole):
    est = whole["estimate"].sel(estimator="gmwm").values
    assert not np.array_equal(est[0], est[1])
    other = run_replicate(MODEL, TRUTH, T_TINY, 0, "another", 11, GMWM, None)
    assert not np.array_equal(other["fits"]["gmwm"]["estimate"], est[0])
    assert not other["mle_ran"] and list(other["fits"]) == ["gmwm"]


def test_input_errors():
    with pytest.raises(InputError, match="WN \\+ RW \\+ AR1 \\+ one SIN"):
        run_replicate("WN+RW+AR1", {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.1,
                                    "RW[1].gamma2": 1e-4}, 1000, 0, "s", 0, GMWM, None)
    with pytest.raises(InputError, match="unknown MLE setting"):
        run_replicate(MODEL, TRUTH, 1000, 0, "s", 0, GMWM, {"tol": 1.0})
    with pytest.raises(InputError, match="start rule"):
        run_replicate(MODEL, TRUTH, 1000, 0, "s", 0, GMWM, {"variants": {"m": "truth"}})
    with pytest.raises(InputError, match="cap"):
        run_chunk(MODEL, TRUTH, 1000, [0], "s", 0, GMWM, MLE, n_mle=-1)


def test_variant_cap_runs_the_variant_on_its_first_replicates_only(whole):
    capped = run_chunk(MODEL, TRUTH, T_TINY, [0, 1, 2], study="t_sim1", base_seed=11,
                       gmwm_settings=GMWM, mle_settings=MLE, n_mle=2,
                       variant_replicates={"mle_default": 1})
    ran = capped["ran"].sel(estimator="mle_default").values
    assert list(ran) == [True, False, False]
    assert "variant's replicate cap" in str(capped["message"].sel(estimator="mle_default",
                                                                  replicate=1).values)
    assert np.isnan(capped["loglike"].sel(estimator="mle_default", replicate=1))
    # the headline, the GMWM-started MLE and the GMWM: the same fits, every replicate
    same = ["gmwm", "mle", "mle_gmwm"]
    for var in ("estimate", "se", "converged", "ran", "loglike", "start"):
        np.testing.assert_array_equal(capped[var].sel(estimator=same).values,
                                      whole[var].sel(estimator=same).values)
    # and the same numbers in the tables (times aside: clocks differ run to run); the capped
    # variant is counted over the replicates where it ran
    _, comp_whole = study_tables([whole])
    _, comp_capped = study_tables([capped])
    clocks = [c for c in comp_whole if "mean_s" in c or "median_s" in c or "speedup" in c]
    keep = comp_whole.variant.isin(["mle", "mle_gmwm"])
    pd.testing.assert_frame_equal(comp_capped[keep].drop(columns=clocks),
                                  comp_whole[keep].drop(columns=clocks))
    row = comp_capped[comp_capped.variant == "mle_default"].iloc[0]
    assert row.n_mle == 1 and row.n_used <= 1 and row.not_converged + row.wrong_optimum <= 1
    long_whole = summarize_comparison(whole)
    long_capped = summarize_comparison(capped)
    cols = ["set", "variant", "method", "parameter", "n_used", "mean", "rmse", "mean_se"]
    sel = long_whole.variant.isin(["", "mle", "mle_gmwm"])
    pd.testing.assert_frame_equal(long_capped[sel][cols], long_whole[sel][cols])
    text = counts_text(comp_capped, MLE)
    assert "[mle_default], fitted on the first replicates only (its own cost cap" in text
    assert f"mle.variant_replicates): T = {T_TINY:,}: 1;" in text
    assert "fitted on the first replicates only (its own" not in counts_text(comp_whole, MLE)


def test_variant_cap_checks():
    caps = {10000: 500, 20000: 400}
    variants = ["mle", "mle_sm", "mle_gmwm"]
    assert variant_replicate_caps({"mle_sm": 100}, variants, caps) == {
        "mle_sm": {10000: 100, 20000: 100}}
    assert variant_replicate_caps({"mle_sm": [100, 50]}, variants, caps) == {
        "mle_sm": {10000: 100, 20000: 50}}
    assert variant_replicate_caps(None, variants, caps) == {}
    with pytest.raises(InputError, match=r"MLE cap \(400\) at T = 20000"):
        variant_replicate_caps({"mle_sm": 450}, variants, caps)
    with pytest.raises(InputError, match="headline"):
        variant_replicate_caps({"mle": 100}, variants, caps)
    with pytest.raises(InputError, match="not one of mle.variants"):
        variant_replicate_caps({"mle_x": 100}, variants, caps)
    with pytest.raises(InputError, match="2 sample sizes"):
        variant_replicate_caps({"mle_sm": [1, 2, 3]}, variants, caps)
    # the runner refuses the same, per chunk
    for bad, match in (({"mle": 1}, "headline"), ({"mle_x": 1}, "not an MLE variant"),
                       ({"mle_default": 3}, "between 0 and the MLE cap")):
        with pytest.raises(InputError, match=match):
            run_chunk(MODEL, TRUTH, 1000, [0], "s", 0, GMWM, MLE, n_mle=2,
                      variant_replicates=bad)


# ---------------------------------------------------------------------------------------------
# summaries on synthetic results (known numbers)


def synthetic(T=1000):
    """5 replicates, variants 'mle' (own start) and 'mle_gmwm'; the MLEs ran on 0..3.

    'mle' failed to converge on 1 and stopped at a wrong optimum on 3 (log-likelihood 5 below
    'mle_gmwm', tolerance 1); 'mle_gmwm' converged on 0..3. GMWM estimates truth + e, MLEs
    truth + e/2, with e = (1, 2, -3, 4, -5) x unit per parameter (unit = 1e-3 x truth), so the
    paired sets are {0, 2} ('mle') and {0, 1, 2, 3} ('mle_gmwm').
    """
    truth = np.array([TRUTH[n] for n in NAMES])
    e = np.array([1.0, 2.0, -3.0, 4.0, -5.0])[:, None] * (1e-3 * truth)[None, :]
    est = np.stack([truth + e, truth + e / 2, truth + e / 2])
    est[1:, 4] = np.nan  # not run
    converged = np.array([[True] * 5, [True, False, True, True, False],
                          [True, True, True, True, False]])
    seconds = np.array([[0.1, 0.1, 0.1, 0.1, 0.3], [1.0, 2.0, 3.0, 2.0, np.nan],
                        [0.5, 0.5, 0.5, 1.5, np.nan]])
    loglike = np.array([[np.nan] * 5, [-10.0, -12.0, -10.0, -15.0, np.nan],
                        [-10.0, -10.5, -10.0, -10.0, np.nan]])
    return xr.Dataset(
        {
            "estimate": (("estimator", "replicate", "parameter"), est),
            "converged": (("estimator", "replicate"), converged),
            "seconds": (("estimator", "replicate"), seconds),
            "loglike": (("estimator", "replicate"), loglike),
            "mle_ran": ("replicate", np.array([True, True, True, True, False])),
        },
        coords={"estimator": ["gmwm", "mle", "mle_gmwm"], "replicate": np.arange(5),
                "parameter": NAMES, "truth": ("parameter", truth)},
        attrs={"n_samples": T, "study": "syn", "model": MODEL, "estimator": "gmwm+mle+mle_gmwm",
               "variants": json.dumps({"mle": "moment", "mle_gmwm": "gmwm"}),
               "wrong_optimum_ll": 1.0},
    )


def test_failures_and_wrong_optima_are_dropped_from_both_and_counted():
    ds = synthetic()
    wrong = wrong_optimum(ds)
    assert list(wrong.sel(estimator="mle").values) == [False, False, False, True, False]
    # a failed fit is not also a wrong optimum, the GMWM never is, and 0.5 < tolerance is a tie
    assert not wrong.sel(estimator=["gmwm", "mle_gmwm"]).values.any()
    assert list(paired_mask(ds)) == [True, False, True, False, False]
    assert list(paired_mask(ds, "mle_gmwm")) == [True, True, True, True, False]
    s = summarize_comparison(ds)
    assert len(s) == (2 * 2 + 1) * len(COMPARED)
    for p in COMPARED:
        unit = 1e-3 * TRUTH[p]
        row = s[(s.parameter == p) & (s.set == "paired") & (s.variant == "mle")].set_index("method")
        assert (row.n_used == 2).all()
        assert (row.n_not_converged == 1).all() and (row.n_wrong_optimum == 1).all()
        # paired errors (1, -3) unit: RMSE sqrt(5) unit for GMWM, half that for the MLE
        np.testing.assert_allclose(row.loc["gmwm", "rmse"], np.sqrt(5) * unit, rtol=1e-9)
        np.testing.assert_allclose(row.loc["mle", "rmse"], np.sqrt(5) * unit / 2, rtol=1e-9)
        np.testing.assert_allclose(row.loc["gmwm", "bias"], -unit, rtol=1e-9)
        warm = s[(s.parameter == p) & (s.variant == "mle_gmwm")].set_index("method")
        assert (warm.n_used == 4).all() and (warm.n_not_converged == 0).all()
        np.testing.assert_allclose(warm.loc["gmwm", "rmse"], np.sqrt(30 / 4) * unit, rtol=1e-9)
        # 'all': every replicate with a converged GMWM fit (1, 2, -3, 4, -5 unit)
        alls = s[(s.parameter == p) & (s.set == "all")].iloc[0]
        assert alls.method == "gmwm" and alls.n_used == 5
        np.testing.assert_allclose(alls.rmse, np.sqrt(55 / 5) * unit, rtol=1e-9)
    # times over the replicates where the MLE ran (failed fits cost time too)
    own = s[(s.set == "paired") & (s.variant == "mle")].set_index("method")
    np.testing.assert_allclose(own.loc["gmwm", "mean_seconds"].iloc[0], 0.1)
    np.testing.assert_allclose(own.loc["mle", "mean_seconds"].iloc[0], 2.0)
    np.testing.assert_allclose(own.loc["mle", "median_seconds"].iloc[0], 2.0)
    warm = s[(s.set == "paired") & (s.variant == "mle_gmwm")].set_index("method")
    np.testing.assert_allclose(warm.loc["mle_gmwm", "mean_seconds"].iloc[0], 0.75)
    np.testing.assert_allclose(warm.loc["mle_gmwm", "median_seconds"].iloc[0], 0.5)


def test_comparison_table_ratios_and_speedups():
    long, comp = study_tables([synthetic(2000), synthetic(1000)])
    assert list(comp.n_samples) == [1000, 1000, 2000, 2000]
    assert list(comp.variant) == ["mle", "mle_gmwm"] * 2
    own, warm = comp.iloc[0], comp.iloc[1]
    assert own.speedup_mean == pytest.approx(20.0) and own.speedup_median == pytest.approx(20.0)
    assert warm.speedup_mean == pytest.approx(7.5) and warm.speedup_median == pytest.approx(5.0)
    for col in ("rmse_ratio_sigma2", "rmse_ratio_phi", "rmse_ratio_ar1_sigma2", "rmse_ratio_gamma2"):
        np.testing.assert_allclose(comp[col], 0.5)
    assert list(comp.not_converged) == [1, 0, 1, 0] and list(comp.wrong_optimum) == [1, 0, 1, 0]
    assert list(comp.n_used) == [2, 4, 2, 4]
    assert comparison_table(long).shape[0] == 4
    text = counts_text(comp, {"variants": {"mle": "moment", "mle_gmwm": "gmwm"}})
    assert "T = 1,000: 1 + 1 of 4" in text and "MLE (GMWM start)" in text
    assert not text.startswith("GMWM:")
    text = counts_text(comp, {"variants": {"mle": "moment"}}, {"n_starts": 8, "nested": False})
    assert text.startswith("GMWM: single-model search") and "8 starts, ci weights" in text
    # settings not given are gmwm.fit's defaults (nested search, 4 starts, CI weights)
    assert gmwm_text({}) == ("GMWM: nested search: the model and each of its submodels, "
                             "4 starts, ci weights.")


def test_standardized_boxplot_data_share_the_mle_scale():
    ds = synthetic()
    std = standardized_by_method(ds, "mle_gmwm")
    assert list(std) == ["GMWM", "MLE (GMWM start)"]
    for p in COMPARED:
        mle = std["MLE (GMWM start)"][p]
        assert len(mle) == 4
        np.testing.assert_allclose(np.std(mle, ddof=1), 1.0)
        # GMWM errors are twice the MLE's on every replicate, so on the common scale twice as wide
        np.testing.assert_allclose(std["GMWM"][p], 2 * mle)


# ---------------------------------------------------------------------------------------------
# the general-purpose baseline (statsmodels' own MLE) and the MLE's standard errors


@pytest.fixture(scope="module")
def baseline():
    return run_baseline_chunk(MODEL, TRUTH, T_TINY, [0, 1], study="t_sim1", base_seed=11,
                              settings={"maxiter": 50})


def test_baseline_fits_the_same_signals_and_merges(whole, baseline):
    b = baseline
    assert list(b["estimator"].values) == [BASELINE] and list(b["replicate"].values) == [0, 1]
    assert b["ran"].values.all()
    assert (b["seconds"].values > 0).all() and (b["seconds_se"] >= b["seconds"]).all()
    assert np.isnan(b["estimate"].sel(parameter="SIN[1].beta")).all()
    merged = add_baseline(whole, b)
    assert list(merged["estimator"].values) == ["gmwm", *VARIANTS, BASELINE]
    assert json.loads(merged.attrs["variants"]) == {**VARIANTS, BASELINE: BASELINE}
    assert list(merged["ran"].sel(estimator=BASELINE).values) == [True, True, False]
    assert not merged["converged"].sel(estimator=BASELINE, replicate=2)
    # same signals: statsmodels' log-likelihood is the project's filter's at its estimate, so
    # the wrong-optimum rule compares like with like (the sinusoid coefficients re-solved by GLS
    # give a likelihood at least as high)
    best_other = merged["loglike"].sel(estimator=list(VARIANTS), replicate=[0, 1]).max("estimator")
    sm_ll = merged["loglike"].sel(estimator=BASELINE, replicate=[0, 1])
    assert (sm_ll <= best_other + 1e-3).all()
    _, comp = study_tables([merged])
    row = comp[comp.variant == BASELINE].iloc[0]
    assert row.n_mle == 2 and row.not_converged + row.wrong_optimum + row.n_used == 2
    assert row.mle_mean_s == pytest.approx(float(b["seconds"].mean()))
    assert row.mle_se_mean_s == pytest.approx(float(b["seconds_se"].mean()))
    assert row.mle_cpu_mean_s == pytest.approx(float(b["cpu_seconds"].mean()))
    assert row.speedup_cpu_mean == pytest.approx(
        row.mle_cpu_mean_s / float(whole["cpu_seconds"].sel(estimator="gmwm",
                                                            replicate=[0, 1]).mean()))
    # the GMWM's time is averaged over the same two signals
    assert row.gmwm_mean_s == pytest.approx(
        float(whole["seconds"].sel(estimator="gmwm", replicate=[0, 1]).mean()))
    text = counts_text(comp, MLE, GMWM, {"maxiter": 50})
    assert "statsmodels' own estimator" in text and "fit(maxiter=50)" in text
    assert "T = 2,048: 2" in text


def test_baseline_merge_rejects_mismatches(whole, baseline):
    with pytest.raises(InputError, match="n_samples"):
        add_baseline(whole, baseline.assign_attrs(n_samples=4096))
    capped = whole.copy()
    capped["mle_ran"] = ("replicate", np.array([True, False, False]))
    with pytest.raises(InputError, match="Kalman-filter MLE did not"):
        add_baseline(capped, baseline)
    with pytest.raises(InputError, match="already"):
        add_baseline(add_baseline(whole, baseline), baseline)
    with pytest.raises(InputError, match="unknown statsmodels baseline setting"):
        run_baseline_chunk(MODEL, TRUTH, T_TINY, [0], "s", 0, {"tol": 1})
    with pytest.raises(InputError, match="cannot be called"):
        run_replicate(MODEL, TRUTH, 1000, 0, "s", 0, GMWM, {"variants": {BASELINE: "moment"}})


@pytest.mark.slow
def test_statsmodels_likelihood_equals_the_project_filter():
    from gmwm.model import Model

    m = Model(MODEL)
    x = m.simulate(np.array([TRUTH[n] for n in m.param_names]), 3000, np.random.default_rng(4))
    res = fit_statsmodels(x, 0.35, maxiter=50, se=True)
    assert res.start == "statsmodels" and np.isfinite(res.loglike)
    assert res.seconds > 0 and res.seconds_se > 0
    t = np.arange(x.size) * 0.35
    # statsmodels' estimate of the sinusoid coefficients is not returned by name, so re-solve it:
    # the GLS coefficients maximise the likelihood at fixed variances
    from gmwm_studies.mle import _Profile, _to_r

    X = np.column_stack([np.cos(t), np.sin(t)])
    _, _, b = _Profile(x, X).solve(_to_r(res.as_dict()))
    assert kalman_loglike(x, 0.35, res.as_dict(), b) >= res.loglike - 1e-6
    assert kalman_loglike(x, 0.35, res.as_dict(), b) <= res.loglike + 1e-2


@pytest.mark.slow
def test_mle_standard_errors_match_statsmodels_numerical_hessian():
    # the observed-information SEs of the project's MLE against statsmodels' own numerical
    # Hessian ('approx') at the same estimate: same likelihood, so they must agree closely
    from statsmodels.tsa.statespace.structural import UnobservedComponents

    from gmwm.model import Model
    from gmwm_studies.mle import _Profile, _to_r

    m = Model(MODEL)
    x = m.simulate(np.array([TRUTH[n] for n in m.param_names]), 8000, np.random.default_rng(3))
    res = fit_mle(x, 0.35, n_starts=1, se=True)
    assert res.converged and res.seconds_se > 0
    d = res.as_dict()
    t = np.arange(x.size) * 0.35
    X = np.column_stack([np.cos(t), np.sin(t)])
    _, _, b = _Profile(x, X).solve(_to_r(d))
    sm = UnobservedComponents(x, level="llevel", autoregressive=1, exog=X, use_exact_diffuse=True)
    p = np.array([d["WN[1].sigma2"], d["RW[1].gamma2"], d["AR1[1].sigma2"], d["AR1[1].phi"], *b])
    bse = dict(zip(sm.param_names, sm.smooth(p, cov_type="approx").bse, strict=True))
    ours = dict(zip(res.param_names, res.se, strict=True))
    for mine, theirs in (("WN[1].sigma2", "sigma2.irregular"), ("RW[1].gamma2", "sigma2.level"),
                         ("AR1[1].sigma2", "sigma2.ar"), ("AR1[1].phi", "ar.L1")):
        assert ours[mine] == pytest.approx(bse[theirs], rel=0.03), mine
    assert np.isnan(ours["SIN[1].alpha"])
    ci = res.conf_int()
    assert (ci[:4, 0] < res.params[:4]).all() and (ci[:4, 1] > res.params[:4]).all()
    assert ci[2, 1] <= 1.0 and (ci[[0, 1, 3], 0] >= 0).all()  # never outside the domain
    # a boundary point has no SEs
    assert np.isnan(mle_covariance(x, 0.35, {**d, "RW[1].gamma2": 0.0})).all()
