"""One entry point for every recording: :func:`read_recording` -> :class:`Recording`.

========================  ===================================  ==============================
format (found by content)  rate from                             units and axis roles from
========================  ===================================  ==============================
ROS 1 bag, ROS 2 bag       ``header.stamp`` (ns)                 the message type (REP 103)
(sqlite3, MCAP)
PX4 ULog                   ``timestamp[_sample]`` (us)           the ULog topic
ArduPilot DataFlash        ``TimeUS`` (us)                       the IMU message (SI)
(``.bin``, text ``.log``)
phone export folder        each sensor file's ``Time (s)``       the headers' units
EuRoC / TUM-VI CSV         ``#timestamp [ns]``                   the bracketed header units
``rostopic echo -p`` CSV   ``field.header.stamp`` (ns)           the message type (REP 103)
CSV/TSV/text (``;``,       a time column (unit by name, else     a unit after a column name
decimal comma, ``.gz``)    by magnitude)                         (``gx [deg/s]``, ``Gyroscope X
                                                                 (deg/s)``), or ``units``
``.npy``, ``.npz``,        a time column / field / dataset, an   ``units``
HDF5                       HDF5 ``freq`` attribute, ``freq``
========================  ===================================  ==============================

Without stamps the rate is ``freq``; without either, :attr:`Recording.time` is None and
:meth:`Recording.require_time` raises (a physical unit or a datasheet needs seconds: never
1 Hz). A ``freq`` that contradicts the stamps by more than 1 % is an error.

Several IMU streams of one bag, ULog, DataFlash log or phone export: :func:`imu_topics` lists
them, :func:`read_recordings` reads them with the file opened once.

The rate is the mean rate between gaps (:class:`gmwm.readers.timebase.TimeBase`); where jitter or
gaps make it ambiguous, :attr:`Recording.rate_ambiguity` says why (a configuration needs
``--freq`` or ``--gaps`` then). Exact duplicate rows are dropped with a note.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError
from gmwm.readers.timebase import (
    TIME_UNITS,
    GapDecision,
    TimeBase,
    decide_gaps,
    time_base,
    time_column,
    time_from_freq,
)
from gmwm.units import parse_unit

__all__ = ["FORMATS", "Recording", "imu_topics", "read_recording", "read_recordings", "sample_range",
           "select_samples"]

FORMATS = ("ros1", "ros2-sqlite3", "ros2-mcap", "ulog", "dataflash", "euroc", "rostopic", "csv",
           "phyphox", "npy", "npz", "hdf5")
#: formats holding several IMU streams, chosen with ``topic``
_MULTI = ("bag", "ulog", "dataflash", "phone")
_TEXT_SUFFIXES = (".csv", ".tsv", ".txt", ".dat", ".gz")
_FREQ_NAMES = ("freq", "frequency", "fs", "rate", "sampling_rate", "sample_rate",
               "sampling_frequency", "update_rate")


@dataclass(frozen=True)
class Recording:
    """Signals of one recording, in the units of the file.

    ``channels`` name -> 1-D float64 array (all one length); ``units`` name -> signal unit (a
    :data:`gmwm.units.SIGNAL_UNITS` key, a raw-count ``'K*UNIT'``, or None: unknown);
    ``roles`` name -> 'gyroscope' / 'accelerometer' / None; ``time`` the measured or given time
    base (None: neither stamps nor ``freq``); ``format`` one of :data:`FORMATS`; ``topic`` the
    bag or ULog topic; ``notes`` what the user should know (shown as warnings); ``time_s`` the
    time of each sample in seconds since the first (from the stamps, else ``i / freq``; None
    without time); ``temperature`` deg C per sample when the file carries one (ULog, a CSV
    column named ``temp*``), from ``temperature_source``."""

    channels: dict[str, np.ndarray]
    units: dict[str, str | None]
    roles: dict[str, str | None]
    time: TimeBase | None
    path: str
    format: str
    topic: str | None = None
    notes: tuple[str, ...] = field(default=())
    time_s: np.ndarray | None = field(default=None, repr=False)
    temperature: np.ndarray | None = field(default=None, repr=False)
    temperature_source: str = ""

    @property
    def freq(self) -> float | None:
        return None if self.time is None else self.time.freq

    @property
    def n(self) -> int:
        return next(iter(self.channels.values())).size if self.channels else 0

    @property
    def rate_ambiguity(self) -> str | None:
        """Why this recording's rate is ambiguous (:attr:`TimeBase.rate_ambiguity`: jitter or
        gaps beyond the limits of :mod:`gmwm.readers.timebase`), or None. A configuration file
        needs one rate: refuse it unless the user gave ``--freq`` (then settled here: None) or
        a gap policy (``--gaps``)."""
        return None if self.time is None else self.time.rate_ambiguity

    @property
    def rate_ambiguous(self) -> bool:
        return self.rate_ambiguity is not None

    def require_rate(self, gaps_given: bool = False, what: str = "configuration files") -> None:
        """Refuse ``what`` when the rate is ambiguous (:attr:`rate_ambiguity`) and the user gave
        neither ``--freq`` (which settles it when reading) nor a gap policy (``gaps_given``):
        an :class:`InputError` of one line naming ``--freq``."""
        why = self.rate_ambiguity
        if why is None or gaps_given:
            return
        tb = self.time
        rates = sorted({f"{r:.6g}" for r in (tb.freq, tb.median_rate, tb.overall_rate) if r},
                       key=float)
        allow = rates[0] if len(rates) == 1 else f"{', '.join(rates[:-1])} or {rates[-1]}"
        raise InputError(f"{why}: no {what} written; give --freq with the rate to assume (the "
                         f"stamps allow {allow} Hz) or a gap policy with --gaps")

    def require_time(self, why: str = "scales in seconds") -> TimeBase:
        """The time base; an :class:`InputError` asking for ``--freq`` when there is none."""
        if self.time is None:
            raise InputError(f"{self.path} has no time stamps and no sampling rate, needed for "
                             f"{why}: give --freq (Hz)")
        return self.time

    def gaps(self, policy: str = "auto") -> GapDecision:
        """The gap policy applied to this recording (see :mod:`gmwm.readers.timebase`)."""
        tb = self.time
        if tb is None:
            return GapDecision("none", ((0, self.n),), self.n, self.n)
        return decide_gaps(tb, policy)

    def summary(self) -> str:
        where = f"{self.path}" + (f" topic {self.topic}" if self.topic else "")
        axes = ", ".join(f"{k} [{self.units.get(k) or '?'}]" for k in self.channels)
        rate = self.time.summary() if self.time else "no time information"
        return f"{where} ({self.format}): {axes}; {rate}"


def _kind(p: Path) -> str:
    from gmwm.readers.dataflash import DATAFLASH_MAGIC, is_text_dataflash
    from gmwm.readers.rosbag import bag_kind
    from gmwm.readers.ulog import ULOG_MAGIC

    if p.is_dir():
        if bag_kind(p) == "ros2-dir":
            return "bag"
        from gmwm.readers.phone import is_phone_folder

        if is_phone_folder(p):
            return "phone"
        raise InputError(f"{p} is a folder, not a ROS 2 bag (no metadata.yaml) nor a phone "
                         "sensor export (no Gyroscope.csv and Accelerometer.csv)")
    with open(p, "rb") as fh:
        head = fh.read(64)
    if not head:
        raise InputError(f"{p} is empty")
    if bag_kind(p) is not None:
        return "bag"
    if head.startswith(ULOG_MAGIC):
        return "ulog"
    if head.startswith(DATAFLASH_MAGIC) or is_text_dataflash(head):
        return "dataflash"
    if head.startswith(b"\x93NUMPY"):
        return "npy"
    if head.startswith(b"PK\x03\x04"):
        from gmwm.readers.phone import is_phone_folder

        return "phone" if is_phone_folder(p) else "npz"
    if head.startswith(b"\x89HDF\r\n\x1a\n"):
        return "hdf5"
    suffix = p.suffix.lower()
    if suffix in (".npy", ".h5", ".hdf5"):  # the table reader says what is wrong with it
        return "npy" if suffix == ".npy" else "hdf5"
    if head.startswith(b"\x1f\x8b") or suffix in _TEXT_SUFFIXES:
        return "text"
    if suffix in (".bag", ".mcap", ".db3", ".ulg", ".npz", ".bin", ".log"):
        raise InputError(f"{p} is not a valid {suffix} file (its first bytes do not match)")
    raise InputError(f"unknown file extension '{p.suffix}' for {p}: gmwm reads ROS 1/2 bags "
                     "(.bag, .db3, .mcap, bag folders), PX4 ULog (.ulg), ArduPilot DataFlash "
                     "(.bin, .log), text tables (.csv, .tsv, .txt, .dat, also gzip-compressed "
                     ".gz), phone export folders, .npy, .npz and HDF5 (.h5)")


def _check_unit_map(units: str | Mapping[str, str] | None, names: Sequence[str], p: Path
                    ) -> dict[str, str | None]:
    if units is None:
        return dict.fromkeys(names)
    if isinstance(units, str):
        return dict.fromkeys(names, units)
    unknown = [c for c in units if c not in names]
    if unknown:
        raise InputError(f"unit given for {', '.join(unknown)}, not among the channels of {p} "
                         f"({', '.join(names)})")
    return {c: units.get(c) for c in names}


def _select(names: list[str], columns: Any, p: Path, default_all: bool) -> list[str]:
    if columns is None:
        if default_all or len(names) == 1:
            return list(names)
        raise InputError(f"{p} has {len(names)} data columns ({', '.join(names)}): choose one "
                         "with --column or several with --columns (or 'all')")
    if isinstance(columns, str) and columns.strip().lower() == "all":
        return list(names)
    if isinstance(columns, str | int):
        columns = [columns]
    out = []
    for c in columns:
        if str(c) in names:
            key = str(c)
        elif isinstance(c, int) or str(c).isdigit():
            i = int(c)
            if not 0 <= i < len(names):
                raise InputError(f"column index {i} out of range for {p}: its data columns are "
                                 + ", ".join(f"{k}={n}" for k, n in enumerate(names)))
            key = names[i]
        else:
            raise InputError(f"column '{c}' not found in {p}; its data columns: "
                             f"{', '.join(names)}")
        if key in out:
            raise InputError(f"column {key} requested twice")
        out.append(key)
    return out


def _finish(p: Path, fmt: str, channels: dict[str, np.ndarray], file_units: dict[str, str | None],
            tb: TimeBase | None, freq: float | None, units: Any, notes: list[str],
            topic: str | None = None, stamps: Any = None,
            temperature: tuple[np.ndarray, str] | None = None) -> Recording:
    """Check the channels, merge the user's units with the file's, settle the time base;
    ``stamps`` (in ``tb.unit``) give :attr:`Recording.time_s`, ``temperature`` (deg C, source)."""
    from gmwm.readers.tables import validated_numbers as _validated

    names = list(channels)
    given = _check_unit_map(units, names, p)
    out_units: dict[str, str | None] = {}
    roles: dict[str, str | None] = {}
    for c in names:
        fu, gu = file_units.get(c), given.get(c)
        pf = parse_unit(fu) if fu else None
        pg = parse_unit(gu) if gu else None
        if pf is not None and pg is not None and pf != pg:
            raise InputError(f"--units {gu} for {c} contradicts the file, which says {fu}")
        chosen = pf or pg
        out_units[c] = None if chosen is None else (fu if pf else gu) if chosen[1] != 1.0 \
            else chosen[0]
        roles[c] = None if chosen is None else chosen[2]
    checked = {c: _validated(np.asarray(x), p, True, c if len(names) > 1 else None)
               for c, x in channels.items()}
    n = {x.size for x in checked.values()}
    if len(n) > 1:
        raise InputError(f"the channels of {p} have different lengths ({sorted(n)})")
    size = n.pop() if n else 0
    if freq is not None:
        if not (np.isfinite(freq) and freq > 0):
            raise InputError(f"--freq must be a positive number of Hz, got {freq}")
        if tb is not None and tb.rate_ambiguity is not None:
            # the stamps allow several rates: --freq chooses one of them (within 1 %)
            cands = [r for r in (tb.freq, tb.median_rate, tb.overall_rate) if r]
            if not min(cands) * 0.99 <= freq <= max(cands) * 1.01:
                raise InputError(f"--freq {freq:g} lies outside the rates the stamps of "
                                 f"{tb.source} allow ({min(cands):.6g}-{max(cands):.6g} Hz)")
            tb = replace(tb, freq=float(freq), rate_given=True,
                         source=f"--freq (the stamps of {tb.source} give {tb.freq:.6g} Hz "
                                "between gaps)",
                         notes=tuple(n for n in tb.notes if " is ambiguous: " not in n))
        elif tb is not None and abs(freq / tb.freq - 1.0) > 0.01:
            raise InputError(f"--freq {freq:g} contradicts the sampling frequency {tb.freq:.6g} "
                             f"Hz measured from {tb.source}; drop --freq or fix the file")
        if tb is None:
            tb = time_from_freq(freq, size)
    if tb is not None and tb.n != size:
        raise InputError(f"{p}: {tb.n} time stamps for {size} samples")
    time_s = None
    if tb is not None:
        if stamps is not None and tb.unit is not None:
            st = np.asarray(stamps)
            time_s = (st - st[0]).astype(np.float64) * TIME_UNITS[tb.unit]
        else:
            time_s = np.arange(size) / tb.freq
    temp, temp_src = (None, "") if temperature is None else temperature
    if temp is not None and temp.size != size:
        raise InputError(f"{p}: {temp.size} temperature values for {size} samples")
    return Recording(checked, out_units, roles, tb, str(p), fmt, topic,
                     tuple(notes) + (tb.notes if tb is not None else ()), time_s,
                     None if temp is None else np.asarray(temp, dtype=np.float64), temp_src)


def _dedupe(stamps: Any, vectors: Mapping[str, np.ndarray], temperature: np.ndarray | None,
            where: str, notes: list[str]
            ) -> tuple[Any, dict[str, np.ndarray], np.ndarray | None]:
    """Drop exact duplicate rows (:func:`gmwm.readers.timebase.drop_duplicate_rows`), the
    count noted; a repeated stamp with other values is an :class:`InputError`."""
    from gmwm.readers.timebase import drop_duplicate_rows

    keep, note = drop_duplicate_rows(stamps, dict(vectors), where)
    if keep is None:
        return stamps, dict(vectors), temperature
    notes.append(note)
    return (np.asarray(stamps)[keep], {k: np.asarray(v)[keep] for k, v in vectors.items()},
            None if temperature is None else np.asarray(temperature)[keep])


def _from_table(p: Path, columns: Any, time_unit: str | None, freq: float | None, units: Any
                ) -> Recording:
    from gmwm.readers.text import numeric, read_text_table

    t = read_text_table(p)
    notes = list(t.notes)
    tnames = list(t.time)
    if t.kind == "rostopic":
        # header stamps (sample time) before %time (when rostopic received the message)
        tnames.sort(key=lambda n: 0 if n == "field.header.stamp" else 1)
        data = [n for n in ("gx", "gy", "gz", "ax", "ay", "az") if n in t.columns]
    else:
        temps = {n for n, _ in t.temperature}
        data = [n for n in t.columns if n not in t.time and t.columns[n].dtype.kind in "iuf"
                and n not in temps]
        if not data:
            data = [n for n in t.columns if n not in t.time]
    if columns is not None and not (isinstance(columns, str) and columns.lower() == "all"):
        wanted = [columns] if isinstance(columns, str | int) else list(columns)
        every = list(t.columns)  # a 0-based index counts every column of the file
        for k, c in enumerate(wanted):
            if (isinstance(c, int) or str(c).isdigit()) and str(c) not in every:
                if not 0 <= int(c) < len(every):
                    raise InputError(f"column index {c} out of range for {p}: it has "
                                     f"{len(every)} columns (0..{len(every) - 1})")
                wanted[k] = every[int(c)]
        columns = wanted
        clash = [str(c) for c in wanted if str(c) in t.time]
        if clash:
            raise InputError(f"{clash[0]} is the time column of {p}, not a signal")
        if t.kind == "rostopic":
            data = [n for n in t.columns if n not in t.time]
    rename: dict[str, str] = {}
    if columns is None and t.kind == "csv" and t.header:
        picked = _imu_columns(t, data, p, notes)
        if picked is not None:
            data, rename = picked
    known = bool(data) and all(t.units.get(n) for n in data)
    names = _select(data, columns, p, default_all=known)
    for n in names:
        if n in t.unit_text and not t.units.get(n):
            notes.append(f"column '{n}' of {p}: unit [{t.unit_text[n]}] is not a known signal "
                         "unit; give it with --units")
    chans = {rename.get(n, n): numeric(t, n, str(p)) for n in names}
    if t.header:  # a WV/AV table read as a very short signal is almost surely a mistake
        from gmwm.readers.tables import check_not_a_table as _check_not_a_table

        _check_not_a_table(list(t.columns), next(iter(chans.values())).size, p)
    tb = None
    keep = None
    if tnames:
        from gmwm.readers.timebase import drop_duplicate_rows

        name = tnames[0]
        stamps = numeric(t, name, str(p))
        if t.kind == "rostopic" and name == "field.header.stamp" and np.all(stamps == 0):
            notes.append(f"{p}: field.header.stamp is zero; %time (receive time) is used")
            name = "%time"
            stamps = numeric(t, name, str(p))
        keep, note = drop_duplicate_rows(stamps, chans, str(p))
        if keep is not None:
            notes.append(note)
            stamps = stamps[keep]
            chans = {n: x[keep] for n, x in chans.items()}
        unit = t.time[name]
        if time_unit is not None:
            if unit is not None and unit != time_unit:
                raise InputError(f"--time-unit {time_unit} contradicts the time column "
                                 f"'{name}' of {p}, labelled {unit}")
            unit = time_unit
        tb = time_base(stamps, name=name, unit=unit, where=f"time column '{name}' of {p}")
    elif time_unit is not None:
        raise InputError(f"--time-unit given but {p} has no time column")
    fmt = t.kind if t.kind in ("euroc", "rostopic") else "csv"
    temp, scale = next(((n, u) for n, u in t.temperature if n not in names), (None, "C"))
    temperature = None
    if temp is not None:
        v = numeric(t, temp, str(p)).astype(np.float64)
        v = v - 273.15 if scale == "K" else (v - 32.0) / 1.8 if scale == "F" else v
        v = v if keep is None else v[keep]
        temperature = (v, f"column '{temp}' of {p.name}")
    return _finish(p, fmt, chans, {rename.get(n, n): t.units.get(n) for n in names}, tb, freq,
                   units, notes, stamps=stamps if tb is not None else None,
                   temperature=temperature)


def _imu_columns(t: Any, data: list[str], p: Path, notes: list[str]
                 ) -> tuple[list[str], dict[str, str]] | None:
    """The IMU axes of a header with units (``Gyroscope X (deg/s)``, ``acc_x [m/s^2]``): the
    columns whose unit is a gyroscope or accelerometer unit, renamed ``gx`` .. ``az`` when each
    has one axis; the other columns (magnetometer, orientation, quaternion, a norm of the axes,
    or any column whose unit is not a signal unit) are ignored, with a note. None when no column
    has a signal unit (the caller then asks for ``--columns``). A column named like an IMU axis
    without a unit, or two columns of one axis, is an :class:`InputError`."""
    from gmwm.readers.text import imu_column
    from gmwm.units import SIGNAL_UNITS

    kinds = {n: imu_column(n, t.units.get(n)) for n in data}
    imu = [n for n in data if t.units.get(n) and kinds[n][0] in ("gyroscope", "accelerometer")]
    if not imu:
        return None
    raw = t.raw_names
    unclear = [n for n in data if n not in imu and kinds[n][0] in ("gyroscope", "accelerometer")]
    if unclear:
        n = unclear[0]
        what = (f"its unit [{t.unit_text[n]}] is not a known signal unit" if n in t.unit_text
                else "it has no unit in the header")
        raise InputError(f"column '{raw.get(n, n)}' of {p} looks like a {kinds[n][0]} axis but "
                         f"{what}: give --units, or choose the columns with --columns")
    ignored = [n for n in data if n not in imu]
    seen: dict[tuple[str, str], str] = {}
    rename: dict[str, str] = {}
    for n in imu:
        role, axis = kinds[n]
        if axis is None:
            rename = {}
            break
        key = (role, axis)
        if key in seen:
            raise InputError(f"columns '{raw.get(seen[key], seen[key])}' and '{raw.get(n, n)}' of "
                             f"{p} both hold the {role} {axis} axis: choose with --columns")
        seen[key] = n
        rename[n] = ("g" if role == "gyroscope" else "a") + axis
    taken = set(data) - set(imu)
    if any(v in taken for v in rename.values()):
        rename = {}
    mapped = ", ".join(f"'{raw.get(n, n)}' -> {rename.get(n, n)} [{t.units[n]}]" for n in imu)
    text = f"{p.name}: IMU axes from the header: {mapped}"
    conv = sorted({u for n in imu if (u := t.units[n]) in SIGNAL_UNITS
                   and SIGNAL_UNITS[u][1] != 1.0})
    if conv:
        text += ("; the configuration files convert " + ", ".join(
            f"{u} to {'rad/s' if SIGNAL_UNITS[u][0] == 'gyroscope' else 'm/s^2'} "
            f"(x {SIGNAL_UNITS[u][1]:.6g})" for u in conv) + ", the report states the "
            "coefficients in the file's units")
    if ignored:
        text += "; not IMU axes, ignored: " + ", ".join(f"'{raw.get(n, n)}'" for n in ignored)
    notes.append(text)
    return imu, rename


def _from_npz(p: Path, columns: Any, time_unit: str | None, freq: float | None, units: Any
              ) -> Recording:
    try:
        z = np.load(p, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise InputError(f"cannot read {p} as .npz: {exc}") from None
    arrays: dict[str, np.ndarray] = {}
    rate = None
    with z:
        for key in z.files:
            try:
                a = z[key]
            except ValueError:
                raise InputError(f"{p}: array '{key}' holds Python objects, not numbers") from None
            if a.ndim == 0 and key.lower() in _FREQ_NAMES:
                rate = float(a)
            elif a.ndim == 1:
                arrays[key] = a
            elif a.ndim == 2:
                for i in range(a.shape[1]):
                    arrays[f"{key}[{i}]"] = a[:, i]
            else:
                raise InputError(f"{p}: array '{key}' has shape {a.shape}; gmwm reads 1-D "
                                 "signals, (N, k) tables and a scalar 'freq'")
    if not arrays:
        raise InputError(f"{p} holds no 1-D or 2-D array")
    tnames = [k for k in arrays if time_column(k)[0]]
    data = [k for k in arrays if k not in tnames]
    names = _select(data, columns, p, default_all=False)
    tb = None
    notes: list[str] = []
    chans = {n: arrays[n] for n in names}
    stamps = None
    if tnames:
        name = tnames[0]
        stamps, chans, _ = _dedupe(arrays[name], chans, None, f"array '{name}' of {p}", notes)
        tb = time_base(stamps, name=name, unit=time_unit or time_column(name)[1],
                       where=f"array '{name}' of {p}")
    elif rate is not None:
        tb = time_from_freq(rate, arrays[names[0]].size, source=f"the 'freq' array of {p}")
    return _finish(p, "npz", chans, {}, tb, freq, units, notes, stamps=stamps)


def _from_io(p: Path, kind: str, columns: Any, dataset: str | None, freq: float | None,
             units: Any) -> Recording:
    from gmwm.readers.tables import read_channels

    ch = read_channels(p, columns, dataset=dataset)
    tb = getattr(ch, "time", None)
    if tb is None and ch.freq is not None:
        tb = time_from_freq(ch.freq, next(iter(ch.signals.values())).size, ch.freq_source or "")
    notes = [n for n in ch.notes if tb is None or n not in tb.notes]
    return _finish(p, kind, dict(ch.signals), {}, tb, freq, units, notes)


def _bag_format(p: Path) -> str:
    from gmwm.readers.rosbag import bag_kind

    fmt = {"ros1": "ros1", "sqlite3": "ros2-sqlite3", "mcap": "ros2-mcap"}.get(bag_kind(p) or "")
    if fmt is None:  # a ROS 2 folder: its storage files say which
        fmt = "ros2-mcap" if any(q.suffix == ".mcap" for q in p.iterdir()) else "ros2-sqlite3"
    return fmt


def _from_bag(p: Path, d: Any, columns: Any, freq: float | None, units: Any,
              fmt: str | None = None) -> Recording:
    """The :class:`Recording` of a decoded bag topic (:class:`gmwm.readers.rosbag.TopicData`)."""
    names = _select(list(d.vectors), columns, p, default_all=True)
    where = f"{d.stamp_source} of topic {d.topic}"
    notes = list(d.notes)
    stamps, vec, _ = _dedupe(d.stamp_ns, d.vectors, None, where, notes)
    tb = time_base(stamps, unit="ns", where=where, source=f"{where} (ns)")
    return _finish(p, fmt or _bag_format(p), {n: vec[n] for n in names}, d.units, tb, freq,
                   units, notes, d.topic, stamps=stamps)


def _from_ulog(p: Path, u: Any, columns: Any, freq: float | None, units: Any) -> Recording:
    """The :class:`Recording` of a ULog topic (:class:`gmwm.readers.ulog.UlogData`)."""
    names = _select(list(u.vectors), columns, p, default_all=True)
    where = f"{u.stamp_field} of {u.topic}"
    notes = list(u.notes)
    stamps, vec, temp = _dedupe(u.stamp_us, u.vectors, u.temperature, where, notes)
    tb = time_base(stamps, unit="us", where=where, source=f"{where} (us)")
    return _finish(p, "ulog", {n: vec[n] for n in names}, u.units, tb, freq, units,
                   notes, u.topic, stamps=stamps,
                   temperature=None if temp is None else (temp, u.temperature_source))


def _from_dataflash(p: Path, d: Any, columns: Any, freq: float | None, units: Any
                    ) -> Recording:
    """The :class:`Recording` of a DataFlash IMU (:class:`gmwm.readers.dataflash.FlashData`)."""
    names = _select(list(d.vectors), columns, p, default_all=True)
    where = f"{d.source} in {p.name}"
    notes = list(d.notes)
    stamps, vec, temp = _dedupe(d.stamp_us, d.vectors, d.temperature, where, notes)
    unit = "ms" if d.source.startswith("TimeMS") else "us"  # either way read as us
    tb = time_base(stamps, unit="us", where=where, source=f"{d.source} ({unit})")
    return _finish(p, "dataflash", {n: vec[n] for n in names}, d.units, tb, freq, units,
                   notes, d.topic, stamps=stamps,
                   temperature=None if temp is None else (temp, d.temperature_source))


def _multi_kind(p: Path, what: str) -> str:
    if not p.exists():
        raise InputError(f"file not found: {p}")
    kind = _kind(p)
    if kind not in _MULTI:
        raise InputError(f"{what} applies to ROS bags and ULog files (also DataFlash logs and "
                         f"phone export folders), not to {p}")
    return kind


def imu_topics(path: str | os.PathLike) -> list[str]:
    """The IMU streams of a ROS bag (:func:`gmwm.readers.rosbag.imu_bag_topics`: the
    ``sensor_msgs/Imu`` topics and the gyroscope/accelerometer ``Vector3Stamped`` topics) or of a
    PX4 ULog (:func:`gmwm.readers.ulog.ulog_imu_topics`: the ``sensor_gyro``/``sensor_accel``
    instances, else ``sensor_combined``), in the file's order. Another format, or a file without
    any, is an :class:`InputError`."""
    p = Path(path)
    kind = _multi_kind(p, "listing IMU topics")
    if kind == "bag":
        from gmwm.readers.rosbag import imu_bag_topics

        return [t.topic for t in imu_bag_topics(p)]
    if kind == "dataflash":
        from gmwm.readers.dataflash import dataflash_imu_topics

        return dataflash_imu_topics(p)
    if kind == "phone":
        from gmwm.readers.phone import phone_topics

        return phone_topics(p)
    from gmwm.readers.ulog import ulog_imu_topics

    return ulog_imu_topics(p)


def read_recordings(path: str | os.PathLike, topics: str | Sequence[str] = "all", *,
                    columns: Any = None, freq: float | None = None,
                    units: str | Mapping[str, str] | None = None) -> dict[str, Recording]:
    """Several IMU streams of one ROS bag or PX4 ULog, the file opened and indexed once.

    ``topics``: ``"all"`` (every stream of :func:`imu_topics`) or a list of topic names.
    Returns topic -> :class:`Recording` in the file's order (``"all"``) or the order given;
    ``columns``, ``freq`` and ``units`` apply to every topic as in :func:`read_recording`. An
    unknown or repeated topic, or another file format, is an :class:`InputError`."""
    p = Path(path)
    kind = _multi_kind(p, "several topics (--topic all)")
    if not isinstance(topics, str) and not all(isinstance(t, str) for t in topics):
        raise InputError("topics must be 'all' or a list of topic names")
    if kind == "bag":
        from gmwm.readers.rosbag import read_bag_topics

        fmt = _bag_format(p)
        return {t: _from_bag(p, d, columns, freq, units, fmt)
                for t, d in read_bag_topics(p, topics).items()}
    if kind == "dataflash":
        from gmwm.readers.dataflash import read_dataflash_topics

        return {t: _from_dataflash(p, d, columns, freq, units)
                for t, d in read_dataflash_topics(p, topics).items()}
    if kind == "phone":
        from gmwm.readers.phone import read_phone_topics

        recs = read_phone_topics(p, topics, freq=freq, units=units,
                                 read_recording=read_recording)
        return {t: r if columns is None else select_columns(r, columns) for t, r in recs.items()}
    from gmwm.readers.ulog import read_ulog_topics

    return {t: _from_ulog(p, u, columns, freq, units)
            for t, u in read_ulog_topics(p, topics).items()}


def read_recording(path: str | os.PathLike, *, topic: str | None = None, columns: Any = None,
                   dataset: str | None = None, freq: float | None = None,
                   time_unit: str | None = None,
                   units: str | Mapping[str, str] | None = None) -> Recording:
    """Read a recording of any supported format (see the module docstring).

    ``topic``: bag or ULog topic; ``columns``: None (the file's IMU axes, or its only data
    column), ``'all'``, or names / 0-based indices; ``dataset``: HDF5 dataset; ``freq``: the
    rate in Hz when the file has no stamps (checked against them otherwise); ``time_unit``: unit
    of an unlabelled time column ('s', 'ms', 'us', 'ns'); ``units``: one signal unit for all
    channels or a mapping channel -> unit (an unknown unit, or one contradicting the file, is an
    :class:`InputError`). Every problem is an :class:`InputError` with a one-line message."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"file not found: {p}")
    kind = _kind(p)
    if topic is not None and kind not in _MULTI:
        raise InputError(f"--topic applies to ROS bags and ULog files (also DataFlash logs and "
                         f"phone export folders), not to {p}")
    if time_unit is not None and time_unit not in ("s", "ms", "us", "ns"):
        raise InputError(f"unknown time unit {time_unit!r}; use s, ms, us or ns")
    if kind == "bag":
        from gmwm.readers.rosbag import read_bag

        return _from_bag(p, read_bag(p, topic), columns, freq, units)
    if kind == "ulog":
        from gmwm.readers.ulog import read_ulog

        return _from_ulog(p, read_ulog(p, topic), columns, freq, units)
    if kind == "dataflash":
        from gmwm.readers.dataflash import read_dataflash

        return _from_dataflash(p, read_dataflash(p, topic), columns, freq, units)
    if kind == "phone":
        from gmwm.readers.phone import read_phone_folder, read_phone_topics

        if topic is not None:
            rec = read_phone_topics(p, [topic], freq=freq, units=units,
                                    read_recording=read_recording)
            return select_columns(next(iter(rec.values())), columns)
        return read_phone_folder(p, columns=columns, freq=freq, units=units,
                                 read_recording=read_recording, finish=_finish,
                                 select=_select)
    if kind == "text":
        return _from_table(p, columns, time_unit, freq, units)
    if kind == "npz":
        return _from_npz(p, columns, time_unit, freq, units)
    return _from_io(p, kind, columns, dataset, freq, units)


def select_columns(rec: Recording, columns: Any) -> Recording:
    """``rec`` with only ``columns`` (None or 'all': every one; names or 0-based indices)."""
    if columns is None:
        return rec
    names = _select(list(rec.channels), columns, Path(rec.path), default_all=True)
    return replace(rec, channels={n: rec.channels[n] for n in names},
                   units={n: rec.units[n] for n in names}, roles={n: rec.roles[n] for n in names})


def with_units(rec: Recording, units: Mapping[str, str | None]) -> Recording:
    """A copy of ``rec`` with units (and roles) set for some channels (validated)."""
    out_u, out_r = dict(rec.units), dict(rec.roles)
    for c, u in units.items():
        parsed = parse_unit(u)
        out_u[c] = None if parsed is None else (parsed[0] if parsed[1] == 1.0 else u)
        out_r[c] = None if parsed is None else parsed[2]
    return replace(rec, units=out_u, roles=out_r)


def time_window(start_s: float | None, end_s: float | None, last: float, where: str
                ) -> tuple[float, float]:
    """``--start/--end`` in seconds since the first sample, checked against a recording whose
    last sample is at ``last`` s: ``(a, b)`` with ``b`` infinite when open; an empty or
    out-of-range request is an :class:`InputError` (shared by recordings and streamed files)."""
    a = 0.0 if start_s is None else float(start_s)
    b = math.inf if end_s is None else float(end_s)
    if a < 0 or not b > a:
        raise InputError(f"--start {a:g} / --end {b:g}: need 0 <= start < end (seconds since "
                         "the first sample)")
    if a > last:
        raise InputError(f"--start {a:g} s is after the end of {where} ({last:.6g} s)")
    return a, b


def sample_range(rec: Recording, start_s: float | None, end_s: float | None) -> tuple[int, int]:
    """Samples ``(i0, i1)`` whose time (seconds since the first sample) lies in
    [``start_s``, ``end_s``); None: from the first / to the last sample. An empty or
    out-of-range request is an :class:`InputError`."""
    t = rec.time_s
    if t is None:
        raise InputError(f"{rec.path} has no time stamps and no sampling rate: --start/--end "
                         "need --freq (Hz)")
    a, b = time_window(start_s, end_s, float(t[-1]) if t.size else 0.0, str(rec.path))
    i0, i1 = int(np.searchsorted(t, a, "left")), int(np.searchsorted(t, b, "left"))
    if i1 - i0 < 2:
        raise InputError(f"--start/--end select {i1 - i0} sample(s) of {rec.path}")
    return i0, i1


def select_samples(rec: Recording, i0: int, i1: int) -> Recording:
    """Samples ``i0:i1`` of ``rec`` (channels, times, temperature), its time base measured on
    them (gaps, jitter, duration) with the rate and its source of the whole recording."""
    if not 0 <= i0 < i1 <= rec.n:
        raise InputError(f"sample range {i0}:{i1} outside 0:{rec.n}")
    if (i0, i1) == (0, rec.n):
        return rec
    tb = rec.time
    if tb is not None and rec.time_s is not None and tb.unit is not None and i1 - i0 >= 2:
        sub = time_base(rec.time_s[i0:i1] - rec.time_s[i0], unit="s",
                        where=f"samples {i0}-{i1 - 1} of {rec.path}")
        tb = replace(sub, freq=tb.freq, source=tb.source, unit=tb.unit, rate_given=tb.rate_given,
                     start_s=(tb.start_s or 0.0) + float(rec.time_s[i0]), notes=())
    elif tb is not None:
        tb = replace(time_from_freq(tb.freq, i1 - i0, tb.source), notes=())
    return replace(rec, channels={c: x[i0:i1] for c, x in rec.channels.items()}, time=tb,
                   time_s=None if rec.time_s is None else rec.time_s[i0:i1],
                   temperature=None if rec.temperature is None else rec.temperature[i0:i1])
