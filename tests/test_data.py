"""Real-data registry and files: local copy, layout/sha256 checks, offline errors, .rda conversion.

No test touches the network: downloads are either disabled or served by a fake ``fetch``.
"""

import hashlib
import json
import urllib.error
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gmwm.errors import DataUnavailableError, InputError
from gmwm_studies import data

SHARED = data.REPO_ROOT.parent / "shared" / "data"
needs_shared = pytest.mark.skipif(not (SHARED / "wv" / "navchip_wv.csv").is_file(),
                                  reason="local copy of the Navchip data not present")
NAMES = ["navchip_wv", "navchip_av"]


@needs_shared
@pytest.mark.parametrize("name", NAMES)
def test_registry_agrees_with_shared_json(name):
    entry = data.dataset_entry(name)
    meta = json.loads((SHARED / entry["meta"]).read_text())
    for key in ("repository", "commit", "file", "sha256", "r_object", "git_blob"):
        reg_key = "path" if key == "file" else key
        assert entry["source"][reg_key] == meta["source"][key]
    assert entry["n"] == meta["n"] and entry["freq_hz"] == meta["freq_hz"]
    assert {k: list(v) for k, v in entry["channels"].items()} == \
        {c["r_name"]: [c["sensor"], c["axis"]] for c in meta["channels"]}
    assert entry["source"]["commit"] in entry["source"]["url"]


@needs_shared
@pytest.mark.parametrize("name", NAMES)
def test_obtain_local_copy(tmp_path, name):
    out = data.obtain(name, tmp_path, local_dir=SHARED, allow_download=False)
    entry = data.dataset_entry(name)
    assert out == tmp_path / Path(entry["file"]).name
    assert out.read_bytes() == (SHARED / entry["file"]).read_bytes()
    assert json.loads(out.with_suffix(".json").read_text())["n"] == 3105250
    assert not list(tmp_path.glob(".*tmp*"))  # atomic write left no temporary file


@needs_shared
def test_default_registry_local_dir_is_shared_data(tmp_path):
    reg = data.load_registry()
    assert reg["local_dir_resolved"] == SHARED.resolve()
    out = data.obtain("navchip_wv", tmp_path / "sub" / "wv.csv", allow_download=False)
    assert out.name == "wv.csv" and out.is_file()


def _fake_local(tmp_path, df):
    local = tmp_path / "local"
    (local / "wv").mkdir(parents=True)
    df.to_csv(local / "wv" / "navchip_wv.csv", index=False)
    return local


@needs_shared
def test_local_copy_layout_checked(tmp_path):
    df = pd.read_csv(SHARED / "wv" / "navchip_wv.csv").drop(columns=["ci_high"])
    local = _fake_local(tmp_path, df)
    with pytest.raises(InputError, match="ci_high"):
        data.obtain("navchip_wv", tmp_path / "out.csv", local_dir=local, allow_download=False)


@needs_shared
def test_modified_local_copy_fails_checksum(tmp_path):
    df = pd.read_csv(SHARED / "wv" / "navchip_wv.csv")
    df.loc[0, "variance"] *= 1.01
    local = _fake_local(tmp_path, df)
    with pytest.raises(data.ChecksumError, match="sha256"):
        data.obtain("navchip_wv", tmp_path / "out.csv", local_dir=local, allow_download=False)
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("name,repo,path", [
    ("navchip_wv", "https://github.com/SMAC-Group/wv", "data/navchip_wv.rda"),
    ("navchip_av", "https://github.com/SMAC-Group/avar", "data/navchip_av.rda"),
])
def test_offline_without_local_copy_names_file_and_source(tmp_path, name, repo, path):
    with pytest.raises(DataUnavailableError) as exc:
        data.obtain(name, tmp_path, local_dir=tmp_path / "nowhere", allow_download=False)
    msg = str(exc.value)
    assert data.dataset_entry(name)["file"] in msg and repo in msg and path in msg
    assert "\n" not in msg


def test_failed_download_names_source(tmp_path):
    def offline(url):
        raise urllib.error.URLError("no network")

    with pytest.raises(DataUnavailableError, match="SMAC-Group/wv"):
        data.obtain("navchip_wv", tmp_path, local_dir=tmp_path / "nowhere", fetch=offline)


def test_download_sha_mismatch(tmp_path):
    with pytest.raises(data.ChecksumError, match="sha256 mismatch"):
        data.obtain("navchip_wv", tmp_path / "x.csv", local_dir=tmp_path / "nowhere",
                    fetch=lambda url: b"not the rda file")
    assert not (tmp_path / "x.csv").exists()


def _rda_like_source(name, entry, df, path):
    """Write an .rda with the structure of the wv/avar packages' imu objects (values from df)."""
    rdata = pytest.importorskip("rdata")
    channels = {}
    for r_name, (sensor, axis) in entry["channels"].items():
        r = df[(df.sensor == sensor) & (df.axis == axis)].sort_values("level")
        if entry["kind"] == "wv":
            channels[r_name] = {"variance": r.variance.to_numpy(), "ci_low": r.ci_low.to_numpy(),
                                "ci_high": r.ci_high.to_numpy(), "scales": r.scale_s.to_numpy()}
        else:
            channels[r_name] = {"levels": r.tau_s.to_numpy(), "allan": r.avar.to_numpy(),
                                "errors": r.rel_error.to_numpy(), "adev": r.adev.to_numpy(),
                                "lci": r.adev_ci_low.to_numpy(), "uci": r.adev_ci_high.to_numpy()}
    key = "wvar" if entry["kind"] == "wv" else "avar"
    obj = {"sensor": "NAVCHIP_FLT", "freq": 250.0, "n": 3105250.0, key: channels}
    rdata.write_rda(path, {entry["source"]["r_object"]: obj})
    return path.read_bytes()


@needs_shared
@pytest.mark.parametrize("name", NAMES)
def test_download_path_converts_rda_to_reference_csv(tmp_path, name):
    entry = data.dataset_entry(name)
    df = pd.read_csv(SHARED / entry["file"])
    payload = _rda_like_source(name, entry, df, tmp_path / "src.rda")
    patched = dict(entry, source=dict(entry["source"],
                                      sha256=hashlib.sha256(payload).hexdigest()))
    urls = []
    out = data.obtain(name, tmp_path / "out.csv", local_dir=tmp_path / "nowhere",
                      registry={"datasets": {name: patched}},
                      fetch=lambda url: urls.append(url) or payload)
    assert urls == [entry["source"]["url"]]
    # byte-identical to the published CSV (float64 written at full precision)
    assert data.sha256_file(out) == entry["csv_sha256"]
    side = json.loads(out.with_suffix(".json").read_text())
    assert side["n"] == 3105250 and side["source"]["repository"] == entry["source"]["repository"]


def _wv_csv():
    return SHARED / "wv" / "navchip_wv.csv"


@needs_shared
def test_load_navchip_wv_keeps_file_ci():
    wv = data.load_navchip_wv(_wv_csv(), "gyro", "x")
    df = pd.read_csv(_wv_csv())
    rows = df[(df.sensor == "gyroscope") & (df.axis == "X")]
    assert np.array_equal(wv.levels, np.arange(1, 21))
    assert np.array_equal(wv.scales, 2.0 ** np.arange(1, 21))
    assert np.array_equal(wv.ci_low, rows.ci_low.to_numpy())
    assert np.array_equal(wv.variance, rows.variance.to_numpy())
    assert wv.n_samples == 3105250 and wv.freq == 250.0
    assert np.array_equal(wv.n, 3105250 - wv.scales.astype(int) + 1)


@needs_shared
def test_load_navchip_av_level_shift():
    av = data.load_navchip_av(SHARED / "av" / "navchip_av.csv", "accelerometer", "Z")
    wv = data.load_navchip_wv(_wv_csv(), "accelerometer", "Z")
    assert np.array_equal(av.clusters, 2 ** np.arange(1, 21))
    assert np.array_equal(av.levels, np.arange(2, 22))  # cluster 2^j = WV level j+1
    # AV = 2 WV at the same M_j terms; avar divides a (T - 2m)-term sum by T - 2m + 1 (docs/METHODS.md §2.4)
    assert np.allclose(av.avar[:19] / 2, wv.variance[1:], rtol=1e-3)
    assert np.all(av.ci_low >= 0) and np.all(av.ci_high > av.avar)


@needs_shared
def test_load_errors(tmp_path):
    with pytest.raises(InputError, match="sensor"):
        data.load_navchip_wv(_wv_csv(), "magnetometer", "X")
    with pytest.raises(InputError, match="axis"):
        data.load_navchip_wv(_wv_csv(), "gyro", "W")
    bad = tmp_path / "bad.csv"
    pd.read_csv(_wv_csv()).drop(columns=["variance"]).to_csv(bad, index=False)
    with pytest.raises(InputError, match="variance"):
        data.load_navchip_wv(bad, "gyro", "X", n_samples=3105250)
    # no sidecar json: the length must be given
    plain = tmp_path / "plain.csv"
    plain.write_bytes(_wv_csv().read_bytes())
    with pytest.raises(InputError, match="n_samples"):
        data.load_navchip_wv(plain, "gyro", "X")
    assert data.load_navchip_wv(plain, "gyro", "X", n_samples=3105250).n_samples == 3105250
    with pytest.raises(InputError, match="unknown dataset"):
        data.obtain("nope", tmp_path, allow_download=False)
