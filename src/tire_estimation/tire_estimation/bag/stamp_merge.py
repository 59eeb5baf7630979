"""Streams decoded window by window, released in blocks of header-stamp order.

A bag read in windows of log time (:mod:`tire_estimation.bag.stream`) gives, per window, each
stream sorted by stamp without repeated stamps (:func:`~tire_estimation.bag.reader.decode_topics`).
:class:`StampMerge` joins the windows of a stream and releases blocks: every row of every stream
with a stamp below a watermark, the watermark trailing the newest stamp of each stream that has
messages to come by ``horizon_ns``. Consecutive blocks are in stamp order, so their samples,
merged block by block, are the samples of the whole bag merged at once, as long as no message
arrives more than ``horizon_ns`` behind its stream's newest stamp (and the rows held stay below
``max_pending_rows``, which otherwise moves the watermark up).

A row whose stamp is not newer than the last one released of its stream cannot be put in order
any more: it is dropped and counted as ``duplicate`` (same stamp, as the whole-bag reader counts
it) or ``out_of_order`` (older), under the names of the node's counters.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from tire_estimation.bag.reader import STREAM_FIELDS, ReadLog

#: topic of each stream field of BagData
FIELD_TOPICS: dict[str, str] = {name: topic for topic, name in STREAM_FIELDS.items()}


def row_fields(stream: Any) -> tuple[str, ...]:
    """The fields of a stream dataclass that hold one row per message (NumPy arrays)."""
    return tuple(
        f.name
        for f in dataclasses.fields(stream)
        if isinstance(getattr(stream, f.name), np.ndarray)
    )


def take(stream: Any, index: Any) -> Any:
    """The rows ``index`` (slice, indices or mask) of a stream dataclass."""
    return dataclasses.replace(
        stream, **{name: getattr(stream, name)[index] for name in row_fields(stream)}
    )


def _column(stream: Any, name: str, like: np.ndarray) -> np.ndarray:
    values = getattr(stream, name)
    if values is None:  # absent in this window (e.g. no velocity): not reported
        return np.full((stream.t_ns.size, *like.shape[1:]), np.nan)
    return np.asarray(values)


def join(first: Any, then: Any) -> tuple[Any, int]:
    """The rows of two sorted streams in stamp order (stable: ``first`` before ``then`` at
    equal stamps), keeping the first row of a repeated stamp; and the number dropped. The
    fields that are not rows (names, noise levels) are ``first``'s."""
    t = np.concatenate([first.t_ns, then.t_ns])
    order = np.argsort(t, kind="stable")
    t_sorted = t[order]
    keep = np.ones(t_sorted.size, dtype=bool)
    keep[1:] = np.diff(t_sorted) > 0
    index = order[keep]
    names = set(row_fields(first)) | set(row_fields(then))
    columns = {}
    for name in names:
        like = getattr(first, name) if name in row_fields(first) else getattr(then, name)
        both = [_column(first, name, like), _column(then, name, like)]
        columns[name] = np.concatenate(both)[index]
    return dataclasses.replace(first, **columns), int(t_sorted.size - index.size)


class StampMerge:
    """Windows of decoded streams in, blocks in stamp order out (see the module docstring).

    Args:
        horizon_ns: how far a stream's messages may arrive behind its newest stamp and still
            be put in order.
        max_pending_rows: rows held at most; beyond, the oldest are released (a stream that
            pauses, or one whose stamps lag the others, does not hold the rest).
        log: counts the dropped rows (``<stream>:duplicate``, ``<stream>:out_of_order``).
    """

    def __init__(self, horizon_ns: int, max_pending_rows: int, log: ReadLog) -> None:
        self.horizon_ns = int(horizon_ns)
        self.max_pending_rows = int(max_pending_rows)
        self.log = log
        self._pending: dict[str, Any] = {}
        self._newest: dict[str, int] = {}
        self._released: dict[str, int] = {}

    def add(self, streams: Mapping[str, Any]) -> None:
        """The streams (BagData field -> stream) decoded from one window."""
        for name, stream in streams.items():
            if stream is None or stream.t_ns.size == 0:
                continue
            topic = FIELD_TOPICS[name]
            released = self._released.get(name)
            if released is not None and stream.t_ns[0] <= released:
                same = stream.t_ns == released
                older = stream.t_ns < released
                self.log.drop(
                    topic, "duplicate", int(same.sum()), "messages with a repeated header stamp"
                )
                self.log.drop(
                    topic,
                    "out_of_order",
                    int(older.sum()),
                    "messages further behind their stream's stamps than the replay orders",
                )
                stream = take(stream, ~(same | older))
                if stream.t_ns.size == 0:
                    continue
            newest = self._newest.get(name)
            if newest is not None and stream.t_ns[0] < newest:
                self.log.remark(f"{topic}: messages were not in header-stamp order; sorted")
            last = int(stream.t_ns[-1])
            self._newest[name] = last if newest is None else max(newest, last)
            held = self._pending.get(name)
            if held is None:
                self._pending[name] = stream
                continue
            joined, repeated = join(held, stream)
            self.log.drop(topic, "duplicate", repeated, "messages with a repeated header stamp")
            self._pending[name] = joined

    def pending_rows(self) -> int:
        """Rows held."""
        return sum(int(s.t_ns.size) for s in self._pending.values())

    def release(self, open_fields: set[str] | None = None) -> dict[str, Any]:
        """The block of rows that no later window can precede: those below the watermark of
        the streams in ``open_fields`` (with messages to come); None: everything held (the
        end of the bag). Streams without rows in the block are left out."""
        watermark: int | None = None
        if open_fields is not None:
            lags = [self._newest[n] - self.horizon_ns for n in open_fields if n in self._newest]
            watermark = min(lags) if lags else None
            held = self.pending_rows()
            if held > self.max_pending_rows:
                stamps = np.concatenate([s.t_ns for s in self._pending.values()])
                cut = int(np.partition(stamps, held - self.max_pending_rows // 2)[
                    held - self.max_pending_rows // 2
                ])  # fmt: skip
                watermark = cut if watermark is None else max(watermark, cut)
        block: dict[str, Any] = {}
        for name, stream in list(self._pending.items()):
            n = (
                stream.t_ns.size
                if watermark is None
                else int(np.searchsorted(stream.t_ns, watermark, side="left"))
            )
            if n == 0:
                continue
            block[name] = take(stream, slice(0, n))
            self._released[name] = int(stream.t_ns[n - 1])
            if n == stream.t_ns.size:
                del self._pending[name]
            else:
                self._pending[name] = take(stream, slice(n, None))
        return block
