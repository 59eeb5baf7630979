"""Bulk CDR encoding and decoding of messages with a fixed layout.

A ROS 2 message serialized as little-endian CDR has a *layout* — the byte offset of every numeric
field — that depends only on its strings and sequence lengths. :func:`walk` derives that layout
from one serialized message, using the field definitions of the ``rosbags`` type store. Every
other message with the same length and the same *structural bytes* (string and sequence length
prefixes and string contents) shares the layout, so a batch of them can be decoded with NumPy
column slices (:func:`decode`) and a batch of new ones can be encoded by stamping values into a
template (:func:`encode`). Both are byte-for-byte equivalent to ``rosbags``' serializer and
deserializer; messages that do not fit (big-endian, unsupported field types) go through
``rosbags`` instead.

Field paths are dotted names (``header.stamp.sec``, ``twist.twist.linear.x``); elements of
arrays or sequences of messages are indexed (``wheels[0].level``). Decoded values are NumPy
arrays with the message index as first axis: ``(k,)`` for a scalar, ``(k, n)`` for an array or
sequence of ``n`` numbers. Strings and string sequences are constant within a batch and kept
apart in :attr:`Batch.strings`.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.interfaces import Nodetype
from rosbags.typesys.store import Typestore

from tire_estimation.errors import BagError

#: NumPy little-endian dtype of each CDR primitive.
PRIMITIVES: dict[str, str] = {
    "bool": "?",
    "byte": "u1",
    "char": "u1",
    "int8": "i1",
    "uint8": "u1",
    "int16": "<i2",
    "uint16": "<u2",
    "int32": "<i4",
    "uint32": "<u4",
    "int64": "<i8",
    "uint64": "<u8",
    "float32": "<f4",
    "float64": "<f8",
}
#: Most batches one message length may split into before the rest is decoded generically.
MAX_LAYOUTS_PER_LENGTH = 32
_ENCAPSULATION_LE = b"\x00\x01"


class LayoutError(ValueError):
    """A serialized message cannot be handled by the fast path (use ``rosbags`` instead)."""


@dataclass(frozen=True)
class Slot:
    """Where one numeric field lives in the serialized bytes (offset includes the 4-byte
    encapsulation header). ``count`` is None for a scalar, else the number of elements."""

    offset: int
    dtype: str
    count: int | None

    @property
    def nbytes(self) -> int:
        """Bytes the field occupies."""
        return np.dtype(self.dtype).itemsize * (1 if self.count is None else self.count)


@dataclass(frozen=True)
class Layout:
    """Layout of one serialized message (see module docstring)."""

    msgtype: str
    size: int
    slots: dict[str, Slot]
    strings: dict[str, str | tuple[str, ...]]
    struct_index: NDArray[np.intp]
    struct_bytes: NDArray[np.uint8]


@dataclass
class Batch:
    """Decoded messages that share one layout.

    ``index``: positions of these messages in the decoded input sequence (int64, ``(k,)``);
    ``arrays``: numeric fields, ``(k,)`` or ``(k, n)``; ``strings``: string fields.
    """

    index: NDArray[np.int64]
    arrays: dict[str, NDArray[Any]]
    strings: dict[str, str | tuple[str, ...]] = field(default_factory=dict)
    fast: bool = True


class _Walker:
    def __init__(self, store: Typestore, raw: bytes) -> None:
        self.store = store
        self.raw = raw
        self.body = memoryview(raw)[4:]
        self.slots: dict[str, Slot] = {}
        self.strings: dict[str, str | tuple[str, ...]] = {}
        self.struct: list[int] = [0, 1]  # encapsulation header

    def _align(self, pos: int, size: int) -> int:
        return (pos + size - 1) & -size

    def _u32(self, pos: int) -> int:
        if pos + 4 > len(self.body):
            raise LayoutError("message truncated")
        self.struct.extend(range(pos + 4, pos + 8))
        return int.from_bytes(self.body[pos : pos + 4], "little")

    def _string(self, pos: int) -> tuple[str, int]:
        pos = self._align(pos, 4)
        length = self._u32(pos)
        pos += 4
        if length < 1 or pos + length > len(self.body) or self.body[pos + length - 1] != 0:
            raise LayoutError("bad string")
        self.struct.extend(range(pos + 4, pos + 4 + length))
        try:
            text = bytes(self.body[pos : pos + length - 1]).decode()
        except UnicodeDecodeError as exc:
            raise LayoutError("string is not UTF-8") from exc
        return text, pos + length

    def _numeric(self, path: str, typ: str, count: int | None, pos: int) -> int:
        dtype = PRIMITIVES.get(typ)
        if dtype is None:
            raise LayoutError(f"unsupported primitive {typ}")
        size = np.dtype(dtype).itemsize
        n = 1 if count is None else count
        if n:
            pos = self._align(pos, size)
        if pos + size * n > len(self.body):
            raise LayoutError("message truncated")
        self.slots[path] = Slot(pos + 4, dtype, count)
        return pos + size * n

    def _elements(self, path: str, sub: tuple[Any, Any], n: int, pos: int) -> int:
        subtype, desc = sub
        if subtype == Nodetype.BASE:
            if desc[0] == "string":
                values = []
                for _ in range(n):
                    text, pos = self._string(pos)
                    values.append(text)
                self.strings[path] = tuple(values)
                return pos
            return self._numeric(path, desc[0], n, pos)
        if subtype == Nodetype.NAME:
            for k in range(n):
                pos = self.fields(desc, f"{path}[{k}].", pos)
            return pos
        raise LayoutError(f"unsupported element node type {subtype}")

    def fields(self, msgtype: str, prefix: str, pos: int) -> int:
        for name, (nodetype, desc) in self.store.fielddefs[msgtype][1]:
            path = prefix + name
            if nodetype == Nodetype.BASE:
                if desc[0] == "string":
                    text, pos = self._string(pos)
                    self.strings[path] = text
                else:
                    pos = self._numeric(path, desc[0], None, pos)
            elif nodetype == Nodetype.NAME:
                pos = self.fields(desc, path + ".", pos)
            elif nodetype == Nodetype.ARRAY:
                sub, n = desc
                pos = self._elements(path, sub, n, pos)
            elif nodetype == Nodetype.SEQUENCE:
                sub, _ = desc
                pos = self._align(pos, 4)
                n = self._u32(pos)
                pos += 4
                if n > len(self.body):
                    raise LayoutError("sequence length exceeds message")
                pos = self._elements(path, sub, n, pos)
            else:
                raise LayoutError(f"unsupported node type {nodetype}")
        return pos


def walk(store: Typestore, msgtype: str, raw: bytes | memoryview) -> Layout:
    """Layout of the serialized message ``raw`` of type ``msgtype``.

    Raises:
        LayoutError: not little-endian CDR, an unsupported field type, or malformed bytes.
    """
    raw = bytes(raw)
    if len(raw) < 4 or raw[:2] != _ENCAPSULATION_LE:
        raise LayoutError("not little-endian CDR")
    walker = _Walker(store, raw)
    end = walker.fields(msgtype, "", 0)
    if end + 4 + 3 < len(raw):
        raise LayoutError("trailing bytes after message")
    index = np.asarray(walker.struct, dtype=np.intp)
    return Layout(
        msgtype=msgtype,
        size=len(raw),
        slots=walker.slots,
        strings=walker.strings,
        struct_index=index,
        struct_bytes=np.frombuffer(raw, dtype=np.uint8)[index].copy(),
    )


def _column(buf: NDArray[np.uint8], slot: Slot) -> NDArray[Any]:
    n = 1 if slot.count is None else slot.count
    width = slot.nbytes
    if width == 0:
        return np.zeros((buf.shape[0], 0), dtype=np.dtype(slot.dtype).newbyteorder("="))
    raw = np.ascontiguousarray(buf[:, slot.offset : slot.offset + width])
    values = raw.view(slot.dtype).astype(np.dtype(slot.dtype).newbyteorder("="), copy=False)
    return values.reshape(buf.shape[0]) if slot.count is None else values.reshape(-1, n)


def decode_rows(layout: Layout, buf: NDArray[np.uint8]) -> dict[str, NDArray[Any]]:
    """Numeric fields of messages ``buf`` (``(k, layout.size)`` uint8) that share ``layout``."""
    return {path: _column(buf, slot) for path, slot in layout.slots.items()}


def flatten(store: Typestore, msgtype: str, message: Any) -> dict[str, Any]:
    """Flatten a ``rosbags`` message object to ``{path: value}`` with the paths of :func:`walk`.

    Numeric values become NumPy scalars / 1-D arrays, strings ``str``, string sequences tuples.
    """
    out: dict[str, Any] = {}

    def visit(typename: str, obj: Any, prefix: str) -> None:
        for name, (nodetype, desc) in store.fielddefs[typename][1]:
            path = prefix + name
            value = getattr(obj, name)
            if nodetype == Nodetype.BASE:
                out[path] = (
                    value if desc[0] == "string" else np.asarray(value, PRIMITIVES[desc[0]])
                )
            elif nodetype == Nodetype.NAME:
                visit(desc, value, path + ".")
            else:
                (subtype, subdesc), _ = desc
                if subtype == Nodetype.NAME:
                    for k, item in enumerate(value):
                        visit(subdesc, item, f"{path}[{k}].")
                elif subdesc[0] == "string":
                    out[path] = tuple(value)
                else:
                    out[path] = np.asarray(value, dtype=PRIMITIVES[subdesc[0]]).reshape(-1)

    visit(msgtype, message, "")
    return out


def _generic_batch(store: Typestore, msgtype: str, raw: bytes, index: int) -> Batch:
    try:
        message = store.deserialize_cdr(raw, msgtype)
    except Exception as exc:  # rosbags raises SerdeError, struct.error, ...
        raise BagError(f"cannot deserialize message {index} as {msgtype}: {exc}") from exc
    flat = flatten(store, msgtype, message)
    arrays = {k: np.asarray(v)[None, ...] for k, v in flat.items() if isinstance(v, np.ndarray)}
    strings = {k: v for k, v in flat.items() if isinstance(v, (str, tuple))}
    return Batch(np.asarray([index], dtype=np.int64), arrays, strings, fast=False)


def decode(
    store: Typestore,
    msgtype: str,
    raws: Sequence[bytes | memoryview] | NDArray[np.uint8],
    *,
    fast: bool = True,
) -> list[Batch]:
    """Decode serialized messages into batches (together they cover every input index once).

    ``raws``: one bytes-like object per message, or an ``(M, length)`` uint8 array of M messages
    of one length. With ``fast`` (default) messages are grouped by length and layout and decoded
    with NumPy; messages without a usable layout, and all messages when ``fast`` is False, are
    decoded by ``rosbags`` one by one.

    Raises:
        BagError: a message that ``rosbags`` cannot deserialize either.
    """
    if isinstance(raws, np.ndarray):
        if raws.ndim != 2 or raws.dtype != np.uint8:
            raise ValueError(f"raws must be an (M, length) uint8 array, got {raws.dtype} "
                             f"{raws.shape}")  # fmt: skip
        if not fast:
            return [_generic_batch(store, msgtype, r.tobytes(), i) for i, r in enumerate(raws)]
        batches: list[Batch] = []
        if raws.shape[0]:
            _decode_group(store, msgtype, np.arange(raws.shape[0]), raws, batches)
        return batches
    if not fast:
        return [_generic_batch(store, msgtype, bytes(r), i) for i, r in enumerate(raws)]
    batches = []
    lengths = np.asarray(list(map(len, raws)), dtype=np.int64)
    unique = np.unique(lengths)
    for length in unique:
        if unique.size == 1:  # the usual case: one layout for the whole topic
            idx = np.arange(len(raws))
            joined = b"".join(raws)
        else:
            idx = np.flatnonzero(lengths == length)
            joined = b"".join([raws[i] for i in idx.tolist()])
        buf = np.frombuffer(joined, dtype=np.uint8).reshape(idx.size, int(length))
        _decode_group(store, msgtype, idx, buf, batches)
    return batches


def _decode_group(
    store: Typestore, msgtype: str, idx: NDArray[np.intp], buf: NDArray[np.uint8],
    batches: list[Batch],
) -> None:  # fmt: skip
    """Decode messages ``buf`` (k, length) of one length, input positions ``idx``, into
    ``batches``: one batch per layout, the generic decoder for messages without one."""
    remaining = np.arange(idx.size)
    layouts = 0
    while remaining.size:
        first = int(remaining[0])
        layout: Layout | None = None
        if layouts < MAX_LAYOUTS_PER_LENGTH:
            try:
                layout = walk(store, msgtype, buf[first].tobytes())
            except LayoutError:
                layout = None
        if layout is None:
            batches.append(_generic_batch(store, msgtype, buf[first].tobytes(), int(idx[first])))
            remaining = remaining[1:]
            continue
        layouts += 1
        sub = buf[remaining] if remaining.size < idx.size else buf
        match = np.all(sub[:, layout.struct_index] == layout.struct_bytes, axis=1)
        rows = remaining[match]
        arrays = decode_rows(layout, sub[match] if not match.all() else sub)
        batches.append(Batch(idx[rows].astype(np.int64), arrays, dict(layout.strings)))
        remaining = remaining[~match]


class Encoder:
    """Encode many messages of one layout: a serialized template plus per-message values.

    ``template`` is a message object; every message produced has the template's strings and
    sequence lengths, and the numeric fields given to :meth:`encode` replace the template's.
    """

    def __init__(self, store: Typestore, msgtype: str, template: Any) -> None:
        self.template_bytes = bytes(store.serialize_cdr(template, msgtype, little_endian=True))
        self.layout = walk(store, msgtype, self.template_bytes)

    def encode(self, count: int, values: Mapping[str, Any]) -> NDArray[np.uint8]:
        """``(count, size)`` uint8 rows; ``values[path]`` is ``(count,)`` / ``(count, n)`` or a
        scalar / ``(n,)`` broadcast to every row. Unknown paths raise KeyError."""
        size = self.layout.size
        base = np.frombuffer(self.template_bytes, dtype=np.uint8)
        out = np.empty((count, size), dtype=np.uint8)
        out[:] = base
        for path, value in values.items():
            slot = self.layout.slots[path]
            n = 1 if slot.count is None else slot.count
            arr = np.asarray(value, dtype=slot.dtype)
            arr = np.broadcast_to(arr.reshape(-1, n) if arr.ndim else arr, (count, n))
            out[:, slot.offset : slot.offset + slot.nbytes] = (
                np.ascontiguousarray(arr).view(np.uint8).reshape(count, slot.nbytes)
            )
        return out


def iter_rows(buf: NDArray[np.uint8]) -> Iterator[memoryview]:
    """Yield each row of a ``(k, size)`` uint8 array as a read-only memoryview."""
    view = memoryview(np.ascontiguousarray(buf)).cast("B")
    size = buf.shape[1]
    for i in range(buf.shape[0]):
        yield view[i * size : (i + 1) * size]
