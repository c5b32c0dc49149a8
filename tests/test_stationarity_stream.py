"""The stationarity check of streamed recordings (gmwm.stationarity.StationarityStream,
check_stationarity_stream; docs/METHODS.md §16): the same report as the in-memory check, bit for
bit, whatever the chunks; in the same read as the streamed WV; the WV of a sample range."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from conftest import load_benchmark
from gmwm.errors import InputError
from gmwm.stationarity import (
    StationarityStream,
    check_stationarity,
    check_stationarity_stream,
)
from gmwm.stream import open_source, uniform_sample_range, wvar_stream
from gmwm.wv import wvar

bs = load_benchmark("bench_stationarity")
FS = 100.0


def _imu(seconds: float, seed: int, moving: bool) -> dict[str, np.ndarray]:
    x = bs.static_imu(1, FS, seconds, np.random.default_rng(seed))
    if moving:
        n = x["gx"].size
        bs.inject_step(x, "gy", 0.02, n // 2)
        bs.inject_tilt(x, FS, 0.3 * seconds, 2.0, 5.0)
    return x


def _assert_same(a, b, *, norm_alert_exact: bool = True) -> None:
    """Same flags, segments, statistics, notes, warnings and timelines, bit for bit."""
    da, db = a.to_json_dict(), b.to_json_dict()
    if not norm_alert_exact:  # streamed: the median |a| comes from the window means
        for d in (da, db):
            d["warnings"] = [w for w in d["warnings"] if "accelerometer norm" not in w]
    assert da == db
    assert a.alerts == b.alerts or not norm_alert_exact
    assert list(a.timeline) == list(b.timeline)
    for c in a.timeline:
        for u, v in zip(a.timeline[c], b.timeline[c], strict=True):
            assert u.tobytes() == v.tobytes(), c
    if a.temperature_timeline is None:
        assert b.temperature_timeline is None
    else:
        for u, v in zip(a.temperature_timeline, b.temperature_timeline, strict=True):
            assert np.array_equal(u, v, equal_nan=True)


@pytest.mark.parametrize("moving", [False, True])
def test_pieces_of_any_size_give_the_in_memory_report(moving: bool) -> None:
    """Rows pushed in random pieces (1 to 3000 rows, so block and bin edges fall anywhere), with a
    temperature column holding NaN/inf gaps across pieces: identical to check_stationarity."""
    x = _imu(150.0, 5, moving)
    n = x["gx"].size
    rng = np.random.default_rng(9)
    temp = np.linspace(20.0, 30.0, n) + rng.normal(0.0, 0.01, n)
    temp[:7] = np.inf
    temp[500:4100] = np.nan
    temp[-60:] = np.nan
    x["gx"] += 2e-3 * np.where(np.isfinite(temp), temp - 25.0, 0.0)
    ref = check_stationarity(x, freq=FS, units=bs.UNITS, temperature=temp)
    assert ref.moving == moving and ref.temperature is not None
    assert ref.temperature.following == ([] if moving else ["gx"])  # the step hides it
    rows = np.column_stack([*x.values(), temp])
    for hi in (40, 3000):
        st = StationarityStream([*x, "T"], n, freq=FS, units=bs.UNITS, temperature="T")
        i = 0
        while i < n:
            m = int(rng.integers(1, hi))
            st.push(rows[i:i + m])
            i += m
        _assert_same(ref, st.finish())


def _write(tmp_path: Path, x: dict[str, np.ndarray], kind: str) -> Path:
    if kind == "npy":
        p = tmp_path / "imu.npy"
        np.save(p, np.column_stack(list(x.values())))
    else:
        p = tmp_path / "imu.h5"
        with h5py.File(p, "w") as f:
            f.attrs["freq"] = FS
            for c, v in x.items():
                f.create_dataset(c, data=v, chunks=(777,))
    return p


@pytest.mark.parametrize("kind", ["npy", "h5"])
@pytest.mark.parametrize("moving", [False, True])
def test_streamed_file_equals_in_memory(tmp_path: Path, kind: str, moving: bool) -> None:
    """A .npy (2-D) or HDF5 (1-D datasets) file read in chunks of 1000 rows: the report of the
    in-memory check of the same samples, static or with a step and a tilt."""
    x = _imu(120.0, 11, moving)
    p = _write(tmp_path, x, kind)
    axes = list(x) if kind == "h5" else [str(k) for k in range(len(x))]  # the source's names
    data = dict(zip(axes, x.values(), strict=True))
    units = dict(zip(axes, (bs.UNITS[c] for c in x), strict=True))
    with open_source(p, columns="all") as src:
        assert sorted(src.names) == sorted(axes)
        got = check_stationarity_stream(src, freq=FS, units=units, chunk=1000)
    ref = check_stationarity({c: data[c] for c in got.channels if c in data}, freq=FS,
                             units=units)
    assert got.moving == moving
    if moving:
        assert any(s.start_s < 60.5 and s.end_s > 59.5 for s in got.segments)  # the step
    _assert_same(ref, got, norm_alert_exact=False)


def test_one_read_gives_the_wv_and_the_check(tmp_path: Path) -> None:
    """wvar_stream(..., observe=check.push) in a small memory budget (many chunks): the WV is that
    of wvar_stream alone and of the in-memory wvar, the check that of check_stationarity."""
    x = _imu(120.0, 3, True)
    p = _write(tmp_path, x, "npy")
    with open_source(p, columns="all") as src:
        units = {nm: bs.UNITS[c] for nm, c in zip(src.names, x, strict=True)}
        check = StationarityStream.for_source(src, freq=FS, units=units)
        both = wvar_stream(src, freq=FS, memory=1 << 16, observe=check.push)
        alone = wvar_stream(src, freq=FS, memory=1 << 16)
        st = check.finish()
    ref = check_stationarity(dict(zip(units, x.values(), strict=True)), freq=FS, units=units)
    _assert_same(ref, st, norm_alert_exact=False)
    assert st.moving
    for k, (c, v) in enumerate(zip(units, x.values(), strict=True)):
        w = wvar(v, freq=FS)
        assert np.array_equal(both[c].wv.variance, alone[c].wv.variance), k
        assert np.array_equal(both[c].wv.variance, w.variance), k


def test_wv_of_a_sample_range_equals_the_slice(tmp_path: Path) -> None:
    """wvar_stream(start=, stop=) (--start/--end, --segment longest-static on a streamed file):
    bit-identical to wvar of the slice, with its first/last samples."""
    x = _imu(60.0, 4, False)
    p = _write(tmp_path, x, "npy")
    a, b = 1234, 5017
    got = wvar_stream(p, columns="all", freq=FS, memory=1 << 15, start=a, stop=b)
    for c, v in zip(got, x.values(), strict=True):
        ref = wvar(v[a:b], freq=FS)
        assert got[c].wv.n_samples == b - a
        assert np.array_equal(got[c].wv.variance, ref.variance)
        assert (got[c].first, got[c].last) == (v[a], v[b - 1])
    with pytest.raises(InputError, match="outside"):
        wvar_stream(p, columns="all", start=10, stop=10**9)


def test_uniform_sample_range_matches_time_stamps() -> None:
    """The sample range of --start/--end without stamps is that of searchsorted on i / freq (as
    gmwm.readers.recording.sample_range on time stamps)."""
    for freq, n in ((100.0, 12345), (333.0, 5000), (0.7, 100)):
        t = np.arange(n) / freq
        for start, end in ((None, None), (1.0, None), (0.01, 7.3), (2.5, 1e9), (None, 3.0)):
            want = (int(np.searchsorted(t, start or 0.0, "left")),
                    n if end is None else int(np.searchsorted(t, end, "left")))
            if want[1] - want[0] < 2 or (start or 0.0) > t[-1]:
                continue
            assert uniform_sample_range(n, freq, start, end) == want, (freq, start, end)
    with pytest.raises(InputError, match="after the end"):
        uniform_sample_range(100, 10.0, 50.0, None)


def test_summaries_are_small_and_bounded() -> None:
    """The per-channel summaries hold O(n / h0) values (h0 = 5 samples at 100 Hz): about a fifth
    of the signal for the window means, a 25th for the noise levels, and a fixed timeline."""
    x = _imu(300.0, 1, False)
    n = x["gx"].size
    st = StationarityStream(list(x), n, freq=FS, units=bs.UNITS)
    rows = np.column_stack(list(x.values()))
    for i in range(0, n, 4096):
        st.push(rows[i:i + 4096])
    assert st.hs[0] == 5 and st.w_noise == 50
    sums = [acc.finish() for acc in st.accs]
    assert len(sums) == 7  # six axes and |a|
    for sm in sums:
        assert sm.means.size == n // 5 and sm.noise.size == (n - 1) // 25
        assert sm.temp_means.size == 0
        assert all(v.size <= 1500 for v in sm.timeline)
        assert sm.means.nbytes + sm.noise.nbytes < 0.25 * n * 8  # 8 bytes per sample: 1/4
        assert sum(v.nbytes for v in sm.timeline) <= 4 * 1500 * 8


def test_nonfinite_sample_is_named_and_counts_are_checked() -> None:
    st = StationarityStream(["a", "b"], 100, freq=10.0)
    rows = np.zeros((60, 2))
    st.push(rows)
    bad = np.zeros((40, 2))
    bad[17, 1] = np.nan
    with pytest.raises(InputError, match=r"channel 'b' of signal contains a NaN value at sample 77"):
        st.push(bad)
    st = StationarityStream(["a"], 100, freq=10.0)
    st.push(np.zeros(60))
    with pytest.raises(InputError, match="60 samples pushed, 100 announced"):
        st.finish()
    with pytest.raises(InputError, match="more than the 100"):
        st.push(np.zeros(41))


# ---- the command line: a streamed file gets the same check as one read whole ----------------------


@pytest.mark.parametrize("extra", [[], ["--segment", "longest-static"], ["--start", "100"]])
def test_cli_streamed_input_warns_like_the_in_memory_path(tmp_path, monkeypatch, capsys, extra):
    import json

    from gmwm.cli import main

    rng = np.random.default_rng(5)
    x = rng.standard_normal((60_000, 2))
    x[30_000:30_400] += 40.0  # a knock in the middle
    path = tmp_path / "x.npy"
    np.save(path, x)
    argv = ["fit", str(path), "WN", "--freq", "100", "--columns", "all", "--json", "-q", *extra]
    runs = {}
    for label, size in (("memory", str(1 << 40)), ("streamed", "0")):
        monkeypatch.setenv("GMWM_STREAM_MIN_BYTES", size)
        code = main(argv)
        cap = capsys.readouterr()
        runs[label] = (code, json.loads(cap.out), cap.err)
    (c_m, j_m, e_m), (c_s, j_s, e_s) = runs["memory"], runs["streamed"]
    assert ("not static" in e_m) == ("not static" in e_s)
    assert c_m == c_s == 0
    assert "not static" in e_s and "is read into memory" not in e_s
    drop = ("seconds", "cpu_seconds")
    assert ({k: v for k, v in j_s["stationarity"].items() if k not in drop}
            == {k: v for k, v in j_m["stationarity"].items() if k not in drop})
    for c in ("0", "1"):
        assert j_s["fits"][c]["wv"]["n_samples"] == j_m["fits"][c]["wv"]["n_samples"]
        assert j_s["fits"][c]["params"] == pytest.approx(j_m["fits"][c]["params"], rel=1e-9)


def test_cli_streamed_strict_refuses_a_moving_recording(tmp_path, monkeypatch, capsys):
    from gmwm.cli import main

    x = np.random.default_rng(6).standard_normal(60_000)
    x[30_000:30_400] += 40.0
    np.save(tmp_path / "x.npy", x)
    monkeypatch.setenv("GMWM_STREAM_MIN_BYTES", "0")
    code = main(["fit", str(tmp_path / "x.npy"), "WN", "--freq", "100", "--strict", "-q"])
    err = capsys.readouterr().err
    assert code == 1 and "--strict" in err and err.count("gmwm: error") == 1
