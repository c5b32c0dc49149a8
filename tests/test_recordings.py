"""Readers of real recordings: bags written by rosbags' own writers, ULog files by a small writer,
text and NumPy files, and the third-party files of the external data folder; each from signals
with known values, checked to the bit (values, stamps) and for rate, units and roles."""

from __future__ import annotations

import gzip
import math
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from _ulog_writer import write_ulog
from gmwm import Model, wvar
from gmwm.errors import InputError
from gmwm.readers.recording import read_recording
from gmwm.readers.timebase import decide_gaps, segments_wv, time_base

pytest.importorskip("rosbags")
pytest.importorskip("pyulog")

FS = 200.0
T0 = 1_700_000_000_000_000_000  # ns since 1970
EXTERNAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "external"
if not EXTERNAL.is_dir():
    EXTERNAL = Path("/work/shared/data/external")


def _signals(n: int, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Gyro (rad/s) and accel (m/s^2) axes: WN+RW with known coefficients, (n, 3) each."""
    model = Model("WN+RW", freq=FS)
    rng = np.random.default_rng(seed)
    g = np.stack([model.simulate(model.theta({"WN[1].sigma2": (1e-3) ** 2 * FS,
                                              "RW[1].gamma2": (1e-5) ** 2 / FS}), n, rng)
                  for _ in range(3)], axis=1)
    a = np.stack([9.81 * (k == 2) + model.simulate(model.theta({"WN[1].sigma2": (2e-2) ** 2 * FS,
                                                                "RW[1].gamma2": (1e-4) ** 2 / FS}),
                                                   n, rng) for k in range(3)], axis=1)
    return g, a


def _stamps(n: int, step_ns: int = 5_000_000) -> np.ndarray:
    return T0 + np.arange(n, dtype=np.int64) * step_ns


def _imu(ts, t: int, g, a, frame: str):
    Imu = ts.types["sensor_msgs/msg/Imu"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    V3 = ts.types["geometry_msgs/msg/Vector3"]
    Q = ts.types["geometry_msgs/msg/Quaternion"]
    cov = np.zeros(9)
    kw = {"seq": 0} if "seq" in Header.__dataclass_fields__ else {}
    return Imu(Header(**kw, stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id=frame),
               Q(0.0, 0.0, 0.0, 1.0), cov, V3(*map(float, g)), cov, V3(*map(float, a)), cov)


def _v3s(ts, t: int, v, frame: str):
    V3S = ts.types["geometry_msgs/msg/Vector3Stamped"]
    Header = ts.types["std_msgs/msg/Header"]
    Time = ts.types["builtin_interfaces/msg/Time"]
    kw = {"seq": 0} if "seq" in Header.__dataclass_fields__ else {}
    return V3S(Header(**kw, stamp=Time(sec=t // 10**9, nanosec=t % 10**9), frame_id=frame),
               ts.types["geometry_msgs/msg/Vector3"](*map(float, v)))


def write_bag(path: Path, kind: str, topics: dict, big_endian: bool = False) -> Path:
    """``topics[name] = (stamps, g, a, frame)`` (Imu) or ``(stamps, v, None, frame)``
    (Vector3Stamped), written by rosbags' writer of ``kind`` 'ros1', 'sqlite3' or 'mcap'."""
    from rosbags.typesys import Stores, get_typestore

    if kind == "ros1":
        from rosbags.rosbag1 import Writer

        ts = get_typestore(Stores.ROS1_NOETIC)
        writer = Writer(path)
        ser = ts.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        ts = get_typestore(Stores.ROS2_HUMBLE)
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(path, version=9, storage_plugin=plugin)

        def ser(m, t):
            return ts.serialize_cdr(m, t, little_endian=not big_endian)
    rows = []
    with writer as w:
        for name, (stamps, g, a, frame) in topics.items():
            mt = "sensor_msgs/msg/Imu" if a is not None else "geometry_msgs/msg/Vector3Stamped"
            conn = w.add_connection(name, mt, typestore=ts)
            for i, t in enumerate(stamps):
                m = _imu(ts, int(t), g[i], a[i], frame) if a is not None else \
                    _v3s(ts, int(t), g[i], frame)
                rows.append((int(t), conn, ser(m, mt)))
        for t, conn, data in sorted(rows, key=lambda r: r[0]):
            w.write(conn, t, data)
    return path


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    d = tmp_path_factory.mktemp("bags")
    n = 600
    g, a = _signals(n)
    g2, a2 = _signals(n // 2, seed=2)
    topics = {"/imu/data": (_stamps(n), g, a, "imu_link"),
              "/imu2/data": (_stamps(n // 2, 10_000_000), g2, a2, "imu"),
              "/camera/gyro": (_stamps(n), g, None, "cam_gyro_frame")}
    out = {"g": g, "a": a, "g2": g2, "n": n}
    for kind, name in (("ros1", "x.bag"), ("sqlite3", "x_db3"), ("mcap", "x_mcap")):
        out[kind] = write_bag(d / name, kind, topics)
    out["be"] = write_bag(d / "be_mcap", "mcap", {"/imu/data": topics["/imu/data"]},
                          big_endian=True)
    return out


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap", "be"])
def test_bag_imu_topic_decodes_exactly(bags, kind):
    rec = read_recording(bags[kind], topic="/imu/data")
    assert list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
    for k, ax in enumerate("xyz"):
        np.testing.assert_array_equal(rec.channels[f"g{ax}"], bags["g"][:, k])
        np.testing.assert_array_equal(rec.channels[f"a{ax}"], bags["a"][:, k])
    assert rec.units == {**dict.fromkeys(["gx", "gy", "gz"], "rad/s"),
                         **dict.fromkeys(["ax", "ay", "az"], "m/s^2")}
    assert set(rec.roles.values()) == {"gyroscope", "accelerometer"}
    assert rec.freq == FS and rec.time.unit == "ns" and rec.time.n_gaps == 0
    assert rec.time.start_s == pytest.approx(T0 * 1e-9)
    assert rec.format == {"ros1": "ros1", "sqlite3": "ros2-sqlite3"}.get(kind, "ros2-mcap")


def test_bag_decoding_matches_rosbags_deserializer(bags):
    from rosbags.highlevel import AnyReader

    rec = read_recording(bags["mcap"], topic="/imu2/data")
    with AnyReader([bags["mcap"]]) as r:
        conn = next(c for c in r.connections if c.topic == "/imu2/data")
        msgs = [r.deserialize(raw, conn.msgtype) for _, _, raw in r.messages([conn])]
    assert len(msgs) == rec.n == 300 and rec.freq == 100.0
    assert [m.angular_velocity.y for m in msgs] == rec.channels["gy"].tolist()
    assert [m.linear_acceleration.z for m in msgs] == rec.channels["az"].tolist()


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_several_imu_topics_need_topic_and_are_listed(bags, kind):
    with pytest.raises(InputError, match="2 IMU topics: choose one with --topic") as e:
        read_recording(bags[kind])
    msg = str(e.value)
    assert "/imu/data (sensor_msgs/Imu, 600 messages, 200 Hz)" in msg
    assert "/imu2/data (sensor_msgs/Imu, 300 messages, 100 Hz)" in msg


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_vector3stamped_topic_role_from_its_name(bags, kind):
    rec = read_recording(bags[kind], topic="/camera/gyro")
    assert list(rec.channels) == ["x", "y", "z"]
    np.testing.assert_array_equal(rec.channels["z"], bags["g"][:, 2])
    assert set(rec.roles.values()) == {"gyroscope"} and set(rec.units.values()) == {"rad/s"}


def test_unknown_topic_lists_topics(bags):
    with pytest.raises(InputError, match=r"topic '/nope' not in .*/imu2/data"):
        read_recording(bags["ros1"], topic="/nope")


def test_bag_out_of_order_and_dropped_messages(tmp_path):
    n = 400
    g, a = _signals(n, 3)
    st = _stamps(n)
    keep = np.ones(n, bool)
    keep[100:103] = False  # three samples lost: one gap of 4 steps
    order = np.arange(n)[keep]
    order[[10, 11]] = order[[11, 10]]  # received out of stamp order
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    with Writer(tmp_path / "o.bag") as w:  # record time = arrival order, stamps swapped
        c = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for i, k in enumerate(order):
            w.write(c, int(T0 + i), ts.serialize_ros1(_imu(ts, int(st[k]), g[k], a[k], "imu"),
                                                      "sensor_msgs/msg/Imu"))
    rec = read_recording(tmp_path / "o.bag")
    assert any("sorted" in m for m in rec.notes)
    np.testing.assert_array_equal(rec.channels["gx"], g[keep, 0])
    tb = rec.time
    assert (tb.n_gaps, tb.dropped, tb.freq) == (1, 3, FS)
    assert tb.longest_gap_s == pytest.approx(4 / FS)


def test_sqlite3_rows_out_of_record_time_order_read_like_rosbags(tmp_path, monkeypatch):
    """The sqlite3 fast path reads table rows in batches (here of 7 rows) and puts them in
    record-time order, ties in table order: the same messages, order and notes as rosbags'
    per-message iterator (ORDER BY timestamp)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from gmwm.readers import rosbag

    n = 60
    g, a = _signals(n, 4)
    st = _stamps(n)
    rec_t = T0 + np.arange(n) * 1000
    rec_t[[5, 6, 7]] = rec_t[[7, 5, 6]]  # rows stored out of record-time order
    rec_t[20:23] = rec_t[20]  # equal record times: table order decides
    st[[30, 31]] = st[[31, 30]]  # and header stamps out of order
    ts = get_typestore(Stores.ROS2_HUMBLE)
    with Writer(tmp_path / "o_db3", version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        c = w.add_connection("/imu", "sensor_msgs/msg/Imu", typestore=ts)
        for i in range(n):
            w.write(c, int(rec_t[i]), ts.serialize_cdr(_imu(ts, int(st[i]), g[i], a[i], "imu"),
                                                        "sensor_msgs/msg/Imu"))
    monkeypatch.setattr(rosbag, "_SQL_ROWS", 7)
    fast = rosbag.read_bag(tmp_path / "o_db3")
    monkeypatch.setattr(rosbag._Ros2, "_sqlite", staticmethod(lambda storage, conn: None))
    slow = rosbag.read_bag(tmp_path / "o_db3")
    np.testing.assert_array_equal(fast.stamp_ns, slow.stamp_ns)
    for k in slow.vectors:
        np.testing.assert_array_equal(fast.vectors[k], slow.vectors[k])
    assert fast.notes == slow.notes and any("sorted" in m for m in fast.notes)
    np.testing.assert_array_equal(np.sort(fast.stamp_ns), np.sort(st))


def _sensor_combined(n: int, g: np.ndarray, a: np.ndarray, t0_us: int = 5_000_000):
    fields = {"sensor_combined": [("timestamp", "uint64_t"), ("gyro_rad", "float[3]"),
                                  ("gyro_integral_dt", "float"),
                                  ("accelerometer_timestamp_relative", "int32_t"),
                                  ("accelerometer_m_s2", "float[3]"),
                                  ("accelerometer_integral_dt", "float")],
              "sensor_gyro": [("timestamp", "uint64_t"), ("timestamp_sample", "uint64_t"),
                              ("x", "float"), ("y", "float"), ("z", "float")]}
    t = t0_us + np.arange(n, dtype=np.uint64) * 4000
    sc = {"timestamp": t, "gyro_rad": g, "gyro_integral_dt": np.zeros(n),
          "accelerometer_timestamp_relative": np.zeros(n, int), "accelerometer_m_s2": a,
          "accelerometer_integral_dt": np.zeros(n)}
    gyro = {"timestamp": t + 100, "timestamp_sample": t, "x": g[:, 0], "y": g[:, 1],
            "z": g[:, 2]}
    return fields, sc, gyro


def test_ulog_sensor_combined_and_raw_instances(tmp_path):
    n = 500
    g, a = (x.astype(np.float32) for x in _signals(n, 4))
    fields, sc, gyro = _sensor_combined(n, g, a)
    p = write_ulog(tmp_path / "f.ulg", {("sensor_combined", 0): sc, ("sensor_gyro", 0): gyro,
                                        ("sensor_gyro", 1): gyro}, fields)
    rec = read_recording(p)
    assert rec.topic == "sensor_combined" and rec.freq == 250.0 and rec.time.unit == "us"
    np.testing.assert_array_equal(rec.channels["az"], a[:, 2].astype(np.float64))
    assert rec.units["gx"] == "rad/s" and rec.roles["ax"] == "accelerometer"
    with pytest.raises(InputError, match="2 instances of sensor_gyro"):
        read_recording(p, topic="sensor_gyro")
    raw = read_recording(p, topic="sensor_gyro:1")
    assert list(raw.channels) == ["gx", "gy", "gz"] and raw.freq == 250.0
    assert "timestamp_sample" in raw.time.source


# ---- text ----------------------------------------------------------------------------------------


def _euroc_text(n: int, g, a, step_ns: int = 5_000_000, sep: str = ",") -> str:
    head = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
            "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]").replace(",", sep)
    rows = [sep.join([str(T0 + i * step_ns), *(repr(float(v)) for v in (*g[i], *a[i]))])
            for i in range(n)]
    return head + "\n" + "\n".join(rows) + "\n"


def test_euroc_csv_units_roles_and_time_from_header(tmp_path):
    n = 300
    g, a = _signals(n, 5)
    p = tmp_path / "data.csv"
    p.write_text(_euroc_text(n, g, a))
    rec = read_recording(p)
    assert rec.format == "euroc" and next(iter(rec.channels)) == "w_RS_S_x"
    assert rec.units["w_RS_S_x"] == "rad/s" and rec.units["a_RS_S_z"] == "m/s^2"
    assert rec.freq == FS and rec.time.unit == "ns"
    np.testing.assert_array_equal(rec.channels["a_RS_S_y"], a[:, 1])
    gz = tmp_path / "data.csv.gz"  # gzip-compressed, same content
    gz.write_bytes(gzip.compress(p.read_bytes()))
    rec2 = read_recording(gz)
    np.testing.assert_array_equal(rec2.channels["w_RS_S_z"], g[:, 2])


def test_semicolons_decimal_commas_and_unlabelled_ns_stamps(tmp_path):
    n = 256
    x = np.round(np.random.default_rng(6).standard_normal(n), 6)
    p = tmp_path / "de.csv"
    p.write_text("timestamp;gx [deg/s]\n" + "".join(
        f"{T0 + i * 5_000_000};{str(float(v)).replace('.', ',')}\n" for i, v in enumerate(x)))
    rec = read_recording(p)
    np.testing.assert_array_equal(rec.channels["gx"], x)
    assert rec.freq == FS and rec.time.unit == "ns" and "magnitude" in rec.time.source
    assert rec.units["gx"] == "deg/s" and rec.roles["gx"] == "gyroscope"


def test_rostopic_echo_csv(tmp_path):
    n = 200
    g, a = _signals(n, 7)
    cols = ["%time", "field.header.seq", "field.header.stamp", "field.header.frame_id",
            *(f"field.orientation.{c}" for c in "xyzw"),
            *(f"field.angular_velocity.{c}" for c in "xyz"),
            *(f"field.linear_acceleration.{c}" for c in "xyz")]
    rows = [",".join([str(T0 + i * 5_000_000 + 777), str(i), str(T0 + i * 5_000_000), "imu",
                      "0", "0", "0", "1", *(repr(float(v)) for v in (*g[i], *a[i]))])
            for i in range(n)]
    p = tmp_path / "echo.csv"
    p.write_text(",".join(cols) + "\n" + "\n".join(rows) + "\n")
    rec = read_recording(p)
    assert rec.format == "rostopic" and list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
    np.testing.assert_array_equal(rec.channels["ay"], a[:, 1])
    assert "field.header.stamp" in rec.time.source and rec.freq == FS


def test_npz_with_time_and_with_freq(tmp_path):
    x = np.random.default_rng(8).standard_normal(512)
    np.savez(tmp_path / "a.npz", t_ms=np.arange(512) * 2.0, gx=x)
    rec = read_recording(tmp_path / "a.npz", units="mdps")
    assert rec.freq == 500.0 and rec.units["gx"] == "mdps"
    np.savez(tmp_path / "b.npz", imu=np.stack([x, 2 * x], 1), freq=np.float64(100.0))
    rec = read_recording(tmp_path / "b.npz", columns="all")
    assert list(rec.channels) == ["imu[0]", "imu[1]"] and rec.freq == 100.0


def test_npy_without_time_has_no_rate_until_freq(tmp_path):
    np.save(tmp_path / "x.npy", np.zeros(64) + np.arange(64))
    rec = read_recording(tmp_path / "x.npy")
    assert rec.time is None
    with pytest.raises(InputError, match="give --freq"):
        rec.require_time()
    assert read_recording(tmp_path / "x.npy", freq=100.0).freq == 100.0


# ---- time and gaps -----------------------------------------------------------------------------


@pytest.mark.parametrize(("unit", "step"), [("s", 0.005), ("ms", 5), ("us", 5000),
                                            ("ns", 5_000_000)])
def test_time_unit_from_magnitude(unit, step):
    t = np.arange(100) * step
    assert time_base(t, name="time").unit == unit
    epoch = {"s": 1.7e9, "ms": 1.7e12, "us": 1.7e15, "ns": 1.7e18}[unit]
    t = (np.int64(epoch) if unit != "s" else epoch) + np.arange(100) * step
    tb = time_base(t, name="stamp")
    assert tb.unit == unit and tb.freq == pytest.approx(FS)


def test_combined_segments_pool_coefficients_exactly():
    x = np.random.default_rng(9).standard_normal(3000)
    t = np.arange(3000) * 0.01
    t[1000:] += 0.05  # gap after sample 999
    t[2500:] += 1.0
    tb = time_base(t, name="t_s")
    assert tb.n_gaps == 2 and tb.dropped == 5 + 100
    dec = decide_gaps(tb)  # longest segment 1500 of 3000 samples: pooling
    assert dec.policy == "combine" and dec.used == 3000
    wv = segments_wv(x, dec.segments, levels=5, freq=100.0)
    for j in range(1, 6):
        tau = 2 ** j
        ss, cnt = 0.0, 0
        for a, b in dec.segments:
            c = np.convolve(x[a:b], np.r_[np.ones(tau // 2), -np.ones(tau // 2)] / tau, "valid")
            ss += float(np.sum(c * c))
            cnt += c.size
        assert wv.variance[j - 1] == pytest.approx(ss / cnt, rel=1e-10)
        assert wv.n[j - 1] == cnt
    assert decide_gaps(tb, "longest").segments == ((1000, 2500),)
    # the pooled WV carries the default interval of a contiguous one (mixture EDF)
    assert wv.ci_kind == "mixture"
    one = segments_wv(x, ((0, 3000),), levels=5, freq=100.0)
    ref = wvar(x, levels=5, freq=100.0)
    assert one.ci_kind == ref.ci_kind
    np.testing.assert_allclose(one.variance, ref.variance, rtol=1e-13)
    np.testing.assert_allclose(one.ci_low, ref.ci_low, rtol=1e-12)
    np.testing.assert_allclose(one.ci_high, ref.ci_high, rtol=1e-12)
    assert segments_wv(x, dec.segments, levels=5, freq=100.0, ci="eta3").ci_kind == "eta3"


# ---- the user's path: gmwm report FILE -o DIR, no options --------------------------------------


@pytest.mark.slow
def test_report_of_a_bag_needs_no_options_and_recovers_densities(tmp_path, capsys):
    import json

    from gmwm.cli import main

    n = 2 ** 14
    g, a = _signals(n, 10)
    bag = write_bag(tmp_path / "imu.bag", "ros1", {"/imu/data": (_stamps(n), g, a, "imu")})
    assert main(["report", str(bag), "-o", str(tmp_path / "rep"), "-q", "--json"]) == 0
    vals = yaml.safe_load((tmp_path / "rep" / "imu.yaml").read_text())
    assert vals["update_rate"] == FS and vals["rostopic"] == "/imu/data"
    # no model given: chosen per axis by the data, every candidate with the WN and RW filters need
    page = (tmp_path / "rep" / "report.md").read_text()
    assert page.count("chosen for the gyroscope") == 3
    assert page.count("chosen for the accelerometer") == 3
    # the largest of three axes: within ~5 % of the simulated 1e-3 and 2e-2 densities
    assert vals["gyroscope_noise_density"] == pytest.approx(1e-3, rel=0.06)
    assert vals["accelerometer_noise_density"] == pytest.approx(2e-2, rel=0.06)
    fits = json.loads(capsys.readouterr().out)["fits"]
    for name, f in fits.items():
        choice = f["model_choice"]
        assert "WN" in choice["model"] and "RW" in choice["model"], name
        assert choice["candidates"][0]["rank"] == 1 and "result" not in choice


# a whole report per unit (~0.6 s each): one accelerometer and one gyroscope unit in the inner
# loop, the other units' table entries in the full suite
@pytest.mark.parametrize(("unit", "factor"), [
    pytest.param("mg", 1e-3 * 9.80665, marks=pytest.mark.slow),
    pytest.param("ug", 1e-6 * 9.80665, marks=pytest.mark.slow),
    ("µg", 1e-6 * 9.80665), ("deg/h", math.pi / 648000),
    pytest.param("mdps", math.pi / 180000, marks=pytest.mark.slow)])
def test_report_yaml_in_si_for_every_unit(tmp_path, unit, factor, one_process):
    from gmwm.cli import main

    n = 2 ** 12
    x = Model("WN").simulate(np.array([FS]), n, np.random.default_rng(11))  # density 1 unit
    np.savez(tmp_path / "x.npz", sig=x, freq=np.float64(FS))
    assert main(["report", str(tmp_path / "x.npz"), "WN", "--units", unit, "-o",
                 str(tmp_path / "r"), "-q"]) == 0
    vals = yaml.safe_load((tmp_path / "r" / "imu.yaml").read_text())
    key = "gyroscope_noise_density" if unit in ("deg/h", "mdps") else "accelerometer_noise_density"
    assert vals[key] == pytest.approx(factor, rel=0.05)


# ---- third-party files (external data folder; absent: skipped) --------------------------------

needs_external = pytest.mark.skipif(not EXTERNAL.is_dir(), reason="external data folder absent")


@needs_external
@pytest.mark.parametrize(("rel", "topic", "count", "rate", "fmt"), [
    ("ros1-rl-husky/test1.bag", "/imu/data", 11865, 30.013, "ros1"),
    ("ros1-imutools-phidgets/phidgets_imu_upside_down.bag", "/imu/data_raw", 13964, 250.0, "ros1"),
    ("px4-pyulog-sample/sample.ulg", "sensor_combined", 17070, 250.0, "ulog"),
    ("euroc-kimera-v101/mav0/imu0/data.csv", None, 29120, 200.0, "euroc")])
def test_external_recordings(rel, topic, count, rate, fmt):
    rec = read_recording(EXTERNAL / rel)
    assert rec.format == fmt and rec.topic == topic and rec.n == count
    assert rec.freq == pytest.approx(rate, rel=0.01)
    gyro = [k for k, r in rec.roles.items() if r == "gyroscope"]
    acc = [k for k, r in rec.roles.items() if r == "accelerometer"]
    assert len(gyro) == len(acc) == 3
    assert {rec.units[k] for k in gyro} == {"rad/s"} and {rec.units[k] for k in acc} == {"m/s^2"}
    norm = np.sqrt(sum(rec.channels[k] ** 2 for k in acc))
    assert 9.5 < norm.mean() < 10.9  # SI accelerations: gravity
    if fmt == "euroc":
        assert rec.time.n_gaps == 0 and rec.time.duration_s == pytest.approx(145.6, abs=0.01)
    if rel.startswith("px4"):
        assert rec.time.n_gaps == 8 and rec.time.longest_gap_s == pytest.approx(0.0648, abs=1e-3)


def test_import_gmwm_stays_light():
    import subprocess

    code = ("import sys, gmwm, gmwm.readers.recording; "
            "print(any(m.startswith(('rosbags', 'pyulog', 'pandas')) for m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
