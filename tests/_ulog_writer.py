"""A minimal PX4 ULog writer for tests (format, subscription and data messages only).

Layout (PX4 ULog file format documentation): a 16-byte header (``ULog`` magic, version, start
time in us), a flag-bits message, then messages of ``uint16 size, uint8 type, payload``:
'F' a format ``name:type field;...``, 'A' a subscription ``uint8 multi_id, uint16 msg_id, name``,
'D' a data message ``uint16 msg_id, fields packed little-endian``.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

_TYPES = {"uint64_t": "Q", "int32_t": "i", "float": "f", "uint8_t": "B"}


def _msg(kind: bytes, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), kind[0]) + payload


def write_ulog(path: Path, topics: dict[tuple[str, int], dict[str, np.ndarray]],
               fields: dict[str, list[tuple[str, str]]]) -> Path:
    """``topics[(name, multi_id)]`` = column arrays (keys as ``fields[name]``, arrays for
    ``float[3]`` fields have shape (n, 3)); rows are written interleaved by timestamp."""
    out = bytearray(b"ULog\x01\x12\x35" + bytes([1]) + struct.pack("<Q", 0))
    out += _msg(b"B", bytes(8) + bytes(8) + bytes(24))  # flag bits: nothing incompatible
    for name, flist in fields.items():
        spec = ";".join(f"{t} {f}" for f, t in flist) + ";"
        out += _msg(b"F", f"{name}:{spec}".encode())
    rows = []
    for msg_id, ((name, inst), cols) in enumerate(topics.items()):
        out += _msg(b"A", struct.pack("<BH", inst, msg_id) + name.encode())
        n = cols["timestamp"].size
        for i in range(n):
            payload = bytearray(struct.pack("<H", msg_id))
            for f, t in fields[name]:
                base, _, count = t.partition("[")
                code = _TYPES[base]
                if count:
                    payload += struct.pack("<" + code * int(count[:-1]), *cols[f][i])
                else:
                    payload += struct.pack("<" + code, cols[f][i])
            rows.append((int(cols["timestamp"][i]), bytes(payload)))
    for _, payload in sorted(rows, key=lambda r: r[0]):
        out += _msg(b"D", payload)
    path.write_bytes(bytes(out))
    return path
