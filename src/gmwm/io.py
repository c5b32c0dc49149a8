"""Signal and table input/output.

* :func:`read_signal` reads a 1-D signal from ``.npy``, ``.csv``/``.tsv``/``.txt`` or HDF5
  (``.h5``/``.hdf5``) and validates it once, at the boundary (finite, numeric, 1-D, non-empty).
* :func:`read_wv_table` reads a wavelet variance shared as a CSV table (scale, variance, CI bounds).
* :func:`atomic_path` and the ``write_*`` helpers write every output through a temporary file in the
  same directory that is renamed onto the target only on success, so a killed job never leaves a file
  that looks complete.

Every user problem raises :class:`gmwm.errors.InputError` with a one-line message naming it.
"""

from __future__ import annotations

import json
import os
import uuid
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = [
    "SIGNAL_SUFFIXES",
    "atomic_path",
    "is_wv_table",
    "read_signal",
    "read_wv_table",
    "save_figure",
    "write_json_atomic",
    "write_signal",
    "write_text_atomic",
]

_CSV_SEPARATORS = {".csv": ",", ".tsv": "\t", ".txt": r"\s+"}
_HDF5_SUFFIXES = (".h5", ".hdf5")
SIGNAL_SUFFIXES = (".npy", *_CSV_SEPARATORS, *_HDF5_SUFFIXES)


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
    p = _existing_file(path)
    suffix = p.suffix.lower()
    if suffix == ".npy":
        x = _select_column(_load_npy(p), column, p)
    elif suffix in _CSV_SEPARATORS:
        x = _read_csv_column(p, column)
    elif suffix in _HDF5_SUFFIXES:
        x = _select_column(_read_hdf5(p, dataset), column, p)
    else:
        raise InputError(
            f"unknown file extension '{p.suffix}' for {p}: use one of {', '.join(SIGNAL_SUFFIXES)}"
        )
    return _validated(x, p, check_finite)


def _existing_file(path: str | os.PathLike) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"file not found: {p}")
    if not p.is_file():
        raise InputError(f"not a regular file: {p}")
    return p


def _load_npy(p: Path) -> np.ndarray:
    try:
        return np.load(p, allow_pickle=False)
    except ValueError as exc:  # object arrays or a corrupt header
        raise InputError(f"cannot read {p} as a numeric .npy array: {exc}") from None


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


def _read_hdf5(p: Path, dataset: str | None) -> np.ndarray:
    import h5py

    try:
        fh = h5py.File(p, "r")
    except OSError as exc:
        raise InputError(f"cannot open {p} as HDF5: {exc}") from None
    with fh:
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


def _validated(x: np.ndarray, p: Path, check_finite: bool) -> np.ndarray:
    if x.dtype.kind not in "biuf":
        raise InputError(f"{p} does not hold numbers (dtype {x.dtype})")
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 1:
        raise InputError(f"{p} holds an array of shape {x.shape}, not a 1-D signal")
    if x.size == 0:
        raise InputError(f"{p} holds an empty signal")
    if check_finite:
        bad = ~np.isfinite(x)
        if bad.any():
            first = int(np.argmax(bad))
            n_nan = int(np.isnan(x).sum())
            n_inf = int(bad.sum()) - n_nan
            what = " and ".join(f"{k} {name}" for k, name in ((n_nan, "NaN"), (n_inf, "inf")) if k)
            raise InputError(
                f"signal in {p} contains {what} value(s) (first at sample {first}); "
                "clean or interpolate it first"
            )
    return x


def is_wv_table(path: str | os.PathLike) -> bool:
    """True when ``path`` is a delimited text file whose header has ``scale`` and ``variance`` columns."""
    p = Path(path)
    sep = _CSV_SEPARATORS.get(p.suffix.lower())
    if sep is None or not p.is_file():
        return False
    header = _csv_header(p, sep)
    if header is None:
        return False
    names = {h.strip().lower() for h in header}
    return "variance" in names and bool(names & {"scale", "scale_s", "level"})


def read_wv_table(
    path: str | os.PathLike,
    n_samples: int | None = None,
    freq: float = 1.0,
    alpha: float = 0.05,
):
    """Read a wavelet variance shared as a table and return a ``gmwm.wv.WaveletVariance``.

    Columns (header required, case-insensitive): ``variance`` and one of ``scale`` (filter length
    tau_j = 2**j in samples), ``scale_s`` (seconds, converted with ``freq``) or ``level`` (j);
    optional ``ci_low``/``ci_high`` (computed from the chi-square rule when absent) and ``n``
    (coefficients per level, M_j = T - tau_j + 1, which gives ``n_samples`` when that is None).
    """
    from gmwm.wv import WaveletVariance

    p = _existing_file(path)
    if p.suffix.lower() not in _CSV_SEPARATORS:
        raise InputError(f"a wavelet-variance table must be a .csv/.tsv/.txt file, got {p}")
    df, header = _read_table(p)
    if header is None:
        raise InputError(f"{p} has no header: a WV table needs columns scale,variance[,ci_low,ci_high]")
    cols = {c.lower(): c for c in df.columns}

    def col(name: str) -> np.ndarray | None:
        if name not in cols:
            return None
        v = df[cols[name]]
        if v.dtype.kind not in "biuf":
            raise InputError(f"column '{cols[name]}' of {p} is not numeric")
        return v.to_numpy(dtype=np.float64)

    variance = col("variance")
    if variance is None:
        raise InputError(f"{p} has no 'variance' column; available columns: {', '.join(df.columns)}")
    if "scale" in cols:
        scales = col("scale")
    elif "scale_s" in cols:
        scales = col("scale_s") * freq
    elif "level" in cols:
        scales = 2.0 ** col("level")
    else:
        raise InputError(f"{p} has no 'scale' column; available columns: {', '.join(df.columns)}")
    levels = np.log2(scales)
    if np.any(np.abs(levels - np.round(levels)) > 1e-6) or np.any(levels < 1):
        raise InputError(
            f"scales in {p} must be dyadic filter lengths 2, 4, 8, ... samples"
            + (" (scale_s is converted with --freq)" if "scale_s" in cols else "")
        )
    ci_low, ci_high = col("ci_low"), col("ci_high")
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
        scales, variance, ci_low=ci_low, ci_high=ci_high, n_samples=int(n_samples), freq=freq,
        alpha=alpha,
    )


# --------------------------------------------------------------------------------------------------
# writing
# --------------------------------------------------------------------------------------------------


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success, remove it on error.

    The temporary name keeps the suffix of ``path`` so writers that infer the format from the
    extension (``np.save``, ``Figure.savefig``) behave as for the final name. Missing parent
    directories are created.
    """
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.stem}.{uuid.uuid4().hex[:12]}.tmp{target.suffix}")
    try:
        yield tmp
        if not tmp.exists():
            raise FileNotFoundError(f"nothing was written to the temporary file for {target}")
        os.replace(tmp, target)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_text_atomic(path: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically; return the path."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_json_atomic(path: str | os.PathLike, obj: Any, indent: int | None = 2) -> Path:
    """Write ``obj`` as strict JSON (numpy values converted, NaN/inf as null) atomically."""
    text = json.dumps(to_jsonable(obj), indent=indent, allow_nan=False)
    return write_text_atomic(path, text + "\n")


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays, paths and tuples to JSON types; non-finite floats become None."""
    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.bool_ | bool):
        return bool(obj)
    if isinstance(obj, np.integer | int):
        return int(obj)
    if isinstance(obj, np.floating | float):
        v = float(obj)
        return v if np.isfinite(v) else None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def write_signal(path: str | os.PathLike, x: np.ndarray, name: str = "signal") -> Path:
    """Write a 1-D signal atomically as ``.npy``, ``.csv``/``.tsv``/``.txt`` (header ``name``) or HDF5
    (dataset ``/name``), chosen by the extension; full float64 precision is kept in every format."""
    p = Path(path)
    suffix = p.suffix.lower()
    x = np.asarray(x, dtype=np.float64)
    if suffix not in SIGNAL_SUFFIXES:
        raise InputError(
            f"unknown output extension '{p.suffix}' for {p}: use one of {', '.join(SIGNAL_SUFFIXES)}"
        )
    with atomic_path(p) as tmp:
        if suffix == ".npy":
            np.save(tmp, x)
        elif suffix in _HDF5_SUFFIXES:
            import h5py

            with h5py.File(tmp, "w") as fh:
                fh.create_dataset(name, data=x)
        else:
            sep = "," if suffix == ".csv" else "\t" if suffix == ".tsv" else " "
            np.savetxt(tmp, x, fmt="%.17g", header=name, comments="", delimiter=sep)
    return p


_FIGURE_FORMATS = ("png", "pdf", "svg", "eps", "ps", "jpg", "jpeg", "tif", "tiff", "webp")


def save_figure(
    fig: Any,
    path: str | os.PathLike,
    formats: Sequence[str] = ("png", "pdf"),
    dpi: int = 200,
) -> list[Path]:
    """Save a matplotlib figure atomically; return the paths written.

    If ``path`` ends with a known image extension (``.png``, ``.pdf``, ``.svg``, ...) exactly that
    file is written; otherwise one file per entry of ``formats`` is written as ``path.<format>``.
    """
    p = Path(path)
    ext = p.suffix.lower().lstrip(".")
    targets = [p] if ext in _FIGURE_FORMATS else [p.with_name(f"{p.name}.{f.lstrip('.')}") for f in formats]
    for target in targets:
        with atomic_path(target) as tmp:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight")
    return targets
