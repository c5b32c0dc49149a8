"""gmwm.io: signal readers (npy/csv/hdf5), WV tables, atomic writes, figure saving."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from gmwm.errors import InputError
from gmwm.io import (
    atomic_path,
    is_wv_table,
    read_signal,
    read_wv_table,
    save_figure,
    write_json_atomic,
    write_signal,
    write_text_atomic,
)


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
