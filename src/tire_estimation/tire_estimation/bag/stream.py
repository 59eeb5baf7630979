"""Read a contract bag in one pass, in bounded memory: blocks of streams in stamp order.

:func:`stream_bag` opens a bag as :func:`~tire_estimation.bag.reader.read_bag` does (same
arguments, checks and errors) and :meth:`BagStream.blocks` reads it window by window of log
time (:data:`WINDOW_S`): the messages of a window are decoded in bulk, checked and counted as
:func:`~tire_estimation.bag.reader.read_bag` does, and joined in header-stamp order across
windows (:class:`~tire_estimation.bag.stamp_merge.StampMerge`, horizon :data:`HORIZON_S`).
Each block is a :class:`~tire_estimation.bag.reader.BagData` holding the rows of a span of
stamps; the blocks follow each other in stamp order, so that
:func:`~tire_estimation.sources.bag_samples` of the blocks one after the other are the samples
of the whole bag. Memory holds a window and the rows not yet released, whatever the length of
the bag. ``window_s=math.inf`` reads the whole bag as one window (one block).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from tire_estimation.bag.reader import (
    STREAM_FIELDS,
    BagData,
    RawTopic,
    ReadLog,
    TopicInfo,
    decode_topics,
    iter_raw,
    iter_raw_fast,
    open_bag,
    open_reader,
)
from tire_estimation.bag.stamp_merge import StampMerge
from tire_estimation.core.wheels import CONTRACT_NAMES, Names

#: log time decoded at once, s
WINDOW_S = 30.0
#: how far a stream's messages may arrive behind its newest stamp and still be ordered, s
HORIZON_S = 10.0
#: rows held for ordering at most (about 10 minutes of a simulated bag's inputs and truth)
MAX_PENDING_ROWS = 300_000


@dataclass
class BagStream:
    """A bag opened for :meth:`blocks`.

    ``meta``: the bag's metadata (:class:`BagData` without streams); ``topics``: the topics
    decoded; ``joints``: the bag's joint names for the contract's wheels and steering joint.
    After :meth:`blocks` has run to its end: ``dropped`` and ``notes`` (as in
    :class:`BagData`), and ``read_s``, the time spent reading and decoding, s.
    """

    meta: BagData
    topics: tuple[str, ...]
    files: list[Path] | None
    fast: bool = True
    window_s: float = WINDOW_S
    horizon_s: float = HORIZON_S
    max_pending_rows: int = MAX_PENDING_ROWS
    joints: Names = CONTRACT_NAMES
    #: added to the header stamps of a stream (by its BagData field name) before the merge, ns
    stamp_shift_ns: Mapping[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    read_s: float = 0.0

    def _windows(self) -> Iterator[dict[str, RawTopic]]:
        window_ns = None if math.isinf(self.window_s) else round(self.window_s * 1e9)
        path = self.meta.path
        if self.files is not None:
            yield from iter_raw_fast(path, self.files, self.topics, window_ns)
            return
        reader = open_reader(path)
        try:
            yield from iter_raw(reader, path, self.topics, window_ns)
        finally:
            reader.close()

    def blocks(self) -> Iterator[BagData]:
        """The bag's streams in blocks of stamps, in stamp order (see the module docstring)."""
        log = ReadLog()
        merge = StampMerge(round(self.horizon_s * 1e9), self.max_pending_rows, log)
        infos = self.meta.topics
        seen: Counter[str] = Counter()
        self.read_s = 0.0
        start = time.perf_counter()
        for raw in self._windows():
            for topic, rt in raw.items():
                seen[topic] += len(rt)
            streams = decode_topics(
                raw, fast=self.fast, log=log, match_velocity=False, joints=self.joints
            )
            for name, shift_ns in self.stamp_shift_ns.items():
                decoded = streams.get(name)
                if decoded is not None and shift_ns:
                    streams[name] = dataclasses.replace(decoded, t_ns=decoded.t_ns + shift_ns)
            merge.add({name: streams.get(name) for name in STREAM_FIELDS.values()})
            open_fields = {
                STREAM_FIELDS[t]
                for t in self.topics
                if t in infos and seen[t] < infos[t].count and t in STREAM_FIELDS
            }
            block = merge.release(open_fields)
            self.read_s += time.perf_counter() - start
            if block:
                yield dataclasses.replace(self.meta, **block)
            start = time.perf_counter()
        block = merge.release(None)
        self.dropped = dict(sorted(log.dropped.items()))
        self.notes = tuple(log.notes)
        self.read_s += time.perf_counter() - start
        if block:
            yield dataclasses.replace(self.meta, **block)


def stream_bag(
    path: Path | str,
    *,
    topics: Iterable[str] | Callable[[Mapping[str, TopicInfo]], Iterable[str]] | None = None,
    require: Iterable[str] = (),
    fast: bool = True,
    window_s: float = WINDOW_S,
    joints: Names = CONTRACT_NAMES,
    stamp_shift_s: Mapping[str, float] | None = None,
) -> BagStream:
    """Open a contract bag for reading in blocks (arguments and errors as
    :func:`~tire_estimation.bag.reader.read_bag`; the messages are read by
    :meth:`BagStream.blocks`, which raises the errors of a corrupt bag). ``stamp_shift_s``:
    seconds added to the header stamps of topics (a stream stamped by another clock), the
    merge holding the other streams back for them."""
    meta, selected, files = open_bag(path, topics=topics, require=require, fast=fast)
    shift_ns = {
        STREAM_FIELDS[topic]: round(seconds * 1e9)
        for topic, seconds in (stamp_shift_s or {}).items()
    }
    return BagStream(
        meta, selected, files, fast=fast, window_s=window_s, joints=joints, stamp_shift_ns=shift_ns
    )
