"""Release samples of several streams in ``(stamp, priority)`` order with a bounded latency.

A live node receives each topic on its own queue, so samples of different streams arrive out of
stamp order. The buffer advances on the *clock* streams (the speed sources, about 100 Hz): the
newest clock sample, moved back by ``delay_ns``, is a watermark, and every held sample whose key
``(stamp, priority)`` does not exceed it is released in key order. Other samples wait until the
watermark passes them, or until any newer sample is ``max_hold_ns`` ahead of them (the clock
may have stopped, or the data have none). A sample that arrives already behind the watermark
is released at once (and may then be out of order; the estimators drop what is too old).

When every stream arrives in its own stamp order and no sample arrives more than ``delay_ns``
after a clock sample with a later stamp, the output is the input sorted by
:func:`~tire_estimation.core.samples.order_key`, however the streams were interleaved: a bag
replayed from a file and the same bag received live give the same sequence.
"""

from __future__ import annotations

import heapq
import itertools
from collections import Counter

from tire_estimation.core.samples import MeasuredVelocity, Sample, WheelSpeeds

#: the streams that advance the buffer's clock
CLOCK_KINDS = frozenset({WheelSpeeds.KIND, MeasuredVelocity.KIND})


class ReorderBuffer:
    """Orders samples by ``(stamp, priority)`` around the clock streams.

    Args:
        max_hold_ns: a held sample is released once a newer sample of any stream is this much
            ahead of it. Default 0.5 s.
        delay_ns: how far the watermark lags the newest clock sample: the transport lag of the
            other streams behind the clock streams that is still put in order. Default 0.
    """

    def __init__(self, max_hold_ns: int = 500_000_000, delay_ns: int = 0) -> None:
        self.max_hold_ns = int(max_hold_ns)
        self.delay_ns = int(delay_ns)
        self._held: list[tuple[int, int, int, Sample]] = []
        self._seq = itertools.count()
        #: the watermark: key (stamp - delay, priority) of the newest clock sample, or None
        self.clock: tuple[int, int] | None = None
        #: the newest stamp seen on any stream
        self.newest_ns: int | None = None
        #: samples that arrived behind the watermark (released at once, out of order), per
        #: stream
        self.late: Counter[str] = Counter()

    def __len__(self) -> int:
        return len(self._held)

    def push(self, sample: Sample) -> list[Sample]:
        """Add a sample; return the samples to process now, in order."""
        t_ns, prio = sample.t_ns, sample.PRIORITY
        if self.newest_ns is None or t_ns > self.newest_ns:
            self.newest_ns = t_ns
        if sample.KIND in CLOCK_KINDS:
            mark = (t_ns - self.delay_ns, prio)
            if self.clock is None or mark > self.clock:
                self.clock = mark
            elif (t_ns, prio) <= self.clock:
                self.late[sample.KIND] += 1
            heapq.heappush(self._held, (t_ns, prio, next(self._seq), sample))
            return self._release(self.clock, self.newest_ns - self.max_hold_ns)
        if self.clock is not None and (t_ns, prio) <= self.clock:
            self.late[sample.KIND] += 1
            return [sample]
        heapq.heappush(self._held, (t_ns, prio, next(self._seq), sample))
        return self._release(self.clock, self.newest_ns - self.max_hold_ns)

    def flush(self) -> list[Sample]:
        """Release every held sample in key order."""
        out = [entry[3] for entry in sorted(self._held)]
        self._held.clear()
        return out

    def _release(self, clock: tuple[int, int] | None, stale_ns: int) -> list[Sample]:
        out: list[Sample] = []
        held = self._held
        while held:
            t_ns, prio = held[0][0], held[0][1]
            if (clock is not None and (t_ns, prio) <= clock) or t_ns <= stale_ns:
                out.append(heapq.heappop(held)[3])
            else:
                break
        return out
