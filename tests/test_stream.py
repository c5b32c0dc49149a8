"""Tests for gmwm.stream: the streamed WV equals the in-memory one bit for bit (odd lengths, chunk
boundaries at every level, large offsets), reads every source layout like gmwm.readers, stays within
its memory budget, names the first non-finite sample, and is what the CLI uses for large files."""

from __future__ import annotations

import json
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pytest

from gmwm import stream
from gmwm.errors import InputError
from gmwm.readers import read_channels
from gmwm.stream import (
    HDF5Source,
    NpySource,
    RawSource,
    avar_stream,
    wvar_chunks,
    wvar_stream,
)
from gmwm.wv import Workspace as _Workspace
from gmwm.wv import avar, wvar


def longdouble_wv(x: np.ndarray, J: int) -> np.ndarray:
    """The local-average recursion in extended precision (independent of the kernel)."""
    v = np.asarray(x, dtype=np.longdouble) - np.longdouble(x[0])
    out = []
    for j in range(1, J + 1):
        m = 2 ** (j - 1)
        a, b = v[m:], v[:-m]
        out.append(float(np.mean(((a - b) / 2) ** 2)))
        v = (a + b) / 2
    return np.array(out)


def signal(T: int, seed: int, offset: float = 0.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return offset + np.cumsum(rng.standard_normal(T)) + 0.1 * rng.standard_normal(T)


def min_memory(T: int, channels: int = 1) -> int:
    """A budget so small that every chunk is one kernel block and the store goes to a file."""
    return 64 * channels


@pytest.fixture
def spills(monkeypatch: pytest.MonkeyPatch) -> list:
    """Records every temporary panel file the stream opens (and whether it was closed)."""
    made: list = []
    original = stream._PanelFile

    class Recording(original):  # type: ignore[misc, valid-type]
        def __init__(self, *a, **k) -> None:
            super().__init__(*a, **k)
            made.append(self)

    monkeypatch.setattr(stream, "_PanelFile", Recording)
    return made


# --------------------------------------------------------------------------------------------------
# the same numbers as the in-memory path


@pytest.mark.parametrize("T", [4, 5, 7, 33, 1001, 2**16 - 1, 2**16 + 1, 100_003, 300_007])
def test_streamed_equals_in_memory_bit_for_bit(tmp_path: Path, T: int, spills: list) -> None:
    x = signal(T, T)
    np.save(tmp_path / "x.npy", x)
    J = T.bit_length() - 1                      # every level, including M_J small
    ref = wvar(x, J)
    for memory in (min_memory(T), 2**30):       # chunk = one block + file store; one chunk in RAM
        got = wvar_stream(tmp_path / "x.npy", J, memory=memory)["x"]
        np.testing.assert_array_equal(got.wv.variance, ref.variance)
        np.testing.assert_array_equal(got.wv.ci_low, ref.ci_low)
        np.testing.assert_array_equal(got.wv.n, ref.n)
        assert (got.first, got.last) == (x[0], x[-1])
    if _Workspace(T, J).phase2:
        assert spills and all(s._fh.closed for s in spills)   # the file path ran, files closed
    assert np.max(np.abs(ref.variance / longdouble_wv(x, J) - 1)) < 1e-12


def test_chunk_boundaries_at_every_level_do_not_matter() -> None:
    # chunks of 2**j - 1, 2**j and 2**j + 1 samples for every level j put chunk boundaries at every
    # offset a level's filter can straddle; the result is the in-memory one, to the bit
    T = 2**15 + 77
    x = signal(T, 1, offset=3e5)
    J = T.bit_length() - 1
    ref = wvar(x, J).variance
    for j in range(1, J + 1):
        for size in (2**j - 1, 2**j, 2**j + 1):
            if size < 1:
                continue
            parts = (x[i:i + size] for i in range(0, T, size))
            got = wvar_chunks(parts, n_samples=T, levels=J, memory=256)["0"].wv.variance
            np.testing.assert_array_equal(got, ref, err_msg=f"chunks of {size}")


def test_offset_1e8_stays_exact(tmp_path: Path) -> None:
    # a 1e8 offset on a random walk with small white noise: every level within 1e-12 of the
    # extended-precision reference (the undemeaned cumulative-sum WV is off by > 1e-6 here)
    T = 2**18 + 5
    rng = np.random.default_rng(8)
    x = 1e8 + np.cumsum(1e-3 * rng.standard_normal(T)) + 1e-5 * rng.standard_normal(T)
    np.save(tmp_path / "x.npy", x)
    J = T.bit_length() - 2
    got = wvar_stream(tmp_path / "x.npy", J, memory=min_memory(T))["x"].wv.variance
    ref = longdouble_wv(x, J)
    assert np.max(np.abs(got / ref - 1)) < 1e-12
    S = np.concatenate(([0.0], np.cumsum(x)))
    naive = [np.mean(((S[2**j:] - 2 * S[2**(j - 1):T + 1 - 2**(j - 1)] + S[:T + 1 - 2**j])
                      / 2**j) ** 2) for j in range(1, J + 1)]
    assert np.max(np.abs(np.array(naive) / ref - 1)) > 1e-6


def test_chunks_without_length_are_spilled_then_streamed() -> None:
    x = signal(70_001, 4)
    parts = [x[i:i + 1234].astype(np.float32) for i in range(0, x.size, 1234)]
    got = wvar_chunks(iter(parts), names=["gz"], memory=256)["gz"].wv.variance
    np.testing.assert_array_equal(got, wvar(np.concatenate(parts).astype(np.float64)).variance)
    with pytest.raises(InputError, match="ended after"):
        wvar_chunks(iter(parts), n_samples=80_000)
    with pytest.raises(InputError, match="more than the 1000"):
        wvar_chunks(iter(parts), n_samples=1000)
    with pytest.raises(InputError, match=r"\(n, 1\) arrays"):
        wvar_chunks([x[:100], np.zeros((100, 2))], n_samples=200)


def test_channels_in_parallel_give_each_channel_its_own_wv(tmp_path: Path) -> None:
    X = np.stack([signal(150_001, s, offset=10.0**s) for s in range(5)], axis=1)
    np.save(tmp_path / "m.npy", X)
    one = wvar_stream(tmp_path / "m.npy", columns="all", memory=min_memory(X.shape[0], 5),
                      threads=1)
    two = wvar_stream(tmp_path / "m.npy", columns="all", memory=2**16, threads=2)
    assert list(one) == ["0", "1", "2", "3", "4"]
    for i in range(5):
        ref = wvar(X[:, i]).variance
        np.testing.assert_array_equal(one[str(i)].wv.variance, ref)
        np.testing.assert_array_equal(two[str(i)].wv.variance, ref)
    av = avar_stream(tmp_path / "m.npy", columns=[3], freq=100.0)["3"]
    np.testing.assert_array_equal(av.avar, avar(X[:, 3], freq=100.0).avar)


def test_memory_stays_within_the_budget(tmp_path: Path) -> None:
    # an 8 MB signal streamed with a 512 KiB budget: Python-side allocations (NumPy's included)
    # peak far below the signal's size
    x = signal(2**20, 9)
    np.save(tmp_path / "x.npy", x)
    del x
    tracemalloc.start()
    try:
        wvar_stream(tmp_path / "x.npy", memory=2**19)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2 * 2**20, peak


# --------------------------------------------------------------------------------------------------
# non-finite samples and bad inputs


@pytest.mark.parametrize(("where", "value"), [(250_001, np.nan), (299_999, np.inf), (0, np.nan)])
def test_nonfinite_sample_in_a_late_chunk_is_named(tmp_path: Path, where: int,
                                                  value: float) -> None:
    x = signal(300_000, 2)
    x[where] = value
    np.save(tmp_path / "x.npy", x)
    what = "NaN" if np.isnan(value) else "infinite"
    with pytest.raises(InputError, match=rf"contains a {what} value at sample {where}\b"):
        wvar_stream(tmp_path / "x.npy", memory=min_memory(x.size))
    X = np.stack([signal(300_000, 3), x], axis=1)
    np.save(tmp_path / "m.npy", X)
    with pytest.raises(InputError, match=rf"channel '1' of .*m.npy contains a {what} value at "
                                         rf"sample {where}\b"):
        wvar_stream(tmp_path / "m.npy", columns="all", memory=min_memory(x.size, 2))


def test_overflow_and_bad_files(tmp_path: Path) -> None:
    np.save(tmp_path / "big.npy", np.r_[1e300, -1e300, 1e300, -1e300, 1.0])
    with pytest.raises(InputError, match="overflow"):
        wvar_stream(tmp_path / "big.npy")
    np.save(tmp_path / "obj.npy", np.array([(1.0, 2)], dtype=[("a", "f8"), ("b", "i4")]))
    with pytest.raises(InputError, match="plain numbers"):
        NpySource(tmp_path / "obj.npy")
    np.save(tmp_path / "cube.npy", np.zeros((4, 4, 4)))
    with pytest.raises(InputError, match="shape"):
        NpySource(tmp_path / "cube.npy")
    data = (tmp_path / "x.npy")
    np.save(data, np.arange(1000.0))
    blob = data.read_bytes()
    (tmp_path / "cut.npy").write_bytes(blob[:-80])
    with pytest.raises(InputError, match="shorter than its header"):
        NpySource(tmp_path / "cut.npy")
    with pytest.raises(InputError, match="T=3"):
        wvar_stream(RawSource(_raw(tmp_path, np.arange(3.0)), "f8"))
    with pytest.raises(InputError, match="file not found"):
        NpySource(tmp_path / "nope.npy")


def test_not_enough_disk_for_the_store(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    x = signal(100_000, 1)
    np.save(tmp_path / "x.npy", x)
    monkeypatch.setattr(stream.shutil, "disk_usage", lambda _: type("U", (), {"free": 10})())
    with pytest.raises(InputError, match=r"GB of temporary space in .*GB free"):
        wvar_stream(tmp_path / "x.npy", memory=256, spill_dir=str(tmp_path))


# --------------------------------------------------------------------------------------------------
# sources: the same channels, names and frequency as gmwm.readers.read_channels


def _raw(tmp_path: Path, a: np.ndarray, name: str = "r.bin", header: bytes = b"") -> Path:
    p = tmp_path / name
    p.write_bytes(header + np.ascontiguousarray(a).tobytes())
    return p


def _same_as_read_channels(src, path: Path, columns, dataset=None) -> None:
    ref = read_channels(path, columns, dataset=dataset)
    with src:
        assert list(src.names) == list(ref.signals)
        assert src.freq == ref.freq and src.freq_source == ref.freq_source
        rows = src.read(0, src.n_samples)
    for i, (name, x) in enumerate(ref.signals.items()):
        np.testing.assert_array_equal(rows[:, i].astype(np.float64), x, err_msg=name)
    got = wvar_stream(type(src)(path, columns, dataset) if isinstance(src, HDF5Source)
                      else NpySource(path, columns), memory=256)
    for name, x in ref.signals.items():
        np.testing.assert_array_equal(got[name].wv.variance, wvar(x).variance)


def test_npy_layouts_match_read_channels(tmp_path: Path) -> None:
    X = np.stack([signal(5000, s) for s in range(3)], axis=1)
    np.save(tmp_path / "c.npy", X)
    np.save(tmp_path / "f.npy", np.asfortranarray(X))
    np.save(tmp_path / "col.npy", X[:, :1])
    np.save(tmp_path / "i16.npy", (X * 100).astype(np.int16))
    for name, cols in (("c", "all"), ("c", ["2", "0"]), ("f", "all"), ("f", [1]),
                       ("col", None), ("i16", "all")):
        p = tmp_path / f"{name}.npy"
        _same_as_read_channels(NpySource(p, cols), p, cols)
    with pytest.raises(InputError, match="3 columns"):
        NpySource(tmp_path / "c.npy")
    with pytest.raises(InputError, match="out of range"):
        NpySource(tmp_path / "c.npy", [5])


def test_hdf5_layouts_match_read_channels(tmp_path: Path) -> None:
    X = np.stack([signal(6000, s) for s in range(3)], axis=1)
    p = tmp_path / "r.h5"
    with h5py.File(p, "w") as f:
        g = f.create_group("imu")
        g.attrs["sampling_rate"] = 400.0
        for i, n in enumerate(("gx", "gy", "gz")):
            g.create_dataset(n, data=X[:, i], chunks=(512,))
        f.create_dataset("mat", data=X.astype(np.float32), chunks=(256, 3))
    for cols, ds in (("all", None), (["imu/gz", "imu/gx"], None), ("all", "mat"), ([2], "mat"),
                     (None, "imu/gy")):
        _same_as_read_channels(HDF5Source(p, cols, ds), p, cols, ds)
    q = tmp_path / "t.h5"
    with h5py.File(q, "w") as f:
        f.create_dataset("time", data=np.arange(6000) / 250.0 + 1e3)
        f.create_dataset("gyro", data=X[:, 0])
        f.create_dataset("acc", data=X[:, 1])
    _same_as_read_channels(HDF5Source(q, "all"), q, "all")
    with pytest.raises(InputError, match="several 1-D datasets"):
        HDF5Source(q)


def test_time_dataset_read_in_chunks_gives_the_rate_and_checks_order(tmp_path: Path) -> None:
    t = np.arange(3 * 2**20 + 5) * 1e-3
    t[2**21 + 7] = t[2**21 + 6]                           # a repeated stamp in the third chunk
    q = tmp_path / "t.h5"
    with h5py.File(q, "w") as f:
        f.create_dataset("t", data=np.arange(3 * 2**20 + 5) * 1e-3)
        f.create_dataset("bad_t", data=t)
    with h5py.File(q, "r") as f:
        freq, notes = stream._stream_time_freq(f["t"], 1.0, "t")
        assert freq == 1000.0 and notes == []
        with pytest.raises(InputError, match=f"row {2**21 + 8}"):
            stream._stream_time_freq(f["bad_t"], 1.0, "bad_t")


def test_raw_binary(tmp_path: Path) -> None:
    X = np.stack([signal(4096, s) for s in range(2)], axis=1)
    be = _raw(tmp_path, (X * 50).astype(">i2"), "be.dat", header=b"HEADER!!")
    src = RawSource(be, ">i2", channels=2, offset=8, columns="all")
    assert src.names == ("0", "1") and src.n_samples == 4096
    got = wvar_stream(src)
    for i in range(2):
        ref = wvar((X[:, i] * 50).astype(">i2").astype(np.float64)).variance
        np.testing.assert_array_equal(got[str(i)].wv.variance, ref)
    one = _raw(tmp_path, X[:, 0].astype(np.float32), "one.f32")
    assert RawSource(one, "float32").names == ("one",)
    with pytest.raises(InputError, match="whole number of rows"):
        RawSource(be, ">i2", channels=3, offset=8)
    with pytest.raises(InputError, match="not a NumPy dtype"):
        RawSource(be, "float33")
    with pytest.raises(InputError, match="plain numbers"):
        RawSource(be, "complex64")


# --------------------------------------------------------------------------------------------------
# the CLI streams large files (GMWM_STREAM_MIN_BYTES=0 makes every .npy / HDF5 file large)


@pytest.fixture
def gmwm_cli(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture):
    """Run ``gmwm ARGS`` in this process in ``cwd``: (exit status, stdout, stderr)."""
    from gmwm.cli import main

    def run(*args: str, stream_all: bool, cwd: Path) -> tuple[int, str, str]:
        monkeypatch.setenv("GMWM_STREAM_MIN_BYTES", "0" if stream_all else str(1 << 40))
        monkeypatch.chdir(cwd)
        capsys.readouterr()
        code = main(list(args))
        got = capsys.readouterr()
        return code, got.out, got.err

    return run


def test_cli_streams_and_prints_the_same_numbers(tmp_path: Path, gmwm_cli, one_process) -> None:
    rng = np.random.default_rng(12)
    T = 60_000
    X = np.stack([1e4 + 0.01 * np.arange(T) + np.cumsum(rng.standard_normal(T)) * 0.01
                  + rng.standard_normal(T), rng.standard_normal(T)], axis=1)
    with h5py.File(tmp_path / "r.h5", "w") as f:
        f.attrs["freq"] = 100.0
        f.create_dataset("gx", data=X[:, 0])
        f.create_dataset("gy", data=X[:, 1])
    cases = [("wv", "r.h5", "--columns", "all", "--json"),
             ("av", "r.h5", "--columns", "gy", "--json"),
             ("fit", "r.h5", "WN+RW+DR", "--columns", "all", "--json"),
             ("select", "r.h5", "WN+RW", "WN+DR", "--columns", "gx", "--json")]
    for case in cases:
        outs = []
        for stream_all in (False, True):
            code, out, err = gmwm_cli(*case, stream_all=stream_all, cwd=tmp_path)
            assert code == 0, err
            obj = json.loads(out)
            outs.append(obj)
        a, b = outs
        if case[0] == "wv":
            assert (a["streamed"], b["streamed"]) == (False, True)
            assert a["wv"] == b["wv"]
        elif case[0] == "av":
            assert a["av"] == b["av"] and a["readings"] == b["readings"]
        elif case[0] == "fit":
            for c in ("gx", "gy"):
                fa, fb = a["fits"][c], b["fits"][c]
                assert fa["params"] == fb["params"] and fa["wv"] == fb["wv"], c
                assert fa["warnings"] == fb["warnings"]
            assert a["fits"]["gx"]["params"]["DR[1].omega"] > 0       # the sign from the signal
        else:
            assert a["rankings"] == b["rankings"]
    code, out, err = gmwm_cli("report", "r.h5", "WN+RW", "--columns", "gy", "-o", "rep",
                           stream_all=True, cwd=tmp_path)
    assert code == 0 and (tmp_path / "rep" / "report.md").exists(), err


def test_cli_raw_nan_and_robust(tmp_path: Path, gmwm_cli) -> None:
    x = signal(50_000, 5)
    _raw(tmp_path, x.astype("<f4"), "x.raw")
    code, out, err = gmwm_cli("wv", "x.raw", "--dtype", "<f4", "--freq", "50", "--json",
                           stream_all=False, cwd=tmp_path)
    assert code == 0, err
    obj = json.loads(out)
    assert obj["streamed"] and obj["freq"] == 50.0
    assert obj["variance"] == wvar(x.astype("<f4").astype(float)).variance.tolist()
    code, out, err = gmwm_cli("wv", "x.raw", "--dtype", "<f4", "--robust", "--json",
                           stream_all=False, cwd=tmp_path)          # robust: read whole
    assert code == 0 and not json.loads(out)["streamed"], err
    y = x.copy()
    y[41_234] = np.nan
    np.save(tmp_path / "y.npy", y)
    code, out, err = gmwm_cli("fit", "y.npy", "WN+RW", stream_all=True, cwd=tmp_path)
    errors = [line for line in err.splitlines() if line.startswith("gmwm: error")]
    assert code == 1 and len(errors) == 1 and "NaN value at sample 41234" in errors[0], err
    assert "Traceback" not in err
    code, out, err = gmwm_cli("wv", "x.raw", "--dtype", "<f4", "--dataset", "a", stream_all=False,
                           cwd=tmp_path)
    assert code == 2 and "--dataset applies to HDF5" in err


# --------------------------------------------------------------------------------------------------
# kernels compiled at install; a command that compiles anyway says so, once


def test_compile_note_is_printed_once(monkeypatch: pytest.MonkeyPatch) -> None:
    import io

    from numba import njit

    from gmwm import _precompile

    monkeypatch.setattr(_precompile._NoteState, "announced", False)
    err = io.StringIO()
    _precompile.announce_compiles(err)
    _precompile.announce_compiles(err)               # registering twice prints once all the same

    @njit(cache=False)
    def twice(v: float) -> float:
        return 2.0 * v

    assert twice(1.5) == 3.0 and twice(2) == 4      # two compilations (float, int)
    assert err.getvalue().count("\n") == 1 and "compiling numerical kernels" in err.getvalue()


def test_warm_up_commands_are_valid_command_lines() -> None:
    # every warm-up command line parses (a typo would silently leave kernels uncompiled)
    from gmwm import _precompile
    from gmwm.cli import build_parser

    parser = build_parser()
    for cmd in _precompile._COMMANDS:
        args = parser.parse_args([a.format(x="x.npy", X="X.npy") for a in cmd])
        assert args.command == cmd[0]


@pytest.mark.slow
def test_compile_note_does_not_import_numba_itself() -> None:
    # commands that run no Numba kernel must not pay for importing Numba: the note is set up by
    # an import hook when something else imports it
    import subprocess
    import sys

    code = ("import sys\nfrom gmwm._precompile import announce_compiles, _NoteState\n"
            "announce_compiles(sys.stderr)\nassert 'numba' not in sys.modules\n"
            "import numba\nassert _NoteState.registered\n"
            "from numba import njit\nnjit(lambda v: v + 1)(1)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.count("compiling numerical kernels") == 1
