"""Atomic output: every file is written through a temporary file in the same directory that is
renamed onto the target only on success, so a killed job never leaves a file that looks complete.

:func:`atomic_path` is the primitive; :func:`write_text_atomic`, :func:`write_json_atomic`,
:func:`write_signal` and :func:`save_figure` are built on it.
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
from gmwm.readers.tables import HDF5_SUFFIXES, SIGNAL_SUFFIXES

__all__ = ["atomic_path", "save_figure", "to_jsonable", "write_json_atomic", "write_signal",
           "write_text_atomic"]


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success, remove it on error.

    The temporary name keeps the suffix of ``path`` so writers that infer the format from the
    extension (``np.save``, ``Figure.savefig``) behave as for the final name. Missing parent
    directories are created.
    """
    target = Path(path)
    if target.is_dir():
        raise InputError(f"output path {target} is a directory: give a file name")
    if target.parent.exists() and not target.parent.is_dir():
        raise InputError(f"cannot write {target}: {target.parent} is not a directory")
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
        elif suffix in HDF5_SUFFIXES:
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
    tight: bool = True,
    png_level: int | None = None,
) -> list[Path]:
    """Save a matplotlib figure atomically; return the paths written.

    If ``path`` ends with a known image extension (``.png``, ``.pdf``, ``.svg``, ...) exactly that
    file is written; otherwise one file per entry of ``formats`` is written as ``path.<format>``.
    ``tight``: crop to the drawn content (``bbox_inches="tight"``, which draws the figure twice);
    False for a figure whose layout engine already fills it (about a third faster).
    ``png_level``: zlib level of a PNG (0-9; None: Pillow's default, 6); the pixels are the same
    at every level, a low one compresses in about half the time into a ~10 % larger file.
    """
    p = Path(path)
    ext = p.suffix.lower().lstrip(".")
    targets = [p] if ext in _FIGURE_FORMATS else [p.with_name(f"{p.name}.{f.lstrip('.')}") for f in formats]
    for target in targets:
        with atomic_path(target) as tmp:
            # no creation date in the file: a rerun with the same numbers writes the same bytes
            kind = target.suffix.lower().lstrip(".")
            extra = {"pil_kwargs": {"compress_level": png_level}} if (
                png_level is not None and kind == "png") else {}
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight" if tight else None,
                        metadata=_NO_DATE.get(kind), **extra)
    return targets


_NO_DATE = {"pdf": {"CreationDate": None}, "svg": {"Date": None}}
