"""Signal and table readers: the boundary where every input is checked once.

* :func:`read_signal` reads a 1-D signal from ``.npy``, ``.csv``/``.tsv``/``.txt`` or HDF5
  (``.h5``/``.hdf5``) and validates it (finite, numeric, 1-D, non-empty).
* :func:`read_channels` reads several columns of one recording and its sampling frequency from a
  time column or an HDF5 attribute.
* :func:`read_wv_table` reads a wavelet (or Allan) variance shared as a CSV table (scale,
  variance, CI bounds).

Every user problem raises :class:`gmwm.errors.InputError` with a one-line message naming it. The
module loads only NumPy (pandas and h5py on first use of a CSV or HDF5 file) and the error classes.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = [
    "MIN_TABLE_SIGNAL",
    "SIGNAL_SUFFIXES",
    "Channels",
    "is_wv_table",
    "read_channels",
    "read_signal",
    "read_weights",
    "read_wv_table",
    "table_channels",
    "time_column_unit",
]

_CSV_SEPARATORS = {".csv": ",", ".tsv": "\t", ".txt": r"\s+"}
HDF5_SUFFIXES = (".h5", ".hdf5")
SIGNAL_SUFFIXES = (".npy", *_CSV_SEPARATORS, *HDF5_SUFFIXES)


# --------------------------------------------------------------------------------------------------
# reading
# --------------------------------------------------------------------------------------------------


def read_signal(
    path: str | os.PathLike,
    column: str | int | None = None,
    dataset: str | None = None,
    *,
    check_finite: bool = True,
) -> np.ndarray:
    """Read a 1-D float64 signal from ``.npy``, ``.csv``/``.tsv``/``.txt`` or HDF5.

    ``column`` selects a column of a table (CSV, or a 2-D ``.npy``/HDF5 array) by header name or
    0-based index; by default the file must hold a single column. ``dataset`` is the HDF5 dataset
    path (default: the only 1-D dataset in the file). With ``check_finite`` NaN or inf raise
    :class:`InputError` naming the first bad sample.
    """
    p = existing_file(path)
    suffix = p.suffix.lower()
    if suffix == ".npy":
        x = _select_column(_load_npy(p), column, p)
    elif suffix in _CSV_SEPARATORS:
        x = _read_csv_column(p, column)
    elif suffix in HDF5_SUFFIXES:
        x = _select_column(_read_hdf5(p, dataset), column, p)
    else:
        raise InputError(
            f"unknown file extension '{p.suffix}' for {p}: use one of {', '.join(SIGNAL_SUFFIXES)}"
        )
    return validated_numbers(x, p, check_finite)


def existing_file(path: str | os.PathLike) -> Path:
    """``path`` as a Path; an InputError when it does not exist or is no file."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if not p.is_file():
        raise InputError(f"not a regular file: {p}")
    return p


_NPY_MAGIC = b"\x93NUMPY"


def _load_npy(p: Path) -> np.ndarray:
    with open(p, "rb") as fh:
        head = fh.read(len(_NPY_MAGIC))
    if head != _NPY_MAGIC:
        what = "an empty file" if not head else "not a NumPy .npy file (no .npy header)"
        raise InputError(f"cannot read {p}: {what}")
    try:
        # memory-mapped, read only: a float64 signal is never copied (the WV kernel reads the
        # page cache directly; 0.2 s saved on 1e7 samples), other dtypes are converted once by
        # the caller; a file that cannot be mapped is read below, which reports the problem
        return np.asarray(np.load(p, mmap_mode="r", allow_pickle=False))
    except (ValueError, OSError, EOFError):
        pass
    try:
        a = np.load(p, allow_pickle=False)
    except ValueError as exc:  # object arrays or a corrupt header: never suggest unpickling
        reason = "it holds Python objects, not numbers" if "pickle" in str(exc) else \
            (str(exc).strip().splitlines() or ["corrupt header"])[0]
        raise InputError(f"cannot read {p} as a numeric .npy array: {reason}") from None
    except (OSError, EOFError) as exc:  # truncated data
        raise InputError(f"cannot read {p} as a .npy array: {exc or 'truncated file'}") from None
    return a


def _select_column(a: np.ndarray, column: str | int | None, p: Path) -> np.ndarray:
    """Return a 1-D view of ``a``: squeeze single rows/columns, pick ``column`` of a 2-D table."""
    if a.dtype.names:  # structured array: columns have names
        names = list(a.dtype.names)
        if column is None:
            if len(names) != 1:
                raise InputError(f"{p} has several columns ({', '.join(names)}): choose one with --column")
            column = names[0]
        key = _resolve_column(column, names, p)
        return np.asarray(a[names[key]])
    if a.ndim == 2 and column is not None:
        ncols = a.shape[1]
        idx = _column_index(column, ncols, p)
        return a[:, idx]
    if a.ndim > 1 and sum(s > 1 for s in a.shape) <= 1:
        return a.reshape(-1)
    if a.ndim != 1:
        if a.ndim == 2:
            raise InputError(
                f"{p} holds a {a.shape[0]}x{a.shape[1]} array, not a 1-D signal: "
                f"choose a column (0..{a.shape[1] - 1}) with --column"
            )
        raise InputError(f"{p} holds an array of shape {a.shape}, not a 1-D signal")
    return a


def _column_index(column: str | int, ncols: int, p: Path) -> int:
    try:
        idx = int(column)
    except (TypeError, ValueError):
        raise InputError(
            f"column '{column}' not found in {p}: it has no header, use a 0-based index 0..{ncols - 1}"
        ) from None
    if not 0 <= idx < ncols:
        raise InputError(f"column index {idx} out of range for {p}: it has {ncols} columns (0..{ncols - 1})")
    return idx


def _resolve_column(column: str | int, names: Sequence[str], p: Path) -> int:
    """Index of ``column`` among ``names``: by exact name first, then as a 0-based integer index."""
    names = [str(n) for n in names]
    if isinstance(column, str) and column in names:
        return names.index(column)
    if isinstance(column, str):
        stripped = [n.strip() for n in names]
        if column.strip() in stripped:
            return stripped.index(column.strip())
    try:
        idx = int(column)
    except (TypeError, ValueError):
        raise InputError(
            f"column '{column}' not found in {p}; available columns: {', '.join(names)}"
        ) from None
    if not 0 <= idx < len(names):
        raise InputError(
            f"column index {idx} out of range for {p}; available columns: "
            + ", ".join(f"{i}={n}" for i, n in enumerate(names))
        )
    return idx


def _csv_header(p: Path, sep: str) -> list[str] | None:
    """The header fields of a delimited text file, or None when the first row is numeric."""
    with open(p, encoding="utf-8", errors="replace") as fh:
        for line in fh:
            if line.strip() and not line.lstrip().startswith("#"):
                break
        else:
            raise InputError(f"{p} is empty")
    fields = line.split() if sep == r"\s+" else line.rstrip("\r\n").split(sep)
    if not fields:
        return None
    for f in fields:
        try:
            float(f)
        except ValueError:
            return [f.strip().strip('"').strip("'") for f in fields]
    return None


def _read_table(p: Path) -> tuple[Any, list[str] | None]:
    """A pandas DataFrame of the delimited file ``p`` and its header (None without one)."""
    import pandas as pd

    sep = _CSV_SEPARATORS[p.suffix.lower()]
    header = _csv_header(p, sep)
    try:
        df = pd.read_csv(
            p,
            sep=sep,
            header=0 if header is not None else None,
            comment="#",
            skipinitialspace=True,
        )
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"cannot parse {p}: {first}") from None
    except pd.errors.EmptyDataError:
        raise InputError(f"{p} is empty") from None
    if header is not None:
        df.columns = [str(c).strip() for c in df.columns]
    return df, header


def _read_csv_column(p: Path, column: str | int | None) -> np.ndarray:
    df, header = _read_table(p)
    names = list(df.columns) if header is not None else [str(i) for i in range(df.shape[1])]
    if column is None:
        if df.shape[1] != 1:
            raise InputError(
                f"{p} has {df.shape[1]} columns ({', '.join(map(str, names))}): choose one with --column"
            )
        idx = 0
    elif header is None:
        idx = _column_index(column, df.shape[1], p)
    else:
        idx = _resolve_column(column, names, p)
    x = _numeric_column(df, idx, names, p)
    check_not_a_table(header, len(df), p)
    return x


def _read_hdf5(p: Path, dataset: str | None) -> np.ndarray:
    import h5py

    try:
        fh = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"cannot open {p} as HDF5: {exc}") from None
    with fh:
        return _read_hdf5_open(fh, p, dataset)


def _read_hdf5_open(fh: Any, p: Path, dataset: str | None) -> np.ndarray:
    import h5py

    candidates: list[tuple[str, tuple[int, ...]]] = []

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Dataset):
            candidates.append((name, obj.shape))

    fh.visititems(visit)
    if dataset is None:
        one_d = [n for n, s in candidates if sum(d > 1 for d in s) == 1]
        if len(one_d) != 1:
            listing = ", ".join(f"/{n} {s}" for n, s in candidates) or "none"
            what = "no 1-D dataset" if not one_d else "several 1-D datasets"
            raise InputError(f"{p} holds {what}: choose one with --dataset (datasets: {listing})")
        dataset = one_d[0]
    key = dataset.lstrip("/") or "/"
    if key not in fh or not isinstance(fh[key], h5py.Dataset):
        listing = ", ".join(f"/{n}" for n, _ in candidates) or "none"
        raise InputError(f"dataset '{dataset}' not found in {p}; available datasets: {listing}")
    ds = fh[key]
    if ds.dtype.kind not in "biuf" and not ds.dtype.names:
        raise InputError(f"dataset '{dataset}' of {p} is not numeric (dtype {ds.dtype})")
    return ds[()]


def validated_numbers(x: np.ndarray, p: Path, check_finite: bool, name: str | None = None) -> np.ndarray:
    """``x`` (read from ``p``) checked to hold numbers (and, with ``check_finite``, no NaN/inf)."""
    where = p if name is None else f"column '{name}' of {p}"
    if x.dtype.kind not in "biuf":
        raise InputError(f"{where} does not hold numbers (dtype {x.dtype})")
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise InputError(f"{where} holds an array of shape {x.shape}, not a 1-D signal")
    if x.size == 0:
        raise InputError(f"{where} holds an empty signal")
    if check_finite:
        bad = ~np.isfinite(x)
        if bad.any():
            first = int(np.argmax(bad))
            n_nan = int(np.isnan(x).sum())
            n_inf = int(bad.sum()) - n_nan
            what = " and ".join(f"{k} {name}" for k, name in ((n_nan, "NaN"), (n_inf, "inf")) if k)
            raise InputError(
                f"signal in {where} contains {what} value(s) (first at sample {first}); "
                "clean or interpolate it first"
            )
    return x


# --------------------------------------------------------------------------------------------------
# several channels of one recording, sampling frequency from a time column or an HDF5 attribute
# --------------------------------------------------------------------------------------------------

#: Header names recognised as a time column, with their unit in seconds (case-insensitive; a unit
#: suffix such as ``_ns``, ``[ms]`` or ``(us)`` overrides the default second).
_TIME_NAME = re.compile(
    r"^\s*(?P<base>%?time(?:stamps?)?|t|timestamps?|stamps?|field\.header\.stamp|secs?|seconds?)"
    r"\s*(?:[_ ]?[\[(]?(?P<unit>ns|nsec|us|usec|µs|ms|msec|s|sec)[\])]?)?\s*$",
    re.IGNORECASE,
)
_TIME_UNITS = {"ns": 1e-9, "nsec": 1e-9, "us": 1e-6, "usec": 1e-6, "µs": 1e-6, "ms": 1e-3,
               "msec": 1e-3, "s": 1.0, "sec": 1.0}
#: HDF5 attributes giving the sampling frequency in Hz, or (second tuple) the sampling period in s.
_FREQ_ATTRS = ("freq", "frequency", "sampling_frequency", "sampling_rate", "sample_rate", "fs",
               "rate", "update_rate")
_PERIOD_ATTRS = ("dt", "sampling_period", "sample_period", "period")
#: Header names of WV/AV tables (a file with them is a table, not a signal).
_TABLE_NAMES = frozenset({"scale", "scale_s", "level", "variance", "ci_low", "ci_high", "allan_var",
                          "avar", "allan_dev", "adev", "cluster_m", "tau_s"})
#: A table-looking file read as a signal must have at least this many samples.
MIN_TABLE_SIGNAL = 64


def time_column_unit(name: str) -> float | None:
    """Seconds per unit of a recognised time column name (``time``, ``t``, ``timestamp_ns``,
    ``%time`` (ROS, ns), ...), or None when ``name`` is not a time column."""
    m = _TIME_NAME.match(str(name))
    if m is None:
        return None
    if m.group("unit"):
        return _TIME_UNITS[m.group("unit").lower()]
    return 1e-9 if m.group("base").lower() in ("%time", "field.header.stamp") else 1.0


@dataclass(frozen=True)
class Channels:
    """Signals of one recording: ``signals`` maps a column name to a 1-D float64 array (all of one
    length); ``freq`` [Hz] comes from a time column or an HDF5 attribute (None when the file has
    neither), ``freq_source`` says which; ``notes`` are things the user should know (e.g. jitter)."""

    signals: dict[str, np.ndarray]
    freq: float | None = None
    freq_source: str | None = None
    notes: tuple[str, ...] = ()
    time: Any = None  # gmwm.readers.timebase.TimeBase of the time column, when there is one


def read_channels(
    path: str | os.PathLike,
    columns: Sequence[str | int] | str | None = None,
    dataset: str | None = None,
    *,
    check_finite: bool = True,
) -> Channels:
    """Read one or several signals of a recording and its sampling frequency when the file has it.

    ``columns``: None (the single data column, a recognised time column aside), ``"all"`` (every
    numeric column except a recognised time column), or a list of names / 0-based indices. For
    HDF5 without ``dataset`` the columns are dataset paths (``"all"``: every 1-D numeric dataset);
    with ``dataset`` (a 2-D or structured array) they select its columns. The frequency comes from
    a time column (``time``, ``t``, ``timestamp[_ns|_us|_ms]``, ``%time``, ...) or from an HDF5
    attribute (``freq``, ``sampling_rate``, ``rate``, ``fs``, ... in Hz; ``dt`` in s).
    """
    p = existing_file(path)
    suffix = p.suffix.lower()
    if suffix == ".npy":
        a = _load_npy(p)
        signals, time = _columns_of_array(a, columns, p)
        freq, source, notes, tb = _time_freq(time, p)
    elif suffix in _CSV_SEPARATORS:
        signals, time = _csv_channels(p, columns)
        freq, source, notes, tb = _time_freq(time, p)
    elif suffix in HDF5_SUFFIXES:
        signals, freq, source, notes, tb = _hdf5_channels(p, columns, dataset)
    else:
        raise InputError(
            f"unknown file extension '{p.suffix}' for {p}: use one of {', '.join(SIGNAL_SUFFIXES)}"
        )
    out = {name: validated_numbers(x, p, check_finite, name if len(signals) > 1 else None)
           for name, x in signals.items()}
    return Channels(out, freq, source, tuple(notes), tb)


def _time_freq(time: tuple[str, np.ndarray, str | None] | None, p: Path
               ) -> tuple[float | None, str | None, list[str], Any]:
    """Rate, its source, notes and time base of a time column (unit by name, else magnitude)."""
    from gmwm.readers.timebase import time_base

    if time is None:
        return None, None, [], None
    name, t, unit = time
    tb = time_base(t, name=name, unit=unit, where=f"time column '{name}' of {p}")
    return tb.freq, f"time column '{name}'", list(tb.notes), tb


def _pick(names: Sequence[str], numeric: Sequence[bool], columns: Any, p: Path,
          time_idx: int | None) -> list[int]:
    """Indices of the requested columns (see :func:`read_channels`)."""
    if columns is None:
        data = [i for i in range(len(names)) if i != time_idx]
        if len(data) != 1:
            listing = ", ".join(map(str, names))
            raise InputError(f"{p} has {len(names)} columns ({listing}): choose one with --column "
                             "or several with --columns")
        return data
    if isinstance(columns, str) and columns.strip().lower() == "all":
        data = [i for i in range(len(names)) if i != time_idx and numeric[i]]
        if not data:
            raise InputError(f"{p} has no numeric column besides its time column")
        return data
    if isinstance(columns, str | int):
        columns = [columns]
    idx = [_resolve_column(c, names, p) for c in columns]
    dup = {names[i] for i in idx if idx.count(i) > 1}
    if dup:
        raise InputError(f"column(s) {', '.join(sorted(map(str, dup)))} requested twice")
    return idx


def _time_index(names: Sequence[str]) -> tuple[int, str | None] | None:
    from gmwm.readers.timebase import time_column

    for i, n in enumerate(names):
        is_time, unit = time_column(n)
        if is_time:
            return i, unit
    return None


def _columns_of_array(a: np.ndarray, columns: Any, p: Path
                      ) -> tuple[dict[str, np.ndarray], tuple[str, np.ndarray, str | None] | None]:
    """Columns of a 2-D or structured array (names: field names, else indices as strings)."""
    if a.dtype.names:
        names = list(a.dtype.names)
        cols = [np.asarray(a[n]).reshape(-1) for n in names]
    elif a.ndim == 2 and (columns is not None or a.shape[1] > 1 and a.shape[0] > 1):
        names = [str(i) for i in range(a.shape[1])]
        cols = [a[:, i] for i in range(a.shape[1])]
    else:
        return {p.stem: _select_column(a, None, p)}, None
    numeric = [c.dtype.kind in "biuf" for c in cols]
    t = _time_index(names) if a.dtype.names else None
    idx = _pick(names, numeric, columns, p, None if t is None else t[0])
    time = None if t is None else (names[t[0]], cols[t[0]], t[1])
    return {names[i]: cols[i] for i in idx}, time


def _csv_channels(p: Path, columns: Any
                  ) -> tuple[dict[str, np.ndarray], tuple[str, np.ndarray, str | None] | None]:
    df, header = _read_table(p)
    names = list(df.columns) if header is not None else [str(i) for i in range(df.shape[1])]
    t = _time_index(names) if header is not None else None
    numeric = [df.iloc[:, i].dtype.kind in "biuf" for i in range(df.shape[1])]
    if columns is None and df.shape[1] == 1:
        idx = [0]
    else:
        idx = _pick(names, numeric, columns, p, None if t is None else t[0])
    out = {str(names[i]): _numeric_column(df, i, names, p) for i in idx}
    check_not_a_table(header, len(df), p)
    time = None if t is None else (names[t[0]], _numeric_column(df, t[0], names, p), t[1])
    return out, time


def check_not_a_table(header: Sequence[str] | None, n_rows: int, p: Path) -> None:
    """A file with WV/AV table columns read as a very short signal is almost surely a mistake."""
    if header is None or n_rows >= MIN_TABLE_SIGNAL:
        return
    found = [h for h in header if _base_name(h) in _TABLE_NAMES]
    if found:
        raise InputError(
            f"{p} looks like a WV/AV table (columns {', '.join(found)}) but would be read as a signal "
            f"of {n_rows} samples (fewer than {MIN_TABLE_SIGNAL}): give 'gmwm fit' the table with its "
            "'scale' or 'level' and 'variance' (or 'cluster_m' and 'allan_var') columns"
        )


def _numeric_column(df: Any, idx: int, names: Sequence[str], p: Path) -> np.ndarray:
    col = df.iloc[:, idx]
    if col.dtype.kind not in "biuf":
        import pandas as pd

        num = pd.to_numeric(col, errors="coerce")
        bad = np.flatnonzero(num.isna().to_numpy() & col.notna().to_numpy())
        if bad.size:
            row = int(bad[0]) + 1
            raise InputError(
                f"column '{names[idx]}' of {p} is not numeric: row {row} holds {col.iloc[bad[0]]!r}"
            )
        col = num
    return col.to_numpy(dtype=np.float64)


def hdf5_freq_attr(obj: Any) -> tuple[float, str] | None:
    """The sampling rate [Hz] an HDF5 object's attributes state (a rate or a period), with the
    attribute's name; None when none does."""
    attrs = {str(k).lower(): k for k in obj.attrs}
    for names, period in ((_FREQ_ATTRS, False), (_PERIOD_ATTRS, True)):
        for n in names:
            if n in attrs:
                try:
                    v = float(np.asarray(obj.attrs[attrs[n]]).reshape(-1)[0])
                except (TypeError, ValueError, IndexError):
                    continue
                if np.isfinite(v) and v > 0:
                    return (1.0 / v if period else v), f"HDF5 attribute '{attrs[n]}' of {obj.name}"
    return None


def _hdf5_channels(p: Path, columns: Any, dataset: str | None
                   ) -> tuple[dict[str, np.ndarray], float | None, str | None, list[str], Any]:
    import h5py

    try:
        fh = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"cannot open {p} as HDF5: {exc}") from None
    with fh:
        if dataset is not None or columns is None:
            a = _read_hdf5_open(fh, p, dataset)
            if columns is None:
                signals = {(dataset or p.stem).strip("/"): _select_column(a, None, p)}
            else:
                signals, _ = _columns_of_array(a, columns, p)
            key = _hdf5_key(fh, p, dataset)
            objs = [fh[key]] if key is not None else []
        else:
            one_d = _hdf5_1d(fh)
            names = list(one_d)
            t = _time_index([n.rsplit("/", 1)[-1] for n in names])
            numeric = [fh[n].dtype.kind in "biuf" for n in names]
            wanted = columns
            if not (isinstance(columns, str) and columns.strip().lower() == "all"):
                wanted = [str(c).lstrip("/") for c in ([columns] if isinstance(columns, str | int)
                                                       else columns)]
            idx = _pick(names, numeric, wanted, p, None if t is None else t[0])
            signals = {names[i]: fh[names[i]][()].reshape(-1) for i in idx}
            objs = [fh[names[i]] for i in idx]
            if t is not None:
                from gmwm.readers.timebase import time_base

                tname = names[t[0]]
                tb = time_base(fh[tname][()].reshape(-1), name=tname.rsplit("/", 1)[-1],
                               unit=t[1], where=f"time dataset /{tname} of {p}")
                return signals, tb.freq, f"time dataset /{tname}", list(tb.notes), tb
        for obj in objs:  # the dataset, then its groups up to the root
            while obj is not None:
                found = hdf5_freq_attr(obj)
                if found is not None:
                    return signals, found[0], found[1], [], None
                obj = obj.parent if obj.name != "/" else None
    return signals, None, None, [], None


def _hdf5_1d(fh: Any) -> dict[str, tuple[int, ...]]:
    import h5py

    out: dict[str, tuple[int, ...]] = {}

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Dataset) and sum(d > 1 for d in obj.shape) == 1:
            out[name] = obj.shape

    fh.visititems(visit)
    if not out:
        raise InputError(f"{fh.filename} holds no 1-D dataset")
    return out


def _hdf5_key(fh: Any, p: Path, dataset: str | None) -> str | None:
    if dataset is not None:
        return dataset.lstrip("/") or "/"
    one_d = list(_hdf5_1d(fh))
    return one_d[0] if len(one_d) == 1 else None


# --------------------------------------------------------------------------------------------------
# WV and AV tables (as written by 'gmwm wv -o' / 'gmwm av -o', or shared by others)
# --------------------------------------------------------------------------------------------------

_CHANNEL = re.compile(r"^(?P<base>[A-Za-z_]+)\[(?P<ch>.+)\]$")


def _base_name(header: str) -> str:
    """'variance[gx]' -> 'variance'; 'Variance' -> 'variance'."""
    m = _CHANNEL.match(header.strip())
    return (m.group("base") if m else header.strip()).lower()


def _table_kind(header: Sequence[str]) -> str | None:
    """'wv' or 'av' from a table header, None when it is not one."""
    names = {_base_name(h) for h in header}
    if "variance" in names and names & {"scale", "scale_s", "level"}:
        return "wv"
    if names & {"allan_var", "avar"} and names & {"cluster_m", "tau_s", "level"}:
        return "av"
    return None


def is_wv_table(path: str | os.PathLike) -> bool:
    """True when ``path`` is a delimited text file holding a WV table (``scale``/``scale_s``/``level``
    and ``variance``) or an AV table (``cluster_m``/``tau_s``/``level`` and ``allan_var``/``avar``)."""
    p = Path(path)
    sep = _CSV_SEPARATORS.get(p.suffix.lower())
    if sep is None or not p.is_file():
        return False
    header = _csv_header(p, sep)
    return header is not None and _table_kind(header) is not None


def table_channels(path: str | os.PathLike) -> list[str]:
    """Channel names of a multi-channel table (columns ``variance[gx]``, ``allan_var[gx]``, ...), in
    file order; [] for a single-channel table."""
    p = existing_file(path)
    header = _csv_header(p, _CSV_SEPARATORS.get(p.suffix.lower(), ","))
    out: list[str] = []
    for h in header or []:
        m = _CHANNEL.match(h.strip())
        if m and m.group("base").lower() in ("variance", "allan_var", "avar") and m.group("ch") not in out:
            out.append(m.group("ch"))
    return out


def read_wv_table(
    path: str | os.PathLike,
    n_samples: int | None = None,
    freq: float | None = None,
    alpha: float = 0.05,
    channel: str | None = None,
):
    """Read a wavelet variance (or Allan variance) shared as a table; return a ``WaveletVariance``.

    WV columns (header required, case-insensitive): ``variance`` and ``scale`` (filter length
    tau_j = 2**j samples), ``level`` (j) or ``scale_s`` (seconds); AV columns: ``allan_var``
    (or ``avar``) and ``cluster_m`` (samples), ``level`` (cluster 2**(j-1)) or ``tau_s`` (seconds);
    the AV is converted to the WV at tau_j = 2 m (WV = AV / 2). Optional ``ci_low``/``ci_high``
    (computed from the chi-square rule when absent) and ``n`` (coefficients per level,
    M_j = T - tau_j + 1, which gives ``n_samples`` when that is None). A multi-channel table has
    ``variance[ch]``, ``ci_low[ch]``, ... columns; pick one with ``channel``.

    The sampling frequency is recorded by a table with both a sample-based (``scale``, ``level``,
    ``cluster_m``) and a seconds column (``scale_s``, ``tau_s``); ``freq`` None takes it (1 Hz
    otherwise), and a ``freq`` that contradicts it is an error.
    """
    from gmwm.wv import WaveletVariance

    p = existing_file(path)
    if p.suffix.lower() not in _CSV_SEPARATORS:
        raise InputError(f"a wavelet-variance table must be a .csv/.tsv/.txt file, got {p}")
    df, header = _read_table(p)
    if header is None:
        raise InputError(f"{p} has no header: a WV table needs columns scale,variance[,ci_low,ci_high]")
    kind = _table_kind(header)
    if kind is None:
        raise InputError(f"{p} has no 'variance' and 'scale' columns (nor 'allan_var' and "
                         f"'cluster_m'); available columns: {', '.join(map(str, df.columns))}")
    channels = table_channels(p)
    if channel is None and len(channels) > 1:
        raise InputError(f"{p} holds {len(channels)} channels ({', '.join(channels)}): choose with --columns")
    if channel is None and channels:
        channel = channels[0]
    if channel is not None and channel not in channels:
        what = f"channels: {', '.join(channels)}" if channels else "it has a single channel"
        raise InputError(f"channel '{channel}' not found in {p} ({what})")
    cols = {c.lower(): c for c in df.columns}

    def col(name: str, per_channel: bool = False) -> np.ndarray | None:
        key = f"{name}[{channel}]".lower() if per_channel and channel is not None else name
        if key not in cols:
            return None
        v = df[cols[key]]
        if v.dtype.kind not in "biuf":
            raise InputError(f"column '{cols[key]}' of {p} is not numeric")
        return v.to_numpy(dtype=np.float64)

    if kind == "wv":
        variance = col("variance", True)
        samples = col("scale") if "scale" in cols else (2.0 ** col("level") if "level" in cols else None)
        seconds = col("scale_s")
        factor = 1.0
    else:
        variance = col("allan_var", True)
        if variance is None:
            variance = col("avar", True)
        samples = (2.0 * col("cluster_m") if "cluster_m" in cols
                   else (2.0 ** col("level") if "level" in cols else None))
        tau = col("tau_s")
        seconds = None if tau is None else 2.0 * tau
        factor = 0.5  # WV = AV / 2 at tau_j = 2 m
    if variance is None:
        raise InputError(f"{p} has no variance column for channel '{channel}'")
    freq = _table_freq(samples, seconds, freq, p)
    scales = samples if samples is not None else seconds * freq
    levels = np.log2(scales)
    if np.any(np.abs(levels - np.round(levels)) > 1e-6) or np.any(levels < 1):
        raise InputError(
            f"scales in {p} must be dyadic filter lengths 2, 4, 8, ... samples"
            + (" (seconds are converted with --freq)" if samples is None else "")
        )
    scales = 2.0 ** np.round(levels)
    ci_low, ci_high = col("ci_low", True), col("ci_high", True)
    if (ci_low is None) != (ci_high is None):
        raise InputError(f"{p} must have both ci_low and ci_high columns, or neither")
    n = col("n")
    if n_samples is None:
        if n is None:
            raise InputError(f"{p} has no 'n' column: give the signal length with --n-samples")
        n_samples = round(float(n[0] + scales[0] - 1))
    for name, v in (("variance", variance), ("ci_low", ci_low), ("ci_high", ci_high)):
        if v is not None and not np.all(np.isfinite(v)):
            raise InputError(f"column '{name}' of {p} contains NaN or inf")
    if np.any(variance <= 0):
        raise InputError(f"column 'variance' of {p} must be positive")
    return WaveletVariance.from_table(
        scales, factor * variance, ci_low=None if ci_low is None else factor * ci_low,
        ci_high=None if ci_high is None else factor * ci_high, n_samples=int(n_samples), freq=freq,
        alpha=alpha,
    )


def _table_freq(samples: np.ndarray | None, seconds: np.ndarray | None, freq: float | None,
                p: Path) -> float:
    """The frequency a table records (samples / seconds), checked against a given ``freq``."""
    if samples is None or seconds is None:
        return 1.0 if freq is None else float(freq)
    if np.any(seconds <= 0) or not np.all(np.isfinite(seconds)):
        raise InputError(f"the seconds column of {p} must be positive")
    ratio = samples / seconds
    recorded = float(np.median(ratio))
    if np.max(np.abs(ratio / recorded - 1.0)) > 1e-6:
        raise InputError(f"{p}: the scales in samples and in seconds disagree (not one frequency)")
    recorded = float(f"{recorded:.12g}")
    if freq is not None and abs(freq / recorded - 1.0) > 1e-6:
        raise InputError(f"--freq {freq:g} contradicts the {recorded:g} Hz recorded in {p} "
                         "(scale / scale_s); drop --freq")
    return recorded


# --------------------------------------------------------------------------------------------------
# scale weights (SVO)
# --------------------------------------------------------------------------------------------------


def read_weights(path: Any) -> np.ndarray:
    """Scale weights from a text file: numbers separated by commas, spaces or newlines, one per
    level from j = 1; ``#`` starts a comment."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"weights file {p} not found")
    tokens = []
    for line in p.read_text(encoding="utf-8", errors="replace").splitlines():
        tokens += line.split("#", 1)[0].replace(",", " ").split()
    try:
        values = np.array([float(t) for t in tokens])
    except ValueError as exc:
        raise InputError(f"weights file {p}: {exc}") from None
    if values.size == 0:
        raise InputError(f"weights file {p} holds no numbers")
    return values
