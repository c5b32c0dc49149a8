"""The stationarity check of streamed recordings (gmwm.stationarity.StationarityStream,
check_stationarity_stream; docs/METHODS.md §16): the same report as the in-memory check, bit for
bit, whatever the chunks; in the same read as the streamed WV; the WV of a sample range."""

from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import pytest

import gmwm.stationarity as st_mod
from conftest import load_benchmark
from gmwm.errors import InputError
from gmwm.stationarity import (
    MIN_DIFFS,
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


def test_summaries_without_a_source_keep_everything() -> None:
    """Pushed without a source (nothing to re-read), every statistic is kept: per window length its
    n // h - 3 window-mean differences, the (n - 1) // 25 - 1 noise levels, a fixed timeline."""
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
        assert [s.vals.size for s in sm.levels] == [n // h - 3 for h in st.hs]
        assert all(s.whole for s in sm.levels) and sm.noise.vals.size == (n - 1) // 25 - 1
        assert sm.temp_means.size == 0
        assert all(v.size <= 1500 for v in sm.timeline)
    assert sums[-1].means.vals.size == n // 5 and sums[0].means is None  # |a| only


# ---- bounded memory: a source to re-read ----------------------------------------------------------


@pytest.mark.parametrize("h", [1, 2, 3, 4, 5, 7, 8, 13])
def test_block_means_have_the_bits_of_a_reshape_mean(h: int) -> None:
    rng = np.random.default_rng(h)
    for m in (1, 5, 1000, 77_777):
        v = rng.standard_normal(m * h) * 10.0 ** rng.integers(-9, 9, m * h)
        assert st_mod._block_means(v, h).tobytes() == v.reshape(m, h).mean(axis=1).tobytes()


def test_cascade_from_any_block_in_any_pieces_gives_the_whole_array_differences() -> None:
    """The window-mean differences of every level, from B_0 pushed in random pieces from block
    ``first`` (a re-read starts anywhere): those of the whole-array expressions, with their
    indices, for every window inside the blocks pushed."""
    rng = np.random.default_rng(3)
    B = rng.standard_normal(5000) * 1e3
    whole, b = [], B
    for i in range(6):
        if i:
            m = b.size // 2
            b = 0.5 * (b[: 2 * m: 2] + b[1: 2 * m: 2])
        whole.append(0.5 * (b[2:-1] + b[3:] - b[:-3] - b[1:-2]))
    for first in (0, 1, 2, 3, 37, 64, 1001):
        cas = st_mod._Cascade(6, first)
        got: dict[int, dict[int, float]] = {i: {} for i in range(6)}
        a = first
        while a < B.size:
            e = min(B.size, a + int(rng.integers(1, 300)))
            for i, j0, d in cas.push(B[a:e]):
                got[i].update(zip(range(j0, j0 + d.size), d.tolist(), strict=True))
            a = e
        for i in range(6):
            j_lo = -(-first // 2 ** i)  # the first level-i block whose samples were all pushed
            want = whole[i][j_lo:]
            assert sorted(got[i]) == list(range(j_lo, j_lo + want.size)), (first, i)
            assert np.array_equal([got[i][j] for j in sorted(got[i])], want), (first, i)


def _write_1d(tmp_path: Path, x: np.ndarray, name: str = "sig") -> Path:
    p = tmp_path / f"{name}.npy"
    np.save(p, x)
    return p


def test_rescanned_flags_are_exact(tmp_path: Path, monkeypatch) -> None:
    """With the same median and scale everywhere (a fixed robust estimate), the bounded check
    (every test subsampled, flagged blocks re-read from the file) flags exactly what the in-memory
    check flags: spans, statistics, sizes and peaks, for window means (a step and a ramp) and noise
    bursts, from several places in the file; also riding on the streamed WV's read."""
    rng = np.random.default_rng(8)
    n = 300_000
    x = rng.standard_normal(n)
    x[100_003:] += 9.0  # a step
    x[200_000:200_500] += np.linspace(0.0, 40.0, 500)  # a ramp, then back
    x[250_000:251_000] += 30.0 * rng.standard_normal(1000)  # a burst of noise
    x[7:19] += 50.0  # at the very start
    monkeypatch.setattr(st_mod, "_robust", lambda v: (0.0, 1.0))
    ref = check_stationarity({"sig": x})
    assert ref.moving and {f.test for f in ref.flags} == {"mean", "noise"}
    p = _write_1d(tmp_path, x)
    with open_source(p) as src:
        for chunk in (4096, 100_000):
            got = check_stationarity_stream(src, chunk=chunk, robust_sample=MIN_DIFFS)
            _assert_same(ref, got)
        check = StationarityStream.for_source(src, robust_sample=MIN_DIFFS)  # as gmwm wv does
        wvar_stream(src, memory=1 << 18, observe=check.push)
        _assert_same(ref, check.finish())


def test_subsampled_scale_finds_the_same_motion(tmp_path: Path) -> None:
    """A moving 6-axis recording checked with a small robust subsample (every test longer than 300
    statistics subsampled): the same verdict and flagged ranges as the in-memory check, thresholds
    and counts identical, largest statistics within a few per cent."""
    x = _imu(600.0, 12, True)
    p = _write(tmp_path, x, "npy")
    with open_source(p, columns="all") as src:
        units = {nm: bs.UNITS[c] for nm, c in zip(src.names, x, strict=True)}
        got = check_stationarity_stream(src, freq=FS, units=units, robust_sample=300)
    ref = check_stationarity(dict(zip(units, x.values(), strict=True)), freq=FS, units=units)
    assert got.moving and ref.moving
    assert got.n_tests == ref.n_tests and got.threshold == ref.threshold
    for a, b in zip(got.peaks, ref.peaks, strict=True):
        assert a[:4] == b[:4] and a[5] == b[5]
        assert abs(a[4] - b[4]) <= 3.0 / math.sqrt(300) * max(b[4], 1.0)  # the scale's error
    assert [(s.i0, s.i1) for s in got.segments] == [(s.i0, s.i1) for s in ref.segments]


def test_streamed_check_memory_does_not_grow_with_the_length(tmp_path: Path, monkeypatch) -> None:
    """tracemalloc peak of the streamed check (small pieces and chunks): a file 4x longer needs
    about the same memory, far below its size (8 bytes per sample), and gets the in-memory
    report of the same samples when every test fits the robust subsample."""
    import tracemalloc

    monkeypatch.setattr(st_mod, "_PIECE", 1 << 13)
    rng = np.random.default_rng(4)
    peaks = {}
    for n in (1 << 18, 1 << 20):
        x = rng.standard_normal(n)
        x[n // 2: n // 2 + 300] += 5.0
        p = _write_1d(tmp_path, x, f"s{n}")
        del x
        with open_source(p) as src:
            if not peaks:  # imports and first-call caches outside the measurement
                check_stationarity_stream(src, chunk=1 << 13, robust_sample=512)
            tracemalloc.start()
            rep = check_stationarity_stream(src, chunk=1 << 13, robust_sample=512)
            peaks[n] = tracemalloc.get_traced_memory()[1]
            tracemalloc.stop()
        assert rep.moving
    small, big = peaks[1 << 18], peaks[1 << 20]
    assert big < 1.2 * small, peaks
    assert big < (1 << 20) * 8 / 8, peaks  # an eighth of the file
    x = np.load(tmp_path / f"s{1 << 18}.npy")
    with open_source(tmp_path / f"s{1 << 18}.npy") as src:
        got = check_stationarity_stream(src, chunk=1 << 13, robust_sample=1 << 16)
    _assert_same(check_stationarity({f"s{1 << 18}": x}), got)


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
    # without --segment the knock lies in the part used: read whole, it is left out when its
    # padded range is within 5 % of that part (the whole file: 4.6 %; from 100 s: 5.5 %, kept)
    cut = "motion excluded" in e_m
    assert cut == (extra == [])
    # the same check; only what the warnings say about the estimate differs when one is cut
    drop = ("seconds", "cpu_seconds", *(("warnings",) if cut else ()))
    assert ({k: v for k, v in j_s["stationarity"].items() if k not in drop}
            == {k: v for k, v in j_m["stationarity"].items() if k not in drop})
    if cut:
        assert "they are excluded from the estimate" in j_m["stationarity"]["warnings"][0]
        assert "which includes" in j_s["stationarity"]["warnings"][0]
    for c in ("0", "1"):
        n_s, n_m = j_s["fits"][c]["wv"]["n_samples"], j_m["fits"][c]["wv"]["n_samples"]
        if not cut:
            assert n_s == n_m
            assert j_s["fits"][c]["params"] == pytest.approx(j_m["fits"][c]["params"], rel=1e-9)
        else:  # read whole, the flagged knock (padded) is left out; a streamed file is not cut
            assert n_m < n_s and n_s - n_m < 0.05 * n_s
    if cut:
        assert "motion excluded" in e_m and "motion NOT excluded" in e_s


def test_cli_streamed_strict_refuses_a_moving_recording(tmp_path, monkeypatch, capsys):
    from gmwm.cli import main

    x = np.random.default_rng(6).standard_normal(60_000)
    x[30_000:30_400] += 40.0
    np.save(tmp_path / "x.npy", x)
    monkeypatch.setenv("GMWM_STREAM_MIN_BYTES", "0")
    code = main(["fit", str(tmp_path / "x.npy"), "WN", "--freq", "100", "--strict", "-q"])
    err = capsys.readouterr().err
    assert code == 1 and "--strict" in err and err.count("gmwm: error") == 1
