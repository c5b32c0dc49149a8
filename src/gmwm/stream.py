"""Streaming Haar wavelet variance and Allan variance of recordings too long to hold in memory.

The WV of a channel needs one read of the file and memory independent of its length ``T``: the
signal is read in chunks and run through phase 1 of the kernel of :mod:`gmwm.wv` (levels
``1..L`` on time blocks, each chunk carrying the last ``2**L - 1`` samples of the previous one as
halo); the local averages ``V_L`` that phase 2 needs (levels ``L+1..J``, lags up to ``T / 4``) go
panel by panel to a temporary file (8 bytes per sample and channel, deleted on close), which
phase 2 then reads back one group of panels at a time. Chunks are whole kernel blocks and every
sum is added in the kernel's block and panel order, so the streamed WV has the same bits as
:func:`gmwm.wv.wvar` on the whole signal, offsets and drifts included.

Sources: a ``.npy`` file (1-D, or 2-D ``(T, C)`` in C or Fortran order; read with positioned
reads, so resident memory stays bounded where a memory map would keep every page it touched),
HDF5 datasets (1-D datasets as channels, or the columns of one 2-D dataset; chunked reads), raw
binary with a declared dtype, ``C`` interleaved channels and a header offset, and any iterable of
``(n, C)`` arrays (:func:`wvar_chunks`; for readers of logs and bags: their chunks are spilled to a
temporary raw file first when the total length is not known). Channels are processed in parallel
on the available cores within the same memory budget.

Channel naming and the sampling frequency follow :func:`gmwm.readers.read_channels` (the 1-D signal of
``x.npy`` is ``x``; columns of 2-D arrays are ``"0"``, ``"1"``, ...; HDF5 channels are dataset
paths; frequency from an HDF5 attribute such as ``freq`` or from a time dataset).
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

import numpy as np

from gmwm.errors import InputError
from gmwm.readers.tables import existing_file as _existing_file
from gmwm.wv import (
    AllanVariance,
    WaveletVariance,
    n_threads,
    wv_from_sums,
)
from gmwm.wv import (
    Workspace as _Workspace,
)
from gmwm.wv import (
    aligned_empty as _aligned,
)
from gmwm.wv import (
    check_alpha_freq as _check_alpha_freq,
)
from gmwm.wv import (
    classical_kernels as _kernels,
)
from gmwm.wv import (
    n_levels_for as _n_levels,
)

__all__ = ["DEFAULT_MEMORY", "ChannelWV", "HDF5Source", "NpySource", "RawSource", "Source",
           "avar_stream", "iter_rows", "open_source", "uniform_sample_range", "wvar_chunks",
           "wvar_stream"]

#: default memory budget of one streaming computation (all channels), bytes
DEFAULT_MEMORY = 256 * 2**20

_NUMERIC = "biuf"


@dataclass(frozen=True)
class ChannelWV:
    """The streamed WV of one channel, its first and last samples (the sign of a drift, which the
    WV does not see) and the wall seconds of the computation (all channels together)."""

    wv: WaveletVariance
    first: float
    last: float
    seconds: float = 0.0

    @property
    def drift_sign(self) -> float:
        """+1 if the signal ends at or above its first sample, else -1 (as :func:`gmwm.fit`)."""
        return 1.0 if self.last >= self.first else -1.0


# --------------------------------------------------------------------------------------------------
# sources


class Source:
    """``n_samples`` rows of ``len(names)`` channels read by row ranges. ``where`` names the
    signal in messages; ``freq`` [Hz] and ``freq_source`` when the file declares a rate."""

    names: tuple[str, ...] = ()
    n_samples: int = 0
    where: str = "signal"
    freq: float | None = None
    freq_source: str | None = None
    notes: tuple[str, ...] = ()
    itemsize: int = 8

    def read(self, start: int, stop: int) -> np.ndarray:
        """Rows ``[start, stop)`` as an array of shape ``(stop - start, len(names))``."""
        raise NotImplementedError

    def close(self) -> None:
        """Release the file."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _check_dtype(dtype: np.dtype, where: str) -> np.dtype:
    if dtype.names or dtype.kind not in _NUMERIC or dtype.hasobject:
        raise InputError(f"{where} does not hold plain numbers (dtype {dtype})")
    return dtype


def _column_indices(columns: Any, n_cols: int, p: Path) -> list[int]:
    """Columns of a 2-D array (names are the 0-based indices as strings): None needs a single
    column, ``"all"`` takes every one, else a list of indices (as :func:`gmwm.readers.read_channels`)."""
    if columns is None:
        if n_cols != 1:
            listing = ", ".join(str(i) for i in range(n_cols))
            raise InputError(f"{p} has {n_cols} columns ({listing}): choose one with --column or "
                             "several with --columns")
        return [0]
    if isinstance(columns, str) and columns.strip().lower() == "all":
        return list(range(n_cols))
    if isinstance(columns, str | int):
        columns = [columns]
    idx = []
    for c in columns:
        try:
            i = int(c)
        except (TypeError, ValueError):
            raise InputError(f"column '{c}' not found in {p}; available columns: "
                             + ", ".join(str(i) for i in range(n_cols))) from None
        if not 0 <= i < n_cols:
            raise InputError(f"column index {i} out of range for {p}; available columns: "
                             + ", ".join(f"{k}={k}" for k in range(n_cols)))
        if i in idx:
            raise InputError(f"column(s) {i} requested twice")
        idx.append(i)
    return idx


class _FileRows(Source):
    """Rows of a flat binary layout: ``n_file`` interleaved columns of ``dtype`` from byte
    ``offset`` (C order), or column-major (Fortran order: column ``c`` holds ``T`` values)."""

    def __init__(self, p: Path, dtype: np.dtype, n_samples: int, n_file: int, offset: int,
                 cols: list[int], names: Sequence[str], fortran: bool = False) -> None:
        self.p, self.dtype, self.n_samples, self.n_file = p, dtype, int(n_samples), int(n_file)
        self.offset, self.cols, self.names, self.fortran = int(offset), cols, tuple(names), fortran
        self.itemsize = dtype.itemsize
        self.where = str(p)
        self._fh = open(p, "rb")  # noqa: SIM115 (closed by close())

    def read(self, start: int, stop: int) -> np.ndarray:
        n = stop - start
        isz = self.dtype.itemsize
        if self.fortran:
            out = np.empty((n, len(self.cols)), dtype=self.dtype)
            col = np.empty(n, dtype=self.dtype)
            for k, c in enumerate(self.cols):
                self._read_into(col, self.offset + (c * self.n_samples + start) * isz)
                out[:, k] = col
            return out
        raw = np.empty(n * self.n_file, dtype=self.dtype)
        self._read_into(raw, self.offset + start * self.n_file * isz)
        rows = raw.reshape(n, self.n_file)
        return rows if len(self.cols) == self.n_file else rows[:, self.cols]

    def _read_into(self, buf: np.ndarray, pos: int) -> None:
        view = memoryview(buf).cast("B")
        self._fh.seek(pos)
        got = self._fh.readinto(view)
        if got != view.nbytes:
            raise InputError(f"{self.p} is shorter than its header says (truncated at byte "
                             f"{pos + (got or 0)})")

    def close(self) -> None:
        self._fh.close()


class NpySource(_FileRows):
    """A ``.npy`` file: 1-D (one channel named after the file) or 2-D ``(T, C)`` (columns named
    ``"0"``, ``"1"``, ...; ``columns`` as in :func:`gmwm.readers.read_channels`)."""

    def __init__(self, path: str | os.PathLike, columns: Any = None) -> None:
        p = _existing_file(path)
        with open(p, "rb") as fh:
            try:
                version = np.lib.format.read_magic(fh)
                if version == (1, 0):
                    shape, fortran, dtype = np.lib.format.read_array_header_1_0(fh)
                else:
                    shape, fortran, dtype = np.lib.format.read_array_header_2_0(fh)
            except (ValueError, OSError, EOFError) as exc:
                raise InputError(f"cannot read {p} as a .npy array: {exc}") from None
            offset = fh.tell()
        _check_dtype(dtype, str(p))
        shape = tuple(int(s) for s in shape)
        if len(shape) == 1 or (len(shape) == 2 and sum(s > 1 for s in shape) <= 1
                               and columns is None):
            T = int(np.prod(shape))
            super().__init__(p, dtype, T, 1, offset, [0], [p.stem])
        elif len(shape) == 2:
            cols = _column_indices(columns, shape[1], p)
            super().__init__(p, dtype, shape[0], shape[1], offset, cols,
                             [str(c) for c in cols], fortran=bool(fortran))
        else:
            raise InputError(f"{p} holds an array of shape {shape}, not a 1-D signal")
        need = offset + self.n_samples * self.n_file * dtype.itemsize
        if p.stat().st_size < need:
            self.close()
            raise InputError(f"{p} is shorter than its header says ({p.stat().st_size} bytes, "
                             f"{need} needed)")


class RawSource(_FileRows):
    """Raw binary samples of ``dtype`` (a NumPy dtype: ``float32``, ``<i2``, ``>f8``, ...), ``channels``
    interleaved per row, after ``offset`` header bytes. Channels are named ``"0"``, ``"1"``, ...
    (the file's stem when there is one channel); ``columns`` selects some of them."""

    def __init__(self, path: str | os.PathLike, dtype: Any, channels: int = 1, offset: int = 0,
                 columns: Any = None) -> None:
        p = _existing_file(path)
        try:
            dt = np.dtype(dtype)
        except TypeError:
            raise InputError(f"--dtype {dtype!r} is not a NumPy dtype (e.g. float32, <i2, >f8)"
                             ) from None
        _check_dtype(dt, f"--dtype {dtype}")
        if channels < 1 or offset < 0:
            raise InputError("raw binary needs channels >= 1 and a header offset >= 0 bytes")
        size = p.stat().st_size - offset
        row = dt.itemsize * channels
        if size <= 0 or size % row:
            raise InputError(f"{p} holds {max(size, 0)} bytes after the {offset}-byte header, not "
                             f"a whole number of rows of {channels} x {dt} ({row} bytes): check "
                             "--dtype, the channel count and the offset")
        if channels == 1 and columns is None:
            cols, names = [0], [p.stem]
        else:
            cols = _column_indices(columns, channels, p)
            names = [str(c) for c in cols]
        super().__init__(p, dt, size // row, channels, offset, cols, names)


class HDF5Source(Source):
    """HDF5: without ``dataset``, channels are 1-D datasets (``columns``: None = the only one,
    ``"all"`` = all but a time dataset, or a list of paths); with ``dataset``, the columns of that
    1-D or 2-D dataset. The frequency comes from a time dataset (median step) or from a rate
    attribute of the dataset or its groups, as :func:`gmwm.readers.read_channels` does."""

    def __init__(self, path: str | os.PathLike, columns: Any = None,
                 dataset: str | None = None) -> None:
        import h5py

        p = _existing_file(path)
        self.where = str(p)
        try:
            self._fh = h5py.File(p, "r")
        except OSError as exc:
            raise InputError(f"cannot open {p} as HDF5: {exc}") from None
        try:
            self._open(p, columns, dataset)
        except BaseException:
            self._fh.close()
            raise

    def _open(self, p: Path, columns: Any, dataset: str | None) -> None:
        import h5py

        from gmwm.readers.tables import hdf5_freq_attr as _hdf5_freq_attr
        from gmwm.readers.tables import time_column_unit

        fh = self._fh
        one_d: list[str] = []
        every: list[str] = []

        def visit(name: str, obj: Any) -> None:
            if isinstance(obj, h5py.Dataset):
                every.append(name)
                if sum(d > 1 for d in obj.shape) == 1:
                    one_d.append(name)

        fh.visititems(visit)
        self._col = None
        if dataset is not None or columns is None:
            if dataset is None and len(one_d) != 1:
                what = "no 1-D dataset" if not one_d else "several 1-D datasets"
                listing = ", ".join(f"/{n} {fh[n].shape}" for n in every) or "none"
                raise InputError(f"{p} holds {what}: choose one with --dataset (datasets: "
                                 f"{listing})")
            key = (dataset if dataset is not None else one_d[0]).lstrip("/") or "/"
            if key not in fh or not isinstance(fh[key], h5py.Dataset):
                listing = ", ".join(f"/{n}" for n in every) or "none"
                raise InputError(f"dataset '{dataset}' not found in {p}; available datasets: "
                                 f"{listing}")
            ds = fh[key]
            _check_dtype(ds.dtype, f"dataset '{dataset}' of {p}")
            shape = ds.shape
            self._dsets = [ds]
            if len(shape) == 1 or (len(shape) == 2 and sum(s > 1 for s in shape) <= 1
                                   and columns is None):
                # as gmwm.readers.tables: named after --dataset, else after the file; a 1-D dataset with
                # --columns is named after the file too
                self.names = ((dataset if columns is None and dataset is not None else p.stem)
                              .strip("/"),)
                self.n_samples = int(np.prod(shape))
                self._flat = len(shape) == 2
            elif len(shape) == 2:
                self._col = _column_indices(columns, shape[1], p)
                self.names = tuple(str(c) for c in self._col)
                self.n_samples = int(shape[0])
                self._flat = False
            else:
                raise InputError(f"{p} holds an array of shape {shape}, not a 1-D signal")
            objs = [ds]
            tname = None
        else:
            tidx = next((n for n in one_d if time_column_unit(n.rsplit("/", 1)[-1]) is not None),
                        None)
            if isinstance(columns, str) and columns.strip().lower() == "all":
                wanted = [n for n in one_d if n != tidx and fh[n].dtype.kind in _NUMERIC]
                if not wanted:
                    raise InputError(f"{p} has no numeric column besides its time column")
            else:
                items = [columns] if isinstance(columns, str | int) else list(columns)
                wanted = []
                for c in items:
                    key = str(c).lstrip("/")
                    if key not in one_d:
                        try:
                            key = one_d[int(c)]
                        except (TypeError, ValueError, IndexError):
                            raise InputError(f"column '{c}' not found in {p}; available columns: "
                                             + ", ".join(one_d)) from None
                    if key in wanted:
                        raise InputError(f"column(s) {key} requested twice")
                    wanted.append(key)
            for n in wanted:
                _check_dtype(fh[n].dtype, f"dataset '/{n}' of {p}")
            lengths = {int(np.prod(fh[n].shape)) for n in wanted}
            if len(lengths) != 1:
                raise InputError(f"the datasets {', '.join(wanted)} of {p} differ in length")
            self._dsets = [fh[n] for n in wanted]
            self._flat = any(len(fh[n].shape) != 1 for n in wanted)
            self.names = tuple(wanted)
            self.n_samples = lengths.pop()
            objs = list(self._dsets)
            tname = tidx
        self.itemsize = max(d.dtype.itemsize for d in self._dsets)
        if tname is not None:
            unit = time_column_unit(tname.rsplit("/", 1)[-1])
            self.freq, notes = _stream_time_freq(fh[tname], unit or 1.0,
                                                 f"time dataset /{tname} of {p}")
            self.freq_source, self.notes = f"time dataset /{tname}", tuple(notes)
            return
        for obj in objs:
            while obj is not None:
                found = _hdf5_freq_attr(obj)
                if found is not None:
                    self.freq, self.freq_source = found
                    return
                obj = obj.parent if obj.name != "/" else None

    def read(self, start: int, stop: int) -> np.ndarray:
        if self._col is not None:
            return self._dsets[0][start:stop, :][:, self._col]
        out = np.empty((stop - start, len(self._dsets)),
                       dtype=np.result_type(*[d.dtype for d in self._dsets]))
        for k, ds in enumerate(self._dsets):
            out[:, k] = _flat_slice(ds, start, stop) if self._flat else ds[start:stop]
        return out

    def close(self) -> None:
        self._fh.close()


def _flat_slice(ds: Any, start: int, stop: int) -> np.ndarray:
    """Rows ``[start, stop)`` of a dataset of shape (T, 1) or (1, T)."""
    if len(ds.shape) == 1:
        return ds[start:stop]
    if ds.shape[0] == 1:
        return ds[0, start:stop]
    return ds[start:stop, 0]


def _stream_time_freq(ds: Any, unit: float, where: str,
                      chunk: int = 1 << 20) -> tuple[float, list[str]]:
    """Sampling frequency from a time dataset read in chunks: the mean rate between gaps, as
    :func:`gmwm.readers.timebase.time_base` defines it (steps up to 1.5 reference steps over their
    time; the reference is the median of the chunks' median steps, a second pass sums), strict
    monotonicity checked everywhere, a note when a step deviates by more than 1 %."""
    n = int(np.prod(ds.shape))
    if n < 2:
        raise InputError(f"{where} must hold at least 2 finite time stamps")
    meds, lo, hi = [], np.inf, -np.inf
    prev = None
    for a in range(0, n, chunk):
        t = np.asarray(ds[a:min(n, a + chunk)], dtype=np.float64).reshape(-1) * unit
        if not np.all(np.isfinite(t)):
            raise InputError(f"{where} must hold at least 2 finite time stamps")
        if prev is not None:
            t = np.concatenate(([prev], t))
        prev = t[-1]
        dt = np.diff(t)
        if dt.size == 0:
            continue
        if np.any(dt <= 0):
            bad = int(np.argmax(dt <= 0)) + a + (1 if a == 0 else 0)
            raise InputError(f"{where} is not strictly increasing (row {bad + 1})")
        meds.append(float(np.median(dt)))
        lo, hi = min(lo, float(dt.min())), max(hi, float(dt.max()))
    step = float(np.median(meds))
    count, total, prev = 0, 0.0, None
    for a in range(0, n, chunk):  # the steps that are not gaps: their count and time
        t = np.asarray(ds[a:min(n, a + chunk)], dtype=np.float64).reshape(-1) * unit
        dt = np.diff(t if prev is None else np.concatenate(([prev], t)))
        prev = t[-1]
        inside = dt[dt <= 1.5 * step]
        count, total = count + inside.size, total + float(inside.sum())
    notes = []
    if max(hi - step, step - lo) / step > 0.01:
        notes.append(f"irregular sampling in {where}: steps from {lo:.6g} s to {hi:.6g} s "
                     f"(the mean rate between gaps used, median step {step:.6g} s)")
    return float(f"{count / total:.9g}"), notes


def open_source(path: str | os.PathLike, columns: Any = None, dataset: str | None = None, *,
                dtype: Any = None, channels: int = 1, offset: int = 0) -> Source:
    """The streaming source of a file: raw binary when ``dtype`` is given, else by extension
    (``.npy``, ``.h5``/``.hdf5``). Raises :class:`InputError` for other files."""
    p = Path(path)
    if dtype is not None:
        return RawSource(p, dtype, channels, offset, columns)
    suffix = p.suffix.lower()
    if suffix == ".npy":
        if dataset is not None:
            raise InputError("--dataset applies to HDF5 files")
        return NpySource(p, columns)
    if suffix in (".h5", ".hdf5"):
        return HDF5Source(p, columns, dataset)
    raise InputError(f"{p}: streaming reads .npy, HDF5 (.h5/.hdf5) or raw binary with --dtype")


class _ChunkSource(Source):
    """An iterable of ``(n, C)`` chunks with a known total length, read once, in order."""

    def __init__(self, chunks: Iterable[Any], names: Sequence[str], n_samples: int,
                 where: str) -> None:
        self._it = iter(chunks)
        self.names, self.n_samples, self.where = tuple(names), int(n_samples), where
        self._buf: list[np.ndarray] = []
        self._pos = 0

    def read(self, start: int, stop: int) -> np.ndarray:
        if start != self._pos:
            raise InputError("a chunk iterator is read once, in order")
        need = stop - start
        have = sum(len(b) for b in self._buf)
        while have < need:
            try:
                chunk = next(self._it)
            except StopIteration:
                raise InputError(f"{self.where} ended after {start + have} samples, "
                                 f"{self.n_samples} declared") from None
            arr = _as_chunk(chunk, len(self.names), self.where)
            self._buf.append(arr)
            have += len(arr)
        rows = np.concatenate(self._buf) if len(self._buf) > 1 else self._buf[0]
        out, rest = rows[:need], rows[need:]
        self._buf = [rest] if len(rest) else []
        self._pos = stop
        if stop == self.n_samples and (self._buf or next(self._it, None) is not None):
            raise InputError(f"{self.where} holds more than the {self.n_samples} samples declared")
        return out


def _as_chunk(chunk: Any, n_ch: int, where: str) -> np.ndarray:
    arr = np.asarray(chunk)
    if arr.ndim == 1 and n_ch == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] != n_ch:
        raise InputError(f"{where}: chunks must be (n, {n_ch}) arrays, got shape {arr.shape}")
    _check_dtype(arr.dtype, where)
    return arr


# --------------------------------------------------------------------------------------------------
# the computation


def _row_range(source: Source, start: int, stop: int | None) -> tuple[int, int]:
    n = int(source.n_samples)
    stop = n if stop is None else int(stop)
    start = int(start)
    if not 0 <= start < stop <= n:
        raise InputError(f"{source.where}: rows {start}:{stop} outside the {n} samples")
    return start, stop


def iter_rows(source: Source, chunk: int, start: int = 0, stop: int | None = None
              ) -> Iterator[tuple[int, np.ndarray]]:
    """``(t_a, rows)`` for consecutive chunks of at most ``chunk`` rows of ``source``, covering
    rows ``[start, stop)`` (default: all) in order, ``t_a`` the index of the first row; the next
    chunk is read in a background thread while the caller works on this one."""
    start, stop = _row_range(source, start, stop)
    chunk = max(1, int(chunk))
    C = len(source.names)
    with cf.ThreadPoolExecutor(max_workers=1) as reader:
        ahead = reader.submit(source.read, start, min(stop, start + chunk))
        for t_a in range(start, stop, chunk):
            rows = ahead.result()
            t_b = min(stop, t_a + chunk)
            if rows.shape != (t_b - t_a, C):
                raise InputError(f"{source.where}: read {rows.shape} at row {t_a}, expected "
                                 f"{(t_b - t_a, C)}")
            if t_b < stop:
                ahead = reader.submit(source.read, t_b, min(stop, t_b + chunk))
            yield t_a, rows


def uniform_sample_range(n: int, freq: float, start_s: float | None, end_s: float | None,
                         where: str = "the recording") -> tuple[int, int]:
    """Samples ``(i0, i1)`` of a recording of ``n`` samples at ``freq`` Hz (sample ``i`` at
    ``i / freq`` s) whose time lies in [``start_s``, ``end_s``), as
    :func:`gmwm.readers.recording.sample_range` does with time stamps; None: from the first / to
    the last sample. An empty or out-of-range request is an :class:`InputError`."""
    from gmwm.readers.recording import time_window

    a, b = time_window(start_s, end_s, (n - 1) / freq if n else 0.0, where)

    def first_at(v: float) -> int:  # the first i with i / freq >= v (exact, as searchsorted)
        if v == math.inf:
            return n
        i = min(max(math.ceil(v * freq), 0), n)
        while i > 0 and (i - 1) / freq >= v:
            i -= 1
        while i < n and i / freq < v:
            i += 1
        return i

    i0, i1 = first_at(a), first_at(b)
    if i1 - i0 < 2:
        raise InputError(f"--start/--end select {i1 - i0} sample(s) of {where}")
    return i0, i1


class _PanelFile:
    """Phase-2 store of one channel in a temporary file (panel-major, as the in-memory store)."""

    def __init__(self, n_values: int, spill_dir: str | None) -> None:
        self._fh = tempfile.TemporaryFile(dir=spill_dir)  # noqa: SIM115 (closed by close())
        self._fh.truncate(n_values * 8)

    def write(self, values: np.ndarray, at: int) -> None:
        view = memoryview(values).cast("B")
        if hasattr(os, "pwrite"):  # one system call per panel segment, no seek
            done = 0
            while done < view.nbytes:
                done += os.pwrite(self._fh.fileno(), view[done:], at * 8 + done)
        else:
            self._fh.seek(at * 8)
            self._fh.write(view)

    def read_into(self, buf: np.ndarray, at: int) -> None:
        self._fh.flush()
        self._fh.seek(at * 8)
        view = memoryview(buf).cast("B")
        if self._fh.readinto(view) != view.nbytes:
            raise OSError("the streaming WV's temporary file was truncated")

    def close(self) -> None:
        self._fh.close()


class _Channel:
    """Per-channel state of a streamed WV: the halo tail, the running sums and the store."""

    def __init__(self, name: str, ws: _Workspace, J: int, chunk: int, in_memory: bool,
                 spill_dir: str | None) -> None:
        self.name, self.ws, self.J = name, ws, J
        L = ws.n_block
        self.halo = (1 << L) - 1
        self.sums = np.zeros(J)
        self.buf = np.empty(self.halo + chunk)
        self.n_tail = 0
        self.first = self.last = np.nan
        self.store: np.ndarray | None = None
        self.spill: _PanelFile | None = None
        if ws.phase2:
            if in_memory:
                self.store = ws.store()
            else:
                self.spill = _PanelFile(ws.rows << L, spill_dir)
                # two phase-1 outputs: one is written to the file while the next chunk fills
                # the other
                self.locals = [_aligned(((chunk >> L) + 2) << L) for _ in range(2)]
                self.writing: list[cf.Future | None] = [None, None]
                self.flip = 0

    def wait_writes(self) -> None:
        """Wait for the pending writes of both phase-1 outputs (errors re-raised here)."""
        for i, f in enumerate(getattr(self, "writing", ())):
            if f is not None:
                self.writing[i] = None
                f.result()

    def close(self) -> None:
        if self.spill is not None:
            self.spill.close()


def _nonfinite_error(where: str, name: str, col: np.ndarray, t0: int) -> InputError:
    bad = ~np.isfinite(col)
    if not bad.any():
        return InputError(f"{where} is too large in magnitude: squared differences overflow "
                          "float64")
    i = int(np.argmax(bad))
    what = "NaN" if np.isnan(col[i]) else "infinite"
    chan = "" if not name else f"channel '{name}' of "
    return InputError(f"{chan}{where} contains a {what} value at sample {t0 + i} (the first "
                      "non-finite one); clean or interpolate it first")


def _phase1(ch: _Channel, col: np.ndarray, t_a: int, threads: int, where: str,
            label: str, writer: cf.Executor) -> None:
    """Phase 1 of rows ``[t_a, t_a + len(col))`` of one channel (``col`` in any numeric dtype)."""
    ws = ch.ws
    n = col.shape[0]
    h = ch.n_tail
    buf = ch.buf
    np.copyto(buf[h:h + n], col, casting="unsafe")
    if t_a == 0:
        ch.first = float(buf[0])
    x = buf[:h + n]
    L, halo = ws.n_block, ch.halo
    t_b = t_a + n
    kern = _kernels()
    if ch.spill is not None:
        t_s = max(t_a, halo)
        if t_s < t_b:
            k_first = (t_s - halo) >> L
            nrows = ((t_b - 1 - halo) >> L) - k_first + 1
        else:
            k_first, nrows = 0, 1
        pending = ch.writing[ch.flip]
        if pending is not None:  # this buffer's previous chunk is still being written
            ch.writing[ch.flip] = None
            pending.result()
        store = ch.locals[ch.flip][:nrows << L]
    else:
        store = ch.store if ch.store is not None else np.empty(0)
        k_first, nrows = 0, ws.rows
    args = (x, t_a - h, t_a, t_b, ch.first, L, ws.block, ch.sums, store, k_first, nrows, ws.panel)
    if kern.__name__ == "gmwm._haar":
        kern.phase1(*args, threads)
    else:
        kern.phase1(*args)
    if not np.isfinite(ch.sums[0]):
        raise _nonfinite_error(where, label, buf[h:h + n], t_a)
    if ch.spill is not None and t_a + n > halo:
        ch.writing[ch.flip] = writer.submit(_spill_rows, ch, store, max(t_a, halo) - halo,
                                            t_b - halo, k_first, nrows)
        ch.flip = 1 - ch.flip
    keep = min(halo, h + n)
    buf[:keep] = buf[h + n - keep:h + n]
    ch.n_tail = keep
    ch.last = float(buf[keep - 1])


def _spill_rows(ch: _Channel, local: np.ndarray, s_a: int, s_b: int, k_first: int,
                nrows: int) -> None:
    """Write the panel segments of ``V_L`` positions ``[s_a, s_b)`` (held panel-major in
    ``local`` with rows ``k_first..``) to their places in the channel's temporary file."""
    ws = ch.ws
    L, P, c, rows = ws.n_block, 1 << ws.n_block, ws.panel, ws.rows

    def index(s: int, r0: int, cp: int) -> int:  # panel index of the first position >= s
        return (s >> L) * cp + min(max((s & (P - 1)) - r0, 0), cp)

    for r0 in range(0, P, c):
        cp = min(c, P - r0)
        q_a, q_b = index(s_a, r0, cp), index(s_b, r0, cp)
        if q_b <= q_a:
            continue
        base = nrows * r0 - k_first * cp
        ch.spill.write(local[base + q_a:base + q_b], rows * r0 + q_a)


def _phase2(ch: _Channel, group_values: int, threads: int) -> None:
    ws = ch.ws
    ch.wait_writes()
    ch.buf = np.empty(0)  # phase 1's buffers are no longer needed
    ch.locals = []
    if not ws.phase2:
        return
    kern = _kernels()
    L, c, rows = ws.n_block, ws.panel, ws.rows
    P = 1 << L
    n2 = ch.J - L
    if ch.store is not None:
        groups = [(0, ws.n_panels)]
        buf = ch.store
    else:
        per = max(1, group_values // (rows * c))
        groups = [(p, min(ws.n_panels, p + per)) for p in range(0, ws.n_panels, per)]
        buf = np.empty(rows * min(per * c, P))
    for p_a, p_b in groups:
        n_vals = rows * (min(p_b * c, P) - p_a * c)
        part = buf[:n_vals]
        if ch.spill is not None:
            ch.spill.read_into(part, rows * p_a * c)
        args = (part, rows, ws.n_out, L, c, p_a, p_b, n2, ch.sums)
        if kern.__name__ == "gmwm._haar":
            kern.phase2(*args, threads)
        else:
            kern.phase2(*args)


def _check_disk(spill_dir: str | None, need: int) -> None:
    where = spill_dir or tempfile.gettempdir()
    free = shutil.disk_usage(where).free
    if free < need * 1.02:
        raise InputError(f"the streaming WV needs {need / 1e9:.2f} GB of temporary space in "
                         f"{where} (8 bytes per sample and channel), {free / 1e9:.2f} GB free: "
                         "free some space or point TMPDIR elsewhere")


def _stream(source: Source, levels: int | None, alpha: float, freq: float, memory: int,
            threads: int | None, spill_dir: str | None, start: int = 0, stop: int | None = None,
            observe: Callable[[np.ndarray], None] | None = None) -> dict[str, ChannelWV]:
    t_start = time.perf_counter()
    start, stop = _row_range(source, start, stop)
    T = stop - start
    J = _n_levels(T, levels)
    _check_alpha_freq(alpha, freq)
    names = list(source.names)
    C = len(names)
    if C == 0:
        raise InputError(f"{source.where}: no channel selected")
    cores = n_threads() if threads is None else max(1, int(threads))
    workers = max(1, min(C, cores))
    per_channel = max(1, cores // C)
    ws = _Workspace(T, J)
    L = ws.n_block
    # memory per chunk row: the source rows twice (one read ahead), and per channel its float64
    # buffer and two panel-major parts of V_L (one being written to the file)
    per_row = 2 * C * max(source.itemsize, 1) + 24 * C
    if observe is not None:  # the observer's float64 copies of a chunk (one per channel, |a|)
        per_row += 24 * (C + 1)
    block = ws.block
    chunk = max(block, (max(memory // 2, per_row) // per_row) // block * block)
    chunk = min(chunk, -(-T // block) * block)
    store_bytes = (ws.rows << L) * 8 * C if ws.phase2 else 0
    in_memory = store_bytes <= memory // 2
    if ws.phase2 and not in_memory:
        _check_disk(spill_dir, store_bytes)
    chans = [_Channel(nm, ws if i == 0 else _Workspace(T, J), J, chunk, in_memory, spill_dir)
             for i, nm in enumerate(names)]
    label = [nm if C > 1 else "" for nm in names]
    try:
        with cf.ThreadPoolExecutor(max_workers=workers) as pool, \
                cf.ThreadPoolExecutor(max_workers=workers) as writer:
            for t_a, rows in iter_rows(source, chunk, start, stop):
                jobs = [pool.submit(_phase1, chans[k], rows[:, k], t_a - start, per_channel,
                                    source.where, label[k], writer) for k in range(C)]
                if observe is not None:  # e.g. the stationarity summaries, while phase 1 runs
                    observe(rows)
                for f in jobs:
                    f.result()
            group = max(1, (memory // 2) // (8 * workers))
            for f in [pool.submit(_phase2, ch, group, per_channel) for ch in chans]:
                f.result()
    finally:
        for ch in chans:
            with contextlib.suppress(Exception):  # an error is already on its way up
                ch.wait_writes()
            ch.close()
    seconds = time.perf_counter() - t_start
    return {ch.name: ChannelWV(wv_from_sums(ch.sums, T, alpha, freq), ch.first, ch.last,
                               seconds) for ch in chans}


def wvar_stream(source: Source | str | os.PathLike, levels: int | None = None,
                alpha: float = 0.05, freq: float | None = None, *, columns: Any = None,
                dataset: str | None = None, memory: int = DEFAULT_MEMORY,
                threads: int | None = None, spill_dir: str | None = None, start: int = 0,
                stop: int | None = None, observe: Callable[[np.ndarray], None] | None = None
                ) -> dict[str, ChannelWV]:
    """Haar WV of every channel of ``source`` (a :class:`Source` or a file path, opened with
    :func:`open_source` and ``columns``/``dataset``) in bounded memory, bit-identical to
    :func:`gmwm.wv.wvar` on each whole channel. ``freq`` [Hz] defaults to the file's rate, else
    1. ``memory`` is the budget in bytes for all channels together (the phase-2 store goes to a
    temporary file in ``spill_dir`` or TMPDIR beyond half of it); ``threads`` defaults to the
    usable cores. A NaN or inf raises :class:`InputError` naming the channel and sample index.

    ``start``/``stop``: the WV of rows ``[start, stop)`` only (bit-identical to
    :func:`gmwm.wv.wvar` of that slice; sample indices in the messages count from ``start``).
    ``observe(rows)`` is called with every chunk of rows read (source dtype, shape ``(m, C)``, in
    order, in the calling thread while the WV works on it): a second computation in the same
    read of the file, e.g. :meth:`gmwm.stationarity.StationarityStream.push`."""
    opened = not isinstance(source, Source)
    src = open_source(source, columns, dataset) if opened else source
    try:
        f = freq if freq is not None else (src.freq if src.freq is not None else 1.0)
        return _stream(src, levels, alpha, float(f), int(memory), threads, spill_dir, start, stop,
                       observe)
    finally:
        if opened:
            src.close()


def avar_stream(source: Source | str | os.PathLike, levels: int | None = None,
                alpha: float = 0.05, freq: float | None = None, **kwargs: Any
                ) -> dict[str, AllanVariance]:
    """Maximal-overlap Allan variance per channel (= 2 x the streamed WV), see
    :func:`wvar_stream`."""
    return {k: AllanVariance.from_wv(v.wv)
            for k, v in wvar_stream(source, levels, alpha, freq, **kwargs).items()}


def wvar_chunks(chunks: Iterable[Any], names: Sequence[str] | None = None,
                n_samples: int | None = None, levels: int | None = None, alpha: float = 0.05,
                freq: float = 1.0, *, memory: int = DEFAULT_MEMORY, threads: int | None = None,
                spill_dir: str | None = None, where: str = "signal") -> dict[str, ChannelWV]:
    """Streamed WV of an iterable of ``(n, C)`` arrays (any numeric dtype; 1-D arrays for one
    channel), e.g. the messages of a log or bag read in batches. ``names`` default to
    ``"0".."C-1"``. With ``n_samples`` the chunks are consumed in one pass; without it they are
    first copied to a temporary float64 file (8 bytes per sample and channel) to learn ``T``."""
    it: Iterator[Any] = iter(chunks)
    first = next(it, None)
    if first is None:
        raise InputError(f"{where} holds no samples")
    n_ch = 1 if np.ndim(first) == 1 else int(np.shape(first)[1])
    names = [str(i) for i in range(n_ch)] if names is None else [str(n) for n in names]
    if len(names) != n_ch:
        raise InputError(f"{where}: {len(names)} names for {n_ch} channels")

    def chained() -> Iterator[Any]:
        yield first
        yield from it

    if n_samples is not None:
        src: Source = _ChunkSource(chained(), names, n_samples, where)
        return _stream(src, levels, alpha, float(freq), int(memory), threads, spill_dir)
    with tempfile.TemporaryFile(dir=spill_dir) as fh:
        total = 0
        for chunk in chained():
            arr = np.ascontiguousarray(_as_chunk(chunk, n_ch, where), dtype=np.float64)
            fh.write(memoryview(arr).cast("B"))
            total += arr.shape[0]
        fh.flush()
        src = _TempRows(fh, total, names, where)
        return _stream(src, levels, alpha, float(freq), int(memory), threads, spill_dir)


class _TempRows(Source):
    """float64 rows of an open temporary file (the spilled chunks of :func:`wvar_chunks`)."""

    def __init__(self, fh: Any, n_samples: int, names: Sequence[str], where: str) -> None:
        self._fh, self.n_samples, self.names, self.where = fh, n_samples, tuple(names), where

    def read(self, start: int, stop: int) -> np.ndarray:
        C = len(self.names)
        out = np.empty((stop - start) * C)
        self._fh.seek(start * C * 8)
        self._fh.readinto(memoryview(out).cast("B"))
        return out.reshape(-1, C)
