"""ArduPilot DataFlash logs (binary ``.bin``, text ``.log``) through pymavlink's ``DFReader``.

IMU streams: the ``IMU`` message of each instance, named ``IMU[0]``, ``IMU[1]``, ... whatever the
firmware's layout:

* older firmware logs one message per IMU, ``IMU``, ``IMU2``, ``IMU3`` (= ``IMU[0..2]``);
* newer firmware logs one ``IMU`` message with an instance column ``I`` (marked ``#`` in its
  FMTU units when logged).

Columns read: ``TimeUS`` (microseconds since boot, the stamps; ``TimeMS``, milliseconds, in logs
of firmware before 2015), ``GyrX/Y/Z`` (rad/s),
``AccX/Y/Z`` (m/s^2, logged ``m/s/s``) and ``T`` (deg C, the IMU temperature). When the log
carries FMTU units, they are checked to be those. A binary log is indexed by pymavlink (message
formats and the offset of every message) and its IMU messages decoded as NumPy records at those
offsets; a text log is read message by message with ``DFReader_text``.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["DATAFLASH_MAGIC", "FlashData", "dataflash_imu_topics", "is_text_dataflash",
           "read_dataflash", "read_dataflash_topics"]

#: the first bytes of a binary log: message header 0xA3 0x95 and type 0x80 (FMT)
DATAFLASH_MAGIC = b"\xa3\x95\x80"
_IMU_NAME = re.compile(r"^IMU([23]?)$")
_TOPIC = re.compile(r"^\s*IMU\s*(?:\[\s*(\d+)\s*\]|(\d))?\s*$", re.IGNORECASE)
_AXES = {"gx": "GyrX", "gy": "GyrY", "gz": "GyrZ", "ax": "AccX", "ay": "AccY", "az": "AccZ"}
_UNITS_EXPECTED = {"GyrX": "rad/s", "GyrY": "rad/s", "GyrZ": "rad/s", "AccX": "m/s/s",
                   "AccY": "m/s/s", "AccZ": "m/s/s"}
#: numpy codes of the DataFlash format characters (pymavlink's FORMAT_TO_STRUCT) and their
#: multipliers
_NP = {"a": "V64", "b": "i1", "B": "u1", "g": "f2", "h": "i2", "H": "u2", "i": "i4", "I": "u4",
       "f": "f4", "n": "V4", "N": "V16", "Z": "V64", "c": "i2", "C": "u2", "e": "i4", "E": "u4",
       "L": "i4", "d": "f8", "M": "u1", "q": "i8", "Q": "u8"}


def is_text_dataflash(head: bytes) -> bool:
    """Whether the first bytes of a file are those of a text DataFlash log (``FMT, ...``)."""
    return head.lstrip(b"\xef\xbb\xbf \r\n").startswith(b"FMT,")


@dataclass
class FlashData:
    """Decoded IMU stream: ``stamp_us`` (int64, TimeUS), ``vectors`` (gx..az), ``units``."""

    topic: str
    stamp_us: np.ndarray
    vectors: dict[str, np.ndarray]
    units: dict[str, str]
    source: str
    notes: list[str] = field(default_factory=list)
    temperature: np.ndarray | None = None
    temperature_source: str = ""


@dataclass
class _Log:
    """A parsed log: per IMU message name its columns (arrays) and FMTU units."""

    path: Path
    columns: dict[str, dict[str, np.ndarray]]
    units: dict[str, dict[str, str]]
    notes: list[str]


def _reader(p: Path, text: bool) -> tuple[Any, str]:
    try:
        from pymavlink import DFReader
    except ModuleNotFoundError:
        raise InputError("reading ArduPilot DataFlash logs needs the package 'pymavlink': "
                         "pip install 'gmwm[recordings]'") from None
    base = DFReader.DFReader_text if text else DFReader.DFReader_binary

    class Reader(base):  # type: ignore[misc, valid-type]
        def init_clock(self) -> None:
            # the stamps are TimeUS: no wall clock is needed, and finding one parses every
            # message in Python when the log has no GPS time (a bench log: ~1 min per 1e6)
            self.clock = None
            self._rewind(keep_messages=True)

    said = io.StringIO()  # pymavlink prints what it skips (also from C): it becomes a note
    try:
        with _c_output() as c_said, contextlib.redirect_stdout(said), \
                contextlib.redirect_stderr(said):
            r = Reader(str(p))
    except Exception as exc:  # noqa: BLE001 - pymavlink raises bare exceptions on damaged logs
        msg = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"cannot read the DataFlash log {p}: {msg}") from None
    return r, said.getvalue() + c_said.getvalue()


@contextlib.contextmanager
def _c_output() -> Any:
    """Capture what is written to the file descriptors 1 and 2 (pymavlink's compiled indexer
    prints one line per damaged byte there) into the StringIO it yields, once the block ends."""
    out = io.StringIO()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no such descriptors (an embedded interpreter): nothing to capture
        yield out
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 1)
        os.dup2(tmp.fileno(), 2)
        try:
            yield out
        finally:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            tmp.seek(0)
            out.write(tmp.read().decode("utf-8", "replace"))


def _binary_columns(r: Any, name: str) -> dict[str, np.ndarray]:
    """Every column of message ``name`` of a binary log, decoded at pymavlink's offsets."""
    mtype = r.name_to_id[name]
    fmt = r.formats[mtype]
    dtype = np.dtype([(c, "<" + _NP[f]) for c, f in zip(fmt.columns, fmt.format, strict=False)])
    if dtype.itemsize != fmt.len - 3:
        raise InputError(f"{r.filehandle.name}: message {name} is {fmt.len} bytes long but its "
                         f"format {fmt.format!r} takes {dtype.itemsize + 3}")
    offs = np.asarray(r.offsets[mtype], dtype=np.int64)
    offs = offs[offs + fmt.len <= r.data_len]  # a message cut at the end of the log
    buf = np.frombuffer(r.data_map, dtype=np.uint8)
    rec = buf[offs[:, None] + 3 + np.arange(dtype.itemsize)].view(dtype).reshape(-1)
    out = {}
    for c, f, mult in zip(fmt.columns, fmt.format, fmt.msg_mults, strict=False):
        v = rec[c]
        if v.dtype.kind == "V":
            continue
        out[c] = v.astype(np.float64) * mult if mult is not None else v
    return out


def _text_columns(r: Any, names: list[str]) -> dict[str, dict[str, list]]:
    out: dict[str, dict[str, list]] = {n: {} for n in names}
    while True:
        m = r.recv_match(type=names)
        if m is None:
            return out
        cols = out[m.get_type()]
        for c in m.get_fieldnames():
            cols.setdefault(c, []).append(getattr(m, c))


def _open(p: Path) -> _Log:
    with open(p, "rb") as fh:
        head = fh.read(64)
    text = is_text_dataflash(head)
    r, said = _reader(p, text)
    try:
        names = sorted({f.name for f in r.formats.values() if _IMU_NAME.match(f.name)})
        fmts = {f.name: f for f in r.formats.values() if f.name in names}
        if text:
            raw = _text_columns(r, names)
            columns = {n: {c: np.asarray(v) for c, v in cols.items()} for n, cols in raw.items()}
        else:
            columns = {n: _binary_columns(r, n) for n in names}
    finally:
        with contextlib.suppress(Exception):
            r.close()
    notes = []
    skipped = [ln for ln in said.splitlines() if ln.strip()]
    if skipped:
        notes.append(f"{p}: damaged data skipped by pymavlink ({len(skipped)} report(s), "
                     f"first: {skipped[0].strip()})")
    units = {n: dict(zip(f.columns, f.units, strict=False)) if f.units else {}
             for n, f in fmts.items()}
    return _Log(p, columns, units, notes)


def _streams(log: _Log) -> list[tuple[str, str, int | None]]:
    """``(label, message, instance value or None)`` of every IMU stream, in instance order."""
    out = []
    for name, cols in log.columns.items():
        stamp = "TimeUS" if "TimeUS" in cols else "TimeMS"
        if not cols or stamp not in cols or cols[stamp].size == 0:
            continue
        if "I" in cols:
            for i in np.unique(cols["I"]):
                out.append((f"IMU[{int(i)}]", name, int(i)))
        else:
            k = _IMU_NAME.match(name).group(1)
            out.append((f"IMU[{int(k) - 1 if k else 0}]", name, None))
    return sorted(out, key=lambda s: int(s[0][4:-1]))


def _listing(streams: list[tuple[str, str, int | None]], log: _Log) -> str:
    parts = []
    for label, name, inst in streams:
        n = next(iter(log.columns[name].values())).size if inst is None else \
            int(np.count_nonzero(log.columns[name]["I"] == inst))
        alias = f" (message {name})" if inst is None and name != "IMU" else ""
        parts.append(f"{label}{alias}: {n} messages")
    return ", ".join(parts) or "none"


def _resolve(topic: str, streams: list[tuple[str, str, int | None]], log: _Log
             ) -> tuple[str, str, int | None]:
    m = _TOPIC.match(topic)
    if m is None:
        raise InputError(f"unknown DataFlash IMU topic {topic!r}: write IMU[N] (IMU[0], IMU[1], "
                         f"...) or IMU2/IMU3; {log.path} logs {_listing(streams, log)}")
    if m.group(1) is not None:
        want = int(m.group(1))
    elif m.group(2) is not None:  # IMU2, IMU3: the second and third IMU
        want = int(m.group(2)) - 1
    elif len(streams) == 1:
        return streams[0]
    else:
        raise InputError(f"{log.path} logs {len(streams)} IMUs: choose one with --topic IMU[N] "
                         f"({_listing(streams, log)}) or --topic all")
    for s in streams:
        if int(s[0][4:-1]) == want:
            return s
    raise InputError(f"topic IMU[{want}] not in {log.path} (IMUs logged: "
                     f"{_listing(streams, log)})")


def _extract(log: _Log, label: str, name: str, inst: int | None) -> FlashData:
    cols = log.columns[name]
    stamp = "TimeUS" if "TimeUS" in cols else "TimeMS"  # TimeMS: logs of firmware before 2015
    missing = [c for c in (stamp, *_AXES.values()) if c not in cols]
    if missing:
        raise InputError(f"message {name} of {log.path} lacks the column(s) {', '.join(missing)}")
    for c, u in log.units.get(name, {}).items():  # FMTU units, when logged: the SI ones
        want = _UNITS_EXPECTED.get(c)
        if want is not None and u and u != want:
            raise InputError(f"column {c} of message {name} in {log.path} is logged in {u}, "
                             f"not {want}: gmwm reads IMU messages in SI units")
    rows = slice(None) if inst is None else cols["I"] == inst
    stamps = np.asarray(cols[stamp][rows]).astype(np.int64) * (1000 if stamp == "TimeMS" else 1)
    vectors = {k: np.asarray(cols[c][rows], dtype=np.float64) for k, c in _AXES.items()}
    u = {k: ("rad/s" if k[0] == "g" else "m/s^2") for k in vectors}
    temp, tsrc = None, ""
    if "T" in cols:
        t = np.asarray(cols["T"][rows], dtype=np.float64)
        if t.size and np.all(np.isfinite(t)) and np.any(t != 0):  # all zero: not logged
            temp, tsrc = t, f"column T of {label}"
    where = name if inst is None else f"{name} with I = {inst}"
    return FlashData(label, stamps, vectors, u, f"{stamp} of {where}", list(log.notes), temp,
                     tsrc)


def dataflash_imu_topics(path: str | os.PathLike) -> list[str]:
    """The IMU streams of a DataFlash log, ``IMU[0]``, ``IMU[1]``, ... (see the module
    docstring); none is an :class:`InputError`."""
    p = Path(path)
    log = _open(p)
    found = _streams(log)
    if not found:
        raise InputError(f"{p} logs no IMU message (IMU, IMU2, IMU3)")
    return [s[0] for s in found]


def read_dataflash_topics(path: str | os.PathLike, topics: str | Sequence[str] = "all"
                          ) -> dict[str, FlashData]:
    """Several IMU streams of a DataFlash log, parsed once: ``"all"`` or names as
    :func:`read_dataflash` takes them; label -> :class:`FlashData` in the order asked."""
    p = Path(path)
    log = _open(p)
    streams = _streams(log)
    if not streams:
        raise InputError(f"{p} logs no IMU message (IMU, IMU2, IMU3)")
    if isinstance(topics, str) and topics.strip().lower() == "all":
        chosen = streams
    else:
        wanted = [topics] if isinstance(topics, str) else list(topics)
        if not wanted:
            raise InputError("no topic given")
        chosen = [_resolve(t, streams, log) for t in wanted]
    out: dict[str, FlashData] = {}
    for label, name, inst in chosen:
        if label in out:
            raise InputError(f"topic {label} requested twice")
        out[label] = _extract(log, label, name, inst)
    return out


def read_dataflash(path: str | os.PathLike, topic: str | None = None) -> FlashData:
    """One IMU stream of a DataFlash log: ``topic`` ``IMU[N]`` (also ``IMU2``, ``IMU3``; ``IMU``
    or None when the log has a single IMU)."""
    p = Path(path)
    log = _open(p)
    streams = _streams(log)
    if not streams:
        raise InputError(f"{p} logs no IMU message (IMU, IMU2, IMU3)")
    label, name, inst = _resolve(topic or "IMU", streams, log)
    return _extract(log, label, name, inst)
