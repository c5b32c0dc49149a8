"""ROS 1 bags and ROS 2 bags (sqlite3 and MCAP storage) through ``rosbags``.

``rosbags`` parses the containers: bag and chunk headers, connections with their message types,
compression, and for ROS 2 the sqlite3 tables and the MCAP summary and chunk index. What is
decoded here is the payload of one topic, for all its messages at once: ``sensor_msgs/Imu`` and
``geometry_msgs/Vector3Stamped`` have a fixed layout once the length of ``header.frame_id`` is
known (ROS 1: packed little-endian; ROS 2: CDR with 8-byte alignment after the 4-byte
encapsulation header, little- or big-endian per message), so the stamps and the vectors are
gathered from the raw bytes with NumPy, grouped by message size, and every group is checked
(frame_id length against the size, encapsulation, record op codes and lengths) before it is
trusted; equally spaced messages (the usual case) are read through strided views of the
chunk, without index arrays. The sqlite3 rows of a topic are fetched a batch of table rows per SQL
aggregate (data concatenated, lengths and record times as text) instead of one Python object per
row, and put in record-time order as rosbag2 reads them. A bag the checks do not fit (a
compressed-per-message ROS 2 bag, an MCAP without chunk index, a sqlite3 database not in UTF-8)
is read through ``rosbags``' own per-message iterator, then decoded the same way.

Units and axis roles come from the message definition (REP 103): ``angular_velocity`` in rad/s
(gyroscope), ``linear_acceleration`` in m/s^2 (accelerometer). Time is ``header.stamp``; a topic
whose stamps are all zero falls back to the bag's record time, with a note.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import Any

import numpy as np

from gmwm.errors import InputError

__all__ = ["BagTopic", "TopicData", "bag_topics", "imu_bag_topics", "read_bag", "read_bag_topics"]

IMU = "sensor_msgs/msg/Imu"
VECTOR3 = "geometry_msgs/msg/Vector3Stamped"
SUPPORTED = (IMU, VECTOR3)
_ROS1_MAGIC = b"#ROSBAG V2.0\n"
_MCAP_MAGIC = b"\x89MCAP0\r\n"
_SQLITE_MAGIC = b"SQLite format 3\x00"
_BLOCK = 65536  # messages gathered per NumPy block
_SQL_ROWS = 1 << 17  # table rows per SQL aggregate (bounds its blob)
_SQL_MMAP = 1 << 30  # SQLite memory-mapped I/O [bytes]


def _rosbags():
    try:
        import rosbags  # noqa: F401
    except ModuleNotFoundError:
        raise InputError("reading ROS bags needs the package 'rosbags': "
                         "pip install 'gmwm[recordings]'") from None


@dataclass(frozen=True)
class BagTopic:
    """A topic of a bag: name, message type, message count and mean rate [Hz] from the bag's
    record times (None for fewer than 2 messages)."""

    topic: str
    msgtype: str
    count: int
    rate: float | None


@dataclass
class TopicData:
    """Decoded messages of one topic: ``stamp_ns`` (int64 header stamps, or record times when
    the stamps are empty), ``vectors`` name -> float64 array, ``units`` and ``roles`` per vector,
    ``notes``."""

    topic: str
    msgtype: str
    stamp_ns: np.ndarray
    vectors: dict[str, np.ndarray]
    units: dict[str, str | None]
    roles: dict[str, str | None]
    stamp_source: str
    notes: list[str] = field(default_factory=list)


# --------------------------------------------------------------------------------------------------
# vectorised decoding of the fixed layouts
# --------------------------------------------------------------------------------------------------

def _stride(buf: np.ndarray, starts: np.ndarray, width: int) -> int | None:
    """The common spacing of ``starts`` when they are equally spaced (the usual case: one topic
    per chunk, one message size) and records of ``width`` bytes fit in ``buf``, else None."""
    n = starts.size
    if n == 0 or int(starts[0]) < 0 or int(starts[-1]) + width > buf.size:
        return None
    if n == 1:
        return width
    stride = int(starts[1] - starts[0])
    if stride < width or int(starts[-1] - starts[0]) != (n - 1) * stride:
        return None
    if n > 2 and not np.all(np.diff(starts) == stride):
        return None
    return stride


def _field(buf: np.ndarray, starts: np.ndarray, off: int, dtype: str, count: int = 1,
           stride: int | None = -1) -> np.ndarray:
    """The ``dtype`` value(s) (``count`` of them: shape (n, count) when count > 1) at byte
    ``off`` of every record ``buf[starts[i]:]``, as a new array. Equally spaced records are read
    through a strided view of ``buf``; others are gathered byte by byte."""
    dt = np.dtype(dtype)
    width = off + dt.itemsize * count
    if stride == -1:
        stride = _stride(buf, starts, width)
    if stride is not None and starts.size:
        shape = (starts.size, count) if count > 1 else (starts.size,)
        strides = (stride, dt.itemsize) if count > 1 else (stride,)
        return np.array(np.ndarray(shape, dtype=dt, buffer=buf, offset=int(starts[0]) + off,
                                   strides=strides))
    b = buf[(starts + off)[:, None] + np.arange(dt.itemsize * count)]
    out = np.ascontiguousarray(b).view(dt)
    return out.reshape(-1, count) if count > 1 else out.reshape(-1)


def _u32(buf: np.ndarray, pos: np.ndarray, big: bool = False) -> np.ndarray:
    return _field(buf, pos, 0, ">u4" if big else "<u4")


def _gather(buf: np.ndarray, starts: np.ndarray, fields: list[tuple[int, str]], big: bool
            ) -> list[np.ndarray]:
    """Gather the fields (byte offset from each start, 'u4'/'i4'/'3f8') of every message."""
    order = ">" if big else "<"
    width = max(off + (24 if k == "3f8" else 4) for off, k in fields)
    stride = _stride(buf, starts, width)
    if stride is not None or starts.size <= _BLOCK:
        return [_field(buf, starts, off, order + ("f8" if k == "3f8" else k),
                       3 if k == "3f8" else 1, stride) for off, k in fields]
    parts = [_gather(buf, starts[a:a + _BLOCK], fields, big)
             for a in range(0, starts.size, _BLOCK)]  # bounded index arrays
    return [np.concatenate([q[i] for q in parts]) for i in range(len(fields))]


def _layout(msgtype: str, cdr: bool, size: int, frame_len: int) -> int | None:
    """Byte offset of the first float64 after the header for a message of ``size`` bytes whose
    frame_id field holds ``frame_len`` bytes; None when the size does not fit the type."""
    tail = 296 if msgtype == IMU else 24
    if cdr:
        o = 4 + ((12 + frame_len + 7) // 8) * 8  # align 8 relative to the CDR payload
    else:
        o = 16 + frame_len
    return o if o + tail == size else None


def decode(buf: np.ndarray, starts: np.ndarray, sizes: np.ndarray, msgtype: str, cdr: bool,
           where: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Stamps [ns, int64] and vectors of messages ``buf[starts[i]:starts[i] + sizes[i]]``."""
    n = starts.size
    stamp = np.empty(n, dtype=np.int64)
    names = ("gx", "gy", "gz", "ax", "ay", "az") if msgtype == IMU else ("x", "y", "z")
    vec = {k: np.empty(n) for k in names}
    if n == 0:
        return stamp, vec
    hdr = 4 if cdr else 0  # CDR: the encapsulation header precedes the payload
    if cdr:
        enc = _field(buf, starts, 0, "u1", 2)
        bad = (enc[:, 0] != 0) | (enc[:, 1] > 1)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(f"{where}: message {i + 1} is not plain CDR (encapsulation "
                             f"{bytes(enc[i]).hex()}); gmwm reads CDR_LE and CDR_BE")
        big_all = enc[:, 1] == 0
    else:
        big_all = np.zeros(n, dtype=bool)
    if sizes.min() == sizes.max() and big_all.min() == big_all.max():
        groups = [(slice(None), int(sizes[0]), bool(big_all[0]))]  # the usual case: one group
    else:
        groups = [(sel, int(size), big) for size in np.unique(sizes) for big in (False, True)
                  if (sel := np.flatnonzero((sizes == size) & (big_all == big))).size]
    stamp_off = hdr + (0 if cdr else 4)
    frame_off = hdr + (8 if cdr else 12)
    for sel, size, big in groups:
        s = starts[sel]
        sec, nsec, flen = _gather(buf, s, [(stamp_off, "u4" if not cdr else "i4"),
                                           (stamp_off + 4, "u4"), (frame_off, "u4")], big)
        o = _layout(msgtype, cdr, size, int(flen[0]))
        if o is None or np.any(flen != flen[0]):
            raise InputError(f"{where}: {s.size} message(s) of {size} bytes do not have "
                             f"the {msgtype} layout (frame_id length {int(flen[0])})")
        if np.any(nsec >= 1_000_000_000):
            raise InputError(f"{where}: header.stamp nanoseconds of 1e9 or more (not a "
                             f"{msgtype} message?)")
        if msgtype == IMU:
            g, a = _gather(buf, s, [(o + 104, "3f8"), (o + 200, "3f8")], big)
            for k, arr in zip(names[:3], g.T, strict=True):
                vec[k][sel] = arr
            for k, arr in zip(names[3:], a.T, strict=True):
                vec[k][sel] = arr
        else:
            (v,) = _gather(buf, s, [(o, "3f8")], big)
            for k, arr in zip(names, v.T, strict=True):
                vec[k][sel] = arr
        stamp[sel] = sec.astype(np.int64) * 1_000_000_000 + nsec
    return stamp, vec


def _ints(text: str | bytes | None, count: int) -> np.ndarray | None:
    """The ``count`` integers of SQLite's comma-separated ``group_concat`` text, else None."""
    if text is None:
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            out = np.fromstring(text, dtype=np.int64, sep=",")
        except (ValueError, DeprecationWarning):
            return None
    return out if out.size == count else None


def _from_blobs(blobs: list[bytes]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sizes = np.fromiter(map(len, blobs), dtype=np.int64, count=len(blobs))
    starts = np.zeros(len(blobs), dtype=np.int64)
    if len(blobs) > 1:
        np.cumsum(sizes[:-1], out=starts[1:])
    return np.frombuffer(b"".join(blobs), dtype=np.uint8), starts, sizes


# --------------------------------------------------------------------------------------------------
# containers
# --------------------------------------------------------------------------------------------------

def bag_kind(path: Path) -> str | None:
    """'ros1', 'mcap', 'sqlite3' or 'ros2-dir' (a folder with metadata.yaml), else None."""
    if path.is_dir():
        return "ros2-dir" if (path / "metadata.yaml").is_file() else None
    with open(path, "rb") as fh:
        head = fh.read(16)
    if head.startswith(_ROS1_MAGIC[:9]):
        return "ros1"
    if head.startswith(_MCAP_MAGIC):
        return "mcap"
    if head.startswith(_SQLITE_MAGIC):
        return "sqlite3"
    return None


def _rate(count: int, t0: int, t1: int) -> float | None:
    return (count - 1) / ((t1 - t0) * 1e-9) if count > 1 and t1 > t0 else None


class _Ros1:
    """A ROS 1 bag opened with rosbags; the per-message index records are read as NumPy arrays
    (rosbags' own index reader builds one Python tuple per message)."""

    def __init__(self, path: Path) -> None:
        from rosbags.rosbag1 import reader as r1

        index: dict[int, list[tuple[int, np.ndarray]]] = {}

        class Reader(r1.Reader):
            def read_index_data(self, pos: int, indexes: Any) -> None:
                head = r1.Header.read(self.bio, r1.RecordType.IDXDATA)
                if head.get_uint32("ver") != 1:
                    raise r1.ReaderError("unsupported IDXDATA version")
                conn, count = head.get_uint32("conn"), head.get_uint32("count")
                size = r1.read_uint32(self.bio)
                if size != 12 * count:
                    raise r1.ReaderError("index data size does not match its count")
                raw = np.frombuffer(r1.read_bytes(self.bio, size), dtype=[
                    ("sec", "<u4"), ("nsec", "<u4"), ("offset", "<u4")])
                index.setdefault(conn, []).append((pos, raw))

        self.r1 = r1
        self.reader = Reader(path)
        self.index = index
        self.reader.open()

    def close(self) -> None:
        self.reader.close()

    def topics(self, rates: bool = True) -> list[tuple[Any, BagTopic]]:
        out = []
        for c in self.reader.connections:
            parts = self.index.get(c.id, [])
            count = sum(p[1].size for p in parts)
            t = [(p[1]["sec"].astype(np.int64) * 10**9 + p[1]["nsec"]) for p in parts if p[1].size]
            t0 = min(int(x.min()) for x in t) if t else 0
            t1 = max(int(x.max()) for x in t) if t else 0
            out.append((c, BagTopic(c.topic, c.msgtype, count, _rate(count, t0, t1))))
        return out

    def read(self, conn: Any, where: str) -> tuple[np.ndarray, dict[str, np.ndarray], Any]:
        stamps, vecs, rec = [], [], []
        bio = self.reader.bio
        for pos, raw in self.index.get(conn.id, []):
            chunk = self.reader.chunks[pos]
            bio.seek(chunk.datapos)
            data = chunk.decompressor(bio.read(chunk.datasize))
            buf = np.frombuffer(data, dtype=np.uint8)
            off = raw["offset"].astype(np.int64)
            if off.size == 0:
                continue
            if np.any(off + 8 > buf.size):
                raise InputError(f"{where}: index offsets point outside their chunk (damaged bag)")
            hl = _u32(buf, off).astype(np.int64)
            dl_pos = off + 4 + hl
            if np.any(dl_pos + 4 > buf.size):
                raise InputError(f"{where}: message records overrun their chunk (damaged bag)")
            dl = _u32(buf, dl_pos).astype(np.int64)
            starts = dl_pos + 4
            if np.any(starts + dl > buf.size):
                raise InputError(f"{where}: message data overrun their chunk (damaged bag)")
            for i in {0, off.size - 1}:  # the container's own parser checks the record ends
                head = self.r1.Header.read(BytesIO(data[off[i]:off[i] + 4 + hl[i]]))
                if head.get_uint8("op") != self.r1.RecordType.MSGDATA or \
                        head.get_uint32("conn") != conn.id:
                    raise InputError(f"{where}: an index entry does not point at a message of "
                                     "this topic (damaged bag)")
            s, v = decode(buf, starts, dl, conn.msgtype, False, where)
            stamps.append(s)
            vecs.append(v)
            rec.append(raw["sec"].astype(np.int64) * 10**9 + raw["nsec"].astype(np.int64))
        return _join(stamps, vecs, rec, conn.msgtype)


def _join(stamps: list[np.ndarray], vecs: list[dict[str, np.ndarray]], rec: list[np.ndarray],
          msgtype: str) -> tuple[np.ndarray, dict[str, np.ndarray], Any]:
    names = ("gx", "gy", "gz", "ax", "ay", "az") if msgtype == IMU else ("x", "y", "z")
    if not stamps:
        return (np.empty(0, np.int64), {k: np.empty(0) for k in names},
                lambda: np.empty(0, np.int64))
    return (np.concatenate(stamps), {k: np.concatenate([v[k] for v in vecs]) for k in names},
            lambda: np.concatenate(rec))


def _mcap_index(bio: Any, chunk: Any, cid: int) -> np.ndarray | None:
    """The MessageIndex record of channel ``cid`` in ``chunk``: (log time, offset) pairs."""
    bio.seek(chunk.message_index_offsets[cid])
    head = bio.read(15)
    if len(head) < 15 or head[0] != 0x07:
        return None
    rec_len = int.from_bytes(head[1:9], "little")
    n_bytes = int.from_bytes(head[11:15], "little")
    if int.from_bytes(head[9:11], "little") != cid or n_bytes % 16 or n_bytes + 6 > rec_len:
        return None
    return np.frombuffer(bio.read(n_bytes), dtype=[("t", "<u8"), ("off", "<u8")])


class _Ros2:
    """A ROS 2 bag (folder, .db3 or .mcap) opened with rosbags."""

    def __init__(self, path: Path) -> None:
        from rosbags.rosbag2 import Reader

        self.reader = Reader(path)
        self.reader.open()
        st = self.reader.storage
        self.storages = list(getattr(st, "storages", [st]))
        meta = getattr(st, "metadata", None)
        self.per_message_zstd = getattr(meta, "compression_mode", "") == "message"

    def close(self) -> None:
        self.reader.close()

    def _parts(self, conn: Any) -> list[tuple[Any, Any]]:
        return [(s, c) for s in self.storages for c in s.connections
                if c.topic == conn.topic and c.msgtype == conn.msgtype]

    def topics(self, rates: bool = True) -> list[tuple[Any, BagTopic]]:
        out = []
        for c in self.reader.connections:
            t0, t1 = None, None
            for s, sc in self._parts(c) if rates else ():
                lo, hi = self._span(s, sc)
                if lo is not None:
                    t0 = lo if t0 is None else min(t0, lo)
                    t1 = hi if t1 is None else max(t1, hi)
            rate = _rate(c.msgcount, t0, t1) if t0 is not None else None
            out.append((c, BagTopic(c.topic, c.msgtype, c.msgcount, rate)))
        return out

    @staticmethod
    def _span(storage: Any, conn: Any) -> tuple[int | None, int | None]:
        if hasattr(storage, "dbconn"):
            row = storage.dbconn.execute("SELECT MIN(timestamp), MAX(timestamp) FROM messages "
                                         "WHERE topic_id = ?", (conn.id,)).fetchone()
            return (row[0], row[1]) if row and row[0] is not None else (None, None)
        chunks = [c for c in getattr(storage, "chunks", []) if c.channel_count.get(conn.id)]
        idx = [_mcap_index(storage.bio, c, conn.id) for c in chunks
               if conn.id in c.message_index_offsets]
        times = [i["t"] for i in idx if i is not None and i.size]
        if times:
            return int(min(t.min() for t in times)), int(max(t.max() for t in times))
        return None, None

    def read(self, conn: Any, where: str) -> tuple[np.ndarray, dict[str, np.ndarray], Any]:
        stamps, vecs, rec = [], [], []
        parts = self._parts(conn)
        got_all: list[tuple] | None = []
        for storage, sc in parts:
            if self.per_message_zstd:
                got = None
            elif hasattr(storage, "dbconn"):
                got = self._sqlite(storage, sc)
            else:
                got = self._mcap(storage, sc, where)
            if got is None or got_all is None:
                got_all = None
                break
            got_all.extend(got)
        if got_all is None:  # the container's per-message iterator, in record-time order
            blobs, times = [], []
            for _, t, data in self.reader.messages([conn]):
                blobs.append(data)
                times.append(t)
            buf, starts, sizes = _from_blobs(blobs)
            got_all = [(buf, starts, sizes, np.asarray(times, dtype=np.int64))]
        elif parts and all(hasattr(st, "dbconn") for st, _ in parts):
            got_all = self._record_order(got_all)
        for buf, starts, sizes, t in got_all:
            s, v = decode(buf, starts, sizes, conn.msgtype, True, where)
            stamps.append(s)
            vecs.append(v)
            rec.append(t)
        return _join(stamps, vecs, rec, conn.msgtype)

    @staticmethod
    def _record_order(got: list[tuple]) -> list[tuple]:
        """sqlite3 batches in record-time order (ties in table order), as rosbag2 and rosbags
        read them; the usual, already ordered, case costs one comparison pass."""
        t = np.concatenate([g[3] for g in got]) if got else np.empty(0, np.int64)
        if not np.any(t[1:] < t[:-1]):
            return got
        order = np.argsort(t, kind="stable")
        bufs = [g[0] for g in got]
        base = np.cumsum([0] + [b.size for b in bufs[:-1]])
        starts = np.concatenate([g[1] + o for g, o in zip(got, base, strict=True)])[order]
        sizes = np.concatenate([g[2] for g in got])[order]
        buf = np.concatenate(bufs) if len(bufs) > 1 else bufs[0]
        return [(buf, starts, sizes, t[order])]

    @staticmethod
    def _sqlite(storage: Any, conn: Any) -> list[tuple] | None:
        """The topic's messages in batches of table rows, each batch one SQL aggregate: the data
        concatenated, their lengths and record times as text (a Python object per message would
        cost several times SQLite's own scan). None when the database does not fit that (the
        per-message iterator then reads it)."""
        db = storage.dbconn
        if (db.execute("PRAGMA encoding").fetchone() or ("",))[0] != "UTF-8":
            return None  # group_concat works on text: other encodings would transcode the bytes
        db.execute(f"PRAGMA mmap_size={_SQL_MMAP}")  # pages read in place, not copied by read()
        lo, hi = db.execute("SELECT min(id), max(id) FROM messages").fetchone()
        out: list[tuple] = []
        if lo is None:
            return out
        for a in range(lo - 1, hi, _SQL_ROWS):
            blob, lengths, times, count = db.execute(
                "SELECT CAST(group_concat(data, x'') AS BLOB), group_concat(length(data)), "
                "group_concat(timestamp), count(*) FROM messages "
                "WHERE topic_id = ? AND id > ? AND id <= ?", (conn.id, a, a + _SQL_ROWS)
            ).fetchone()
            if not count:
                continue
            sizes, t = _ints(lengths, count), _ints(times, count)
            if sizes is None or t is None or blob is None or int(sizes.sum()) != len(blob):
                return None
            starts = np.zeros(count, dtype=np.int64)
            np.cumsum(sizes[:-1], out=starts[1:])
            out.append((np.frombuffer(blob, dtype=np.uint8), starts, sizes, t))
        return out

    @staticmethod
    def _mcap(storage: Any, conn: Any, where: str) -> list[tuple] | None:
        from rosbags.rosbag2.storage_mcap import decompress

        chunks = [c for c in getattr(storage, "chunks", []) if c.channel_count.get(conn.id)]
        if not chunks or any(conn.id not in c.message_index_offsets for c in chunks):
            return None  # no chunk index: rosbags scans the file
        bio = storage.bio
        out = []
        for c in chunks:
            idx = _mcap_index(bio, c, conn.id)
            if idx is None:
                return None
            bio.seek(c.chunk_start_offset + 9 + 24)
            crc = int.from_bytes(bio.read(4), "little")
            bio.seek(c.chunk_start_offset + 9 + 40 + len(c.compression))
            data = decompress(bio.read(c.compressed_size), c.compression, c.uncompressed_size, crc)
            buf = np.frombuffer(data, dtype=np.uint8)
            off = idx["off"].astype(np.int64)
            if off.size == 0:
                continue
            if off.min() < 0 or off.max() + 31 > buf.size or np.any(buf[off] != 0x05):
                raise InputError(f"{where}: the MCAP message index does not point at messages "
                                 "(damaged file)")
            stride = _stride(buf, off, 31)
            length = _field(buf, off, 1, "<u8", stride=stride)
            chan = _field(buf, off, 9, "<u2", stride=stride)
            if np.any(chan != conn.id):
                raise InputError(f"{where}: the MCAP message index points at another channel")
            sizes = length.astype(np.int64) - 22
            starts = off + 31
            if np.any(sizes < 0) or np.any(starts + sizes > buf.size):
                raise InputError(f"{where}: MCAP message records overrun their chunk")
            out.append((buf, starts, sizes, idx["t"].astype(np.int64)))
        return out


# --------------------------------------------------------------------------------------------------
# public entry points
# --------------------------------------------------------------------------------------------------

def _open(path: Path) -> _Ros1 | _Ros2:
    _rosbags()
    kind = bag_kind(path)
    try:
        if kind == "ros1":
            return _Ros1(path)
        if kind in ("mcap", "sqlite3", "ros2-dir"):
            return _Ros2(path)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags' ReaderError and friends: one line
        msg = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise InputError(f"cannot read the bag {path}: {msg}") from None
    raise InputError(f"{path} is not a ROS bag")


def bag_topics(path: str | os.PathLike) -> list[BagTopic]:
    """Every topic of a bag with its type, message count and rate."""
    bag = _open(Path(path))
    try:
        return [t for _, t in bag.topics(rates=True)]
    finally:
        bag.close()


def _listing(topics: list[BagTopic]) -> str:
    return "; ".join(f"{t.topic} ({t.msgtype.replace('/msg/', '/')}, {t.count} messages"
                     + (f", {t.rate:.4g} Hz" if t.rate else "") + ")" for t in topics)


def _role(topic: str) -> tuple[str | None, str | None]:
    low = topic.lower()
    if any(k in low for k in ("gyro", "angular")):
        return "gyroscope", "rad/s"
    if any(k in low for k in ("acc", "linear")):
        return "accelerometer", "m/s^2"
    return None, None


def read_bag(path: str | os.PathLike, topic: str | None = None) -> TopicData:
    """Decode the IMU topic of a ROS 1 or ROS 2 bag (see the module docstring).

    ``topic``: the topic to read; None picks the only ``sensor_msgs/Imu`` topic (or the only
    ``Vector3Stamped`` one). Several candidates, an unknown topic or an unsupported type are an
    :class:`InputError` listing the topics with their message counts and rates."""
    p = Path(path)
    bag = _open(p)
    try:
        listed = bag.topics(rates=False)

        def listing(which: list[str] | None = None) -> str:
            return _listing([t for _, t in bag.topics(rates=True)
                             if which is None or t.topic in which]) or "none"

        if topic is not None:
            found = [(c, t) for c, t in listed if t.topic == topic or t.topic == "/" + topic]
            if not found:
                raise InputError(f"topic {topic!r} not in {p}; its topics: {listing()}")
            conn, info = found[0]
            if info.msgtype not in SUPPORTED:
                raise InputError(f"topic {info.topic} of {p} has type {info.msgtype}; gmwm reads "
                                 "sensor_msgs/Imu and geometry_msgs/Vector3Stamped")
        else:
            imu = [(c, t) for c, t in listed if t.msgtype == IMU and t.count]
            vec = [(c, t) for c, t in listed if t.msgtype == VECTOR3 and t.count]
            cands = imu or vec
            if not cands:
                raise InputError(f"{p} has no sensor_msgs/Imu or Vector3Stamped topic with "
                                 f"messages; its topics: {listing()}")
            if len(cands) > 1:
                raise InputError(f"{p} has {len(cands)} IMU topics: choose one with --topic: "
                                 + listing([t.topic for _, t in cands]))
            conn, info = cands[0]
        return _decoded(bag, conn, info, p)
    finally:
        bag.close()


def _decoded(bag: _Ros1 | _Ros2, conn: Any, info: BagTopic, p: Path) -> TopicData:
    """Decode the topic of ``conn`` from the open ``bag``: stamps checked and sorted, units and
    roles from the message type (or, for Vector3Stamped, from the topic name)."""
    if info.count == 0:
        raise InputError(f"topic {info.topic} of {p} has no messages")
    where = f"topic {info.topic} of {p}"
    stamp, vectors, rec = bag.read(conn, where)
    notes: list[str] = []
    source = "header.stamp"
    if stamp.size and np.all(stamp == 0):
        stamp, source = rec(), "bag record time"
    if source != "header.stamp":
        notes.append(f"{where}: header.stamp is zero in every message; the bag's record times "
                     "are used (they include transport delays)")
    elif np.any(stamp == 0):
        raise InputError(f"{where}: {int(np.sum(stamp == 0))} messages have a zero header.stamp")
    order = np.argsort(stamp, kind="stable")
    moved = int(np.count_nonzero(order != np.arange(order.size)))
    if moved:
        stamp = stamp[order]
        vectors = {k: v[order] for k, v in vectors.items()}
        notes.append(f"{where}: {moved} messages were stored out of {source} order and were "
                     "sorted by it")
    if info.msgtype == IMU:
        units = {k: ("rad/s" if k[0] == "g" else "m/s^2") for k in vectors}
        roles = {k: ("gyroscope" if k[0] == "g" else "accelerometer") for k in vectors}
    else:
        role, unit = _role(info.topic)
        units = dict.fromkeys(vectors, unit)
        roles = dict.fromkeys(vectors, role)
        if role is None:
            notes.append(f"{where} (Vector3Stamped) does not say whether it is a gyroscope or an "
                         "accelerometer: give --units")
    return TopicData(info.topic, info.msgtype, stamp, vectors, units, roles, source, notes)


def _imu_candidates(listed: list[tuple[Any, BagTopic]]) -> list[tuple[Any, BagTopic]]:
    """The IMU streams among a bag's topics, in the bag's order (see :func:`imu_bag_topics`)."""
    keep = [(c, t) for c, t in listed if t.count and (
        t.msgtype == IMU or (t.msgtype == VECTOR3 and _role(t.topic)[0] is not None))]
    return keep or [(c, t) for c, t in listed if t.count and t.msgtype == VECTOR3]


def imu_bag_topics(path: str | os.PathLike) -> list[BagTopic]:
    """The IMU streams of a bag, in the bag's order: every ``sensor_msgs/Imu`` topic with
    messages and every ``Vector3Stamped`` topic whose name marks a gyroscope or an accelerometer
    (``gyro``/``angular``, ``acc``/``linear``); a bag with neither gives its other
    ``Vector3Stamped`` topics (as :func:`read_bag` does with no topic). Each Vector3Stamped topic
    is one single-sensor stream: gmwm does not merge a gyroscope topic and an accelerometer topic
    (their stamps differ). None at all is an :class:`InputError` listing the bag's topics."""
    p = Path(path)
    bag = _open(p)
    try:
        found = _imu_candidates(bag.topics(rates=False))
        if not found:
            raise InputError(f"{p} has no sensor_msgs/Imu or Vector3Stamped topic with messages; "
                             f"its topics: {_listing([t for _, t in bag.topics(rates=True)])}")
        rated = {t.topic: t for _, t in bag.topics(rates=True)}
        return [rated[t.topic] for _, t in found]
    finally:
        bag.close()


def read_bag_topics(path: str | os.PathLike, topics: str | Sequence[str] = "all"
                    ) -> dict[str, TopicData]:
    """Decode several IMU topics of one bag, opened (container index parsed) once.

    ``topics``: ``"all"`` (the streams of :func:`imu_bag_topics`) or topic names (a leading
    ``/`` may be left out). Returns topic -> :class:`TopicData` in the order asked for (the bag's
    order for ``"all"``). An unknown or repeated topic, an unsupported type or an empty topic is
    an :class:`InputError` naming it."""
    p = Path(path)
    bag = _open(p)
    try:
        listed = bag.topics(rates=False)
        if isinstance(topics, str) and topics.strip().lower() == "all":
            chosen = _imu_candidates(listed)
            if not chosen:
                raise InputError(f"{p} has no sensor_msgs/Imu or Vector3Stamped topic with "
                                 f"messages; its topics: "
                                 f"{_listing([t for _, t in bag.topics(rates=True)]) or 'none'}")
        else:
            names = [topics] if isinstance(topics, str) else list(topics)
            if not names:
                raise InputError("no topic given")
            chosen = []
            for name in names:
                found = [(c, t) for c, t in listed if t.topic in (name, "/" + name)]
                if not found:
                    raise InputError(f"topic {name!r} not in {p}; its topics: "
                                     f"{_listing([t for _, t in bag.topics(rates=True)])}")
                conn, info = found[0]
                if info.msgtype not in SUPPORTED:
                    raise InputError(f"topic {info.topic} of {p} has type {info.msgtype}; gmwm "
                                     "reads sensor_msgs/Imu and geometry_msgs/Vector3Stamped")
                if any(t.topic == info.topic for _, t in chosen):
                    raise InputError(f"topic {info.topic} requested twice")
                chosen.append((conn, info))
        return {info.topic: _decoded(bag, conn, info, p) for conn, info in chosen}
    finally:
        bag.close()
