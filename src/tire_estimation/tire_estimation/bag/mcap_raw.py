"""Fast raw message access to MCAP files (the storage format of contract bags).

``rosbags``' reader costs about 6 µs per message in Python generator layers; this module reads
the MCAP records directly and returns the serialized messages of the wanted topics. It is used by
:mod:`tire_estimation.bag.reader` only for plain ``.mcap`` files (chunks uncompressed, zstd or
lz4); anything else goes through ``rosbags``. Message order is the file order (for bags written
by :mod:`tire_estimation.bag.writer`, log-time order).

Record layout (MCAP spec): ``opcode u8, length u64, content``. A Message record's content is
``channel_id u16, sequence u32, log_time u64, publish_time u64, data``. A MessageIndex record
after a Chunk lists ``(log_time u64, offset u64)`` of one channel's messages in that chunk.

Two ways through a chunk: where MessageIndex records follow it and agree with the bytes they
point at (opcode, channel, log time, record bounds; checked with NumPy over all entries), the
messages are located from the index without a Python step per message, and only the bytes no
index entry covers (Schema and Channel records) are walked record by record; otherwise the whole
chunk is walked (about 1 µs per message). Messages of a topic that all have one length are
returned as one ``(M, length)`` uint8 array (:attr:`RawMessages.rows`), which
:func:`tire_estimation.bag.cdr.decode` takes without copying each message.

The file is read one record at a time: :func:`iter_mcap` hands over the messages chunk by chunk
(memory: one chunk), :func:`read_mcap` joins them.
"""

from __future__ import annotations

import os
import struct
import sys
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO

import numpy as np
from lz4.frame import decompress as lz4_decompress  # type: ignore[import-untyped]
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from tire_estimation.core.arrays import I64

if sys.version_info >= (3, 14):  # pragma: no cover
    from compression import zstd
else:
    from backports import zstd

MAGIC = b"\x89MCAP0\r\n"
OP_SCHEMA = 0x03
OP_CHANNEL = 0x04
OP_MESSAGE = 0x05
OP_CHUNK = 0x06
OP_MESSAGE_INDEX = 0x07
OP_DATA_END = 0x0F
OP_FOOTER = 0x02

_REC = struct.Struct("<BQ")
#: opcode, record length, channel id, (sequence skipped), log time of a Message record.
_REC_MSG = struct.Struct("<BQH4xQ")
_U16 = struct.Struct("<H")
_U32 = struct.Struct("<I")
_U64 = struct.Struct("<Q")
_CHUNK_HEAD = struct.Struct("<QQQI")
#: Bytes of a Message record before its data: opcode, length, channel, sequence, two times.
_MSG_HEAD = 31
U8 = NDArray[np.uint8]


class McapFormatError(ValueError):
    """The file is not a well-formed MCAP file."""


@dataclass
class RawMessages:
    """Serialized messages of one topic, in file order.

    ``log_ns``: log times (M,) int64 ns. The CDR payloads are either ``rows`` (M, length) uint8
    when every message has the same length, or ``data`` (M bytes objects) otherwise; the other
    one is None. ``schema``: encoding and text of the channel's Schema record (e.g.
    ``("ros2msg", "std_msgs/Header header ...")``), empty strings when the file has none.
    """

    msgtype: str
    log_ns: I64
    rows: U8 | None = None
    data: list[bytes] | None = None
    schema: tuple[str, str] = ("", "")

    def __len__(self) -> int:
        return int(self.log_ns.size)


@dataclass
class _Part:
    """Payloads of one channel found in one buffer (``rows`` if of one length, else ``data``)."""

    log_ns: I64
    rows: U8 | None
    data: list[bytes] | None


def _part(buffer: bytes, starts: I64, lengths: I64, log_ns: I64) -> _Part:
    """Copy the payloads at ``starts`` (``lengths`` bytes each) out of ``buffer``."""
    width = int(lengths[0])
    if width > 0 and np.all(lengths == width):
        window = sliding_window_view(np.frombuffer(buffer, dtype=np.uint8), width)
        return _Part(log_ns, window[starts], None)
    ends = starts + lengths
    data = [buffer[s:e] for s, e in zip(starts.tolist(), ends.tolist(), strict=True)]
    return _Part(log_ns, None, data)


@dataclass
class _Loose:
    """Messages found by the record walk, pending until their buffer is done."""

    starts: list[int] = field(default_factory=list)
    lengths: list[int] = field(default_factory=list)
    log_ns: list[int] = field(default_factory=list)


def _string(buf: bytes | memoryview, pos: int) -> tuple[str, int]:
    (n,) = _U32.unpack_from(buf, pos)
    pos += 4
    return bytes(buf[pos : pos + n]).decode(), pos + n


def _decompress(compression: str, data: bytes, size: int) -> bytes:
    if compression == "":
        return bytes(data)
    if compression == "zstd":
        out = zstd.decompress(data)
    elif compression == "lz4":
        out = lz4_decompress(data)
    else:
        raise McapFormatError(f"unsupported chunk compression {compression!r}")
    if len(out) != size:
        raise McapFormatError("chunk size mismatch after decompression")
    return out


def _field(heads: U8, start: int, dtype: str) -> NDArray[np.generic]:
    """Column ``dtype`` at byte ``start`` of every row of ``heads`` (k, _MSG_HEAD) uint8."""
    width = np.dtype(dtype).itemsize
    return np.ascontiguousarray(heads[:, start : start + width]).view(dtype)[:, 0]


class _Scanner:
    def __init__(self, topics: set[str]) -> None:
        self.topics = topics
        self.schemas: dict[int, tuple[str, str, str]] = {}  # id -> name, encoding, text
        self.channel_topic: dict[int, str] = {}
        self.wanted: dict[int, str] = {}
        self.msgtypes: dict[str, tuple[str, str, str]] = {}
        self.buffer = b""
        self.parts: dict[str, list[_Part]] = {}
        self.loose: dict[int, _Loose] = {}

    def _channel(self, buf: bytes, pos: int) -> None:
        (cid,) = _U16.unpack_from(buf, pos)
        (sid,) = _U16.unpack_from(buf, pos + 2)
        topic, _ = _string(buf, pos + 4)
        if cid in self.channel_topic or topic not in self.topics:
            self.channel_topic.setdefault(cid, topic)
            return
        self.channel_topic[cid] = topic
        self.msgtypes.setdefault(topic, self.schemas.get(sid, ("", "", "")))
        self.parts.setdefault(topic, [])
        self.wanted[cid] = topic

    def _schema(self, buf: bytes, pos: int) -> None:
        (sid,) = _U16.unpack_from(buf, pos)
        name, p = _string(buf, pos + 2)
        encoding, p = _string(buf, p)
        (n,) = _U32.unpack_from(buf, p)
        try:
            text = bytes(buf[p + 4 : p + 4 + n]).decode()
        except UnicodeDecodeError:  # not a text schema: the message type name is enough
            text = ""
        self.schemas[sid] = (name, encoding, text)

    def _flush(self, extra: dict[int, tuple[I64, I64, I64]] | None = None) -> None:
        """Close the current buffer: its walked messages (merged in file order with the
        indexed ones of ``extra``, channel -> starts, lengths, log times) become parts."""
        extra = extra or {}
        for cid in set(self.loose) | set(extra):
            loose = self.loose.get(cid, _Loose())
            starts = np.asarray(loose.starts, dtype=np.int64)
            lengths = np.asarray(loose.lengths, dtype=np.int64)
            logs = np.asarray(loose.log_ns, dtype=np.int64)
            if cid in extra:
                s, n, t = extra[cid]
                starts, lengths, logs = (
                    np.concatenate([s, starts]),
                    np.concatenate([n, lengths]),
                    np.concatenate([t, logs]),
                )
                order = np.argsort(starts, kind="stable")
                starts, lengths, logs = starts[order], lengths[order], logs[order]
            if starts.size:
                self.parts[self.wanted[cid]].append(_part(self.buffer, starts, lengths, logs))
        self.loose = {}

    def records(self, buf: bytes, start: int, end: int) -> None:
        """Walk the records of ``buf[start:end]`` (top-level records other than chunks, or the
        content of a chunk); ``buf`` is :attr:`buffer`, where the messages found are read."""
        pos = start
        rec_unpack = _REC.unpack_from
        msg_unpack = _REC_MSG.unpack_from
        wanted = self.wanted
        while pos < end:
            if pos + 9 > end:
                raise McapFormatError("truncated record header")
            if buf[pos] == OP_MESSAGE and pos + _MSG_HEAD <= end:
                _, length, cid, log_ns = msg_unpack(buf, pos)
                nxt = pos + 9 + length
                if nxt > end or length < _MSG_HEAD - 9:
                    raise McapFormatError("message record exceeds the data")
                if cid in wanted:
                    loose = self.loose.setdefault(cid, _Loose())
                    loose.starts.append(pos + _MSG_HEAD)
                    loose.lengths.append(nxt - pos - _MSG_HEAD)
                    loose.log_ns.append(log_ns)
                pos = nxt
                continue
            op, length = rec_unpack(buf, pos)
            body = pos + 9
            nxt = body + length
            if nxt > end:
                raise McapFormatError("record exceeds the data")
            if op == OP_MESSAGE:
                raise McapFormatError("truncated message record")
            elif op == OP_SCHEMA:
                self._schema(buf, body)
            elif op == OP_CHANNEL:
                self._channel(buf, body)
            pos = nxt

    def walk(self, buf: bytes) -> None:
        """Read a run of top-level records other than chunks."""
        self.buffer = buf
        self.records(buf, 0, len(buf))
        self._flush()

    def chunk(self, content: bytes, index: list[tuple[int, bytes]]) -> None:
        """Read a Chunk record's content with the MessageIndex records that followed it
        (``(channel id, entries)``)."""
        _, _, size, _ = _CHUNK_HEAD.unpack_from(content, 0)
        compression, p = _string(content, 28)
        (clen,) = _U64.unpack_from(content, p)
        p += 8
        if p + clen > len(content):
            raise McapFormatError("chunk data exceeds its record")
        inner = _decompress(compression, content[p : p + clen], size)
        self.buffer = inner
        if not (index and self._indexed(inner, index)):
            self.records(inner, 0, len(inner))
            self._flush()

    def _indexed(self, inner: bytes, index: list[tuple[int, bytes]]) -> bool:
        """Locate the chunk's messages from its MessageIndex records; walk only the bytes
        between them. False (nothing done) if the index disagrees with the chunk's bytes."""
        arr = np.frombuffer(inner, dtype=np.uint8)
        size = arr.size
        tables = [np.frombuffer(rec, dtype="<u8").reshape(-1, 2) for _, rec in index]
        if size < _MSG_HEAD or not any(t.size for t in tables):
            return False
        cids = np.concatenate([np.full(len(t), c, dtype=np.int64) for (c, _), t in
                               zip(index, tables, strict=True)])  # fmt: skip
        both = np.concatenate(tables)
        if np.any(both[:, 1] > size - _MSG_HEAD):
            return False
        offsets = both[:, 1].astype(np.int64)
        logs = both[:, 0]
        # the Message record header at each offset: opcode, length, channel, sequence, log time
        heads = sliding_window_view(arr, _MSG_HEAD)[offsets]
        lengths = _field(heads, 1, "<u8")
        if (
            np.any(heads[:, 0] != OP_MESSAGE)
            or np.any(lengths < _MSG_HEAD - 9)
            or np.any(lengths > size)
            or np.any(_field(heads, 9, "<u2") != cids)
            or np.any(_field(heads, 15, "<u8") != logs)
        ):
            return False
        ends = offsets + 9 + lengths.astype(np.int64)
        order = np.argsort(offsets, kind="stable")
        s_sorted, e_sorted = offsets[order], ends[order]
        if e_sorted[-1] > size or np.any(e_sorted[:-1] > s_sorted[1:]):
            return False
        # bytes no index entry covers: Schema / Channel records, unindexed messages
        gap_start = np.concatenate([[0], e_sorted])
        gap_end = np.concatenate([s_sorted, [size]])
        for a, b in zip(gap_start.tolist(), gap_end.tolist(), strict=True):
            if b > a:
                self.records(inner, a, b)
        extra: dict[int, tuple[I64, I64, I64]] = {}
        for cid in np.unique(cids).tolist():
            if cid in self.wanted:
                sel = cids == cid
                extra[cid] = (
                    offsets[sel] + _MSG_HEAD,
                    ends[sel] - offsets[sel] - _MSG_HEAD,
                    logs[sel].astype(np.int64),
                )
        self._flush(extra)
        return True

    def take(self, empty: bool = False) -> dict[str, RawMessages]:
        """The messages found since the last call, per wanted topic; topics without any are
        left out, or (``empty``) given with none when the file has their channel."""
        self._flush()
        out: dict[str, RawMessages] = {}
        for topic, parts in self.parts.items():
            if parts or empty:
                name, encoding, text = self.msgtypes[topic]
                out[topic] = assemble(name, parts)
                out[topic].schema = (encoding, text)
            self.parts[topic] = []
        return out


def assemble(msgtype: str, parts: Sequence[_Part | RawMessages]) -> RawMessages:
    """Join ``parts`` (in order: the per-chunk parts of one file, or the messages of several
    files) into :class:`RawMessages`: ``rows`` if every payload has one length, else ``data``."""
    if not parts:
        return RawMessages(msgtype, np.zeros(0, dtype=np.int64), data=[])
    log_ns = np.concatenate([p.log_ns for p in parts])
    widths = {p.rows.shape[1] if p.rows is not None else -1 for p in parts}
    if len(widths) == 1 and -1 not in widths:
        return RawMessages(msgtype, log_ns, rows=np.concatenate([p.rows for p in parts]))
    data: list[bytes] = []
    for p in parts:
        data.extend(p.data if p.data is not None else [r.tobytes() for r in p.rows])
    return RawMessages(msgtype, log_ns, data=data)


#: top-level records other than chunks are read in runs of about this many bytes
LOOSE_BYTES = 4 << 20


def _check_magic(f: BinaryIO, path: Path) -> int:
    """Check both magic strings; return where the data section ends (the closing magic)."""
    size = os.fstat(f.fileno()).st_size
    head = f.read(len(MAGIC))
    f.seek(max(size - len(MAGIC), 0))
    tail = f.read(len(MAGIC))
    if size < 2 * len(MAGIC) or head != MAGIC or tail != MAGIC:
        raise McapFormatError(f"{path} is not a complete MCAP file (magic bytes missing)")
    f.seek(len(MAGIC))
    return size - len(MAGIC)


def _read(f: BinaryIO, n: int) -> bytes:
    data = f.read(n)
    if len(data) != n:
        raise McapFormatError("file ends inside a record")
    return data


def _message_index(f: BinaryIO, end: int) -> list[tuple[int, bytes]]:
    """The MessageIndex records at the file position (those after a chunk), read."""
    index: list[tuple[int, bytes]] = []
    while f.tell() + 9 <= end:
        pos = f.tell()
        op, length = _REC.unpack(_read(f, 9))
        if op != OP_MESSAGE_INDEX:
            f.seek(pos)
            break
        if pos + 9 + length > end or length < 6:
            raise McapFormatError("message index record exceeds the data")
        body = _read(f, length)
        (cid,) = _U16.unpack_from(body, 0)
        (n,) = _U32.unpack_from(body, 2)
        if 6 + n > length or n % 16:
            raise McapFormatError("malformed message index record")
        index.append((cid, body[6 : 6 + n]))
    return index


def iter_mcap(path: Path, topics: Iterable[str]) -> Iterator[dict[str, RawMessages]]:
    """Serialized messages of ``topics`` in the MCAP file ``path``, one dict per chunk (or run
    of top-level records) in file order, holding the topics with messages there; the last dict
    also names, with no messages, the wanted topics the file has a channel for. Memory: one
    chunk.

    Raises:
        McapFormatError: not MCAP, truncated, or malformed.
        OSError: the file cannot be read.
    """
    scanner = _Scanner(set(topics))
    try:
        with path.open("rb") as f:
            end = _check_magic(f, path)
            loose = bytearray()
            while True:
                pos = f.tell()
                if pos + 9 > end:
                    raise McapFormatError("no DataEnd record (file truncated?)")
                head = _read(f, 9)
                op, length = _REC.unpack(head)
                if pos + 9 + length > end:
                    raise McapFormatError("record exceeds the data")
                if loose and (op in (OP_DATA_END, OP_CHUNK) or len(loose) >= LOOSE_BYTES):
                    scanner.walk(bytes(loose))
                    loose.clear()
                    found = scanner.take()
                    if found:
                        yield found
                if op == OP_DATA_END:
                    break
                body = _read(f, length)
                if op == OP_CHUNK:
                    scanner.chunk(body, _message_index(f, end))
                    found = scanner.take()
                    if found:
                        yield found
                else:
                    loose += head
                    loose += body
            yield scanner.take(empty=True)
    except (struct.error, UnicodeDecodeError, zstd.ZstdError, RuntimeError) as exc:
        raise McapFormatError(f"{path}: {exc}") from exc


def read_mcap(path: Path, topics: Iterable[str]) -> dict[str, RawMessages]:
    """Serialized messages of ``topics`` in the MCAP file ``path`` (topics absent: no key).

    Raises:
        McapFormatError: not MCAP, truncated, or malformed.
        OSError: the file cannot be read.
    """
    parts: dict[str, list[RawMessages]] = {}
    for found in iter_mcap(path, topics):
        for topic, msgs in found.items():
            parts.setdefault(topic, [])
            if len(msgs):
                parts[topic].append(msgs)
            elif not parts[topic]:
                parts[topic] = [msgs]
    out: dict[str, RawMessages] = {}
    for topic, msgs_list in parts.items():
        nonempty = [m for m in msgs_list if len(m)] or msgs_list[:1]
        first = nonempty[0]
        joined = first if len(nonempty) == 1 else assemble(first.msgtype, nonempty)
        joined.schema = first.schema
        out[topic] = joined
    return out
