"""Library-level tests of the runners behind workflow/rules/uncertainty.smk: replicate fits equal the
studies' own fits, chunk invariance of the coverage runner, NetCDF round trip of bootstrap chunks,
Table-1 rows, coverage summaries and figure, identifiability summary rows, Navchip estimates."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from gmwm import bootstrap as bs
from gmwm import identify
from gmwm.errors import InputError
from gmwm.estimator import fit
from gmwm.model import Model
from gmwm_studies import uncertainty as un
from gmwm_studies.data import local_copy
from gmwm_studies.montecarlo import estimator_settings, fit_chunk, replicate_fit, simulate_wv_chunk

MODEL = "WN+AR1"
TRUTH = {"WN[1].sigma2": 1.0, "AR1[1].phi": 0.9, "AR1[1].sigma2": 0.5}
T = 2**11
SETTINGS = {"method": "gmwm", "weights": "ci", "n_starts": 2, "reweight": 0}
NAVCHIP_WV = local_copy("navchip_wv")  # the registry's local copy (../shared/data), or None


@pytest.fixture(scope="module")
def cov_ds() -> xr.Dataset:
    return un.coverage_chunk(MODEL, TRUTH, T, [0, 1, 2, 3], study="t", base_seed=5, B=6,
                             settings=SETTINGS)


def test_replicate_fit_equals_the_study_fit():
    chunk = simulate_wv_chunk(MODEL, TRUTH, T, [3], study="s", base_seed=9)
    ds = fit_chunk(chunk, SETTINGS)
    res = replicate_fit(MODEL, TRUTH, T, 3, study="s", base_seed=9, settings=SETTINGS)
    np.testing.assert_array_equal(res.params, ds["estimate"].values[0])
    # the single-model setting (Simulation 1's gmwm_single) reaches the fit
    single = replicate_fit(MODEL, TRUTH, T, 3, study="s", base_seed=9,
                           settings={**SETTINGS, "nested": False})
    assert res.settings.nested is True and single.settings.nested is False
    # an estimator's settings are validated: another estimator's option is an error
    assert estimator_settings({"n_starts": 2, "max_nfev": 50}).max_nfev == 50
    with pytest.raises(InputError, match="do not apply"):
        estimator_settings({"n_starts": 2, "min_edof": 2})


def test_coverage_chunk_does_not_depend_on_chunking(cov_ds):
    parts = [un.coverage_chunk(MODEL, TRUTH, T, reps, study="t", base_seed=5, B=6,
                               settings=SETTINGS) for reps in ([2, 3], [0, 1])]
    joined = xr.concat(parts, dim="replicate").sortby("replicate")
    for var in ("estimate", "sandwich_se", "boot_se", "ci"):
        np.testing.assert_array_equal(joined[var].values, cov_ds[var].values)
    assert list(cov_ds["kind"].values) == list(un.CI_KINDS)
    # Wald interval = estimate -/+ 1.959964 sandwich SE
    wald = cov_ds["ci"].sel(kind="wald").values
    est, se = cov_ds["estimate"].values, cov_ds["sandwich_se"].values
    np.testing.assert_allclose(wald[..., 1] - est, 1.959964 * se, rtol=1e-6)
    # basic = 2 estimate - reversed percentile for phi; on the log scale (estimate^2 / reversed
    # percentile) for the positive parameters WN sigma2 and AR1 sigma2
    pct, bas = cov_ds["ci"].sel(kind="percentile").values, cov_ds["ci"].sel(kind="basic").values
    np.testing.assert_allclose(bas[:, 1, 0], 2 * est[:, 1] - pct[:, 1, 1], rtol=1e-12)
    for i in (0, 2):
        np.testing.assert_allclose(bas[:, i, 0], est[:, i] ** 2 / pct[:, i, 1], rtol=1e-12)
    assert np.all(bas[:, [0, 2], 0] > 0)


def test_coverage_summary_and_figure(cov_ds):
    df = un.coverage_summary(cov_ds)
    assert len(df) == 3 * len(un.CI_KINDS) and df.attrs["R"] == 4 and df.attrs["B"] == 6
    hits = bs.covers(cov_ds["ci"].sel(kind="wald").values, cov_ds["truth"].values).mean(axis=0)
    wald = df[df.interval == "wald"]
    np.testing.assert_allclose(wald.coverage, hits)
    np.testing.assert_allclose(wald.mc_se, np.sqrt(hits * (1 - hits) / 4))
    ratio = np.mean(cov_ds["boot_se"].values / cov_ds["sandwich_se"].values, axis=0)
    np.testing.assert_allclose(wald.mean_se_ratio, ratio)
    fig = un.plot_coverage(df)
    assert len(fig.axes[0].containers) == len(un.CI_KINDS)


def test_bootstrap_chunks_round_trip_and_table():
    est = replicate_fit(MODEL, TRUTH, T, 0, study="t", base_seed=1, settings=SETTINGS)
    ss = np.random.SeedSequence(7, spawn_key=(123,))
    parts = [bs.parametric_bootstrap(est, seed=ss, draws=d, n_starts=2)
             for d in (range(4), range(4, 9))]
    back = [un.bootstrap_from_dataset(un.bootstrap_to_dataset(p), est) for p in parts]
    whole = bs.parametric_bootstrap(est, 9, seed=ss, n_starts=2)
    joined = bs.BootstrapResult.combine(back[::-1])
    np.testing.assert_array_equal(joined.theta, whole.theta)
    np.testing.assert_array_equal(joined.wv, whole.wv)
    df = un.bootstrap_table(joined, "t 0")
    np.testing.assert_allclose(df.pct_low, whole.percentile_ci()[:, 0])
    q_lo = whole.quantiles()[:, 0]
    expected = np.where([True, False, True], est.params**2 / q_lo, 2 * est.params - q_lo)
    np.testing.assert_allclose(df.basic_high, expected)
    np.testing.assert_allclose(df.boot_se, whole.se)
    assert (df.B == 9).all() and list(df.parameter) == est.param_names
    other = replicate_fit(MODEL, TRUTH, T, 1, study="t", base_seed=1, settings=SETTINGS)
    with pytest.raises(InputError):
        un.bootstrap_from_dataset(un.bootstrap_to_dataset(parts[0]), other)


def test_summary_row_pass_and_warn():
    good = replicate_fit(MODEL, TRUTH, 2**14, 0, study="t", base_seed=2, settings=SETTINGS)
    rep = identify.check(good, n_starts=4)
    row = un.summary_row("good", rep)
    assert row == un.summary_row("good", json.loads(json.dumps(rep.to_json_dict())))
    assert row["status"] == "pass" and row["reasons"] == "" and row["posterior"] == "not run"
    # two AR1 fitted to a one-AR1 signal: flagged, with reasons
    model = Model(MODEL)
    x = model.simulate(model.theta(TRUTH), 2**12, np.random.default_rng(3))
    bad = fit(x, "WN+2*AR1", n_starts=2)
    row = un.summary_row("bad", identify.check(bad, n_starts=4))
    assert row["status"] == "warn" and row["reasons"]


@pytest.mark.skipif(NAVCHIP_WV is None,
                    reason="Navchip WV file not in ../shared/data (config/datasets.yaml local_dir)")
def test_navchip_result_reproduces_the_recorded_fit(tmp_path):
    navchip = pytest.importorskip("gmwm_studies.navchip")
    settings = {"weights": "ci", "n_starts": 2, "seed": 1}
    fits = navchip.fit_channels(NAVCHIP_WV, "QN+WN+2*GM+RW+DR", ["gyroscope"], axes=["X"],
                                fit_settings=settings)
    path = tmp_path / "fits.json"
    path.write_text(json.dumps(navchip.fits_to_json(fits, settings)))
    res = un.navchip_result(str(NAVCHIP_WV), str(path), "gyroscope", "X")
    np.testing.assert_allclose(res.params, fits[0].params, rtol=1e-9)
    assert not res.diagnostics["navchip_refit_differs"]
    assert res.wv.n_samples == 3105250
    with pytest.raises(InputError):
        un.navchip_result(str(NAVCHIP_WV), str(path), "gyroscope", "Y")
