"""Phone sensor exports: a folder (or a zip archive, as phyphox exports) holding
``Gyroscope.csv`` and ``Accelerometer.csv``.

phyphox (and apps like it) export each sensor to its own table, on its own clock: ``Time (s)``
and ``Gyroscope x (rad/s)`` ... in one file, ``Time (s)`` and ``Acceleration x (m/s^2)`` ... in
the other, with a norm column (``Absolute (rad/s)``) that is not an axis. Each file is read as a
text recording (units and axes from the header, see :mod:`gmwm.readers.text`); then:

* **a common rate** (the two measured rates within :data:`COMMON_RATE` of each other): one
  six-axis :class:`~gmwm.readers.recording.Recording`; each gyroscope sample is paired with the
  accelerometer sample nearest in time (within half a step, each used once), samples without a
  partner are dropped (counted in a note), the time base is the gyroscope's stamps of the pairs;
* **no common rate**: two streams, ``Gyroscope`` and ``Accelerometer``, each with its own time
  base and rate, read with ``topic`` (``--topic all`` calibrates both, each fitted at its own
  rate); reading the folder as one recording is then an :class:`InputError` saying so.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["COMMON_RATE", "SENSOR_FILES", "is_phone_folder", "phone_topics", "read_phone_folder",
           "read_phone_topics"]

#: two sensors share a rate when their measured rates differ by less than this fraction
COMMON_RATE = 0.01
#: topic -> (file name, role), the file name matched case-insensitively
SENSOR_FILES = {"Gyroscope": ("gyroscope.csv", "gyroscope"),
                "Accelerometer": ("accelerometer.csv", "accelerometer")}


def _files(p: Path) -> dict[str, Path]:
    """topic -> the sensor's file: in a folder, or a member of a zip archive (phyphox exports
    zip files) as ``archive/member``."""
    if p.is_dir():
        by_name = {q.name.lower(): q for q in p.iterdir() if q.is_file()}
    else:
        with zipfile.ZipFile(p) as z:
            members = [m for m in z.namelist() if not m.endswith("/")]
        by_name = {}
        for m in sorted(members, key=lambda m: m.count("/")):  # the shallowest one of a name
            by_name.setdefault(m.rsplit("/", 1)[-1].lower(), p / m)
    return {t: by_name[f] for t, (f, _) in SENSOR_FILES.items() if f in by_name}


def is_phone_folder(p: str | os.PathLike) -> bool:
    """Whether a folder (or a zip archive) holds ``Gyroscope.csv`` and ``Accelerometer.csv``
    (any case)."""
    q = Path(p)
    if not q.is_dir() and not zipfile.is_zipfile(q):
        return False
    try:
        return len(_files(q)) == len(SENSOR_FILES)
    except (zipfile.BadZipFile, OSError):
        return False


def _sensor(p: Path, topic: str, freq: float | None, units: Any, read_recording: Any) -> Any:
    """One sensor's file as a :class:`Recording` (its IMU axes from the header), topic set;
    ``read_recording`` the reader of one CSV (:func:`gmwm.readers.recording.read_recording`,
    passed in by its module: this one sits below it)."""
    f = _files(p)[topic]
    if p.is_dir():
        rec = read_recording(f, freq=freq, units=units)
    else:  # a member of a zip archive: read from a temporary copy, named as the member
        member = str(f.relative_to(p))
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / f.name
            with zipfile.ZipFile(p) as z:
                copy.write_bytes(z.read(member))
            rec = _renamed(read_recording(copy, freq=freq, units=units), str(copy), str(f))
    role = SENSOR_FILES[topic][1]
    wrong = [c for c, r in rec.roles.items() if r != role]
    if wrong:
        raise InputError(f"{f} should hold {role} axes, but column(s) {', '.join(wrong)} are "
                         f"{' / '.join(sorted({str(rec.roles[c]) for c in wrong}))}")
    rec.require_time(f"the {role} of the phone export {p}")
    return replace(rec, topic=topic, format="phyphox")


def _renamed(rec: Any, old: str, new: str) -> Any:
    """``rec`` with the file name ``old`` replaced by ``new`` in its path, notes and time base."""
    tb = rec.time
    if tb is not None:
        tb = replace(tb, source=tb.source.replace(old, new),
                     notes=tuple(n.replace(old, new) for n in tb.notes))
    return replace(rec, path=new, time=tb, notes=tuple(n.replace(old, new) for n in rec.notes))


def phone_topics(path: str | os.PathLike) -> list[str]:
    """The sensor streams of a phone export folder: ``Gyroscope``, ``Accelerometer``."""
    p = Path(path)
    if not is_phone_folder(p):
        raise InputError(f"{p} is not a phone export folder (Gyroscope.csv and "
                         "Accelerometer.csv)")
    return list(SENSOR_FILES)


def read_phone_topics(path: str | os.PathLike, topics: str | Sequence[str] = "all", *,
                      read_recording: Any,
                      freq: float | None = None, units: Any = None) -> dict[str, Any]:
    """Each sensor of a phone export as its own recording (own clock, own rate): ``"all"`` or
    topic names (``Gyroscope``, ``Accelerometer``, any case)."""
    p = Path(path)
    names = phone_topics(p)
    if isinstance(topics, str) and topics.strip().lower() == "all":
        wanted = names
    else:
        wanted = []
        for t in [topics] if isinstance(topics, str) else list(topics):
            hit = [n for n in names if n.lower() == str(t).strip().lower()]
            if not hit:
                raise InputError(f"topic {t!r} not in the phone export {p}: its sensors are "
                                 f"{', '.join(names)}")
            if hit[0] in wanted:
                raise InputError(f"topic {hit[0]} requested twice")
            wanted.append(hit[0])
    return {t: _sensor(p, t, freq, units, read_recording) for t in wanted}


def _pair(tg: np.ndarray, ta: np.ndarray, half: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (i, j) pairing each gyroscope stamp with the nearest accelerometer stamp within
    ``half`` [s], each accelerometer sample used once (the first gyroscope sample wins)."""
    j = np.clip(np.searchsorted(ta, tg), 1, max(ta.size - 1, 1))
    left = ta[j - 1]
    right = ta[np.minimum(j, ta.size - 1)]
    j = np.where(np.abs(tg - left) <= np.abs(right - tg), j - 1, np.minimum(j, ta.size - 1))
    ok = np.abs(ta[j] - tg) <= half
    i = np.flatnonzero(ok)
    j = j[ok]
    first = np.concatenate(([True], np.diff(j) > 0)) if j.size else np.zeros(0, bool)
    return i[first], j[first]


def read_phone_folder(path: str | os.PathLike, *, read_recording: Any, finish: Any, select: Any,
                      columns: Any = None, freq: float | None = None,
                      units: str | Mapping[str, str] | None = None) -> Any:
    """A phone export as one six-axis recording when its sensors share a rate (see the module
    docstring); otherwise an :class:`InputError` pointing to ``--topic all``. The reading,
    column choice and finishing of :mod:`gmwm.readers.recording` are passed in by it."""
    from gmwm.readers.timebase import time_base

    p = Path(path)
    recs = read_phone_topics(p, "all", units=units, read_recording=read_recording)
    g, a = recs["Gyroscope"], recs["Accelerometer"]
    fg, fa = g.time.freq, a.time.freq
    files = _files(p)
    rates = (f"gyroscope {fg:.6g} Hz ({files['Gyroscope'].name}), accelerometer {fa:.6g} Hz "
             f"({files['Accelerometer'].name})")
    if abs(fg / fa - 1.0) > COMMON_RATE:
        raise InputError(f"the sensors of the phone export {p} have no common rate ({rates}): "
                         "calibrate each on its own clock and rate with --topic all (or "
                         "--topic Gyroscope / --topic Accelerometer)")
    tg = g.time_s + (g.time.start_s or 0.0)
    ta = a.time_s + (a.time.start_s or 0.0)
    i, j = _pair(tg, ta, 0.5 / fg)
    if i.size < 0.5 * min(tg.size, ta.size):
        raise InputError(f"the sensors of the phone export {p} share a rate ({rates}) but only "
                         f"{i.size} of their samples coincide within half a step: calibrate "
                         "each on its own clock with --topic all")
    chans = {**{c: x[i] for c, x in g.channels.items()}, **{c: x[j] for c, x in a.channels.items()}}
    names = select(list(chans), columns, p, default_all=True)
    off = np.abs(ta[j] - tg[i])
    notes = [*g.notes, *a.notes,
             (f"phone export {p}: {rates}, one common rate; each gyroscope sample paired with "
             f"the accelerometer sample nearest in time (largest offset {1e3 * off.max():.3g} "
             f"ms), {tg.size - i.size} gyroscope and {ta.size - j.size} accelerometer samples "
             "without a partner dropped; time from the gyroscope's stamps")]

    stamps = tg[i]
    tb = time_base(stamps, unit="s", where=f"the paired stamps of {p}",
                   source=f"the paired gyroscope stamps of {files['Gyroscope'].name} (s)")
    u = {**g.units, **a.units}
    return finish(p, "phyphox", {n: chans[n] for n in names}, {n: u[n] for n in names}, tb, freq,
                   None, notes, stamps=stamps)
