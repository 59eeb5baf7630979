"""Fast raw message access to MCAP files (the storage format of contract bags).

``rosbags``' reader costs about 6 µs per message in Python generator layers; this module walks
the MCAP records directly (about 1 µs per message) and returns the serialized messages of the
wanted topics. It is used by :mod:`tire_estimation.bag.reader` only for plain ``.mcap`` files
(chunks uncompressed, zstd or lz4); anything else goes through ``rosbags``. Message order is the
file order (for bags written by :mod:`tire_estimation.bag.writer`, log-time order).

Record layout (MCAP spec): ``opcode u8, length u64, content``. A Message record's content is
``channel_id u16, sequence u32, log_time u64, publish_time u64, data``.
"""

from __future__ import annotations

import struct
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

from lz4.frame import decompress as lz4_decompress  # type: ignore[import-untyped]

if sys.version_info >= (3, 14):  # pragma: no cover
    from compression import zstd
else:
    from backports import zstd

MAGIC = b"\x89MCAP0\r\n"
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_DATA_END = 0x0F
OP_FOOTER = 0x02

_REC = struct.Struct("<BQ")
#: opcode, record length, channel id, (sequence skipped), log time of a Message record.
_REC_MSG = struct.Struct("<BQH4xQ")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQI")


class McapFormatError(ValueError):
    """The file is not a well-formed MCAP file."""


@dataclass
class RawMessages:
    """Serialized messages of one topic: log times (ns) and CDR payloads, in file order."""

    msgtype: str
    log_ns: list[int] = field(default_factory=list)
    data: list[bytes] = field(default_factory=list)


def _string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    return bytes(buf[pos : pos + n]).decode(), pos + n


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        return data
    if compression == "zstd":
        out = zstd.decompress(data)
    elif compression == "lz4":
        out = lz4_decompress(data)
    else:
        raise McapFormatError(f"unsupported chunk compression {compression!r}")
    if len(out) != size:
        raise McapFormatError("chunk size mismatch after decompression")
    return out


class _Scanner:
    def __init__(self, topics: set[str]) -> None:
        self.topics = topics
        self.schemas: dict[int, str] = {}
        self.channel_topic: dict[int, str] = {}
        self.wanted: dict[int, RawMessages] = {}
        self.out: dict[str, RawMessages] = {}

    def _channel(self, buf: bytes, pos: int) -> None:
        (cid,) = _U16.unpack_from(buf, pos)
        (sid,) = _U16.unpack_from(buf, pos + 2)
        topic, _ = _string(buf, pos + 4)
        if cid in self.channel_topic or topic not in self.topics:
            self.channel_topic.setdefault(cid, topic)
            return
        self.channel_topic[cid] = topic
        msgtype = self.schemas.get(sid, "")
        raw = self.out.setdefault(topic, RawMessages(msgtype))
        self.wanted[cid] = raw

    def _schema(self, buf: bytes, pos: int) -> None:
        (sid,) = _U16.unpack_from(buf, pos)
        name, _ = _string(buf, pos + 2)
        self.schemas[sid] = name

    def records(self, buf: bytes, start: int, end: int, top: bool) -> None:
        """Walk the records of ``buf[start:end]`` (top level or a decompressed chunk)."""
        pos = start
        rec_unpack = _REC.unpack_from
        msg_unpack = _REC_MSG.unpack_from
        wanted = self.wanted
        while pos < end:
            if pos + 9 > end:
                raise McapFormatError("truncated record header")
            if buf[pos] == OP_MESSAGE and pos + 31 <= end:
                _, length, cid, log_ns = msg_unpack(buf, pos)
                nxt = pos + 9 + length
                if nxt > end or length < 22:
                    raise McapFormatError("message record exceeds the data")
                raw = wanted.get(cid)
                if raw is not None:
                    raw.log_ns.append(log_ns)
                    raw.data.append(buf[pos + 31 : nxt])
                pos = nxt
                continue
            op, length = rec_unpack(buf, pos)
            body = pos + 9
            nxt = body + length
            if nxt > end:
                raise McapFormatError("record exceeds the data")
            if op == OP_MESSAGE:
                raise McapFormatError("truncated message record")
            elif op == OP_CHUNK and top:
                _, _, size, _ = _CHUNK_HEAD.unpack_from(buf, body)
                compression, p = _string(buf, body + 28)
                (clen,) = _U64.unpack_from(buf, p)
                p += 8
                if p + clen > nxt:
                    raise McapFormatError("chunk data exceeds its record")
                inner = _decompress(compression, buf[p : p + clen], size)
                self.records(inner, 0, len(inner), top=False)
            elif op == OP_SCHEMA:
                self._schema(buf, body)
            elif op == OP_CHANNEL:
                self._channel(buf, body)
            elif op == OP_DATA_END and top:
                return
            pos = nxt
        if top:
            raise McapFormatError("no DataEnd record (file truncated?)")


def read_mcap(path: Path, topics: Iterable[str]) -> dict[str, RawMessages]:
    """Serialized messages of ``topics`` in the MCAP file ``path`` (topics absent: no key).

    Raises:
        McapFormatError: not MCAP, truncated, or malformed.
        OSError: the file cannot be read.
    """
    data = path.read_bytes()
    if not data.startswith(MAGIC) or not data.endswith(MAGIC):
        raise McapFormatError(f"{path} is not a complete MCAP file (magic bytes missing)")
    scanner = _Scanner(set(topics))
    try:
        scanner.records(data, len(MAGIC), len(data) - len(MAGIC), top=True)
    except (struct.error, UnicodeDecodeError, zstd.ZstdError, RuntimeError) as exc:
        raise McapFormatError(f"{path}: {exc}") from exc
    return scanner.out
