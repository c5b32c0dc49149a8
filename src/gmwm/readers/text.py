"""Delimited text recordings, read by pandas' C parser.

What is recognised, from the first lines of the file:

* the separator: ``,`` ``;`` tab or blanks; with ``;`` or tab, numbers written with a decimal
  comma (``0,0123``) are read as such;
* gzip compression (by its magic bytes, whatever the suffix: ``imu.csv.gz``);
* a header, also when it is a ``#`` comment line (EuRoC / TUM-VI: ``#timestamp [ns],w_RS_S_x
  [rad s^-1],...,a_RS_S_x [m s^-2]``); a unit in brackets or parentheses after a column name is
  read with :func:`gmwm.units.parse_unit` (``rad s^-1`` = rad/s, ``m s^-2`` = m/s^2) or, for
  a time column, :func:`gmwm.readers.timebase.time_column`;
* ``rostopic echo -p`` output of a ``sensor_msgs/Imu`` topic (``%time,field.header.stamp,...,
  field.angular_velocity.x,...``): the gyroscope (rad/s) and accelerometer (m/s^2) axes by ROS's
  REP 103, time from ``field.header.stamp`` (ns).

Integer columns (nanosecond stamps) are read as int64, never through float64.
"""

from __future__ import annotations

import gzip
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gmwm.errors import InputError
from gmwm.readers.timebase import time_column
from gmwm.units import parse_unit

__all__ = ["Table", "imu_column", "read_text_table", "temperature_column"]

_SNIFF_LINES = 64
_UNIT_SUFFIX = re.compile(r"^(?P<name>.*?)\s*[\[(](?P<unit>[^\])]*)[\])]\s*$")
_TEMPERATURE = re.compile(r"^(imu[_ .]?|sensor[_ .]?|board[_ .]?)?(temp|temperature)"
                          r"([_ .]?(c|degc|celsius|k|kelvin|f))?$", re.IGNORECASE)
_TEMP_UNITS = {"c": "C", "degc": "C", "°c": "C", "celsius": "C", "deg c": "C", "k": "K",
               "kelvin": "K", "f": "F", "degf": "F", "°f": "F"}
_ROS_IMU = {"field.angular_velocity.x": "gx", "field.angular_velocity.y": "gy",
            "field.angular_velocity.z": "gz", "field.linear_acceleration.x": "ax",
            "field.linear_acceleration.y": "ay", "field.linear_acceleration.z": "az"}


@dataclass(frozen=True)
class Table:
    """Columns of a text recording: ``columns`` name -> array (numbers, or object for text),
    ``units`` name -> signal unit from the header (None when it gives none or an unknown one),
    ``time`` name -> time unit ('s', 'ms', 'us', 'ns' or None: unlabelled) of every time column,
    ``kind`` 'euroc', 'rostopic' or 'csv', ``notes`` things the user should know,
    ``temperature`` name -> 'C'/'K'/'F' of every temperature column, ``unit_text`` name -> the
    unit written in the header (known or not), ``raw_names`` name -> the header field."""

    columns: dict[str, np.ndarray]
    units: dict[str, str | None]
    time: dict[str, str | None]
    kind: str
    header: bool
    notes: tuple[str, ...] = ()
    temperature: tuple[tuple[str, str], ...] = ()
    unit_text: dict[str, str] = field(default_factory=dict)
    raw_names: dict[str, str] = field(default_factory=dict)


def temperature_column(name: str, unit: str | None = None) -> tuple[bool, str]:
    """Whether a column (name without its bracketed unit, and that unit) holds a temperature:
    ``temp``, ``temperature``, ``imu_temp``, ``temp_c``, ... ; and its scale 'C', 'K' or 'F'
    (default C)."""
    m = _TEMPERATURE.match(name.strip())
    if m is None:
        return False, "C"
    u = (unit or m.group(4) or "c").strip().lower()
    return True, _TEMP_UNITS.get(u, "C")


def _open_text(p: Path) -> tuple[bytes, bool]:
    with open(p, "rb") as fh:
        head = fh.read(2)
    return head, head == b"\x1f\x8b"


def _first_lines(p: Path, gz: bool) -> list[str]:
    opener = gzip.open if gz else open
    lines: list[str] = []
    try:
        with opener(p, "rt", encoding="utf-8", errors="strict", newline="") as fh:
            for line in fh:
                lines.append(line.rstrip("\r\n"))
                if len(lines) >= _SNIFF_LINES:
                    break
    except UnicodeDecodeError:
        raise InputError(f"cannot read {p}: not UTF-8 text (a binary file with a text suffix?)"
                         ) from None
    except (OSError, EOFError) as exc:
        raise InputError(f"cannot read {p}: {exc}") from None
    return lines


def _is_number(field: str, decimal: str) -> bool:
    f = field.strip().strip('"')
    if decimal == ",":
        f = f.replace(",", ".")
    try:
        float(f)
    except ValueError:
        return False
    return True


def _split(line: str, sep: str) -> list[str]:
    return line.split() if sep == r"\s+" else line.split(sep)


def _sniff(lines: list[str], p: Path) -> tuple[str, str, int, list[str] | None]:
    """(separator, decimal mark, rows to skip before the data, header fields or None)."""
    body = [(i, ln) for i, ln in enumerate(lines) if ln.strip()]
    if not body:
        raise InputError(f"{p} is empty")
    data = [(i, ln) for i, ln in body if not ln.lstrip().startswith("#")]
    if not data:
        raise InputError(f"{p} holds only comment lines, no data")
    sample = [ln for _, ln in data[1:9]] or [data[0][1]]
    if any(";" in ln for ln in sample):
        sep = ";"
    elif any("\t" in ln for ln in sample):
        sep = "\t"
    elif any("," in ln for ln in sample):
        sep = ","
    else:
        sep = r"\s+"
    decimal = "," if sep != "," and any(re.search(r"\d,\d", ln) for ln in sample) else "."
    # the data open at the first line of numbers; with a text column (the frame_id of
    # rostopic echo -p) at the line after the first non-comment line
    start = next((i for i, ln in data if all(_is_number(f, decimal)
                                             for f in _split(ln.strip(), sep))), None)
    if start is None:
        if len(data) < 2:
            raise InputError(f"{p} has a header but no data rows")
        start = data[1][0]
    before = [ln for i, ln in body if i < start]
    if not before:
        return sep, decimal, start, None
    line = before[-1].strip()
    comment = line.startswith("#")
    fields = [f.strip().strip('"').strip("'") for f in _split(line.lstrip("#").strip(), sep)]
    n_data = len(_split(lines[start].strip(), sep))
    if len(fields) == n_data and not all(_is_number(f, decimal) for f in fields):
        return sep, decimal, start, fields
    if not comment:
        raise InputError(f"{p}: the header has {len(fields)} fields but the data rows have "
                         f"{n_data} (separator {sep!r})")
    return sep, decimal, start, None


def read_text_table(path: str | Path) -> Table:
    """Read a delimited text recording (see the module docstring)."""
    import pandas as pd

    p = Path(path)
    _, gz = _open_text(p)
    lines = _first_lines(p, gz)
    sep, decimal, start, header = _sniff(lines, p)
    try:
        df = pd.read_csv(p, sep=sep, decimal=decimal, header=None, skiprows=start,
                         compression="gzip" if gz else None, engine="c", comment="#",
                         skipinitialspace=True, skip_blank_lines=True)
    except (pd.errors.ParserError, ValueError, UnicodeDecodeError, EOFError, OSError) as exc:
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"cannot parse {p}: {first}") from None
    except pd.errors.EmptyDataError:
        raise InputError(f"{p} has no data rows") from None
    names = header if header is not None else [str(i) for i in range(df.shape[1])]
    if len(names) != df.shape[1]:
        raise InputError(f"{p}: the header names {len(names)} columns but the rows have "
                         f"{df.shape[1]}")
    columns: dict[str, np.ndarray] = {}
    units: dict[str, str | None] = {}
    time: dict[str, str | None] = {}
    notes: list[str] = []
    temps: list[tuple[str, str]] = []
    unit_texts: dict[str, str] = {}
    raw_names: dict[str, str] = {}
    rostopic = header is not None and any(n in _ROS_IMU for n in names)
    euroc = header is not None and any(ln.lstrip().startswith("#") and ln.lstrip()[1:2] != "#"
                                       for ln in lines[:start] if ln.strip())
    for i, raw in enumerate(names):
        name, unit_text = raw, None
        m = _UNIT_SUFFIX.match(raw)
        if m and m.group("name"):
            name, unit_text = m.group("name").strip(), m.group("unit").strip()
        if rostopic and raw in _ROS_IMU:
            name = _ROS_IMU[raw]
            unit_text = "rad/s" if name[0] == "g" else "m/s^2"
        if name in columns:
            raise InputError(f"{p}: column name {name!r} appears twice in the header")
        col = df.iloc[:, i]
        is_time, tunit = time_column(raw if unit_text is None else f"{name} [{unit_text}]")
        if not is_time:
            is_time, tunit = time_column(name)
        if is_time:
            time[name] = tunit
            units[name] = None
        elif temperature_column(name, unit_text)[0]:
            units[name] = None  # a temperature, not a signal unit (Recording.temperature)
            temps.append((name, temperature_column(name, unit_text)[1]))
        else:
            try:
                parsed = parse_unit(unit_text) if unit_text else None
            except InputError:  # a magnetometer's uT, an angle's deg: said when it is read
                parsed = None
            units[name] = None if parsed is None else (
                parsed[0] if parsed[1] == 1.0 else unit_text)
        if unit_text is not None:
            unit_texts[name] = unit_text
        raw_names[name] = raw
        if col.dtype.kind in "iu":
            columns[name] = col.to_numpy(dtype=np.int64)
        elif col.dtype.kind == "f":
            columns[name] = col.to_numpy(dtype=np.float64)
        else:
            columns[name] = col.to_numpy()
    kind = "rostopic" if rostopic else ("euroc" if euroc and time else "csv")
    return Table(columns, units, time, kind, header is not None, tuple(notes), tuple(temps),
                 unit_texts, raw_names)


#: words of a column name marking a norm of the axes, or a quantity other than an IMU axis
#: (ignored when the IMU axes are chosen from the header)
_NORM = re.compile(r"absolute|norm|magnitude|\babs\b|total", re.IGNORECASE)
_NOT_IMU = re.compile(r"magnet|\bmag\b|compass|quat|orient|roll|pitch|yaw|euler|heading|attitude"
                      r"|pressure|baro|light|\blux|proxim|gps|latitude|longitude|altitude|speed"
                      r"|humid|\bq[wxyz0-3]?\b", re.IGNORECASE)
_GYRO_WORD = re.compile(r"gyr|angular|rotation|omega", re.IGNORECASE)
_ACC_WORD = re.compile(r"acc|linear", re.IGNORECASE)
_AXIS = re.compile(r"(?:^|[^a-z])(?P<pre>gyro|gyr|acc|accel|w|a|g|omega)?_?(?P<axis>[xyz])$",
                   re.IGNORECASE)


def imu_column(name: str, unit: str | None) -> tuple[str | None, str | None]:
    """What a column named ``name`` (its unit removed) with signal unit ``unit`` (a
    :func:`gmwm.datasheet.parse_unit` key or None) holds: ``(role, axis)`` with role
    'gyroscope', 'accelerometer', 'other' (a norm of the axes, a magnetometer, an orientation, a
    quaternion, ...) or None (unknown), axis 'x'/'y'/'z' or None. A name whose sensor
    contradicts its unit ('Gyroscope X (g)') is an :class:`InputError`."""
    n = name.strip()
    if _NORM.search(n):
        return "other", None
    by_name = ("gyroscope" if _GYRO_WORD.search(n) else
               "accelerometer" if _ACC_WORD.search(n) else None)
    m = _AXIS.search(n)
    axis = m.group("axis").lower() if m else None
    if by_name is None and _NOT_IMU.search(n):
        return "other", None
    if by_name is None and m is not None and m.group("pre"):
        pre = m.group("pre").lower()
        by_name = "gyroscope" if pre in ("gyro", "gyr", "w", "g", "omega") else "accelerometer"
    by_unit = None if unit is None else parse_unit(unit)[2]
    if by_unit is not None and by_name is not None and by_unit != by_name:
        raise InputError(f"column '{name}' is named like a {by_name} axis but its unit {unit} is "
                         f"a {by_unit} unit: fix the header or choose columns with --columns")
    return by_unit or by_name, axis


def numeric(table: Table, name: str, where: str) -> np.ndarray:
    """Column ``name`` as numbers; a text cell is an error naming its row."""
    col = table.columns[name]
    if col.dtype.kind in "iuf":
        return col
    import pandas as pd

    num = pd.to_numeric(pd.Series(col), errors="coerce")
    bad = np.flatnonzero(num.isna().to_numpy() & pd.notna(pd.Series(col)).to_numpy())
    if bad.size:
        raise InputError(f"column '{name}' of {where} is not numeric: row {int(bad[0]) + 1} "
                         f"holds {col[bad[0]]!r}")
    return num.to_numpy(dtype=np.float64)

