"""Several IMUs in one run: every IMU stream of a bag (written by rosbags' own writers) or a ULog
read at once, calibrated together (in worker processes too) and written as one page with a
section and a folder of configuration files per IMU, each matching its own simulated truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from _ulog_writer import write_ulog
from gmwm import Model
from gmwm.calibrate import calibrate_imus
from gmwm.errors import InputError
from gmwm.readers import imu_topics, read_recording, read_recordings
from gmwm.report import imu_folders, write_multi_report
from test_recordings import T0, _sensor_combined, write_bag

pytest.importorskip("rosbags")
pytest.importorskip("pyulog")

N = 2 ** 13
# (rate Hz, gyro white density rad/s/sqrt(Hz), accel white density m/s^2/sqrt(Hz)) per IMU
TRUTH = {"/imu0/data": (200.0, 1e-3, 2e-2), "/imu1/data": (100.0, 4e-3, 6e-2)}


def _simulate(rate: float, gyro: float, acc: float, seed: int):
    """WN+RW axes with continuous densities ``gyro``/``acc`` (and small random walks)."""
    m = Model("WN+RW", freq=rate)
    rng = np.random.default_rng(seed)
    tg = m.theta({"WN[1].sigma2": gyro ** 2 * rate, "RW[1].gamma2": (gyro / 100) ** 2 / rate})
    ta = m.theta({"WN[1].sigma2": acc ** 2 * rate, "RW[1].gamma2": (acc / 200) ** 2 / rate})
    g = np.stack([m.simulate(tg, N, rng) for _ in range(3)], axis=1)
    a = np.stack([m.simulate(ta, N, rng) + 9.81 * (k == 2) for k in range(3)], axis=1)
    return g, a


@pytest.fixture(scope="module")
def two_imu_bags(tmp_path_factory):
    d = tmp_path_factory.mktemp("multi")
    topics, sims = {}, {}
    for i, (topic, (rate, gd, ad)) in enumerate(TRUTH.items()):
        g, a = _simulate(rate, gd, ad, 20 + i)
        sims[topic] = (g, a)
        topics[topic] = (T0 + np.arange(N, dtype=np.int64) * int(1e9 / rate), g, a, f"imu{i}")
    return {"ros1": write_bag(d / "two.bag", "ros1", topics),
            "mcap": write_bag(d / "two_mcap", "mcap", topics), "sims": sims}


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_read_recordings_all_gives_every_imu_with_its_rate_and_units(two_imu_bags, kind):
    bag = two_imu_bags[kind]
    assert imu_topics(bag) == list(TRUTH)
    recs = read_recordings(bag, "all")
    assert list(recs) == list(TRUTH)
    for topic, rec in recs.items():
        g, a = two_imu_bags["sims"][topic]
        assert rec.topic == topic and rec.n == N and rec.freq == TRUTH[topic][0]
        assert rec.format == ("ros1" if kind == "ros1" else "ros2-mcap")
        assert {rec.units[c] for c in ("gx", "gy", "gz")} == {"rad/s"}
        assert {rec.units[c] for c in ("ax", "ay", "az")} == {"m/s^2"}
        np.testing.assert_array_equal(rec.channels["gy"], g[:, 1])
        np.testing.assert_array_equal(rec.channels["az"], a[:, 2])
    # a list keeps its order (a leading "/" may be left out); each equals the single read
    picked = read_recordings(bag, ["imu1/data", "/imu0/data"])
    assert list(picked) == ["/imu1/data", "/imu0/data"]
    one = read_recording(bag, topic="/imu1/data")
    np.testing.assert_array_equal(picked["/imu1/data"].channels["gx"], one.channels["gx"])
    assert picked["/imu1/data"].time == one.time


def test_read_recordings_errors_name_the_problem(two_imu_bags, tmp_path):
    bag = two_imu_bags["ros1"]
    with pytest.raises(InputError, match=r"topic '/nope' not in .*/imu1/data"):
        read_recordings(bag, ["/imu0/data", "/nope"])
    with pytest.raises(InputError, match="requested twice"):
        read_recordings(bag, ["/imu0/data", "imu0/data"])
    (tmp_path / "x.csv").write_text("t,gx\n0,1\n0.01,2\n")
    with pytest.raises(InputError, match="applies to ROS bags and ULog files"):
        read_recordings(tmp_path / "x.csv", "all")


def test_imu_topics_lists_named_vector3stamped_streams(tmp_path):
    g, a = _simulate(200.0, 1e-3, 2e-2, 3)
    st = T0 + np.arange(N // 16, dtype=np.int64) * 5_000_000
    k = N // 16
    bag = write_bag(tmp_path / "v.bag", "ros1", {
        "/imu/data": (st, g[:k], a[:k], "imu"), "/camera/gyro": (st, g[:k], None, "cam"),
        "/odom/velocity": (st, a[:k], None, "base")})
    assert imu_topics(bag) == ["/imu/data", "/camera/gyro"]
    only_v3 = write_bag(tmp_path / "w.bag", "ros1", {"/odom/velocity": (st, a[:k], None, "b")})
    assert imu_topics(only_v3) == ["/odom/velocity"]  # as the single-topic default reads it


def test_ulog_streams_are_raw_instances_read_in_one_parse(tmp_path):
    n = 300
    g, a = (x.astype(np.float32) for x in _simulate(250.0, 1e-3, 2e-2, 4))
    fields, sc, gyro = _sensor_combined(n, g[:n], a[:n])
    fields["sensor_accel"] = fields["sensor_gyro"]
    acc = {**gyro, "x": a[:n, 0], "y": a[:n, 1], "z": a[:n, 2]}
    p = write_ulog(tmp_path / "f.ulg", {("sensor_combined", 0): sc, ("sensor_gyro", 0): gyro,
                                        ("sensor_gyro", 1): gyro, ("sensor_accel", 0): acc},
                   fields)
    assert imu_topics(p) == ["sensor_gyro:0", "sensor_accel:0", "sensor_gyro:1"]
    recs = read_recordings(p, "all")
    assert list(recs) == imu_topics(p)
    assert list(recs["sensor_accel:0"].channels) == ["ax", "ay", "az"]
    assert recs["sensor_gyro:1"].freq == 250.0
    np.testing.assert_array_equal(recs["sensor_accel:0"].channels["az"], a[:n, 2])
    assert list(read_recordings(p, ["sensor_combined"])) == ["sensor_combined"]


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_multi_imu_report_one_page_and_a_folder_per_imu(two_imu_bags, tmp_path, kind):
    recs = read_recordings(two_imu_bags[kind], "all")
    imus = calibrate_imus(recs, "WN+RW", fit_options={"seed": 1},
                          workers=2 if kind == "ros1" else 1)
    out = tmp_path / "rep"
    files = write_multi_report(out, imus, source="two.bag", title="Two IMUs",
                               targets=("kalibr", "openvins"))
    md = (out / "report.md").read_text()
    page = (out / "report.html").read_text()
    folders = imu_folders(list(TRUTH))
    assert folders == {"/imu0/data": "imu0_data", "/imu1/data": "imu1_data"}
    for topic, (rate, gd, ad) in TRUTH.items():
        f = folders[topic]
        assert f"## IMU {topic}" in md and f"<h2>IMU {topic}</h2>" in page
        assert f"![WV of gx with the fitted model]({f}_gx_wv.png)" in md
        assert (out / f"{f}_gx_wv.png").is_file() and (out / f"{f}_stationarity.png").is_file()
        assert (out / f / "kalibr_imu_chain.yaml").is_file()  # the other target, per IMU
        vals = yaml.safe_load((out / f / "imu.yaml").read_text())
        assert vals["rostopic"] == topic and vals["update_rate"] == rate
        # the worst of three axes, each within a few % (N = 8192 samples) of its own truth
        assert vals["gyroscope_noise_density"] == pytest.approx(gd, rel=0.1)
        assert vals["accelerometer_noise_density"] == pytest.approx(ad, rel=0.1)
    assert md.count("### Stationarity") == 2 and md.count("### Summary") == 2
    assert not (out / "imu.yaml").exists()
    assert {p.name for p in files} >= {"report.md", "report.html", "imu.yaml"}


def test_parallel_fits_equal_serial_fits(two_imu_bags):
    recs = read_recordings(two_imu_bags["ros1"], "all")
    serial = calibrate_imus(recs, "WN+RW", fit_options={"seed": 1}, workers=1)
    for executor in ("process", "thread"):
        par = calibrate_imus(recs, "WN+RW", fit_options={"seed": 1}, workers=2,
                             executor=executor)
        for topic, sec in serial.items():
            for c, a in sec.axes.items():
                np.testing.assert_array_equal(par[topic].axes[c]["result"].params,
                                              a["result"].params)


@pytest.mark.slow
def test_one_imu_with_all_gives_the_single_imu_layout(tmp_path):
    g, a = _simulate(200.0, 1e-3, 2e-2, 5)
    st = T0 + np.arange(N, dtype=np.int64) * 5_000_000
    bag = write_bag(tmp_path / "one.bag", "ros1", {"/imu/data": (st, g, a, "imu")})
    recs = read_recordings(bag, "all")
    assert list(recs) == ["/imu/data"]
    imus = calibrate_imus(recs, "WN+RW", workers=1)
    write_multi_report(tmp_path / "r", imus, source="one.bag", title="One")
    md = (tmp_path / "r" / "report.md").read_text()
    assert "## IMU" not in md and "## Stationarity" in md and (tmp_path / "r" / "gx_wv.png").is_file()
    vals = yaml.safe_load((tmp_path / "r" / "imu.yaml").read_text())
    assert vals["rostopic"] == "/imu/data"
    assert vals["gyroscope_noise_density"] == pytest.approx(1e-3, rel=0.1)


def test_imu_folders_are_distinct():
    assert imu_folders(["/imu/data", "/imu_data", "sensor_gyro:1", "/"]) == {
        "/imu/data": "imu_data", "/imu_data": "imu_data-2", "sensor_gyro:1": "sensor_gyro_1",
        "/": "imu"}


@pytest.mark.slow
def test_ulog_streams_have_no_rostopic(tmp_path):
    # a ULog stream name is not a ROS topic: its configuration files hold the placeholder
    n = N  # 2^13 samples: above gmwm.verdict.MIN_SAMPLES
    g, a = (x.astype(np.float32) for x in _simulate(250.0, 1e-3, 2e-2, 6))
    fields, _, gyro = _sensor_combined(n, g[:n], a[:n])
    p = write_ulog(tmp_path / "f.ulg", {("sensor_gyro", 0): gyro, ("sensor_gyro", 1): gyro},
                   fields)
    imus = calibrate_imus(read_recordings(p, "all"), "WN+RW", workers=1)
    assert [s.rostopic for s in imus.values()] == [None, None]
    write_multi_report(tmp_path / "r", imus, source=Path(p).name, title="U")
    assert (tmp_path / "r" / "sensor_gyro_1" / "imu.yaml").is_file()


def test_prepare_longest_static_avoids_the_flagged_range(tmp_path):
    from gmwm.calibrate import prepare
    from gmwm.stationarity import NonStationaryError

    g, _ = _simulate(200.0, 1e-3, 2e-2, 7)
    x = g[:, 0].copy()
    x[int(0.7 * N):int(0.72 * N)] += 0.5  # a short bump at 70 %: the static start is longest
    np.savez(tmp_path / "b.npz", t_s=np.arange(N) / 200.0, gx=x)
    rec = read_recording(tmp_path / "b.npz", units="rad/s")
    prep = prepare(rec, segment="longest-static")
    st = prep.stationarity
    a, b = st.used
    assert st.segments and all(s.i1 <= a or s.i0 >= b for s in st.segments)
    assert a == 0 and b - a > N // 2 and prep.recording.n == b - a
    with pytest.raises(NonStationaryError, match="not static in the part used"):
        prepare(rec, strict=True)


@pytest.mark.slow
def test_cli_report_topic_all_and_repeated_topics(two_imu_bags, tmp_path, capsys):
    import json

    from gmwm.cli import main

    bag = str(two_imu_bags["ros1"])
    out = tmp_path / "rep"
    code = main(["report", bag, "--topic", "all", "-o", str(out), "--json", "-q",
                 "--export", "kalibr,openvins"])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    obj = json.loads(cap.out)
    assert list(obj["imus"]) == list(TRUTH)
    for topic, (rate, gd, _) in TRUTH.items():
        fits = obj["imus"][topic]["fits"]
        assert set(fits) == {"gx", "gy", "gz", "ax", "ay", "az"}
        # no model given: chosen per axis, with the WN and RW terms filters need
        assert all("WN" in f["model_choice"]["model"] and "RW" in f["model_choice"]["model"]
                   for f in fits.values())
        folder = imu_folders(list(TRUTH))[topic]
        vals = yaml.safe_load((out / folder / "imu.yaml").read_text())
        assert vals["rostopic"] == topic and vals["update_rate"] == rate
        assert vals["gyroscope_noise_density"] == pytest.approx(gd, rel=0.1)
        assert (out / folder / "kalibr_imu_chain.yaml").is_file()
    # the same two topics named one by one, with an explicit model
    out2 = tmp_path / "rep2"
    assert main(["report", bag, "WN+RW", "--topic", "/imu1/data", "--topic", "/imu0/data",
                 "-o", str(out2), "-q"]) == 0
    md = (out2 / "report.md").read_text()
    assert md.index("## IMU /imu1/data") < md.index("## IMU /imu0/data")
    capsys.readouterr()
    # several topics are for the report only, and 'all' stands alone
    assert main(["fit", bag, "WN+RW", "--topic", "all"]) == 2
    assert main(["report", bag, "--topic", "all", "--topic", "/imu0/data", "-o",
                 str(tmp_path / "r3")]) == 2
    err = capsys.readouterr().err
    assert "gmwm report" in err and "give it alone" in err


# -- one calibration path: one topic alone or among all, and topics that fail ----------------------
def _values(path: Path) -> dict:
    """The configuration values of an imu.yaml (its comment header names the source)."""
    return yaml.safe_load(path.read_text())


@pytest.mark.slow
def test_one_topic_alone_or_in_topic_all_gives_identical_results(two_imu_bags, tmp_path, capsys):
    from gmwm.calibrate import calibrate
    from gmwm.cli import main

    bag = two_imu_bags["ros1"]
    cols = ["gx", "ax"]  # one gyroscope and one accelerometer axis keep it short
    alone = calibrate(bag, "WN+RW", topics="/imu1/data", columns=cols, fit={"seed": 1},
                      workers=1)
    every = calibrate(bag, "WN+RW", topics="all", columns=cols, fit={"seed": 1}, workers=2)
    assert not alone.several and every.several and list(every.topics) == list(TRUTH)
    one, same = alone.only(), every.topics["/imu1/data"]
    assert one.ok and same.ok and one.freq == same.freq == 100.0
    assert one.rostopic == same.rostopic == "/imu1/data"
    for c, a in one.axes.items():
        np.testing.assert_array_equal(a.result.params, same.axes[c].result.params)
        assert a.datasheet == same.axes[c].datasheet
    # the command line: the same configuration values through gmwm report, one topic or all
    for args, out in ((["--topic", "/imu1/data"], "c1"), (["--topic", "all"], "c2")):
        assert main(["report", str(bag), "WN+RW", *args, "--columns", "gx,ax", "-o",
                     str(tmp_path / out), "-q"]) == 0
    capsys.readouterr()
    vals = _values(tmp_path / "c1" / "imu.yaml")
    assert vals == _values(tmp_path / "c2" / "imu1_data" / "imu.yaml")
    assert vals["update_rate"] == 100.0 and vals["rostopic"] == "/imu1/data"
    assert vals["accelerometer_noise_density"] == pytest.approx(TRUTH["/imu1/data"][2], rel=0.1)


@pytest.fixture(scope="module")
def broken_bag(tmp_path_factory):
    """Three IMU topics: /imu0/data fine, /imu1/data with a repeated stamp (different values),
    /imu2/data too short for a fit."""
    g, a = _simulate(200.0, 1e-3, 2e-2, 8)
    st = T0 + np.arange(N, dtype=np.int64) * 5_000_000
    bad = st.copy()
    bad[100] = bad[99]
    return write_bag(tmp_path_factory.mktemp("broken") / "broken.bag", "ros1", {
        "/imu0/data": (st, g, a, "imu0"), "/imu1/data": (bad, g, a, "imu1"),
        "/imu2/data": (st[:3], g[:3], a[:3], "imu2")})


def test_a_broken_topic_does_not_stop_the_others(broken_bag):
    from gmwm.calibrate import calibrate

    res = calibrate(broken_bag, "WN+RW", topics="all", fit={"seed": 1}, workers=2)
    assert list(res.topics) == ["/imu0/data", "/imu1/data", "/imu2/data"]
    assert list(res.calibrated) == ["/imu0/data"]
    assert set(res.failed) == {"/imu1/data", "/imu2/data"}
    assert "repeats a stamp" in res.failed["/imu1/data"]
    assert all("\n" not in r for r in res.failed.values())
    assert res.to_json_dict()["topics"]["/imu1/data"]["status"] == "failed"
    alone = calibrate(broken_bag, "WN+RW", topics="/imu0/data", fit={"seed": 1}, workers=1)
    for c, a in alone.only().axes.items():
        np.testing.assert_array_equal(a.result.params,
                                      res.topics["/imu0/data"].axes[c].result.params)
    with pytest.raises(InputError, match="repeats a stamp"):  # alone: its own error
        calibrate(broken_bag, "WN+RW", topics="/imu1/data")


@pytest.mark.slow
def test_cli_topic_all_lists_failed_topics_with_exit_status_4(broken_bag, tmp_path, capsys):
    import json

    from gmwm.cli import main

    out = tmp_path / "rep"
    code = main(["report", str(broken_bag), "WN+RW", "--topic", "all", "--columns", "gx,az",
                 "-o", str(out), "-q", "--json"])
    cap = capsys.readouterr()
    assert code == 4, cap.err
    obj = json.loads(cap.out)
    assert list(obj["imus"]) == ["/imu0/data"]
    assert set(obj["failed"]) == {"/imu1/data", "/imu2/data"}
    assert "gmwm: warning: /imu1/data: not calibrated: header.stamp" in cap.err
    assert "2 of 3 topics not calibrated (/imu1/data, /imu2/data)" in cap.err
    assert "Traceback" not in cap.err
    md = (out / "report.md").read_text()
    assert "## IMU /imu1/data" in md and "Not calibrated: header.stamp" in md
    assert "| /imu2/data | FAILED: " in md
    assert (out / "imu0_data" / "imu.yaml").is_file()
    assert not (out / "imu1_data").exists() and not (out / "imu2_data").exists()
    # one broken topic asked for alone: the one-line error, exit status 1
    assert main(["report", str(broken_bag), "--topic", "/imu1/data", "-o",
                 str(tmp_path / "r1")]) == 1
    err = capsys.readouterr().err
    assert err.startswith("gmwm: error: header.stamp") and err.count("\n") == 1
    # the exit status is documented
    assert main(["report", "--help"]) == 0
    assert "4  (report, several topics) some topics could not be calibrated" in \
        capsys.readouterr().out
