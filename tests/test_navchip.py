"""Navchip analysis (gmwm_studies.navchip) on the real local data and on small synthetic inputs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gmwm.errors import DataUnavailableError
from gmwm.estimator import fit
from gmwm.wv import WaveletVariance
from gmwm_studies import navchip as nv
from gmwm_studies.data import load_navchip_wv, load_registry

MODEL = "QN+WN+2*GM+RW+DR"
SETTINGS = {"weights": "ci", "n_starts": 2, "max_nfev": 600, "seed": 1}
LOCAL = load_registry()["local_dir_resolved"]
needs_data = pytest.mark.skipif(not (LOCAL / "wv" / "navchip_wv.csv").is_file(),
                                reason="Navchip data not available locally")


@pytest.fixture(scope="module")
def data_csv(tmp_path_factory):
    if not (LOCAL / "wv" / "navchip_wv.csv").is_file():
        pytest.skip("Navchip data not available locally")
    return nv.obtain_navchip(tmp_path_factory.mktemp("navdata"), allow_download=False)


@pytest.fixture(scope="module")
def gyro_x(data_csv):
    return nv.fit_channel(load_navchip_wv(data_csv, "gyroscope", "X"), MODEL, "gyroscope", "X",
                          SETTINGS)


def test_missing_data_names_file_and_source(tmp_path):
    with pytest.raises(DataUnavailableError) as err:
        nv.obtain_navchip(tmp_path / "out", data_dir=tmp_path / "nowhere", allow_download=False)
    msg = str(err.value)
    assert "wv/navchip_wv.csv" in msg and "github.com/SMAC-Group/wv" in msg
    assert "\n" not in msg


@needs_data
def test_gyro_x_fit_on_real_data(gyro_x):
    cf = gyro_x
    assert cf.converged and cf.sensor == "gyroscope" and cf.wv.n_levels == 20
    # the model follows the WV closely: inside the (narrow) CI at >= half of the scales, and
    # within 15 % of the empirical WV at every scale; the datasheet model is far off
    assert cf.gof >= 0.5 and cf.gof_datasheet <= 0.1
    assert np.max(np.abs(cf.model_wv() / cf.wv.variance - 1)) < 0.15
    # white-noise density within 25 % of the datasheet's 0.003 deg/s/sqrt(Hz)
    table = nv.gof_table([cf], threshold=0.6)
    assert 0.75 < table["wn_density_ratio"].iloc[0] < 1.25
    assert bool(table["model_fits"].iloc[0])
    # finite positive SEs for every interior parameter; QN and WN are sharply determined
    ok = ~cf.boundary
    assert np.all(np.isfinite(cf.se[ok])) and np.all(cf.se[ok] > 0)
    assert np.all(cf.se[:2] / cf.params[:2] < 0.02)


def test_inside_ci_and_boundary_flags():
    scales = 2.0 ** np.arange(1, 9)
    wv = WaveletVariance.from_table(scales, 1.0 / scales, n_samples=4096, freq=250.0)
    inside = nv.inside_ci(wv, wv.variance * np.r_[1.0, 1.0, 10.0, 1, 1, 1, 1, 1])
    assert inside.tolist() == [True, True, False, True, True, True, True, True]
    res = fit(wv, "WN+RW", weights="gaussian")  # pure WN: RW estimated at the boundary 0
    assert nv._boundary(res).tolist() == [False, True]
    assert np.isnan(res.se[1]) and np.isfinite(res.se[0])


@needs_data
def test_fits_file_round_trip(tmp_path, data_csv, gyro_x):
    path = tmp_path / "fits.json"
    path.write_text(json.dumps(nv.fits_to_json([gyro_x], SETTINGS, {"repo": "x"})))
    rec = nv.load_fits(path)[("gyroscope", "X")]
    assert rec["model"] == MODEL and rec["n_samples"] == 3105250 and rec["freq"] == 250.0
    assert rec["params"] == gyro_x.as_dict()
    back = nv.channels_from_fits(data_csv, path)[0]
    np.testing.assert_array_equal(back.params, gyro_x.params)
    np.testing.assert_array_equal(back.se, gyro_x.se)
    assert back.gof == gyro_x.gof
    tables = [tmp_path / f for f in ("e.csv", "e.md", "g.csv", "g.md")]
    nv.write_tables(nv.estimates_table([back]), nv.gof_table([back], 0.6), 0.6, MODEL, *tables)
    assert "GM[2].beta" in tables[1].read_text() and "gyroscope X: fits" in tables[3].read_text()


@needs_data
def test_figures_one_panel_per_axis(gyro_x):
    fig3 = nv.figure_wv_datasheet([gyro_x], threshold=0.6)
    labels = [ln.get_label() for ln in fig3.axes[0].lines]
    assert "Datasheet model WV" in labels and "GMWM model WV" in labels
    assert "RW not given" in fig3._suptitle.get_text()
    fig4 = nv.figure_decomposition([gyro_x])
    drawn = {ln.get_label() for ln in fig4.axes[0].lines}
    assert {"QN[1]", "WN[1]", "GM[1]", "GM[2]"} <= drawn
