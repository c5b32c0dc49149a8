"""On-disk cache of Monte Carlo wavelet variances (HDF5) and of estimates (NetCDF/HDF5).

Only wavelet variances are cached, never raw signals: at T = 1e7 a signal is 80 MB while its WV
is 22 numbers. Every write goes through :func:`gmwm.atomic.atomic_path` (temporary file in the target's
directory, then ``os.replace``, atomic on POSIX), so a killed job never leaves a file that a later
run would take for complete.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from gmwm.atomic import atomic_path
from gmwm.errors import InputError

if TYPE_CHECKING:
    import xarray as xr

__all__ = [
    "WVChunk",
    "read_dataset",
    "read_wv_chunk",
    "read_wv_chunks",
    "write_dataset",
    "write_wv_chunk",
]

WV_FORMAT_VERSION = 1
NETCDF_ENGINE = "netcdf4"


@dataclass(frozen=True)
class WVChunk:
    """Wavelet variances of a chunk of replicates of one study at one sample size.

    ``variances[r, j]`` is the WV of replicate ``replicates[r]`` at level ``levels[j]``
    (scale ``scales[j] = 2**levels[j]`` samples, ``n[j]`` coefficients). ``seconds_simulate`` and
    ``seconds_wv`` are per-replicate wall times [s] of the simulation and of the WV computation.
    """

    study: str
    model: str
    truth: dict[str, float]
    n_samples: int
    base_seed: int
    replicates: np.ndarray
    levels: np.ndarray
    scales: np.ndarray
    n: np.ndarray
    variances: np.ndarray
    seconds_simulate: np.ndarray | None = None
    seconds_wv: np.ndarray | None = None
    attrs: dict[str, str | int | float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        r, j = len(self.replicates), len(self.scales)
        if np.shape(self.variances) != (r, j):
            raise InputError(
                f"variances has shape {np.shape(self.variances)}, expected ({r}, {j}) "
                "(replicates x scales)"
            )
        if len(self.levels) != j or len(self.n) != j:
            raise InputError("levels, scales and n must have one entry per scale")


def write_wv_chunk(path: str | os.PathLike, chunk: WVChunk) -> None:
    """Write ``chunk`` to an HDF5 file atomically (datasets + study attributes)."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f.create_dataset("variance", data=np.asarray(chunk.variances, dtype=np.float64))
        f.create_dataset("replicate", data=np.asarray(chunk.replicates, dtype=np.int64))
        f.create_dataset("level", data=np.asarray(chunk.levels, dtype=np.int64))
        f.create_dataset("scale", data=np.asarray(chunk.scales, dtype=np.float64))
        f.create_dataset("n", data=np.asarray(chunk.n, dtype=np.int64))
        for name in ("seconds_simulate", "seconds_wv"):
            value = getattr(chunk, name)
            if value is not None:
                f.create_dataset(name, data=np.asarray(value, dtype=np.float64))
        f.attrs["format_version"] = WV_FORMAT_VERSION
        f.attrs["study"] = chunk.study
        f.attrs["model"] = chunk.model
        f.attrs["truth"] = json.dumps(chunk.truth, sort_keys=True)
        f.attrs["n_samples"] = int(chunk.n_samples)
        f.attrs["base_seed"] = int(chunk.base_seed)
        for key, value in chunk.attrs.items():
            f.attrs[key] = value


def read_wv_chunk(path: str | os.PathLike) -> WVChunk:
    """Read a chunk written by :func:`write_wv_chunk`."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"WV cache file not found: {path}")
    with h5py.File(path, "r") as f:
        reserved = {"format_version", "study", "model", "truth", "n_samples", "base_seed"}
        extra = {k: _py(v) for k, v in f.attrs.items() if k not in reserved}
        return WVChunk(
            study=str(f.attrs["study"]),
            model=str(f.attrs["model"]),
            truth=json.loads(f.attrs["truth"]),
            n_samples=int(f.attrs["n_samples"]),
            base_seed=int(f.attrs["base_seed"]),
            replicates=f["replicate"][()],
            levels=f["level"][()],
            scales=f["scale"][()],
            n=f["n"][()],
            variances=f["variance"][()],
            seconds_simulate=f["seconds_simulate"][()] if "seconds_simulate" in f else None,
            seconds_wv=f["seconds_wv"][()] if "seconds_wv" in f else None,
            attrs=extra,
        )


def read_wv_chunks(paths: list[str | os.PathLike]) -> WVChunk:
    """Read several chunks of one study and sample size into one, sorted by replicate id."""
    chunks = [read_wv_chunk(p) for p in paths]
    if not chunks:
        raise InputError("no WV chunk files given")
    first = chunks[0]
    for c in chunks[1:]:
        if (c.study, c.model, c.n_samples) != (first.study, first.model, first.n_samples) or not (
            np.array_equal(c.scales, first.scales)
        ):
            raise InputError(
                f"WV chunks do not match: {c.study}/T={c.n_samples} vs {first.study}/T={first.n_samples}"
            )
    reps = np.concatenate([c.replicates for c in chunks])
    order = np.argsort(reps, kind="stable")

    def cat(name: str) -> np.ndarray | None:
        parts = [getattr(c, name) for c in chunks]
        return None if any(p is None for p in parts) else np.concatenate(parts)[order]

    return WVChunk(
        study=first.study, model=first.model, truth=first.truth, n_samples=first.n_samples,
        base_seed=first.base_seed, replicates=reps[order], levels=first.levels,
        scales=first.scales, n=first.n, variances=np.vstack([c.variances for c in chunks])[order],
        seconds_simulate=cat("seconds_simulate"), seconds_wv=cat("seconds_wv"), attrs=first.attrs,
    )


def _py(value: object) -> object:
    """numpy scalar -> Python scalar (HDF5 attributes come back as numpy types)."""
    return value.item() if isinstance(value, np.generic) else value


def write_dataset(ds: xr.Dataset, path: str | os.PathLike) -> None:
    """Write an xarray Dataset to NetCDF-4 (HDF5) atomically."""
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine=NETCDF_ENGINE)


def read_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Read a Dataset fully into memory and close the file (no handle left open)."""
    import xarray as xr  # lazily: a simulate_wv job never needs it (start-up)

    path = Path(path)
    if not path.exists():
        raise InputError(f"estimates file not found: {path}")
    with xr.open_dataset(path, engine=NETCDF_ENGINE) as ds:
        return ds.load()
