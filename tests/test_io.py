"""gmwm.readers (npy/csv/hdf5 signals, WV tables) and gmwm.atomic (atomic writes, figure saving)."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from gmwm.atomic import (
    atomic_path,
    save_figure,
    write_json_atomic,
    write_signal,
    write_text_atomic,
)
from gmwm.errors import InputError
from gmwm.readers import is_wv_table, read_signal, read_weights, read_wv_table


@pytest.fixture
def x() -> np.ndarray:
    return np.random.default_rng(1).standard_normal(64)


# ---- .npy -------------------------------------------------------------------------------------


def test_npy_roundtrip_and_column_squeeze(tmp_path, x):
    np.save(tmp_path / "a.npy", x)
    np.save(tmp_path / "col.npy", x[:, None])
    np.save(tmp_path / "two.npy", np.column_stack([x, 2 * x]))
    np.testing.assert_array_equal(read_signal(tmp_path / "a.npy"), x)
    np.testing.assert_array_equal(read_signal(tmp_path / "col.npy"), x)
    np.testing.assert_array_equal(read_signal(tmp_path / "two.npy", column=1), 2 * x)
    with pytest.raises(InputError, match="--column"):
        read_signal(tmp_path / "two.npy")


def test_npy_integer_signal_becomes_float(tmp_path):
    np.save(tmp_path / "i.npy", np.arange(10, dtype=np.int16))
    y = read_signal(tmp_path / "i.npy")
    assert y.dtype == np.float64 and y[-1] == 9.0


# ---- CSV --------------------------------------------------------------------------------------


def test_csv_with_header_by_name_and_index(tmp_path, x):
    p = tmp_path / "t.csv"
    p.write_text("time,gyro_z\n" + "".join(f"{i},{float(v)!r}\n" for i, v in enumerate(x)))
    np.testing.assert_array_equal(read_signal(p, column="gyro_z"), x)
    np.testing.assert_array_equal(read_signal(p, column=1), x)
    np.testing.assert_array_equal(read_signal(p, column="1"), x)


def test_csv_without_header_single_column(tmp_path, x):
    p = tmp_path / "t.csv"
    p.write_text("".join(f"{float(v)!r}\n" for v in x))
    np.testing.assert_array_equal(read_signal(p), x)


def test_csv_errors_name_the_problem(tmp_path, x):
    p = tmp_path / "t.csv"
    p.write_text("time,gyro_z\n" + "".join(f"{i},{float(v)!r}\n" for i, v in enumerate(x)))
    with pytest.raises(InputError, match=r"2 columns \(time, gyro_z\): choose one with --column"):
        read_signal(p)
    with pytest.raises(InputError, match=r"column 'gyro_x' not found.*time, gyro_z"):
        read_signal(p, column="gyro_x")
    with pytest.raises(InputError, match="out of range"):
        read_signal(p, column=5)
    q = tmp_path / "bad.csv"
    q.write_text("v\n1.0\n2.0\nabc\n4.0\n")
    with pytest.raises(InputError, match=r"not numeric: row 3 holds 'abc'"):
        read_signal(q)


def test_tsv_and_whitespace_txt(tmp_path, x):
    (tmp_path / "a.tsv").write_text("a\tb\n" + "".join(f"{float(v)!r}\t0\n" for v in x))
    (tmp_path / "a.txt").write_text("".join(f"  {float(v)!r}   1\n" for v in x))
    np.testing.assert_array_equal(read_signal(tmp_path / "a.tsv", column="a"), x)
    np.testing.assert_array_equal(read_signal(tmp_path / "a.txt", column=0), x)


# ---- HDF5 -------------------------------------------------------------------------------------


def test_hdf5_default_dataset_and_path(tmp_path, x):
    p = tmp_path / "a.h5"
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu/gyro_z", data=x)
        fh.create_dataset("meta/scalar", data=3.0)
    np.testing.assert_array_equal(read_signal(p), x)
    np.testing.assert_array_equal(read_signal(p, dataset="/imu/gyro_z"), x)
    with pytest.raises(InputError, match=r"dataset '/imu/accel' not found.*/imu/gyro_z"):
        read_signal(p, dataset="/imu/accel")


def test_hdf5_several_or_not_1d(tmp_path, x):
    p = tmp_path / "two.hdf5"
    with h5py.File(p, "w") as fh:
        fh.create_dataset("a", data=x)
        fh.create_dataset("b", data=x)
        fh.create_dataset("cube", data=np.zeros((2, 3, 4)))
    with pytest.raises(InputError, match="several 1-D datasets.*--dataset"):
        read_signal(p)
    np.testing.assert_array_equal(read_signal(p, dataset="b"), x)
    with pytest.raises(InputError, match=r"shape \(2, 3, 4\), not a 1-D signal"):
        read_signal(p, dataset="cube")


# ---- common validation ------------------------------------------------------------------------


def test_missing_file_and_unknown_extension(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_signal(tmp_path / "nope.npy")
    p = tmp_path / "a.xlsx"
    p.write_text("1\n")
    with pytest.raises(InputError, match=r"unknown file extension '.xlsx'"):
        read_signal(p)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_rejected_with_position(tmp_path, x, bad):
    y = x.copy()
    y[17] = bad
    np.save(tmp_path / "a.npy", y)
    with pytest.raises(InputError, match="first at sample 17"):
        read_signal(tmp_path / "a.npy")
    assert np.isnan(read_signal(tmp_path / "a.npy", check_finite=False)[17]) == np.isnan(bad)


def test_empty_signal(tmp_path):
    np.save(tmp_path / "e.npy", np.array([]))
    with pytest.raises(InputError, match="empty"):
        read_signal(tmp_path / "e.npy")


# ---- writing ----------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", [".npy", ".csv", ".tsv", ".txt", ".h5"])
def test_write_signal_roundtrip_is_exact(tmp_path, x, ext):
    p = write_signal(tmp_path / f"sub/s{ext}", x)
    np.testing.assert_array_equal(read_signal(p), x)  # %.17g text keeps every bit
    assert [q.name for q in p.parent.iterdir()] == [p.name]  # no temporary left behind


def test_atomic_path_success_and_failure(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".txt" and tmp != target
        tmp.write_text("half written")
        raise RuntimeError("killed")
    assert target.read_text() == "old"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["out.txt"]
    with atomic_path(target) as tmp:
        tmp.write_text("new")
        assert target.read_text() == "old"  # not visible until the block succeeds
    assert target.read_text() == "new"


def test_write_json_and_text_atomic(tmp_path):
    p = write_json_atomic(tmp_path / "a.json", {"x": np.arange(3), "y": np.float64(np.nan),
                                                  "ok": np.bool_(True)})
    assert json.loads(p.read_text()) == {"x": [0, 1, 2], "y": None, "ok": True}
    assert write_text_atomic(tmp_path / "b.txt", "hi\n").read_text() == "hi\n"


def test_save_figure_formats(tmp_path):
    from matplotlib.figure import Figure

    fig = Figure()
    fig.add_subplot().plot([1, 2], [3, 4])
    written = save_figure(fig, tmp_path / "fig")
    assert [p.name for p in written] == ["fig.png", "fig.pdf"]
    assert (tmp_path / "fig.png").read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "fig.pdf").read_bytes()[:4] == b"%PDF"
    assert save_figure(fig, tmp_path / "one.svg") == [tmp_path / "one.svg"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fig.pdf", "fig.png", "one.svg"]


# ---- WV tables --------------------------------------------------------------------------------


def test_read_wv_table_with_and_without_n(tmp_path):
    scales = 2.0 ** np.arange(1, 6)
    var = 1.0 / scales
    T = 1000
    p = tmp_path / "wv.csv"
    p.write_text("scale,variance,n\n" + "".join(f"{s:g},{float(v)!r},{T - int(s) + 1}\n"
                                               for s, v in zip(scales, var, strict=True)))
    assert is_wv_table(p)
    wv = read_wv_table(p)
    assert wv.n_samples == T
    np.testing.assert_array_equal(wv.variance, var)
    assert np.all(wv.ci_low < wv.variance) and np.all(wv.variance < wv.ci_high)

    q = tmp_path / "wv_s.csv"  # seconds at 100 Hz, explicit CI, no n
    q.write_text("scale_s,variance,ci_low,ci_high\n" + "".join(
        f"{float(s) / 100!r},{float(v)!r},{0.9 * float(v)!r},{1.1 * float(v)!r}\n" for s, v in zip(scales, var, strict=True)))
    with pytest.raises(InputError, match="--n-samples"):
        read_wv_table(q, freq=100.0)
    wv = read_wv_table(q, n_samples=T, freq=100.0)
    np.testing.assert_allclose(wv.scales, scales)
    np.testing.assert_allclose(wv.ci_high, 1.1 * var)
    assert not is_wv_table(tmp_path / "wv.npy")


def test_read_wv_table_rejects_non_dyadic(tmp_path):
    p = tmp_path / "wv.csv"
    p.write_text("scale,variance\n2,1.0\n3,0.5\n")
    with pytest.raises(InputError, match="dyadic"):
        read_wv_table(p, n_samples=100)


# ---- several channels, sampling frequency from the file ----------------------------------------


def _imu_csv(p, n=128, fs=50.0, time_name="time", scale=1.0):
    rng = np.random.default_rng(4)
    data = rng.standard_normal((n, 3))
    t = np.arange(n) / fs * scale
    p.write_text(f"{time_name},gx,label,gy\n" + "".join(
        f"{float(t[i])!r},{float(data[i, 0])!r},a,{float(data[i, 1])!r}\n" for i in range(n)))
    return data


def test_read_channels_csv_time_column_gives_freq(tmp_path):
    from gmwm.readers import read_channels

    p = tmp_path / "imu.csv"
    data = _imu_csv(p)
    ch = read_channels(p, "all")  # numeric columns, the time column aside
    assert list(ch.signals) == ["gx", "gy"]
    np.testing.assert_array_equal(ch.signals["gy"], data[:, 1])
    assert ch.freq == 50.0 and ch.freq_source == "time column 'time'"
    assert list(read_channels(p, ["gy", 1]).signals) == ["gy", "gx"]
    with pytest.raises(InputError, match="not numeric"):
        read_channels(p, ["label"])


@pytest.mark.parametrize(("name", "scale"), [("timestamp_ns", 1e9), ("t[ms]", 1e3), ("%time", 1e9)])
def test_time_column_units(tmp_path, name, scale):
    from gmwm.readers import read_channels, time_column_unit

    assert time_column_unit(name) == pytest.approx(1 / scale)
    p = tmp_path / "imu.csv"
    _imu_csv(p, fs=200.0, time_name=name, scale=scale)
    assert read_channels(p, ["gx"]).freq == pytest.approx(200.0)


def test_time_column_problems(tmp_path):
    from gmwm.readers import read_channels

    p = tmp_path / "bad.csv"
    p.write_text("time,gx\n0,1\n0.1,2\n0.1,3\n0.3,4\n")
    with pytest.raises(InputError, match="not strictly increasing"):
        read_channels(p, ["gx"])
    q = tmp_path / "jitter.csv"
    q.write_text("time,gx\n" + "".join(f"{float(t)!r},{i}\n" for i, t in
                                       enumerate(np.cumsum([0.01] * 70 + [0.05] + [0.01] * 20))))
    ch = read_channels(q, ["gx"])
    assert ch.freq == pytest.approx(100.0) and "irregular sampling" in ch.notes[0]


def test_read_channels_hdf5_datasets_and_attribute(tmp_path, x):
    from gmwm.readers import read_channels

    p = tmp_path / "imu.h5"
    with h5py.File(p, "w") as fh:
        g = fh.create_group("imu")
        g.attrs["sampling_rate"] = 400.0
        g.create_dataset("gx", data=x)
        g.create_dataset("gy", data=2 * x)
    ch = read_channels(p, "all")
    assert list(ch.signals) == ["imu/gx", "imu/gy"] and ch.freq == 400.0
    assert "sampling_rate" in ch.freq_source
    ch = read_channels(p, ["/imu/gy"])
    np.testing.assert_array_equal(ch.signals["imu/gy"], 2 * x)
    assert read_channels(p, None, dataset="/imu/gx").freq == 400.0


def test_read_channels_npy_matrix(tmp_path, x):
    from gmwm.readers import read_channels

    np.save(tmp_path / "m.npy", np.column_stack([x, 2 * x, 3 * x]))
    ch = read_channels(tmp_path / "m.npy", "all")
    assert list(ch.signals) == ["0", "1", "2"] and ch.freq is None
    np.testing.assert_array_equal(read_channels(tmp_path / "m.npy", [2]).signals["2"], 3 * x)


# ---- edge cases of .npy files and outputs ------------------------------------------------------


@pytest.mark.parametrize("content", [b"", b"\x00\x01garbage" * 20, b"\x93NUMPY\x01\x00junk"])
def test_junk_npy_is_one_clear_error_without_pickle_advice(tmp_path, content):
    p = tmp_path / "j.npy"
    p.write_bytes(content)
    with pytest.raises(InputError) as info:
        read_signal(p)
    msg = str(info.value)
    assert "j.npy" in msg and "pickle" not in msg and "\n" not in msg


def test_object_npy_says_python_objects(tmp_path):
    p = tmp_path / "o.npy"
    np.save(p, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(InputError, match="Python objects") as info:
        read_signal(p)
    assert "allow_pickle" not in str(info.value)


def test_atomic_path_rejects_a_directory(tmp_path):
    (tmp_path / "out.csv").mkdir()
    with pytest.raises(InputError, match=r"out.csv is a directory"):
        write_text_atomic(tmp_path / "out.csv", "x\n")


# ---- tables that round-trip ---------------------------------------------------------------------


def test_wv_table_records_its_frequency(tmp_path):
    p = tmp_path / "wv.csv"
    p.write_text("level,scale,scale_s,variance,n\n" + "".join(
        f"{j},{2 ** j},{2 ** j / 250},{1 / 2 ** j},{1000 - 2 ** j + 1}\n" for j in range(1, 6)))
    assert read_wv_table(p).freq == 250.0
    assert read_wv_table(p, freq=250.0).freq == 250.0
    with pytest.raises(InputError, match="contradicts the 250 Hz"):
        read_wv_table(p, freq=100.0)


def test_av_table_reads_as_wv(tmp_path):
    from gmwm.wv import wvar

    x = np.random.default_rng(5).standard_normal(4096)
    wv = wvar(x, freq=10.0)
    m = wv.scales / 2
    p = tmp_path / "av.csv"
    p.write_text("cluster_m,tau_s,allan_var,ci_low,ci_high,allan_dev,n\n" + "".join(
        f"{int(mi)},{float(mi) / 10!r},{float(2 * v)!r},{float(2 * lo)!r},{float(2 * hi)!r},"
        f"{float(np.sqrt(2 * v))!r},{n}\n"
        for mi, v, lo, hi, n in zip(m, wv.variance, wv.ci_low, wv.ci_high, wv.n, strict=True)))
    assert is_wv_table(p)
    got = read_wv_table(p)
    assert got.freq == 10.0 and got.n_samples == 4096
    np.testing.assert_allclose(got.variance, wv.variance, rtol=1e-14)
    np.testing.assert_allclose(got.ci_high, wv.ci_high, rtol=1e-14)


def test_multichannel_table_needs_a_channel(tmp_path):
    from gmwm.readers import table_channels

    p = tmp_path / "wv.csv"
    p.write_text("level,scale,scale_s,n,variance[gx],ci_low[gx],ci_high[gx],variance[gy],ci_low[gy],"
                 "ci_high[gy]\n" + "".join(
                     f"{j},{2 ** j},{2 ** j / 100},{900 - 2 ** j + 1},{1 / 2 ** j},{0.9 / 2 ** j},"
                     f"{1.1 / 2 ** j},{2 / 2 ** j},{1.8 / 2 ** j},{2.2 / 2 ** j}\n" for j in range(1, 5)))
    assert table_channels(p) == ["gx", "gy"]
    with pytest.raises(InputError, match="2 channels"):
        read_wv_table(p)
    wv = read_wv_table(p, channel="gy")
    np.testing.assert_allclose(wv.variance, 2 / 2.0 ** np.arange(1, 5))
    assert wv.freq == 100.0
    with pytest.raises(InputError, match="channel 'gz' not found"):
        read_wv_table(p, channel="gz")


def test_short_table_like_csv_is_not_read_as_a_signal(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("cluster_m,allan_var\n" + "".join(f"{2 ** j},{1 / 2 ** j}\n" for j in range(10)))
    with pytest.raises(InputError, match="looks like a WV/AV table.*10 samples"):
        read_signal(p, column="allan_var")


def test_read_channels_hdf5_time_dataset(tmp_path, x):
    from gmwm.readers import read_channels

    p = tmp_path / "imu.h5"
    with h5py.File(p, "w") as fh:
        fh.create_dataset("imu/timestamp_ns", data=np.arange(x.size, dtype=np.int64) * 2_500_000)
        fh.create_dataset("imu/gz", data=x)
    ch = read_channels(p, "all")
    assert list(ch.signals) == ["imu/gz"] and ch.freq == pytest.approx(400.0)
    assert ch.freq_source == "time dataset /imu/timestamp_ns"


def test_saved_figures_carry_no_creation_date(tmp_path):
    # the committed reports are compared byte for byte after a rerun: a date would differ
    from matplotlib.figure import Figure

    fig = Figure()
    fig.add_subplot().plot([1, 2], [3, 4])
    png, pdf, svg = save_figure(fig, tmp_path / "fig", formats=("png", "pdf", "svg"))
    assert b"CreationDate" not in pdf.read_bytes() and pdf.read_bytes()[:4] == b"%PDF"
    assert b"<dc:date>" not in svg.read_bytes()
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_read_weights_numbers_commas_comments(tmp_path):
    p = tmp_path / "w.txt"
    p.write_text("# scale weights\n0.5, 0.25\n0.125 0.125  # last two\n")
    np.testing.assert_array_equal(read_weights(p), [0.5, 0.25, 0.125, 0.125])
    (tmp_path / "empty.txt").write_text("# nothing\n")
    with pytest.raises(InputError, match="holds no numbers"):
        read_weights(tmp_path / "empty.txt")
    (tmp_path / "bad.txt").write_text("0.5 x\n")
    with pytest.raises(InputError, match="bad.txt"):
        read_weights(tmp_path / "bad.txt")
    with pytest.raises(InputError, match="not found"):
        read_weights(tmp_path / "missing.txt")
