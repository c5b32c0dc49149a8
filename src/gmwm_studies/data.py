"""Real-data files: obtain them by a fixed rule, verify them, and load them as WV / AV tables.

Rule (:func:`obtain`), with the registry ``config/datasets.yaml``:

1. ``<local_dir>/<file>`` exists (tests/CI: ``../shared/data`` relative to the repository) -> check its
   CSV layout and sha256, copy it (and its ``.json`` sidecar) atomically to ``dest``.
2. Otherwise, if downloads are allowed: fetch the original ``.rda`` from its public source (registry
   ``source.url``), check its sha256, read it with ``rdata`` and write the same CSV layout and a
   ``.json`` sidecar built from the registry.
3. Otherwise raise :class:`~gmwm.errors.DataUnavailableError` naming the file and its source.

CSV layouts (data README): WV ``dataset, sensor, axis, level, scale_s, variance, ci_low, ci_high``
with ``scale_s = 2^level / f_s``; AV ``dataset, sensor, axis, level, tau_s, avar, rel_error, adev,
adev_ci_low, adev_ci_high`` with cluster ``2^level`` samples (= WV level ``level + 1``).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import urllib.error
import urllib.request
import warnings
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import yaml

from gmwm.atomic import atomic_path
from gmwm.errors import DataUnavailableError, InputError

Fetch = Callable[[str], bytes]

REPO_ROOT = Path(__file__).resolve().parents[2]
DEFAULT_REGISTRY = REPO_ROOT / "config" / "datasets.yaml"
_AXES = ("X", "Y", "Z")


class ChecksumError(DataUnavailableError):
    """A file's sha256 differs from the registry: corrupted download or modified local copy."""


# --- registry -----------------------------------------------------------------------------------

def load_registry(registry: str | os.PathLike | Mapping | None = None) -> dict[str, Any]:
    """Read the dataset registry (default ``config/datasets.yaml``); a mapping is returned as is.

    A relative ``local_dir`` is resolved against the repository root (the registry's parent's
    parent) and stored as ``local_dir_resolved``.
    """
    if isinstance(registry, Mapping):
        reg = dict(registry)
        base = Path.cwd()
    else:
        path = Path(registry) if registry is not None else DEFAULT_REGISTRY
        if not path.is_file():
            raise InputError(f"dataset registry not found: {path}")
        with open(path, encoding="utf-8") as fh:
            reg = yaml.safe_load(fh) or {}
        base = path.resolve().parent.parent
    if not isinstance(reg.get("datasets"), Mapping):
        raise InputError("dataset registry has no 'datasets' mapping")
    local = reg.get("local_dir")
    if local is not None:
        local = Path(local)
        reg["local_dir_resolved"] = local if local.is_absolute() else (base / local).resolve()
    return reg


def dataset_entry(name: str, registry: Mapping | str | os.PathLike | None = None) -> dict[str, Any]:
    """Registry entry of one dataset, e.g. ``dataset_entry('navchip_wv')``."""
    reg = registry if isinstance(registry, Mapping) and "datasets" in registry else \
        load_registry(registry)
    try:
        return dict(reg["datasets"][name])
    except KeyError:
        known = ", ".join(reg["datasets"])
        raise InputError(f"unknown dataset {name!r}; known: {known}") from None


def describe_source(entry: Mapping) -> str:
    """One-line public source of a dataset: repository URL, path and commit."""
    src = entry.get("source", {})
    return (f"{src.get('repository', '?')} file {src.get('path', '?')} "
            f"(commit {str(src.get('commit', '?'))[:12]})")


# --- checks -------------------------------------------------------------------------------------

def sha256_file(path: str | os.PathLike) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def check_sha256(path: str | os.PathLike, expected: str, what: str) -> None:
    """Raise ChecksumError if the file's sha256 is not ``expected``."""
    got = sha256_file(path)
    if got != expected.lower():
        raise ChecksumError(f"sha256 mismatch for {what}: expected {expected}, got {got}")


def check_layout(path: str | os.PathLike, columns: list[str]) -> pd.DataFrame:
    """Read a CSV and check it has the required columns; return it."""
    try:
        df = pd.read_csv(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot read CSV {path}: {exc}") from None
    missing = [c for c in columns if c not in df.columns]
    if missing:
        raise InputError(f"{path}: missing column(s) {', '.join(missing)}")
    if df.empty:
        raise InputError(f"{path}: no rows")
    return df


# --- obtain -------------------------------------------------------------------------------------

def _dest_file(dest: str | os.PathLike, entry: Mapping) -> Path:
    dest = Path(dest)
    if dest.is_dir() or str(dest).endswith(os.sep):
        return dest / Path(entry["file"]).name
    return dest


def _copy_atomic(src: Path, dst: Path) -> None:
    if dst.exists() and src.resolve() == dst.resolve():
        return
    with atomic_path(dst) as tmp:
        shutil.copyfile(src, tmp)


def _http_fetch(url: str, timeout: float = 60.0) -> bytes:
    with urllib.request.urlopen(url, timeout=timeout) as resp:
        return resp.read()


def _local_file(reg: Mapping, name: str, local_dir: str | os.PathLike | None) -> Path | None:
    """Dataset ``name`` in ``local_dir`` (default: the loaded registry's ``local_dir``), or None."""
    base = Path(local_dir) if local_dir is not None else reg.get("local_dir_resolved")
    if base is None:
        return None
    path = Path(base) / dataset_entry(name, reg)["file"]
    return path if path.is_file() else None


def local_copy(name: str, local_dir: str | os.PathLike | None = None, *,
               registry: Mapping | str | os.PathLike | None = None) -> Path | None:
    """Path of dataset ``name`` in ``local_dir`` (default: the registry's ``local_dir``), or
    None when no such file is on disk. The first place :func:`obtain` looks."""
    return _local_file(load_registry(registry), name, local_dir)


def obtain(name: str, dest: str | os.PathLike, local_dir: str | os.PathLike | None = None,
           allow_download: bool = True, *, registry: Mapping | str | os.PathLike | None = None,
           fetch: Fetch | None = None) -> Path:
    """Put dataset ``name`` (e.g. 'navchip_wv') at ``dest`` (a CSV path or a directory); return it.

    ``local_dir`` overrides the registry's ``local_dir``. ``fetch(url) -> bytes`` replaces the HTTP
    download (tests). The ``.json`` sidecar is written next to the CSV. Writes are atomic.
    """
    reg = load_registry(registry)
    entry = dataset_entry(name, reg)
    target = _dest_file(dest, entry)
    base = Path(local_dir) if local_dir is not None else reg.get("local_dir_resolved")
    local = _local_file(reg, name, local_dir)

    if local is not None:
        check_layout(local, list(entry["columns"]))
        if entry.get("csv_sha256"):
            check_sha256(local, entry["csv_sha256"], f"local copy {local}")
        _copy_atomic(local, target)
        meta = Path(base) / entry["meta"] if entry.get("meta") else None
        if meta is not None and meta.is_file():
            _copy_atomic(meta, target.with_suffix(".json"))
        else:
            _write_sidecar(entry, target)
        return target

    where = f"not found in {base}" if base is not None else "no local directory configured"
    if not allow_download:
        raise DataUnavailableError(f"{entry['file']} {where} and download disabled; "
                                   f"public source: {describe_source(entry)}")
    url = entry["source"]["url"]
    try:
        payload = (fetch or _http_fetch)(url)
    except (urllib.error.URLError, OSError, TimeoutError) as exc:
        raise DataUnavailableError(f"{entry['file']} {where} and download of {url} failed ({exc}); "
                                   f"public source: {describe_source(entry)}") from None
    got = hashlib.sha256(payload).hexdigest()
    if got != entry["source"]["sha256"]:
        raise ChecksumError(f"sha256 mismatch for {url}: expected {entry['source']['sha256']}, "
                            f"got {got}")
    with tempfile.TemporaryDirectory() as tmpdir:
        rda = Path(tmpdir) / Path(entry["source"]["path"]).name
        rda.write_bytes(payload)
        table = rda_to_table(rda, entry)
    with atomic_path(target) as tmp:
        table.to_csv(tmp, index=False)
    _write_sidecar(entry, target)
    return target


def _write_sidecar(entry: Mapping, target: Path) -> None:
    meta = {
        "dataset": entry.get("dataset"), "kind": entry.get("kind"),
        "sensor_name": entry.get("sensor_name"), "freq_hz": entry.get("freq_hz"),
        "n": entry.get("n"), "n_levels": entry.get("n_levels"), "units": entry.get("units"),
        "source": dict(entry.get("source", {})),
        "note": "written by gmwm_studies.data.obtain from the registry config/datasets.yaml",
    }
    with atomic_path(target.with_suffix(".json")) as tmp:
        tmp.write_text(json.dumps(meta, indent=2), encoding="utf-8")


# --- .rda conversion ------------------------------------------------------------------------------

def _vec(obj: Mapping, key: str, where: str) -> np.ndarray:
    try:
        return np.asarray(obj[key], dtype=float).ravel()
    except KeyError:
        raise InputError(f"{where}: no element {key!r}") from None


def rda_to_table(path: str | os.PathLike, entry: Mapping) -> pd.DataFrame:
    """Read an ``imu_wvar`` (package wv) or ``imu_avar`` (package avar) object into the CSV layout.

    Per channel the wv object holds ``variance, ci_low, ci_high, scales`` (scales in seconds); the
    avar object holds ``levels`` (tau in seconds), ``allan, errors, adev, lci, uci``.
    """
    import rdata

    with warnings.catch_warnings():
        # classes imu_wvar/wvar/avar have no Python constructor: the plain named lists are what we want
        warnings.filterwarnings("ignore", message="Missing constructor for R class")
        parsed = rdata.read_rda(str(path))
    r_object = entry["source"]["r_object"]
    if r_object not in parsed:
        raise InputError(f"{path}: no R object {r_object!r} (found {', '.join(map(str, parsed))})")
    obj = {str(k): v for k, v in parsed[r_object].items()}
    kind = entry["kind"]
    per_channel = obj.get("wvar" if kind == "wv" else "avar")
    if not isinstance(per_channel, Mapping):
        raise InputError(f"{path}: {r_object} has no per-channel list {'wvar' if kind == 'wv' else 'avar'!r}")
    freq = float(np.ravel(obj.get("freq", [entry["freq_hz"]]))[0])
    frames = []
    for r_name, ch in per_channel.items():
        r_name = str(r_name)
        if r_name not in entry["channels"]:
            raise InputError(f"{path}: unknown channel {r_name!r}")
        sensor, axis = entry["channels"][r_name]
        ch = {str(k): v for k, v in ch.items()}
        where = f"{path} channel {r_name}"
        if kind == "wv":
            scale_s = _vec(ch, "scales", where)
            cols = {"scale_s": scale_s, "variance": _vec(ch, "variance", where),
                    "ci_low": _vec(ch, "ci_low", where), "ci_high": _vec(ch, "ci_high", where)}
        else:
            scale_s = _vec(ch, "levels", where)
            cols = {"tau_s": scale_s, "avar": _vec(ch, "allan", where),
                    "rel_error": _vec(ch, "errors", where), "adev": _vec(ch, "adev", where),
                    "adev_ci_low": _vec(ch, "lci", where), "adev_ci_high": _vec(ch, "uci", where)}
        level = np.rint(np.log2(scale_s * freq)).astype(int)
        head = {"dataset": entry.get("dataset", r_object), "sensor": sensor, "axis": axis,
                "level": level}
        frames.append(pd.DataFrame({**head, **cols}))
    table = pd.concat(frames, ignore_index=True)
    return table[list(entry["columns"])]


# --- loading ------------------------------------------------------------------------------------

def _sidecar(path: Path) -> dict[str, Any]:
    meta = path.with_suffix(".json")
    if not meta.is_file():
        return {}
    with open(meta, encoding="utf-8") as fh:
        return json.load(fh)


def _channel_rows(path: str | os.PathLike, sensor: str, axis: str,
                  columns: list[str]) -> tuple[pd.DataFrame, dict[str, Any]]:
    from gmwm_studies.sensors import canonical_sensor

    path = Path(path)
    if not path.is_file():
        raise InputError(f"data file not found: {path}")
    df = check_layout(path, columns)
    sensor = canonical_sensor(sensor)
    axis = str(axis).upper()
    if axis not in _AXES:
        raise InputError(f"unknown axis {axis!r}: expected X, Y or Z")
    rows = df[(df["sensor"] == sensor) & (df["axis"] == axis)].sort_values("level")
    if rows.empty:
        raise InputError(f"{path}: no rows for sensor {sensor!r} axis {axis!r}")
    if rows["level"].duplicated().any():
        raise InputError(f"{path}: duplicated levels for {sensor} {axis}")
    return rows, _sidecar(path)


def _n_and_freq(meta: Mapping, n_samples: int | None, freq: float | None,
                path: str | os.PathLike) -> tuple[int, float]:
    n = n_samples if n_samples is not None else meta.get("n")
    if n is None:
        raise InputError(f"{path}: signal length unknown (no .json sidecar with 'n'); pass n_samples")
    f = freq if freq is not None else meta.get("freq_hz", 250.0)
    return int(n), float(f)


def load_navchip_wv(path: str | os.PathLike, sensor: str, axis: str, *,
                    n_samples: int | None = None, freq: float | None = None):
    """WaveletVariance of one Navchip channel from the WV CSV (keeps the file's CI).

    Scales are 2^level samples; ``n_samples`` and ``freq`` default to the ``.json`` sidecar
    (``n``, ``freq_hz``; 250 Hz if absent).
    """
    from gmwm.wv import WaveletVariance

    cols = ["dataset", "sensor", "axis", "level", "scale_s", "variance", "ci_low", "ci_high"]
    rows, meta = _channel_rows(path, sensor, axis, cols)
    n, f = _n_and_freq(meta, n_samples, freq, path)
    level = rows["level"].to_numpy(dtype=int)
    scales = 2.0 ** level
    if not np.allclose(rows["scale_s"].to_numpy(float), scales / f, rtol=1e-9):
        raise InputError(f"{path}: scale_s is not 2**level / {f:g} Hz")
    alpha = float(meta.get("estimator", {}).get("alpha", 0.05))
    return WaveletVariance.from_table(
        scales, rows["variance"].to_numpy(float), rows["ci_low"].to_numpy(float),
        rows["ci_high"].to_numpy(float), n_samples=n, freq=f, alpha=alpha)


def load_navchip_av(path: str | os.PathLike, sensor: str, axis: str, *,
                    n_samples: int | None = None, freq: float | None = None):
    """AllanVariance of one Navchip channel from the AV CSV.

    The file's cluster 2^level samples is WV level ``level + 1`` (docs/METHODS.md §2.4 index trap). The file's
    AD interval adev (1 -/+ 2 rel_error) is kept as the AV interval [max(low, 0)^2, high^2].
    """
    from gmwm.wv import AllanVariance

    cols = ["dataset", "sensor", "axis", "level", "tau_s", "avar", "rel_error", "adev",
            "adev_ci_low", "adev_ci_high"]
    rows, meta = _channel_rows(path, sensor, axis, cols)
    n, f = _n_and_freq(meta, n_samples, freq, path)
    level = rows["level"].to_numpy(dtype=np.int64)
    clusters = 2 ** level
    tau = rows["tau_s"].to_numpy(float)
    if not np.allclose(tau, clusters / f, rtol=1e-9):
        raise InputError(f"{path}: tau_s is not 2**level / {f:g} Hz")
    if n < 2 * clusters[-1]:
        raise InputError(f"{path}: n_samples {n} is shorter than two clusters of {clusters[-1]}")
    avar = rows["avar"].to_numpy(float)
    low = np.maximum(rows["adev_ci_low"].to_numpy(float), 0.0) ** 2
    high = rows["adev_ci_high"].to_numpy(float) ** 2
    return AllanVariance(levels=level + 1, clusters=clusters, tau=tau, avar=avar, ci_low=low,
                         ci_high=high, n=n - 2 * clusters + 1, n_samples=n, freq=f, alpha=0.05)
