"""The stationarity check (gmwm.stationarity, docs/METHODS.md §16): false alarms on static
recordings, detection of steps, motion and noise bursts, the four real moving recordings, the
temperature check, and the CLI/report surfaces (--strict, --segment longest-static, --start/--end).

The real recordings are read from ../shared/data/external next to the repository (or the folder
named by $GMWM_EXTERNAL_DATA); those tests skip when it is absent."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from _ulog_writer import write_ulog
from conftest import load_benchmark
from gmwm.cli import main
from gmwm.readers.recording import read_recording, sample_range, select_samples
from gmwm.stationarity import check_stationarity

bs = load_benchmark("bench_stationarity")

EXTERNAL = bs.EXTERNAL
needs_external = pytest.mark.skipif(not EXTERNAL.is_dir(),
                                    reason="../shared/data/external absent")
FS = 100.0


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _imu(profile: int = 0, seconds: float = 180.0, seed: int = 1, fs: float = FS):
    return bs.static_imu(profile, fs, seconds, np.random.default_rng(seed))


def _overlaps(st, a: float, b: float) -> bool:
    return any(s.end_s > a and s.start_s < b for s in st.segments)


# ---- false alarms and detection -------------------------------------------------------------


def test_static_recordings_rarely_flagged():
    """40 static 6-axis recordings (4 profiles, 100-400 Hz, 2-5 min): at most one flagged (the
    benchmark measures the rate on hundreds: docs/stationarity_results.md)."""
    rng = np.random.default_rng(2024)
    flagged = []
    for r in range(40):
        p = r % len(bs.PROFILES)
        fs, sec = ((100.0, 300.0), (200.0, 120.0), (400.0, 120.0), (100.0, 120.0))[r // 10]
        st = bs.check(bs.static_imu(p, fs, sec, rng), fs)
        assert st.tested and st.n_tests > 0
        if st.moving:
            flagged.append((r, [f.channel for f in st.flags]))
    assert len(flagged) <= 1, flagged


@pytest.mark.parametrize("axis", ["gx", "ay"])
def test_step_is_flagged_where_it_happens(axis):
    x = _imu(seed=3)
    n = x["gx"].size
    at = int(0.6 * n)
    bs.inject_step(x, axis, 20 * bs.sd_min(0, axis, FS, n), at)
    st = bs.check(x, FS)
    assert st.moving and axis in {c for s in st.segments for c in s.channels}
    t = at / FS
    assert _overlaps(st, t - 0.5, t + 0.5)
    a, b = st.clean_segment()  # the longest static stretch is one side of the step
    assert not (a <= at < b)
    assert max(b - a, 0) > 0.3 * n
    # within a window (what --segment longest-static uses with --start/--end)
    first = min(s.i0 for s in st.segments)
    assert st.clean_segment(0, first) == (0, first)
    assert st.clean_segment(first, first + 1) == (first, first)   # all flagged: empty


def test_small_step_not_flagged():
    """A step of one sd_min (the noise of the best window) is below the threshold."""
    x = _imu(seed=4)
    n = x["gx"].size
    bs.inject_step(x, "gx", 1.0 * bs.sd_min(0, "gx", FS, n), n // 2)
    assert not bs.check(x, FS).moving


@pytest.mark.parametrize(("inject", "size", "channel"), [
    (bs.inject_tilt, 2.0, "ay"), (bs.inject_turn, 10.0, "gz"), (bs.inject_push, 0.05, "ax")])
def test_a_few_seconds_of_motion_are_flagged(inject, size, channel):
    x = _imu(seed=5)
    inject(x, FS, 90.0, 3.0, size)
    st = bs.check(x, FS)
    assert _overlaps(st, 90.0, 93.0)
    hit = [s for s in st.segments if s.end_s > 90.0 and s.start_s < 93.0]
    assert channel in hit[0].channels
    assert all(s.end_s > 80.0 and s.start_s < 103.0 for s in st.segments)  # nowhere else


def test_continuous_motion_needs_the_static_ceiling():
    """A platform rocking throughout: its own robust scale is inflated, so only the static
    ceiling (known units) flags it; without units nothing can."""
    x = _imu(seed=6)
    t = np.arange(x["gx"].size) / FS
    rng = np.random.default_rng(0)
    rate = np.convolve(rng.standard_normal(t.size), np.ones(50) / 50, "same") * 2.0  # rad/s
    x["gx"] += rate
    ang = np.cumsum(rate) / FS
    x["ay"] += bs.G * np.sin(ang)
    x["az"] += bs.G * (np.cos(ang) - 1)
    st = bs.check(x, FS)
    assert st.moving and "ceiling" in {f.test for f in st.flags}
    assert sum(s.i1 - s.i0 for s in st.segments) > 0.5 * st.n
    bare = check_stationarity(x, freq=FS)  # no units
    assert not any(f.test == "ceiling" for f in bare.flags)
    assert any("no gyroscope/accelerometer unit" in n for n in bare.notes)


def test_noise_burst_is_flagged():
    x = _imu(seed=7)
    i0, i1 = int(100 * FS), int(105 * FS)
    k = np.arange(i1 - i0)
    x["az"][i0:i1] += 0.2 * np.sin(2 * np.pi * 23.0 * k / FS)  # a motor at 23 Hz for 5 s
    st = bs.check(x, FS)
    noise = [f for f in st.flags if f.test == "noise" and f.channel == "az"]
    assert noise and noise[0].start_s < 105.0 and noise[0].end_s > 100.0


def test_quantised_static_signal_not_flagged():
    """A coarse sensor whose noise is below one step: rare one-step flips are not motion."""
    rng = np.random.default_rng(8)
    x = np.round(1e-4 * rng.standard_normal(30_000) / 1e-3) * 1e-3 + 0.5
    assert not check_stationarity({"gx": x}, freq=FS, units={"gx": "rad/s"}).moving


def test_report_contents_and_json():
    x = _imu(seed=9)
    bs.inject_tilt(x, FS, 60.0, 3.0, 5.0)
    st = bs.check(x, FS)
    d = st.to_json_dict()
    assert d["static"] is False and d["segments"] and d["flags"]
    assert json.loads(json.dumps(d)) == d  # plain JSON
    assert {"i0", "i1", "start_s", "end_s", "how"} <= set(d["used"])
    a, b = st.clean_segment()
    used = st.using(a, b, "longest static segment")
    assert used.moving and not used.moving_in_used
    assert "excludes them" in used.warnings()[0]
    assert "includes" in st.warnings()[0] and "--segment longest-static" in st.warnings()[0]
    assert "MOVING" in st.summary()


def test_timeline_figure(tmp_path):
    from gmwm.atomic import save_figure
    from gmwm.plots import plot_stationarity

    x = _imu(seed=10)
    bs.inject_turn(x, FS, 30.0, 3.0, 45.0)
    st = check_stationarity(x, freq=FS, units=bs.UNITS, temperature=np.linspace(20, 30, 18000))
    fig = plot_stationarity(st.using(*st.clean_segment(), "longest static segment"))
    assert len(fig.axes) == 8  # six axes, |a|, temperature
    (p,) = save_figure(fig, tmp_path / "t.png", dpi=40)
    assert p.read_bytes()[:4] == b"\x89PNG"


# ---- temperature ----------------------------------------------------------------------------


def test_bias_following_temperature_is_named():
    x = _imu(seed=11, seconds=600.0)
    n = x["gx"].size
    temp = 25.0 + 10.0 * (1 - np.exp(-np.arange(n) / (FS * 200.0)))  # warm-up
    x["gx"] += 2e-3 * (temp - 25.0)  # 2e-3 rad/s per degC
    st = check_stationarity(x, freq=FS, units=bs.UNITS, temperature=temp)
    assert st.temperature is not None and st.temperature.following == ["gx"]
    _r, slope, _p, follows = st.temperature.channels["gx"]
    assert follows and slope == pytest.approx(2e-3, rel=0.2)
    assert any("follows the temperature" in w and "gx" in w for w in st.warnings())


def test_independent_temperature_not_blamed():
    rng = np.random.default_rng(12)
    blamed = []
    for r in range(8):
        p = r % len(bs.PROFILES)
        x = bs.static_imu(p, FS, 600.0, rng)
        n = x["gx"].size
        temp = 25.0 + np.cumsum(rng.standard_normal(n)) * 0.01  # a wandering temperature
        st = check_stationarity(x, freq=FS, units=bs.UNITS, temperature=temp)
        blamed += st.temperature.following
    assert blamed == []


def _csv(path: Path, x: dict, fs: float, temp: np.ndarray | None = None) -> Path:
    n = x["gx"].size
    cols = [np.arange(n) / fs] + [x[c] for c in bs.AXES]
    head = "time [s]," + ",".join(f"{c} [{bs.UNITS[c]}]" for c in bs.AXES)
    if temp is not None:
        cols.append(temp)
        head += ",temp [degC]"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=head, comments="",
               fmt="%.10g")
    return path


def test_csv_temperature_column_is_not_a_signal(tmp_path):
    x = _imu(seconds=20.0)
    temp = np.linspace(20.0, 22.0, x["gx"].size)
    rec = read_recording(_csv(tmp_path / "imu.csv", x, FS, temp))
    assert list(rec.channels) == list(bs.AXES)
    np.testing.assert_allclose(rec.temperature, temp, atol=1e-8)
    assert "temp" in rec.temperature_source
    assert rec.time_s[-1] == pytest.approx((x["gx"].size - 1) / FS)


def test_ulog_temperature_from_sensor_accel(tmp_path):
    n = 2500
    rng = np.random.default_rng(1)
    g = (1e-3 * rng.standard_normal((n, 3))).astype(np.float32)
    a = (np.array([0, 0, -9.81]) + 1e-2 * rng.standard_normal((n, 3))).astype(np.float32)
    t = 5_000_000 + np.arange(n, dtype=np.uint64) * 4000
    fields = {"sensor_combined": [("timestamp", "uint64_t"), ("gyro_rad", "float[3]"),
                                  ("accelerometer_timestamp_relative", "int32_t"),
                                  ("accelerometer_m_s2", "float[3]")],
              "sensor_accel": [("timestamp", "uint64_t"), ("x", "float"), ("y", "float"),
                               ("z", "float"), ("temperature", "float")]}
    ta = t[::250]  # 1 Hz
    temp = np.linspace(30.0, 39.0, ta.size).astype(np.float32)
    p = write_ulog(tmp_path / "t.ulg", {
        ("sensor_combined", 0): {"timestamp": t, "gyro_rad": g,
                                 "accelerometer_timestamp_relative": np.zeros(n, int),
                                 "accelerometer_m_s2": a},
        ("sensor_accel", 0): {"timestamp": ta, "x": a[::250, 0], "y": a[::250, 1],
                              "z": a[::250, 2], "temperature": temp}}, fields)
    rec = read_recording(p)
    assert "sensor_accel:0" in rec.temperature_source
    assert rec.temperature[0] == pytest.approx(30.0) and rec.temperature[-1] == pytest.approx(39.0)
    np.testing.assert_allclose(np.diff(rec.temperature[:250]), 1e-3 * 4, rtol=1e-4)
    raw = read_recording(p, topic="sensor_accel")
    np.testing.assert_allclose(raw.temperature, temp)


# ---- recording slices ------------------------------------------------------------------------


def test_sample_range_and_select_samples(tmp_path):
    x = _imu(seconds=30.0)
    rec = read_recording(_csv(tmp_path / "imu.csv", x, FS, np.full(3000, 21.0)))
    i0, i1 = sample_range(rec, 10.0, 20.0)
    assert (i0, i1) == (1000, 2000)
    sub = select_samples(rec, i0, i1)
    assert sub.n == 1000 and sub.freq == rec.freq and sub.time.n == 1000
    np.testing.assert_array_equal(sub.channels["az"], rec.channels["az"][1000:2000])
    assert sub.temperature.size == 1000
    with pytest.raises(Exception, match="after the end"):
        sample_range(rec, 40.0, None)
    with pytest.raises(Exception, match="start < end"):
        sample_range(rec, 20.0, 10.0)


# ---- real moving recordings -------------------------------------------------------------------


@needs_external
@pytest.mark.parametrize("rel", bs.EXTERNAL_FILES)
def test_real_moving_recordings_are_flagged(rel):
    st = check_stationarity(read_recording(EXTERNAL / rel))
    assert st.tested and st.moving
    a, b = st.clean_segment()
    assert b - a < st.n


@needs_external
def test_px4_flight_flagged_then_static():
    """The PX4 sample is handled for about 6 s, then sits still: only the start is flagged."""
    st = check_stationarity(read_recording(EXTERNAL / "px4-pyulog-sample/sample.ulg"))
    assert len(st.segments) == 1
    s = st.segments[0]
    assert s.start_s < 3.0 and 6.0 < s.end_s < 10.0


# ---- CLI and report ---------------------------------------------------------------------------


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("stationarity")
    static = _imu(seed=21, seconds=240.0)
    moving = {c: v.copy() for c, v in static.items()}
    bs.inject_tilt(moving, FS, 150.0, 3.0, 5.0)
    return {"static": _csv(d / "static.csv", static, FS),
            "moving": _csv(d / "moving.csv", moving, FS), "dir": d}


def test_cli_moving_warns_and_strict_fails(capsys, files):
    code, out, err = run(capsys, "fit", files["moving"], "WN+RW", "--column", "ay")
    assert code == 0 and "not static" in err and "150" in err
    code, out, err = run(capsys, "fit", files["moving"], "WN+RW", "--column", "ay", "--strict")
    assert code == 1 and out == ""
    assert err.count("\n") == 1 and err.startswith("gmwm: error: ") and "--strict" in err
    assert "Traceback" not in err


def test_cli_static_strict_passes(capsys, files):
    code, out, err = run(capsys, "fit", files["static"], "WN+RW", "--columns", "all", "--strict",
                         "--json")
    assert code == 0 and "not static" not in err
    st = json.loads(out)["stationarity"]
    assert st["static"] and st["used"]["how"] == "the whole recording"


def test_cli_longest_static_segment(capsys, files):
    code, out, _err = run(capsys, "fit", files["moving"], "WN+RW", "--column", "ay",
                         "--segment", "longest-static", "--strict", "--json")
    assert code == 0
    d = json.loads(out)
    used = d["stationarity"]["used"]
    assert used["how"] == "longest static segment" and used["end_s"] <= 150.0
    assert d["n"] == used["i1"] - used["i0"]
    assert d["stationarity"]["moving_in_used_part"] is False


def test_cli_start_end(capsys, files):
    code, out, err = run(capsys, "fit", files["moving"], "WN+RW", "--column", "gx",
                         "--start", "10", "--end", "100")
    assert code == 0 and out.startswith("recording part used: 10-100 s (the asked start/end range")
    code, out, err = run(capsys, "fit", files["moving"], "WN+RW", "--column", "gx",
                         "--start", "500")
    assert code == 1 and "after the end" in err


@pytest.mark.slow
def test_report_has_stationarity_section(capsys, files):
    outdir = files["dir"] / "report"
    code, _out, err = run(capsys, "report", files["moving"], "WN+RW", "--columns", "all",
                          "-o", outdir)
    # the tilt's flagged range, padded, is more than 5 % of these 4 minutes: no configuration
    # file, the report says why (tests/test_trust.py covers the policy)
    assert code == 5 and not (outdir / "imu.yaml").exists()
    assert "gmwm: verdict: configuration NOT written: the recording moved" in err
    md = (outdir / "report.md").read_text()
    assert "Warning: the recording is not static" in md and "## Stationarity" in md
    assert "stationarity.png" in md and (outdir / "stationarity.png").exists()
    html = (outdir / "report.html").read_text()
    assert "Stationarity" in html and "not static" in html


def test_timeline_drawn_while_fitting_is_not_drawn_again(tmp_path, one_process):
    """gmwm.report.warm_up draws the stationarity timeline ahead (the CLI does it while the
    axes' models are chosen); write_report with it in ``drawn`` lists the file and leaves it."""
    import gmwm
    from gmwm.datasheet import datasheet
    from gmwm.report import warm_up, write_report

    moving = _imu(seed=23, seconds=120.0)
    bs.inject_tilt(moving, FS, 60.0, 3.0, 5.0)
    units = {c: ("rad/s" if c.startswith("g") else "m/s^2") for c in moving}
    st = check_stationarity(moving, freq=FS, units=units)
    assert st.moving and st.tested and st.timeline
    drawn = warm_up(st, tmp_path)
    png = tmp_path / "stationarity.png"
    assert drawn == [png] and png.stat().st_size > 0
    before = png.stat().st_mtime_ns
    res = gmwm.fit(moving["gx"], "WN+RW", freq=FS)
    axes = {"gx": {"result": res, "units": "rad/s", "warnings": [],
                   "datasheet": datasheet(res, "rad/s")}}
    files = write_report(tmp_path, axes, source="sim.csv", title="IMU", stationarity=st,
                         drawn=drawn)
    assert png in files and (tmp_path / "gx_wv.png") in files
    assert png.stat().st_mtime_ns == before
    assert "stationarity.png" in (tmp_path / "report.md").read_text()
