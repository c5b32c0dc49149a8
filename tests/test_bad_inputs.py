"""Bad recordings, one class per case: formats, timestamps, units, topics and gaps. Each gives one
exception of the stated type whose one-line message names the problem, never a wrong number."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from _ulog_writer import write_ulog
from gmwm.errors import GMWMError, InputError
from gmwm.readers.recording import read_recording
from gmwm.readers.timebase import decide_gaps, segments_wv, time_base
from gmwm.units import parse_unit
from test_recordings import T0, _sensor_combined, _signals, _stamps, write_bag

pytest.importorskip("rosbags")


def _csv(d: Path, name: str, text: str) -> Path:
    p = d / name
    p.write_text(text)
    return p


def _rows(n: int, step, t0=0, fmt=str) -> str:
    return "".join(f"{fmt(t0 + i * step)},{np.sin(i):.6f}\n" for i in range(n))


def _bag(d: Path, kind: str, topics: dict) -> Path:
    return write_bag(d / f"b_{kind}_{len(topics)}", kind, topics)


def _imu_topic(n=64, step=5_000_000, seed=0):
    g, a = _signals(n, seed)
    return (_stamps(n, step), g, a, "imu")


# name -> (builder(tmp_path) -> zero-argument call, exception type, regex of the message)
CASES = {
    # ---- formats ----
    "missing file": (lambda d: lambda: read_recording(d / "nope.csv"), InputError,
                     "file not found"),
    "empty file": (lambda d: lambda: read_recording(_csv(d, "e.csv", "")), InputError, "is empty"),
    "only comments": (lambda d: lambda: read_recording(_csv(d, "c.csv", "# a\n# b\n")),
                      InputError, "only comment lines"),
    "header without rows": (lambda d: lambda: read_recording(_csv(d, "h.csv", "t,gx\n")),
                            InputError, "no data rows"),
    "unknown extension": (lambda d: lambda: read_recording(_csv(d, "x.xlsx", "1\n")), InputError,
                          "unknown file extension '.xlsx'"),
    "binary with .csv suffix": (lambda d: lambda: read_recording(
        (d / "b.csv").write_bytes(b"\xff\xfe\x00\x81" * 10) and d / "b.csv"), InputError,
        "not UTF-8 text"),
    "bag suffix, not a bag": (lambda d: lambda: read_recording(_csv(d, "x.bag", "hello\n")),
                              InputError, r"not a valid \.bag file"),
    "ulg suffix, not a ULog": (lambda d: lambda: read_recording(_csv(d, "x.ulg", "hello\n")),
                               InputError, r"not a valid \.ulg file"),
    "truncated ROS 1 bag": (lambda d: lambda: read_recording(
        (d / "t.bag").write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 10) and d / "t.bag"),
        InputError, "cannot read the bag"),
    "folder without metadata.yaml": (lambda d: lambda: read_recording(d), InputError,
                                     "not a ROS 2 bag"),
    "corrupt gzip": (lambda d: lambda: read_recording(
        (d / "z.csv.gz").write_bytes(gzip.compress(("t_s,gx\n" + _rows(4000, 0.01)).encode())[:4000]) and d / "z.csv.gz"),
        InputError, "cannot"),
    "header and rows disagree": (lambda d: lambda: read_recording(
        _csv(d, "m.csv", "a,b,c\n1,2\n3,4\n")), InputError, "header has 3 fields"),
    "text in a numeric column": (lambda d: lambda: read_recording(
        _csv(d, "n.csv", "gx\n1\n2\nthree\n")), InputError, "not numeric: row 3"),
    "NaN in a signal": (lambda d: lambda: read_recording(_csv(d, "nan.csv", "gx\n1\nnan\n2\n")),
                        InputError, "NaN"),
    "npz with objects": (lambda d: lambda: read_recording(
        (np.savez(d / "o.npz", x=np.array([{}, 1], dtype=object)), d / "o.npz")[1]), InputError,
        "Python objects"),
    "npz with a 3-D array": (lambda d: lambda: read_recording(
        (np.savez(d / "c.npz", x=np.zeros((4, 4, 4))), d / "c.npz")[1]), InputError,
        r"shape \(4, 4, 4\)"),
    "several columns, none chosen": (lambda d: lambda: read_recording(
        _csv(d, "two.csv", "a,b\n" + "1,2\n" * 80)), InputError, "choose one with --column"),
    "unknown column": (lambda d: lambda: read_recording(
        _csv(d, "u.csv", "a,b\n" + "1,2\n" * 80), columns=["c"]), InputError,
        "column 'c' not found"),
    "time column taken as a signal": (lambda d: lambda: read_recording(
        _csv(d, "tc.csv", "time_s,gx\n" + _rows(80, 0.01)), columns=["time_s"]), InputError,
        "is the time column"),
    "column index out of range": (lambda d: lambda: read_recording(
        _csv(d, "ci.csv", "t_s,gx\n" + _rows(80, 0.01)), columns=[5]), InputError,
        "index 5 out of range"),
    "column requested twice": (lambda d: lambda: read_recording(
        _csv(d, "ct.csv", "t_s,gx\n" + _rows(80, 0.01)), columns=["gx", "gx"]), InputError,
        "requested twice"),
    # ---- timestamps ----
    "ns stamps labelled as seconds": (lambda d: lambda: read_recording(
        _csv(d, "ns.csv", "time [s],gx\n" + _rows(80, 5_000_000, T0))), InputError,
        r"gives a sampling rate of 2e-07 Hz.*200 Hz if ns"),
    "ambiguous unlabelled stamps": (lambda d: lambda: read_recording(
        _csv(d, "amb.csv", "time,gx\n" + _rows(80, 1))), InputError,
        r"time column 'time'.*1 Hz if s, 1000 Hz if ms.*--time-unit"),
    "no unit gives an IMU rate": (lambda d: lambda: time_base(np.arange(50) * 3e-6, name="t"),
                                  InputError, "no unit gives a sampling rate"),
    "repeated stamp": (lambda d: lambda: read_recording(
        _csv(d, "rep.csv", "t_s,gx\n0,1\n0.1,2\n0.1,3\n0.3,4\n")), InputError,
        "repeats a stamp at row 3"),
    "stamps going back": (lambda d: lambda: read_recording(
        _csv(d, "back.csv", "t_s,gx\n0,1\n0.2,2\n0.1,3\n0.3,4\n")), InputError,
        "goes back in time at row 3"),
    "single stamp": (lambda d: lambda: time_base([1.0], name="t_s"), InputError,
                     "at least 2 time stamps"),
    "NaN stamp": (lambda d: lambda: time_base([0.0, np.nan, 0.2], name="t_s"), InputError,
                  "NaN or inf"),
    "stamps too irregular": (lambda d: lambda: time_base(
        np.cumsum(np.random.default_rng(0).exponential(0.01, 200)), name="t_s"), InputError,
        "too irregular"),
    "--freq contradicts the stamps": (lambda d: lambda: read_recording(
        _csv(d, "f.csv", "t_s,gx\n" + _rows(80, 0.01)), freq=250.0), InputError,
        "contradicts the sampling frequency 100 Hz"),
    "--time-unit contradicts the label": (lambda d: lambda: read_recording(
        _csv(d, "tu.csv", "t_ms,gx\n" + _rows(80, 10)), time_unit="us"), InputError,
        "--time-unit us contradicts"),
    "--time-unit without time column": (lambda d: lambda: read_recording(
        _csv(d, "nt.csv", "gx\n" + "1\n" * 80), time_unit="ms"), InputError,
        "no time column"),
    "unknown time unit": (lambda d: lambda: read_recording(
        _csv(d, "ut.csv", "gx\n" + "1\n" * 80), time_unit="min"), InputError,
        "unknown time unit 'min'"),
    "non-positive --freq": (lambda d: lambda: read_recording(
        (np.save(d / "x.npy", np.zeros(64)), d / "x.npy")[1], freq=-5.0), InputError,
        "positive number of Hz"),
    "unit without any time": (lambda d: lambda: read_recording(
        (np.save(d / "y.npy", np.zeros(64)), d / "y.npy")[1], units="deg/s").require_time(
        "coefficients in deg/s"), InputError, "give --freq"),
    "zero header stamps in some messages": (lambda d: lambda: read_recording(_bag(d, "ros1", {
        "/imu": (np.r_[np.int64(0), _stamps(63)[1:]], *_imu_topic()[1:])})), InputError,
        "zero header.stamp"),
    # ---- units ----
    "unknown unit": (lambda d: lambda: parse_unit("dgs"), InputError,
                     "unknown unit 'dgs'; known units: rad/s, deg/s"),
    "unit typo through the reader": (lambda d: lambda: read_recording(
        _csv(d, "ut2.csv", "t_s,gx\n" + _rows(80, 0.01)), units="mgs"), InputError,
        "unknown unit 'mgs'"),
    "zero count scale": (lambda d: lambda: parse_unit("0*deg/s"), InputError,
                         "count scale must be a positive number"),
    "unit contradicts the file": (lambda d: lambda: read_recording(_bag(d, "ros1", {
        "/imu": _imu_topic()}), units={"gx": "deg/s"}), InputError,
        "--units deg/s for gx contradicts the file, which says rad/s"),
    "unit for an absent channel": (lambda d: lambda: read_recording(
        _csv(d, "ua.csv", "t_s,gx\n" + _rows(80, 0.01)), units={"gy": "deg/s"}), InputError,
        "unit given for gy"),
    # ---- topics ----
    "several IMU topics": (lambda d: lambda: read_recording(_bag(d, "sqlite3", {
        "/a": _imu_topic(), "/b": _imu_topic(seed=1)})), InputError,
        r"2 IMU topics: choose one with --topic: /a \(sensor_msgs/Imu, 64 messages, 200 Hz\)"),
    "unknown topic": (lambda d: lambda: read_recording(_bag(d, "mcap", {"/a": _imu_topic()}),
                                                       topic="/x"), InputError,
                      r"topic '/x' not in .*/a \(sensor_msgs/Imu"),
    "no IMU topic": (lambda d: lambda: read_recording(_bag(d, "ros1", {})), InputError,
                     "no sensor_msgs/Imu or Vector3Stamped topic"),
    "--topic on a CSV": (lambda d: lambda: read_recording(
        _csv(d, "tp.csv", "gx\n" + "1\n" * 80), topic="/imu"), InputError,
        "--topic applies to ROS bags and ULog"),
    "ULog without sensor_combined": (lambda d: lambda: read_recording(write_ulog(
        d / "g.ulg", {("sensor_gyro", 0): _sensor_combined(64, *_signals(64))[2]},
        _sensor_combined(64, *_signals(64))[0])), InputError, "no sensor_combined topic"),
    "ULog unsupported topic": (lambda d: lambda: read_recording(write_ulog(
        d / "h.ulg", {("sensor_combined", 0): _sensor_combined(64, *_signals(64))[1]},
        _sensor_combined(64, *_signals(64))[0]), topic="vehicle_status"), InputError,
        "not 'vehicle_status'"),
    "ULog malformed instance": (lambda d: lambda: read_recording(write_ulog(
        d / "i.ulg", {("sensor_combined", 0): _sensor_combined(64, *_signals(64))[1]},
        _sensor_combined(64, *_signals(64))[0]), topic="sensor_gyro:x"), InputError,
        "malformed ULog topic"),
    # ---- gaps ----
    "gap policy 'error'": (lambda d: lambda: decide_gaps(
        time_base(np.r_[np.arange(100), np.arange(110, 200)] * 0.01, name="t_s"), "error"),
        InputError, r"1 gap\(s\) in the time stamps.*--gaps longest"),
    "unknown gap policy": (lambda d: lambda: decide_gaps(
        time_base(np.arange(100) * 0.01, name="t_s"), "splice"), InputError,
        "unknown gap policy 'splice'"),
    "no segment long enough": (lambda d: lambda: decide_gaps(time_base(
        np.cumsum(np.tile([0.01, 0.01, 0.05], 40)), name="t_s"), "combine"), InputError,
        "no clean segment has 4 samples"),
    "too many levels for the segments": (lambda d: lambda: segments_wv(
        np.zeros(100), ((0, 40), (40, 100)), levels=7), InputError,
        "allows at most 5 levels"),
}


def test_at_least_forty_classes():
    assert len(CASES) >= 40


@pytest.mark.parametrize("case", list(CASES))
def test_bad_input(tmp_path, case):
    build, exc, pattern = CASES[case]
    call = build(tmp_path)
    with pytest.raises(exc, match=pattern) as e:
        call()
    assert isinstance(e.value, GMWMError)
    assert "\n" not in str(e.value)


def test_cli_prints_one_line(tmp_path, capsys):
    from gmwm.cli import main

    p = _csv(tmp_path, "ns.csv", "timestamp,gx\n" + _rows(300, 5_000_000, T0))
    assert main(["report", str(p), "--units", "mg/s", "-o", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown unit 'mg/s'" in err
    np.save(tmp_path / "x.npy", np.random.default_rng(0).standard_normal(512))
    assert main(["fit", str(tmp_path / "x.npy"), "WN", "--units", "deg/s"]) == 1
    assert "give --freq" in capsys.readouterr().err
    assert main(["report", str(tmp_path / "x.npy"), "WN", "-o", str(tmp_path / "r2")]) == 1
    assert "give --freq" in capsys.readouterr().err
