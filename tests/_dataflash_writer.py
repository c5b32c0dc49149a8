"""A minimal ArduPilot DataFlash writer for tests (binary ``.bin`` and text ``.log``).

pymavlink reads DataFlash logs but writes none, so the test files are written here from the
documented layout (ArduPilot's "Downloading and analysing data logs" / the ``LogStructure.h``
format). Binary: every message is ``0xA3 0x95 <type id>`` followed by its fields packed
little-endian; type 0x80 is ``FMT`` (``Type B, Length B, Name 4s, Format 16s, Columns 64s``,
89 bytes in all), which defines each other message: its type id, total length, name, format
characters and comma-separated column names. ``UNIT`` (``Id b, Label Z``) and ``FMTU`` (``FmtType
B, UnitIds N, MultIds N``) give the column units; a ``#`` in UnitIds marks the instance column.
Text (what Mission Planner writes as ``.log``): one line per message, ``NAME, v1, v2, ...``, the
``FMT`` lines first.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: format character -> struct code (DataFlash ``LogStructure.h``), the ones the tests use
_CODES = {"Q": "Q", "q": "q", "B": "B", "b": "b", "H": "H", "h": "h", "I": "I", "i": "i",
          "f": "f", "d": "d", "n": "4s", "N": "16s", "Z": "64s"}
HEAD = b"\xa3\x95"
FMT_ID = 0x80

#: ArduPilot 4.x: one IMU message, the instance in column I; older firmware: IMU, IMU2, IMU3
IMU_INSTANCE = ("QBffffffIIfBBHH", "TimeUS,I,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz")
IMU_OLD = ("QffffffIIfBBHH", "TimeUS,GyrX,GyrY,GyrZ,AccX,AccY,AccZ,EG,EA,T,GH,AH,GHz,AHz")
#: units of those columns (UNIT ids: s seconds, # instance, E rad/s, o m/s/s, O degC, z Hz)
IMU_INSTANCE_UNITS = ("s#EEEooo--O--zz", "F-000000-------")
IMU_OLD_UNITS = ("sEEEooo--O--zz", "F000000-------")
_UNITS = {"s": "s", "#": "instance", "E": "rad/s", "o": "m/s/s", "O": "degC", "z": "Hz",
          "-": ""}


@dataclass
class Message:
    """A message type: ``name`` (at most 4 characters), ``fmt`` format characters, ``columns``
    comma-separated, ``rows`` one tuple of values per message, ``units`` optional (UnitIds,
    MultIds) written as an FMTU message."""

    name: str
    fmt: str
    columns: str
    rows: Sequence[tuple]
    units: tuple[str, str] | None = None


def imu_rows(t_us: np.ndarray, gyro: np.ndarray, acc: np.ndarray, instance: int | None,
             temp: float = 25.0) -> list[tuple]:
    """Rows of an IMU message (``instance`` None: the old layout without column I)."""
    rows = []
    for k in range(t_us.size):
        head = (int(t_us[k]),) if instance is None else (int(t_us[k]), instance)
        rows.append((*head, *map(float, gyro[k]), *map(float, acc[k]), 0, 0, float(temp), 1, 1,
                     400, 400))
    return rows


def _struct(fmt: str) -> str:
    return "<" + "".join(_CODES[c] for c in fmt)


def _pack(fmt: str, row: tuple) -> bytes:
    vals = [v.encode() if isinstance(v, str) else v for v in row]
    return struct.pack(_struct(fmt), *vals)


def _fmt_msg(type_id: int, m: Message) -> bytes:
    length = 3 + struct.calcsize(_struct(m.fmt))
    return HEAD + bytes([FMT_ID]) + struct.pack("<BB4s16s64s", type_id, length, m.name.encode(),
                                                m.fmt.encode(), m.columns.encode())


def _with_units(messages: Sequence[Message]) -> list[Message]:
    """The messages plus UNIT / FMTU messages for those with ``units`` (FMTU refers to the
    type id, so the data messages' ids are fixed here: 1, 2, ... in order)."""
    if not any(m.units for m in messages):
        return list(messages)
    unit = Message("UNIT", "QbZ", "TimeUS,Id,Label",
                   [(0, ord(k), v) for k, v in _UNITS.items()])
    fmtu = Message("FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds",
                   [(0, i + 1, *m.units) for i, m in enumerate(messages) if m.units])
    return [*messages, unit, fmtu]


def write_dataflash_bin(path: Path, messages: Sequence[Message]) -> Path:
    """A binary DataFlash log: the FMT messages, then the UNIT/FMTU messages, then the data
    messages interleaved by their first column (TimeUS)."""
    msgs = _with_units(messages)
    out = bytearray()
    for i, m in enumerate(msgs):
        out += _fmt_msg(i + 1, m)
    rows = []
    for i, m in enumerate(msgs):
        for r in m.rows:
            rows.append((0 if m.name in ("UNIT", "FMTU") else int(r[0]), len(rows),
                         HEAD + bytes([i + 1]) + _pack(m.fmt, r)))
    for *_, b in sorted(rows):
        out += b
    path.write_bytes(bytes(out))
    return path


def _text(v: object) -> str:
    if isinstance(v, float):
        return repr(v)
    return str(v)


def write_dataflash_text(path: Path, messages: Sequence[Message]) -> Path:
    """A text DataFlash log (``.log``): ``FMT, type, length, name, format, columns`` lines, then
    one ``NAME, values`` line per message, interleaved by TimeUS."""
    msgs = _with_units(messages)
    lines = ["FMT, 128, 89, FMT, BBnNZ, Type,Length,Name,Format,Columns"]
    for i, m in enumerate(msgs):
        length = 3 + struct.calcsize(_struct(m.fmt))
        lines.append(f"FMT, {i + 1}, {length}, {m.name}, {m.fmt}, {m.columns}")
    rows = []
    for m in msgs:
        for r in m.rows:
            vals = list(r)
            if m.name == "UNIT":
                vals[1] = vals[1]  # the id stays a number (chr() of it names the unit)
            rows.append((0 if m.name in ("UNIT", "FMTU") else int(r[0]), len(rows),
                         ", ".join([m.name, *map(_text, vals)])))
    lines += [s for *_, s in sorted(rows)]
    path.write_text("\n".join(lines) + "\n")
    return path
