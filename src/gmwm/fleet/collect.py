"""The fleet's inputs and each recording's estimates.

Inputs (:func:`find_recordings`): files, folders (searched recursively for recordings; a folder
holding ``metadata.yaml`` is one ROS 2 bag), glob patterns, or a manifest CSV (a header with a
``path`` column; optional ``unit``, ``date`` (YYYY-MM-DD), ``topic``, ``datasheet``,
``temperature``; relative paths are relative to the manifest's folder).

Unit identity (:data:`UNIT_RULE`): the manifest's ``unit``; else a file name
``<unit>_<YYYY-MM-DD>...`` gives the unit and the date; else the file name without its suffix is
the unit (one recording per unit). A recording's name in ``OUT/units/<unit>/<recording>/`` is its
file name without the suffix (made unique within the unit).

Estimates (:func:`estimates_from_folder`): from a recording's calibration folder, the per-axis
noise density, random walk and bias instability of ``imu_noise.json`` (the ``json`` export of
``gmwm report``), with the report's datasheet verdicts and the fleet job's ``status.json``.
"""

from __future__ import annotations

import csv
import datetime as _dt
import glob
import hashlib
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gmwm.errors import InputError
from gmwm.fleet.core import Estimate

__all__ = ["RECORDING_SUFFIXES", "UNIT_RULE", "Recording", "content_hash",
           "estimates_from_folder", "find_recordings"]

RECORDING_SUFFIXES = (".bag", ".db3", ".mcap", ".ulg", ".csv", ".tsv", ".txt", ".dat", ".gz",
                      ".npy", ".npz", ".h5", ".hdf5")
UNIT_RULE = ("unit identity: the manifest's 'unit' column; else a file name '<unit>_<YYYY-MM-DD>"
             "...' gives the unit and the recording's date; else the file name without its "
             "suffix is the unit (one recording per unit)")
_NAME_RULE = re.compile(r"^(?P<unit>.+?)_(?P<date>\d{4}-\d{2}-\d{2})(?:$|[_.\-T])")
_SAFE = re.compile(r"[^A-Za-z0-9._-]+")
_MANIFEST_COLUMNS = ("path", "unit", "date", "topic", "datasheet", "temperature")
#: quantities of imu_noise.json read per axis: key -> (quantity name, value key)
_QUANTITIES = (("noise_density", "estimate"), ("random_walk", "estimate"),
               ("bias_instability", "value"))
_VALUE_UNITS = {("gyroscope", "noise_density"): "rad/s/sqrt(Hz)",
                ("gyroscope", "random_walk"): "rad/s^2/sqrt(Hz)",
                ("accelerometer", "noise_density"): "m/s^2/sqrt(Hz)",
                ("accelerometer", "random_walk"): "m/s^3/sqrt(Hz)"}
_FLAGS = {"boundary": "at the boundary 0", "weak": "not distinguishable from 0 (below 1.96 SE)"}
#: the datasheet verdict term that stands for a quantity: from the fitted component
_COMPONENT_OF = {"noise_density": "WN", "random_walk": "RW"}


@dataclass(frozen=True)
class Recording:
    """One input recording: ``path``; the ``unit`` it belongs to and its ``name`` there (safe
    for a folder name); ``date`` if known; the manifest's ``topic``, ``datasheet`` and
    ``temperature`` (deg C, informative)."""

    path: Path
    unit: str
    name: str
    date: _dt.date | None = None
    topic: str | None = None
    datasheet: str | None = None
    temperature: float | None = None
    extra: dict[str, str] = field(default_factory=dict)

    @property
    def key(self) -> str:
        """``<unit>/<name>``: the recording's place below ``OUT/units``."""
        return f"{self.unit}/{self.name}"


def _safe(text: str) -> str:
    out = _SAFE.sub("_", text.strip()).strip("._")
    return out or "unnamed"


def _stem(path: Path) -> str:
    name = path.name
    for suf in (".gz",):
        if name.lower().endswith(suf):
            name = name[: -len(suf)]
    return Path(name).stem if Path(name).suffix else name


def _date(text: str, where: str) -> _dt.date:
    try:
        return _dt.date.fromisoformat(text.strip())
    except ValueError:
        raise InputError(f"{where}: date {text!r} is not YYYY-MM-DD") from None


def _from_name(path: Path) -> tuple[str, _dt.date | None]:
    stem = _stem(path)
    m = _NAME_RULE.match(stem)
    if m:
        return m.group("unit"), _date(m.group("date"), str(path))
    return stem, None


def _is_manifest(path: Path) -> bool:
    if path.suffix.lower() != ".csv" or not path.is_file():
        return False
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        header = fh.readline()
    return "path" in [c.strip().lower() for c in header.split(",")]


def _walk(folder: Path) -> list[Path]:
    if (folder / "metadata.yaml").is_file():  # a ROS 2 bag
        return [folder]
    if (folder / ".fleet").is_dir():  # a fleet's output folder: its tables are no recordings
        return []
    found: list[Path] = []
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_dir():
            found.extend(_walk(p))
        elif p.suffix.lower() in RECORDING_SUFFIXES and not _is_manifest(p):
            found.append(p)
    return found


def _manifest(path: Path) -> list[Recording]:
    out = []
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    for i, row in enumerate(rows, start=2):
        row = {(k or "").strip().lower(): (v or "").strip() for k, v in row.items()}
        where = f"{path} line {i}"
        if not row.get("path"):
            raise InputError(f"{where}: empty 'path'")
        p = Path(row["path"])
        p = p if p.is_absolute() else path.parent / p
        unit, date = _from_name(p)
        if row.get("unit"):
            unit = row["unit"]
        if row.get("date"):
            date = _date(row["date"], where)
        temp = None
        if row.get("temperature"):
            try:
                temp = float(row["temperature"])
            except ValueError:
                raise InputError(f"{where}: temperature {row['temperature']!r} is not a number "
                                 "(deg C)") from None
        extra = {k: v for k, v in row.items() if k not in _MANIFEST_COLUMNS and v}
        out.append(Recording(p, _safe(unit), _safe(_stem(p)), date, row.get("topic") or None,
                             row.get("datasheet") or None, temp, extra))
    return out


def find_recordings(inputs: Sequence[str]) -> list[Recording]:
    """Every recording named by ``inputs`` (module docstring), in a stable order, with unique
    ``<unit>/<name>`` keys. A named file that does not exist, or a pattern or folder that matches
    nothing, is an InputError."""
    recs: list[Recording] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            paths = _walk(p)
            if not paths:
                raise InputError(f"{item}: no recordings found in this folder (suffixes "
                                 f"{', '.join(RECORDING_SUFFIXES)}, or ROS 2 bag folders)")
        elif p.is_file():
            if _is_manifest(p):
                recs.extend(_manifest(p))
                continue
            paths = [p]
        elif any(ch in item for ch in "*?["):
            paths = [Path(g) for g in sorted(glob.glob(item, recursive=True))]
            if not paths:
                raise InputError(f"{item}: the pattern matches no file")
        else:
            raise InputError(f"{item}: no such file or folder")
        for q in paths:
            unit, date = _from_name(q)
            recs.append(Recording(q, _safe(unit), _safe(_stem(q)), date))
    seen: dict[str, int] = {}
    out: list[Recording] = []
    paths_seen: set[Path] = set()
    for r in recs:
        real = r.path.resolve()
        if real in paths_seen:  # the same file named twice (folder and glob): once
            continue
        paths_seen.add(real)
        name, n = r.name, seen.get(r.key, 0)
        seen[r.key] = n + 1
        if n:
            name = f"{r.name}-{n + 1}"
        out.append(Recording(r.path, r.unit, name, r.date, r.topic, r.datasheet, r.temperature,
                             r.extra))
    if not out:
        raise InputError("no recordings given")
    return out


def content_hash(path: Path, chunk: int = 1 << 20) -> str:
    """SHA-256 of a recording's bytes (a folder: of its files' relative names and bytes)."""
    h = hashlib.sha256()
    files = sorted(q for q in path.rglob("*") if q.is_file()) if path.is_dir() else [path]
    for q in files:
        if path.is_dir():
            h.update(str(q.relative_to(path)).encode() + b"\0")
        with open(q, "rb") as fh:
            while block := fh.read(chunk):
                h.update(block)
    return h.hexdigest()


# --------------------------------------------------------------------------------------------------
# one recording's estimates
# --------------------------------------------------------------------------------------------------


def _read_json(path: Path) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _ci(raw: Any) -> tuple[float, float] | None:
    if not raw or len(raw) != 2 or raw[0] is None or raw[1] is None:
        return None
    return (float(raw[0]), float(raw[1]))


def _datasheet(fit: dict[str, Any], quantity: str, value: float | None
               ) -> tuple[str | None, float | None]:
    """This axis's datasheet verdict for ``quantity`` and the datasheet value in the quantity's
    own unit (scaled by the ratio of the estimate to the verdict's measured value)."""
    verdict = fit.get("datasheet_verdict") or fit.get("verdict") or {}
    rows = verdict.get("rows") or []
    if quantity == "bias_instability":
        term = "BI"
    else:
        comp = _COMPONENT_OF[quantity]
        term = next((k for k, d in (fit.get("datasheet") or {}).items()
                     if any(p.startswith(comp + "[") for p in d.get("parameters", []))), None)
    row = next((r for r in rows if r.get("term") == term and not r.get("quantity")), None)
    if row is None:
        return None, None
    ds = row.get("datasheet")
    meas = row.get("measured")
    scaled = (ds * value / meas if ds is not None and value and meas and meas > 0 else None)
    return row.get("verdict"), scaled


def estimates_from_folder(folder: Path, rec: Recording) -> tuple[list[Estimate], str | None]:
    """The recording's estimates from its calibration folder and, if it failed, the one-line
    reason (no estimates then). Terms the fleet job found not identifiable at the length used
    (``status.json``: ``not_identifiable``) and flagged terms are kept but excluded, with why."""
    status = _read_json(folder / "status.json")
    if status is None:
        return [], "no calibration result (the job did not finish)"
    if not status.get("ok"):
        return [], status.get("reason") or "calibration failed"
    noise = _read_json(folder / "imu_noise.json")
    if noise is None:
        return [], "no imu_noise.json in the calibration folder"
    report = _read_json(folder / "report.json") or {}
    fits = report.get("fits") or {}
    unident = status.get("not_identifiable") or {}
    used_s = status.get("used_s")
    out: list[Estimate] = []
    for axis, a in (noise.get("axes") or {}).items():
        sensor = a.get("sensor") or ""
        for quantity, vkey in _QUANTITIES:
            q = a.get(quantity)
            if not q:
                continue
            value = q.get(vkey)
            value = None if value is None else float(value)
            ci = _ci(q.get("ci95"))
            why = None
            if quantity == "bias_instability":
                vunit = q.get("unit") or ""
                if q.get("at_end"):
                    why = ("Allan-deviation minimum at the longest cluster time: floor not "
                           "reached (an upper bound)")
            else:
                vunit = _VALUE_UNITS.get((sensor, quantity), "")
                flag = q.get("flag")
                if flag:
                    why = _FLAGS.get(flag, str(q.get("note") or flag))
                comp = _COMPONENT_OF[quantity]
                if why is None and unident.get(axis, {}).get(comp):
                    why = (f"not identifiable at the {used_s:.0f} s used (gmwm plan rule)"
                           if used_s else "not identifiable at the length used (gmwm plan rule)")
            verdict, ds_value = _datasheet(fits.get(axis) or {}, quantity, value)
            if value is not None and not math.isfinite(value):
                value, why = None, why or "no finite estimate"
            out.append(Estimate(rec.unit, rec.name, f"{axis}.{quantity}", value, ci, vunit,
                                sensor, rec.date, why, verdict, ds_value))
    if not out:
        return [], "no gyroscope or accelerometer axis in the report (give --units)"
    return out, None
