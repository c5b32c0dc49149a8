"""Navigation emulation ([Vibration] sec. 5): trajectory/IMU consistency, rate conversion, filter
consistency (NEES against the Monte Carlo spread of the errors), ratio statistics."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

from gmwm.errors import InputError
from gmwm_studies import ekf
from gmwm_studies import navigation as nv

CFG = {"gyro_axes": ["x", "y", "z"], "accel_vrw": 0.1, "gnss_sd": 1.0,
       "initial_sd": {"position": 1.0, "velocity": 0.1, "roll_pitch": 0.5, "yaw": 1.0}}
TRUTH200 = np.array([0.1851173, 3.559081e-2, 8.692479e-10])  # Table 5 AR1 + RW, deg/s at 200 Hz


def test_ideal_imu_reproduces_the_trajectory():
    tr = nv.make_trajectory(duration=60.0, rate=100.0)
    p, v, C = ekf.mechanize(tr.pos[0], tr.vel[0], tr.C[0], tr.gyro, tr.accel, tr.dt)
    assert np.abs(p - tr.pos).max() < 1e-6 and np.abs(v - tr.vel).max() < 1e-8
    assert np.abs(C - tr.C).max() < 1e-9
    # a flying vehicle: specific force mostly along body up (coordinated turns)
    assert np.all(tr.accel[:, 2] > 8.0) and np.abs(tr.accel[:, 1]).max() < 0.5


def test_rotation_helpers_invert_each_other():
    rng = np.random.default_rng(0)
    phi = rng.normal(scale=0.8, size=(50, 3))
    np.testing.assert_allclose(ekf.log_so3(ekf.exp_so3(phi)), phi, atol=1e-10)
    R = ekf.exp_so3(phi)
    np.testing.assert_allclose(R @ np.swapaxes(R, -1, -2), np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)


def test_rate_conversion_keeps_correlation_time_and_rw_coefficient():
    th = nv.convert_basic(TRUTH200, 200.0, 100.0)
    assert th[0] == pytest.approx(TRUTH200[0] ** 2)
    q200 = TRUTH200[1] / (1 - TRUTH200[0] ** 2)
    assert th[1] / (1 - th[0] ** 2) == pytest.approx(q200)
    assert th[2] == pytest.approx(2 * TRUTH200[2])
    np.testing.assert_allclose(nv.convert_basic(th, 100.0, 200.0), TRUTH200, rtol=1e-12)
    with pytest.raises(InputError, match="phi"):
        nv.convert_basic(np.array([-0.1, 1.0, 0.0]), 200.0, 100.0)


def test_gnss_schedule_has_the_outage_gap():
    tr = nv.make_trajectory(duration=235.0, rate=100.0)
    t = tr.t[nv.gnss_schedule(tr, 1.0, (160.0, 210.0))]
    assert t[0] == 1.0 and t[-1] == 235.0 and len(t) == 235 - 49
    assert np.max(np.diff(t)) == 50.0 and not np.any((t > 160) & (t < 210))


def _nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Mean over runs of e^T P^-1 e at each recorded epoch."""
    return np.einsum("bri,bri->br", err, np.linalg.solve(cov, err[..., None])[..., 0]).mean(0)


@pytest.fixture(scope="module")
def consistency_runs():
    # 200 runs of a 30 s flight at 50 Hz with GNSS at 1 Hz and an outage (15, 25) s; filters tuned
    # with the true model (0) and with the gyro noise under-stated 20x (1).
    tr = nv.make_trajectory(duration=30.0, rate=50.0, turns=((5.0, 20.0, 8.0),),
                            climbs=((3.0, 18.0, 2.0),))
    setup = nv.filter_setup(CFG, 50.0)
    th = nv.convert_basic(TRUTH200, 200.0, 50.0)
    wrong = th * np.array([1.0, 0.05, 0.05])
    n = 200
    fp = np.stack([np.stack([th, wrong])] * n)
    out = nv.emulate(tr, setup, th, fp, range(n), "nees_test", 3, nv.gnss_schedule(tr, 1.0, (15, 25)),
                     record_every=25, return_states=True)
    raw = out["raw"]
    sel = {k: raw[k].reshape(n, 2, *raw[k].shape[1:]) for k in ("pos_err", "pos_cov", "att_err",
                                                                  "att_cov")}
    return out["time"], sel


@pytest.mark.slow
def test_filter_covariance_matches_monte_carlo_spread(consistency_runs):
    t, r = consistency_runs
    keep = t > 0
    # 3-dof NEES averaged over 200 runs: mean 3, MC SD sqrt(6 / 200) = 0.17; 4 SDs allowed
    for err, cov in (("pos_err", "pos_cov"), ("att_err", "att_cov")):
        nees = _nees(r[err][:, 0], r[cov][:, 0])[keep]
        assert np.all(np.abs(nees - 3.0) < 4 * np.sqrt(6 / 200)), (err, nees.round(2))
    # per-axis empirical position variance against the filter's in the outage (ratio near 1)
    k = np.argmin(np.abs(t - 24.0))
    emp = r["pos_err"][:, 0, k].var(axis=0, ddof=1)
    pred = np.diagonal(r["pos_cov"][:, 0, k], axis1=-2, axis2=-1).mean(0)
    assert np.all(np.abs(emp / pred - 1) < 0.35), emp / pred  # chi2(199)/199: SD 0.1


@pytest.mark.slow
def test_understated_gyro_noise_is_detected(consistency_runs):
    t, r = consistency_runs
    k = np.argmin(np.abs(t - 24.0))
    nees = _nees(r["att_err"][:, 1, k:k + 1], r["att_cov"][:, 1, k:k + 1])
    assert nees[0] > 5  # consistent: 3 +- 0.17


def test_ratio_ci_is_paired_delta_method():
    rng = np.random.default_rng(5)
    e2 = rng.gamma(4.0, 1.0, size=(400, 3))
    e1 = 1.2 * e2 + rng.normal(scale=0.2, size=e2.shape)
    ci = nv.ratio_with_ci(e1, e2)
    assert np.all(ci["lo"] < 1.2) and np.all(ci["hi"] > 1.2)
    # paired: far narrower than an unpaired CI would be (SD of e2 / mean e2 ~ 0.5)
    assert np.all(ci["hi"] - ci["lo"] < 0.02)
    ds = xr.Dataset({"pos_err_norm": (("iteration", "model", "time"),
                                      np.stack([e1, e2], axis=1))},
                    coords={"model": ["model1", "model2"], "time": [100.0, 170.0, 220.0]})
    tab = nv.ratio_summary(ds, n_boot=199).set_index("window")
    assert tab.loc["GNSS outage", "time_s"] == 170.0
    row = tab.loc["whole flight"]
    assert row["boot_max_lo"] <= row["max_ratio"] <= row["boot_max_hi"] + 0.01


def _fake_fits(n: int) -> dict[str, xr.Dataset]:
    """Gathered-estimate Datasets of two models for replicates 0..n-1 (Table 5 basic values)."""
    names = ["AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2"]
    out = {}
    for m, scale in (("model1", 2.0), ("model2", 1.0)):
        est = np.tile(TRUTH200 * [1.0, scale, 1.0], (n, 1))
        out[m] = xr.Dataset({"estimate": (("replicate", "parameter"), est),
                             "converged": ("replicate", np.ones(n, dtype=bool))},
                            coords={"replicate": np.arange(n), "parameter": names})
    out["model1"]["converged"][1] = False
    out["model2"]["estimate"][3, 0] = -0.2
    return out


@pytest.mark.slow
def test_run_chunk_drops_bad_fits_and_ignores_chunking():
    cfg = {**CFG, "models": ["model1", "model2"], "seed": 4, "freq_calibration": 200.0,
           "imu_rate": 100.0, "duration": 20.0, "gnss_rate": 1.0, "outage": [8.0, 15.0],
           "gyro_unit": "deg/s", "record_rate": 10.0}
    truth = dict(zip(["AR1[1].phi", "AR1[1].sigma2", "RW[1].gamma2"], TRUTH200, strict=True))
    fits = _fake_fits(5)
    whole = nv.run_chunk(cfg, fits, truth, range(5))
    assert list(whole["iteration"].values) == [0, 2, 4]
    assert set(json.loads(whole.attrs["dropped"])) == {"1", "3"}
    parts = [nv.run_chunk(cfg, fits, truth, r) for r in ([0, 1, 2], [3, 4])]
    joined = xr.concat(parts, dim="iteration")
    np.testing.assert_array_equal(joined["pos_err_norm"].values, whole["pos_err_norm"].values)
    # model1 assumes twice the gyro noise: a larger predicted position SD in the outage
    sd = whole["pos_sd"].sel(time=14.0, method="nearest")
    assert np.all(sd.sel(model="model1") > sd.sel(model="model2"))


def test_variant_config_overrides_only_its_keys():
    nav = {"iterations": 500, "chunk_size": 25, "seed": 7, "gyro_axes": ["x", "y", "z"],
           "variants": {"z_only": {"gyro_axes": ["z"], "iterations": 100},
                        "bad": {"seed": 3}}}
    cfg = nv.variant_config(nav, "z_only")
    assert cfg == {"iterations": 100, "chunk_size": 25, "seed": 7, "gyro_axes": ["z"],
                   "variant": "z_only"}
    assert list(cfg)[:4] == ["iterations", "chunk_size", "seed", "gyro_axes"]  # params repr stable
    assert nav["gyro_axes"] == ["x", "y", "z"]  # the main config is not modified
    with pytest.raises(InputError, match="cannot be varied"):
        nv.variant_config(nav, "bad")  # the seed is the main study's: common random numbers
    with pytest.raises(InputError, match="unknown variant"):
        nv.variant_config(nav, "xy")


def _chunk(iterations: list[int], dropped: dict[int, str], scale: float) -> xr.Dataset:
    rng = np.random.default_rng(len(iterations))
    e2 = rng.gamma(4.0, 1.0, size=(len(iterations), 4))
    err = np.stack([scale * e2, e2], axis=1)
    return xr.Dataset({"pos_err_norm": (("iteration", "model", "time"), err),
                       "pos_sd": (("iteration", "model", "time"), err / 2)},
                      coords={"iteration": iterations, "model": ["model1", "model2"],
                              "time": [0.0, 1.0, 2.0, 3.0]},
                      attrs={"dropped": json.dumps(dropped)})


def test_concat_chunks_and_ratio_series():
    ds, dropped = nv.concat_chunks([_chunk([3, 5], {4: "model1 fit did not converge"}, 1.5),
                                    _chunk([0, 1], {2: "x"}, 1.5)])
    assert list(ds["iteration"].values) == [0, 1, 3, 5] and dropped == {4: "model1 fit did not converge", 2: "x"}
    series = nv.ratio_series(ds)
    assert list(series.columns) == ["time_s", "ratio", "ci_lo", "ci_hi", "mean_err_model1_m",
                                    "mean_err_model2_m", "mean_sd_model1_m", "mean_sd_model2_m"]
    np.testing.assert_allclose(series["ratio"], 1.5)
    np.testing.assert_allclose(series["mean_sd_model1_m"], series["mean_err_model1_m"] / 2)
    with pytest.raises(InputError, match="no chunk"):
        nv.concat_chunks([])


def test_both_profiles_configure_the_z_only_variant():
    """config.yaml and config.yaml + quick.yaml (merged as --configfile does) run the z_only
    sensitivity variant on the main study's settings, within the misspec replicates; the schema
    refuses a variant that overrides anything but gyro_axes / iterations / chunk_size."""
    import copy
    from pathlib import Path

    import yaml
    pytest.importorskip("snakemake")
    from snakemake.exceptions import WorkflowError
    from snakemake.utils import update_config, validate

    root = Path(__file__).resolve().parents[1]
    schema = str(root / "workflow" / "schemas" / "config.schema.yaml")
    full = yaml.safe_load((root / "config" / "config.yaml").read_text())
    quick = copy.deepcopy(full)
    update_config(quick, yaml.safe_load((root / "config" / "quick.yaml").read_text()))
    for cfg, n in ((full, 100), (quick, 4)):
        validate(cfg, schema)
        nav = cfg["navigation"]
        v = nv.variant_config(nav, "z_only")
        assert v["gyro_axes"] == ["z"] and v["iterations"] == n
        assert v["iterations"] <= cfg["studies"][nav["estimates_from"]]["replicates"]
        assert {k: x for k, x in v.items() if k not in ("gyro_axes", "iterations", "variant")} == {
            k: x for k, x in nav.items() if k not in ("gyro_axes", "iterations", "variants")}
    bad = copy.deepcopy(full)
    bad["navigation"]["variants"]["z_only"]["seed"] = 3
    with pytest.raises(WorkflowError, match="seed"):
        validate(bad, schema)
