"""Formats people bring (issue 40 part 7) and one defined rate (part 4): ArduPilot DataFlash logs
written from the documented format and read back through pymavlink, vendor CSV headers with
units, phone export folders, exact duplicate rows, and the rate the estimate assumes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from _dataflash_writer import (
    IMU_INSTANCE,
    IMU_INSTANCE_UNITS,
    IMU_OLD,
    IMU_OLD_UNITS,
    Message,
    imu_rows,
    write_dataflash_bin,
    write_dataflash_text,
)
from gmwm.errors import InputError
from gmwm.readers import imu_topics, read_recording, read_recordings
from gmwm.readers.timebase import JITTER_LIMIT, time_base

pytest.importorskip("pymavlink")

EXTERNAL = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "external"
if not EXTERNAL.is_dir():
    EXTERNAL = Path("/work/shared/data/external")


def _imu(n: int, seed: int, offset: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Gyro (rad/s) and accel (m/s^2) samples as float32 (what the log stores)."""
    rng = np.random.default_rng(seed)
    g = (offset + 1e-3 * rng.standard_normal((n, 3))).astype(np.float32)
    a = (np.array([0.0, 0.0, -9.81]) + 1e-2 * rng.standard_normal((n, 3))).astype(np.float32)
    return g, a


N = 300
T_US = 3_000_000 + np.arange(N, dtype=np.int64) * 2500  # 400 Hz


# ------------------------------------------------------------------------------------------------
# ArduPilot DataFlash
# ------------------------------------------------------------------------------------------------

def _three_old(tmp_path: Path, writer=write_dataflash_bin, ext: str = "bin") -> tuple[Path, list]:
    """Older firmware: IMU, IMU2, IMU3 messages, each its own IMU (different values, stamps)."""
    data = [_imu(N, k, offset=k) for k in range(3)]
    msgs = [Message(name, *IMU_OLD, imu_rows(T_US + 11 * k, *data[k], None, temp=30.0 + k),
                    IMU_OLD_UNITS if k == 0 else None)
            for k, name in enumerate(("IMU", "IMU2", "IMU3"))]
    msgs += [Message("MSG", "QZ", "TimeUS,Message", [(int(T_US[0]), "ArduCopter V4.0.0")]),
             Message("PARM", "QNf", "TimeUS,Name,Value", [(int(T_US[1]), "INS_ACCEL_FILTER",
                                                          20.0)]),
             Message("GPS", "QBIH", "TimeUS,Status,GMS,GWk", [(int(t), 3, 1000 * i, 2300)
                                                              for i, t in enumerate(T_US[::40])])]
    return writer(tmp_path / f"old.{ext}", msgs), data


def _instances(tmp_path: Path, writer=write_dataflash_bin, ext: str = "bin") -> tuple[Path, list]:
    """Newer firmware: one IMU message with the instance in column I (marked # in FMTU)."""
    data = [_imu(N, 10 + k, offset=k) for k in range(3)]
    rows = [r for k in range(3) for r in imu_rows(T_US + 7 * k, *data[k], k, temp=40.0 + k)]
    return writer(tmp_path / f"new.{ext}", [Message("IMU", *IMU_INSTANCE, rows,
                                                     IMU_INSTANCE_UNITS)]), data


@pytest.mark.parametrize("form", ["old", "instance"])
@pytest.mark.parametrize("kind", ["bin", "log"])
def test_dataflash_every_imu_decodes_exactly(tmp_path, form, kind):
    writer = write_dataflash_bin if kind == "bin" else write_dataflash_text
    path, data = (_three_old if form == "old" else _instances)(tmp_path, writer, kind)
    assert imu_topics(path) == ["IMU[0]", "IMU[1]", "IMU[2]"]
    recs = read_recordings(path, "all")
    assert list(recs) == ["IMU[0]", "IMU[1]", "IMU[2]"]
    for k, (topic, rec) in enumerate(recs.items()):
        g, a = data[k]
        assert rec.format == "dataflash" and rec.topic == topic
        assert list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
        for i, c in enumerate("xyz"):  # float32 in the log, read to the bit
            np.testing.assert_array_equal(rec.channels[f"g{c}"], g[:, i].astype(np.float64))
            np.testing.assert_array_equal(rec.channels[f"a{c}"], a[:, i].astype(np.float64))
        assert rec.units["gx"] == "rad/s" and rec.units["az"] == "m/s^2"
        assert rec.roles["gx"] == "gyroscope" and rec.roles["az"] == "accelerometer"
        assert rec.time.freq == pytest.approx(400.0, rel=1e-12) and rec.time.unit == "us"
        assert rec.time.start_s == pytest.approx((T_US[0] + (11 if form == "old" else 7) * k)
                                                 * 1e-6)
        assert rec.temperature is not None
        assert rec.temperature[0] == (30.0 if form == "old" else 40.0) + k
    # --topic picks one; the old message names are aliases of the instances
    one = read_recording(path, topic="IMU[2]")
    np.testing.assert_array_equal(one.channels["gz"], recs["IMU[2]"].channels["gz"])
    np.testing.assert_array_equal(read_recording(path, topic="IMU2").channels["gx"],
                                  recs["IMU[1]"].channels["gx"])


def test_dataflash_binary_equals_pymavlinks_own_messages(tmp_path):
    """The NumPy decoding at pymavlink's offsets gives what its recv_match gives."""
    from pymavlink import DFReader

    path, _ = _instances(tmp_path)
    r = DFReader.DFReader_binary(str(path))
    got = {k: [] for k in range(3)}
    while (m := r.recv_match(type="IMU")) is not None:
        got[m.I].append((m.TimeUS, m.GyrX, m.AccZ))
    for k in range(3):
        rec = read_recording(path, topic=f"IMU[{k}]")
        t, gx, az = map(np.array, zip(*got[k], strict=True))
        np.testing.assert_array_equal(rec.time_s, (t - t[0]) * 1e-6)
        np.testing.assert_array_equal(rec.channels["gx"], gx)
        np.testing.assert_array_equal(rec.channels["az"], az)


def test_dataflash_topic_errors_list_the_imus(tmp_path):
    path, _ = _instances(tmp_path)
    with pytest.raises(InputError, match=r"logs 3 IMUs: choose one with --topic IMU\[N\] "
                                         r"\(IMU\[0\]: 300 messages.*--topic all"):
        read_recording(path)
    with pytest.raises(InputError, match=r"topic IMU\[5\] not in"):
        read_recording(path, topic="IMU[5]")
    with pytest.raises(InputError, match="unknown DataFlash IMU topic 'GPS'"):
        read_recording(path, topic="GPS")
    single = write_dataflash_bin(tmp_path / "one.bin", [
        Message("IMU", *IMU_OLD, imu_rows(T_US, *_imu(N, 1), None))])
    assert read_recording(single).topic == "IMU[0]"  # one IMU needs no --topic


def test_dataflash_units_other_than_si_are_refused(tmp_path):
    msgs = [Message("IMU", *IMU_OLD, imu_rows(T_US, *_imu(N, 1), None),
                    ("sOOOooo--O--zz", IMU_OLD_UNITS[1]))]  # gyro logged as degC: not rad/s
    path = write_dataflash_bin(tmp_path / "odd.bin", msgs)
    with pytest.raises(InputError, match="column GyrX of message IMU .* logged in degC, not "
                                         "rad/s"):
        read_recording(path)


def test_dataflash_not_a_log_and_no_imu(tmp_path):
    bad = tmp_path / "junk.bin"
    bad.write_bytes(b"\x00\x01junk" * 10)
    with pytest.raises(InputError, match=r"junk.bin is not a valid .bin file"):
        read_recording(bad)
    gps = write_dataflash_bin(tmp_path / "gps.bin", [
        Message("GPS", "QI", "TimeUS,GMS", [(int(t), 0) for t in T_US[:5]])])
    with pytest.raises(InputError, match=r"logs no IMU message \(IMU, IMU2, IMU3\)"):
        read_recording(gps)


# ------------------------------------------------------------------------------------------------
# vendor CSV headers with units, phone exports
# ------------------------------------------------------------------------------------------------

def _vendor_csv(path: Path, n: int = 400, fs: float = 100.0) -> tuple[Path, np.ndarray]:
    rng = np.random.default_rng(3)
    x = rng.standard_normal((n, 6)) * 1e-2 + [0, 0, 0, 0, 0, 1.0]
    mag = rng.standard_normal((n, 3)) * 40
    head = ("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
            "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g),Magnetometer X (uT),"
            "Magnetometer Y (uT),Magnetometer Z (uT),Temperature (°C),Quaternion W,Roll (deg)")
    rows = [",".join([f"{k / fs:.6f}", *(f"{v:.9g}" for v in x[k]), *(f"{v:.6g}" for v in mag[k]),
                      f"{25 + k * 1e-3:.4f}", "1.0", "0.5"]) for k in range(n)]
    path.write_text(head + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path, x


def test_vendor_csv_units_in_parentheses_map_to_axes(tmp_path):
    path, x = _vendor_csv(tmp_path / "vendor.csv")
    rec = read_recording(path)  # no --columns: the IMU columns are unambiguous
    assert list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
    assert rec.units["gx"] == "deg/s" and rec.units["az"] == "g"
    assert rec.roles["gy"] == "gyroscope" and rec.roles["ax"] == "accelerometer"
    np.testing.assert_allclose(rec.channels["gz"], x[:, 2], rtol=1e-8)
    np.testing.assert_allclose(rec.channels["az"], x[:, 5], rtol=1e-8)
    assert rec.time.freq == pytest.approx(100.0, rel=1e-6)
    assert rec.temperature is not None and rec.temperature[1] == pytest.approx(25.001)
    note = next(n for n in rec.notes if "IMU axes from the header" in n)
    assert "'Gyroscope X (deg/s)' -> gx [deg/s]" in note
    assert "convert deg/s to rad/s (x 0.0174533)" in note and "g to m/s^2 (x 9.80665)" in note
    assert "ignored: 'Magnetometer X (uT)'" in note and "'Quaternion W'" in note


@pytest.mark.parametrize("head, units", [
    ("t,gyro_x [rad/s],gyro_y [rad/s],gyro_z [rad/s],acc_x [m/s^2],acc_y [m/s^2],acc_z [m/s^2]",
     ("rad/s", "m/s^2")),
    ("time,gx (dps),gy (dps),gz (dps),ax (mg),ay (mg),az (mg),mx (uT)", ("deg/s", "mg")),
])
def test_vendor_csv_brackets_and_aliases(tmp_path, head, units):
    n = len(head.split(","))
    body = "\n".join(",".join([f"{k * 0.01:.2f}"] + [f"{0.1 * j + k * 1e-4:.6f}"
                                                     for j in range(1, n)]) for k in range(300))
    p = tmp_path / "v.csv"
    p.write_text(head + "\n" + body + "\n")
    rec = read_recording(p)
    assert list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
    assert (rec.units["gx"], rec.units["ax"]) == units


def test_vendor_csv_ambiguity_still_asks(tmp_path):
    p = tmp_path / "two.csv"  # raw and gravity-free acceleration: which one?
    p.write_text("t,Acceleration x (m/s^2),Linear Acceleration x (m/s^2)\n"
                 + "".join(f"{k * 0.01:.2f},{k},{k}\n" for k in range(100)))
    with pytest.raises(InputError, match="both hold the accelerometer x axis: choose with "
                                         "--columns"):
        read_recording(p)
    q = tmp_path / "nounit.csv"
    q.write_text("t,gyro_x (rad/s),gyro_y\n" + "".join(f"{k * 0.01:.2f},1,2\n"
                                                       for k in range(100)))
    with pytest.raises(InputError, match="'gyro_y' .* looks like a gyroscope axis but it has no "
                                         "unit"):
        read_recording(q)
    r = tmp_path / "wrong.csv"
    r.write_text("t,Gyroscope X (g)\n" + "".join(f"{k * 0.01:.2f},1\n" for k in range(100)))
    with pytest.raises(InputError, match="named like a gyroscope axis but its unit g"):
        read_recording(r)


def _phyphox(folder: Path, fg: float, fa: float, n: int = 800, lag: float = 0.0013,
             sep: str = ",") -> Path:
    """A phyphox-style export: Gyroscope.csv and Accelerometer.csv, each on its own clock."""
    folder.mkdir()
    rng = np.random.default_rng(5)
    for name, fs, t0, head, g in (
            ("Gyroscope.csv", fg, 0.0, ["Gyroscope x (rad/s)", "Gyroscope y (rad/s)",
                                        "Gyroscope z (rad/s)", "Absolute (rad/s)"], 0.0),
            ("Accelerometer.csv", fa, lag, ["Acceleration x (m/s^2)", "Acceleration y (m/s^2)",
                                            "Acceleration z (m/s^2)",
                                            "Absolute acceleration (m/s^2)"], 9.81)):
        m = int(n * fs / fg)
        v = rng.standard_normal((m, 3)) * 1e-2 + [0, 0, g]
        lines = [sep.join(f'"{h}"' for h in ["Time (s)", *head])]
        lines += [sep.join(f"{x:.9E}" for x in (t0 + k / fs, *v[k], np.linalg.norm(v[k])))
                  for k in range(m)]
        (folder / name).write_text("\n".join(lines) + "\n")
    return folder


def test_phone_folder_with_a_common_rate_is_one_six_axis_recording(tmp_path):
    folder = _phyphox(tmp_path / "phyphox", 200.0, 200.0)
    rec = read_recording(folder)
    assert rec.format == "phyphox"
    assert list(rec.channels) == ["gx", "gy", "gz", "ax", "ay", "az"]
    assert rec.units["gx"] == "rad/s" and rec.units["ax"] == "m/s^2"
    assert rec.time.freq == pytest.approx(200.0, rel=1e-6)
    assert rec.n == 800
    assert any("gyroscope 200 Hz (Gyroscope.csv), accelerometer 200 Hz (Accelerometer.csv), "
               "one common rate" in n for n in rec.notes)


@pytest.mark.slow
def test_phone_folder_without_a_common_rate_gives_each_sensor_its_rate(tmp_path):
    folder = _phyphox(tmp_path / "phone", 400.0, 100.0)
    with pytest.raises(InputError, match=r"no common rate \(gyroscope 400 Hz .*accelerometer "
                                         r"100 Hz.*--topic all"):
        read_recording(folder)
    assert imu_topics(folder) == ["Gyroscope", "Accelerometer"]
    recs = read_recordings(folder, "all")
    assert recs["Gyroscope"].time.freq == pytest.approx(400.0, rel=1e-6)
    assert recs["Accelerometer"].time.freq == pytest.approx(100.0, rel=1e-6)
    assert list(recs["Gyroscope"].channels) == ["gx", "gy", "gz"]
    assert list(recs["Accelerometer"].channels) == ["ax", "ay", "az"]
    # each sensor's fit runs at its own rate: the WV's scales in seconds follow it
    from gmwm import wvar

    for t, f in (("Gyroscope", 400.0), ("Accelerometer", 100.0)):
        r = recs[t]
        wv = wvar(r.channels[next(iter(r.channels))], freq=r.time.freq)
        assert wv.scales[0] / wv.freq == pytest.approx(2.0 / f, rel=1e-6)
    one = read_recording(folder, topic="accelerometer")
    assert one.topic == "Accelerometer" and one.n == 200


def test_phone_folder_semicolons_and_an_empty_folder(tmp_path):
    rec = read_recording(_phyphox(tmp_path / "semi", 100.0, 100.0, sep=";"))
    assert rec.n == 800
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="not a ROS 2 bag .* nor a phone sensor export"):
        read_recording(empty)


# ------------------------------------------------------------------------------------------------
# duplicate rows, one defined rate
# ------------------------------------------------------------------------------------------------

def test_exact_duplicate_rows_dropped_with_their_count(tmp_path):
    rows = [f"{k * 0.01:.2f},{k % 7},{k % 5}" for k in range(200)]
    dup = rows[:50] + [rows[49], rows[49]] + rows[50:120] + [rows[119]] + rows[120:]
    p = tmp_path / "dup.csv"
    p.write_text("time,gx [deg/s],gy [deg/s]\n" + "\n".join(dup) + "\n")
    rec = read_recording(p)
    assert rec.n == 200
    assert any("3 exact duplicate row(s) (same stamp, same values) dropped" in n
               for n in rec.notes)
    np.testing.assert_array_equal(rec.channels["gx"], [k % 7 for k in range(200)])


def test_repeated_stamp_with_other_values_is_an_error(tmp_path):
    rows = [f"{k * 0.01:.2f},{k % 7}" for k in range(100)]
    rows.insert(30, f"{29 * 0.01:.2f},99")
    p = tmp_path / "clash.csv"
    p.write_text("time,gx [deg/s]\n" + "\n".join(rows) + "\n")
    with pytest.raises(InputError, match=r"repeats a stamp at row 31 with a different gx "
                                         r"\(1 then 99\)"):
        read_recording(p)


def test_duplicates_in_a_dataflash_log(tmp_path):
    g, a = _imu(N, 1)
    rows = imu_rows(T_US, g, a, None)
    path = write_dataflash_bin(tmp_path / "dup.bin", [Message("IMU", *IMU_OLD,
                                                              rows + rows[100:104])])
    rec = read_recording(path)
    assert rec.n == N and any("4 exact duplicate row(s)" in n for n in rec.notes)


def test_the_rate_is_the_mean_rate_between_gaps():
    """(steps that are not gaps) / (their time): (n - 1) / span without gaps, whatever the
    jitter; short steps count, gaps do not."""
    rng = np.random.default_rng(2)
    d = 5e-3 * (1 + 0.03 * rng.standard_normal(3000))
    d[[500, 1700]] = [0.05, 0.08]  # two gaps
    d[900] = 1e-3  # a short step
    t = np.concatenate(([0.0], np.cumsum(d)))
    tb = time_base(t, unit="s")
    inside = np.delete(d, [500, 1700])
    assert tb.freq == pytest.approx(inside.size / inside.sum(), rel=1e-8)
    assert tb.overall_rate == pytest.approx(3000 / t[-1], rel=1e-8)
    assert tb.n_gaps == 2 and tb.rate_ambiguity is None
    clean = time_base(np.arange(1000) * 4e-3 + 7.0, unit="s")
    assert clean.freq == pytest.approx(250.0, rel=1e-9)
    assert clean.summary().startswith("250 Hz from") and "median step" not in clean.summary()


def test_ambiguous_rate_named_and_settled_by_freq(tmp_path):
    rng = np.random.default_rng(4)
    d = 5e-3 * np.abs(1 + 0.2 * rng.standard_normal(4000))  # 20 % jitter
    t = np.concatenate(([0.0], np.cumsum(d)))
    p = tmp_path / "jitter.csv"
    p.write_text("time,gx [rad/s]\n" + "".join(f"{s:.9f},{v:.6f}\n"
                                               for s, v in zip(t, rng.standard_normal(t.size),
                                                               strict=True)))
    rec = read_recording(p)
    assert rec.rate_ambiguous
    assert "jitter" in rec.rate_ambiguity and f"limit {100 * JITTER_LIMIT:g} %" in \
        rec.rate_ambiguity
    assert rec.rate_ambiguity.startswith("the sampling rate of time column 'time'")
    with pytest.raises(InputError, match=r"ambiguous: .*no configuration files written; give "
                                         r"--freq with the rate to assume \(the stamps allow "
                                         r".* Hz\) or a gap policy with --gaps$"):
        rec.require_rate()
    rec.require_rate(gaps_given=True)  # the user chose how gaps are handled: accepted
    assert any(n.endswith("a configuration file needs --freq or --gaps") for n in rec.notes)
    given = read_recording(p, freq=200.0)
    given.require_rate()
    assert not any(" is ambiguous: " in n for n in given.notes)
    assert not given.rate_ambiguous and given.time.freq == 200.0
    assert given.time.source.startswith("--freq")
    with pytest.raises(InputError, match="--freq 150 lies outside the rates the stamps"):
        read_recording(p, freq=150.0)
    # a regular recording is not ambiguous; --freq is then only checked
    q = tmp_path / "regular.csv"
    q.write_text("time,gx [rad/s]\n" + "".join(f"{k * 5e-3:.6f},{k % 3}\n" for k in range(500)))
    assert not read_recording(q).rate_ambiguous
    with pytest.raises(InputError, match="contradicts the sampling frequency"):
        read_recording(q, freq=150.0)


def test_gaps_beyond_the_limit_make_the_rate_ambiguous():
    d = np.full(2000, 5e-3)
    d[::50] = 0.03  # 40 gaps of 5 missing samples each: 9 % of the time lost
    tb = time_base(np.concatenate(([0.0], np.cumsum(d))), unit="s")
    assert tb.rate_ambiguity is not None and "gaps take" in tb.rate_ambiguity
    assert tb.freq == pytest.approx(200.0, rel=1e-9)  # the rate between the gaps


@pytest.mark.slow
def test_update_rate_is_the_defined_rate_on_every_surface(tmp_path):
    """The configuration's update_rate = the report's rate = the mean rate between gaps
    computed by hand from the stamps; --rostopic names the topic."""
    import yaml

    from gmwm.cli import main

    rng = np.random.default_rng(8)
    n = 2 ** 13  # above gmwm.verdict.MIN_SAMPLES: a configuration is written
    d = 5e-3 * (1 + 0.03 * rng.standard_normal(n - 1))
    d[1000] = 0.04  # one gap
    t = np.concatenate(([0.0], np.cumsum(d)))
    x = rng.standard_normal(n) * 0.1
    p = tmp_path / "imu.csv"
    p.write_text("Time (s),Gyroscope X (deg/s),Magnetometer X (uT)\n"
                 + "".join(f"{t[k]:.9f},{x[k]:.6f},40\n" for k in range(n)))
    inside = np.delete(np.diff(np.round(t, 9)), 1000)
    rate = inside.size / inside.sum()
    assert main(["report", str(p), "WN", "-o", str(tmp_path / "a"), "-q", "--gaps", "longest",
                 "--rostopic", "/phone/imu"]) == 0
    vals = yaml.safe_load((tmp_path / "a" / "imu.yaml").read_text())
    assert vals["update_rate"] == pytest.approx(rate, rel=1e-8)
    assert vals["rostopic"] == "/phone/imu"
    page = (tmp_path / "a" / "report.md").read_text()
    assert f"{vals['update_rate']:.6g} Hz from time column 'Time'" in page


def test_streamed_time_dataset_gives_the_same_rate(tmp_path):
    """Large HDF5 files are streamed: their rate is the same mean rate between gaps."""
    h5py = pytest.importorskip("h5py")
    from gmwm import stream

    rng = np.random.default_rng(6)
    d = 4e-3 * (1 + 0.02 * rng.standard_normal(5000))
    d[[1234, 4321]] = 0.03
    t = np.concatenate(([0.0], np.cumsum(d)))
    with h5py.File(tmp_path / "t.h5", "w") as f:
        f.create_dataset("t", data=t)
    with h5py.File(tmp_path / "t.h5", "r") as f:
        freq, _ = stream._stream_time_freq(f["t"], 1.0, "t", chunk=777)
    assert freq == pytest.approx(time_base(t, unit="s").freq, rel=1e-8)


def test_dataflash_of_old_firmware_with_timems(tmp_path):
    g, a = _imu(200, 3)
    rows = [(5000 + 20 * k, *map(float, g[k]), *map(float, a[k])) for k in range(200)]
    path = write_dataflash_bin(tmp_path / "old.bin", [
        Message("IMU", "Iffffff", "TimeMS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ", rows)])
    rec = read_recording(path)
    assert rec.time.freq == pytest.approx(50.0, rel=1e-12)
    assert rec.time.source == "TimeMS of IMU (ms)" and rec.time.start_s == pytest.approx(5.0)
    np.testing.assert_array_equal(rec.channels["ay"], a[:, 1].astype(np.float64))


def test_dataflash_damaged_bytes_are_a_note_not_a_flood(tmp_path, capfd):
    g, a = _imu(N, 2)
    path = write_dataflash_bin(tmp_path / "d.bin", [Message("IMU", *IMU_OLD,
                                                            imu_rows(T_US, g, a, None))])
    raw = path.read_bytes()
    import struct

    size = 3 + struct.calcsize("<" + IMU_OLD[0])  # one IMU message
    cut = 89 + 100 * size  # after the FMT message and 100 IMU messages
    path.write_bytes(raw[:cut] + b"\x00" * 700 + raw[cut:])
    rec = read_recording(path)
    assert rec.n == N
    np.testing.assert_array_equal(rec.channels["az"], a[:, 2].astype(np.float64))
    assert any("damaged data skipped by pymavlink" in n for n in rec.notes)
    out, err = capfd.readouterr()
    assert "bad header" not in out + err


def test_phone_export_as_a_zip_archive(tmp_path):
    """phyphox exports a zip of its CSV files (and a meta folder): read as the folder."""
    import zipfile

    folder = _phyphox(tmp_path / "ph", 100.0, 100.0)
    z = tmp_path / "Gyro and acc 2026-01-01.zip"
    with zipfile.ZipFile(z, "w") as f:
        for q in folder.iterdir():
            f.write(q, q.name)
        f.writestr("meta/device.csv", "property,value\nmodel,phone\n")
    rec = read_recording(z)
    direct = read_recording(folder)
    assert rec.format == "phyphox" and rec.path == str(z)
    for c in direct.channels:
        np.testing.assert_array_equal(rec.channels[c], direct.channels[c])
    assert rec.time.freq == direct.time.freq
    assert imu_topics(z) == ["Gyroscope", "Accelerometer"]
    assert read_recording(z, topic="Gyroscope").path == str(z / "Gyroscope.csv")
    assert not any("/tmp" in n and str(tmp_path) not in n for n in rec.notes)


def test_dataflash_numpy_layout_matches_pymavlinks_formats():
    """Every DataFlash format character decodes to as many bytes as pymavlink's struct code."""
    import struct

    from pymavlink.DFReader import FORMAT_TO_STRUCT

    from gmwm.readers.dataflash import _NP

    assert set(_NP) == set(FORMAT_TO_STRUCT)
    for c, (code, _, _) in FORMAT_TO_STRUCT.items():
        assert struct.calcsize("<" + code) == np.dtype("<" + _NP[c]).itemsize, c
