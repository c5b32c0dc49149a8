"""PX4 ULog files through ``pyulog``.

Topics read: ``sensor_combined`` (``gyro_rad[0..2]`` rad/s, ``accelerometer_m_s2[0..2]`` m/s^2,
stamped by ``timestamp`` in microseconds since boot; its accelerometer relative timestamp is
checked to be constant), or the raw ``sensor_gyro`` (``x, y, z`` rad/s) / ``sensor_accel``
(``x, y, z`` m/s^2) topics of one instance (``multi_id``), each with its own ``timestamp_sample``
when logged (else ``timestamp``). Units, roles and time all come from the ULog message formats.

Temperature (deg C): the ``temperature`` field of ``sensor_gyro`` / ``sensor_accel``; for
``sensor_combined`` that of ``sensor_accel:0`` (else ``sensor_gyro:0``) interpolated on its stamps
(PX4 logs those topics at about 1 Hz), else the barometer's ``baro_temp_celcius`` of older logs
(the board temperature, labelled as such).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["ULOG_MAGIC", "UlogData", "read_ulog", "read_ulog_topics", "ulog_imu_topics"]

ULOG_MAGIC = b"ULog\x01\x12\x35"
_TOPICS = ("sensor_combined", "sensor_gyro", "sensor_accel")


@dataclass
class UlogData:
    """Decoded ULog topic: ``stamp_us`` (int64, us), ``vectors``, ``units``, ``roles``."""

    topic: str
    stamp_us: np.ndarray
    vectors: dict[str, np.ndarray]
    units: dict[str, str]
    roles: dict[str, str]
    stamp_field: str
    notes: list[str] = field(default_factory=list)
    temperature: np.ndarray | None = None
    temperature_source: str = ""


def _split_topic(topic: str) -> tuple[str, int | None]:
    name, _, inst = topic.partition(":")
    if inst:
        try:
            return name, int(inst)
        except ValueError:
            raise InputError(f"malformed ULog topic {topic!r}: write NAME or NAME:INSTANCE "
                             "(e.g. sensor_gyro:1)") from None
    return name, None


def _open(p: Path) -> tuple[Any, dict[tuple[str, int], Any], str]:
    """The parsed ULog (IMU topics only), its topics by (name, instance) and their listing."""
    try:
        from pyulog import ULog
    except ModuleNotFoundError:
        raise InputError("reading PX4 ULog files needs the package 'pyulog': "
                         "pip install 'gmwm[recordings]'") from None
    try:
        ulog = ULog(str(p), list(_TOPICS))
    except Exception as exc:  # noqa: BLE001 - pyulog raises bare exceptions on damaged files
        msg = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"cannot read the ULog {p}: {msg}") from None
    have = {(d.name, d.multi_id): d for d in ulog.data_list}
    listing = ", ".join(f"{n}:{i} ({d.data['timestamp'].size} messages)"
                        for (n, i), d in sorted(have.items())) or "none"
    return ulog, have, listing


def _streams(have: dict[tuple[str, int], Any]) -> list[tuple[str, int]]:
    """The IMU streams of a log (see :func:`ulog_imu_topics`)."""
    raw = sorted(((n, i) for n, i in have if n != "sensor_combined"),
                 key=lambda k: (k[1], k[0] != "sensor_gyro"))
    return raw or sorted(k for k in have if k[0] == "sensor_combined")


def _label(name: str, inst: int) -> str:
    return name if name == "sensor_combined" and inst == 0 else f"{name}:{inst}"


def ulog_imu_topics(path: str | os.PathLike) -> list[str]:
    """The IMU streams of a PX4 ULog: every logged instance of ``sensor_gyro`` and
    ``sensor_accel`` (``sensor_gyro:0``, ``sensor_accel:0``, ``sensor_gyro:1``, ... by instance),
    else ``sensor_combined``. The raw topics are preferred because ``sensor_combined`` repeats the
    primary IMU's data; a gyroscope and an accelerometer instance stay separate streams (each has
    its own stamps). None logged is an :class:`InputError`."""
    p = Path(path)
    have = _open(p)[1]
    found = _streams(have)
    if not found:
        raise InputError(f"{p} logs no IMU topic ({', '.join(_TOPICS)})")
    return [_label(n, i) for n, i in found]


def read_ulog_topics(path: str | os.PathLike, topics: str | Sequence[str] = "all"
                     ) -> dict[str, UlogData]:
    """Read several IMU topics of a PX4 ULog, parsed once: ``topics`` ``"all"`` (the streams of
    :func:`ulog_imu_topics`) or names as :func:`read_ulog` takes them. Returns label ->
    :class:`UlogData` (labels ``sensor_combined``, ``sensor_gyro:1``, ...) in the order asked."""
    p = Path(path)
    ulog, have, listing = _open(p)
    if isinstance(topics, str) and topics.strip().lower() == "all":
        wanted = [_label(n, i) for n, i in _streams(have)]
        if not wanted:
            raise InputError(f"{p} logs no IMU topic ({', '.join(_TOPICS)})")
    else:
        wanted = [topics] if isinstance(topics, str) else list(topics)
        if not wanted:
            raise InputError("no topic given")
    out: dict[str, UlogData] = {}
    for t in wanted:
        d = _extract(p, ulog, have, listing, t)
        if d.topic in out:
            raise InputError(f"topic {d.topic} requested twice")
        out[d.topic] = d
    return out


def read_ulog(path: str | os.PathLike, topic: str | None = None) -> UlogData:
    """Read the IMU topic of a PX4 ULog. ``topic``: ``sensor_combined`` (default when logged),
    ``sensor_gyro`` or ``sensor_accel``, optionally ``:INSTANCE`` (``sensor_gyro:1``)."""
    p = Path(path)
    ulog, have, listing = _open(p)
    return _extract(p, ulog, have, listing, topic)


def _extract(p: Path, ulog: Any, have: dict[tuple[str, int], Any], listing: str,
             topic: str | None) -> UlogData:
    """The IMU topic ``topic`` (see :func:`read_ulog`) of the parsed log."""
    if topic is None:
        if ("sensor_combined", 0) in have:
            name, inst = "sensor_combined", 0
        else:
            raise InputError(f"{p} has no sensor_combined topic; choose one with --topic "
                             f"(IMU topics logged: {listing})")
    else:
        name, inst = _split_topic(topic)
        if name not in _TOPICS:
            raise InputError(f"gmwm reads the ULog topics {', '.join(_TOPICS)}, not {name!r}")
        insts = sorted(i for n, i in have if n == name)
        if inst is None:
            if len(insts) > 1:
                raise InputError(f"{p} logs {len(insts)} instances of {name}: choose one with "
                                 f"--topic {name}:N (logged: {listing})")
            inst = insts[0] if insts else 0
        if (name, inst) not in have:
            raise InputError(f"topic {name}:{inst} not in {p} (IMU topics logged: {listing})")
    d = have[(name, inst)].data
    notes: list[str] = []
    if name == "sensor_combined":
        fields = {"gx": "gyro_rad[0]", "gy": "gyro_rad[1]", "gz": "gyro_rad[2]",
                  "ax": "accelerometer_m_s2[0]", "ay": "accelerometer_m_s2[1]",
                  "az": "accelerometer_m_s2[2]"}
        rel = d.get("accelerometer_timestamp_relative")
        if rel is not None and rel.size and np.any(rel != rel[0]):
            notes.append(f"{name} of {p}: the accelerometer is sampled at varying offsets from "
                         "the gyroscope (accelerometer_timestamp_relative); the gyroscope "
                         "stamps are used for both")
    else:
        prefix = "g" if name == "sensor_gyro" else "a"
        fields = {f"{prefix}{c}": c for c in "xyz"}
    missing = [f for f in fields.values() if f not in d]
    if missing:
        raise InputError(f"{name} of {p} lacks the field(s) {', '.join(missing)}")
    stamp_field = "timestamp_sample" if "timestamp_sample" in d else "timestamp"
    vectors = {k: np.asarray(d[f], dtype=np.float64) for k, f in fields.items()}
    units = {k: ("rad/s" if k[0] == "g" else "m/s^2") for k in vectors}
    roles = {k: ("gyroscope" if k[0] == "g" else "accelerometer") for k in vectors}
    if ulog.dropouts:
        lost = sum(getattr(x, "duration", 0) for x in ulog.dropouts)
        notes.append(f"{p}: the logger reports {len(ulog.dropouts)} dropout(s) ({lost} ms in all)")
    label = _label(name, inst)
    stamps = np.asarray(d[stamp_field], dtype=np.int64)
    temp, source = _temperature(have, name, d, stamps, label)
    return UlogData(label, stamps, vectors, units, roles, stamp_field, notes, temp, source)


def _temperature(have: dict, name: str, d: dict, stamps: np.ndarray, label: str
                 ) -> tuple[np.ndarray | None, str]:
    """Temperature per IMU sample (deg C) and where it comes from (see the module docstring)."""
    if "temperature" in d and np.any(d["temperature"] != 0):  # all zero: not logged
        return np.asarray(d["temperature"], dtype=np.float64), f"temperature of {label}"
    if name != "sensor_combined":
        return None, ""
    for other in (("sensor_accel", 0), ("sensor_gyro", 0)):
        o = have.get(other)
        if o is not None and "temperature" in o.data and o.data["timestamp"].size >= 2:
            t = np.asarray(o.data["timestamp"], dtype=np.float64)
            v = np.asarray(o.data["temperature"], dtype=np.float64)
            ok = np.isfinite(v) & (v != 0)
            if ok.sum() >= 2:
                src = (f"temperature of {other[0]}:{other[1]} ({int(ok.sum())} messages, "
                       "interpolated)")
                return np.interp(stamps.astype(np.float64), t[ok], v[ok]), src
    if "baro_temp_celcius" in d and np.any(d["baro_temp_celcius"] != 0):
        return (np.asarray(d["baro_temp_celcius"], dtype=np.float64),
                "barometer temperature of sensor_combined (board temperature)")
    return None, ""
