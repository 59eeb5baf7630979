"""Release samples of several streams in header-stamp order with no added latency.

A live node receives each topic on its own queue, so samples of different streams can arrive
out of stamp order. The estimator advances on the *clock* stream (wheel speeds, ~100 Hz); the
dispatcher holds samples of the other streams whose stamp lies ahead of the last clock sample and
releases them just before the first clock sample that passes them. Samples that arrive already
behind the clock are released at once (the estimator tolerates that small lag). The order of
released samples matches the offline replay's merge: on equal stamps the clock sample first.
"""

from __future__ import annotations

import heapq
import itertools
from typing import Any

Sample = tuple[int, str, Any]


class StampOrderedDispatcher:
    """Orders ``(t_ns, kind, payload)`` samples by stamp around a clock stream.

    Args:
        clock_kind: the stream that drives the estimator (released immediately).
        max_hold_ns: a held sample is released anyway once a newer sample of any stream is
            this much ahead of it (the clock stream may have stopped). Default 0.5 s.
    """

    def __init__(self, clock_kind: str, max_hold_ns: int = 500_000_000) -> None:
        self.clock_kind = clock_kind
        self.max_hold_ns = int(max_hold_ns)
        self._held: list[tuple[int, int, str, Any]] = []
        self._seq = itertools.count()
        self.last_clock_ns: int | None = None

    def __len__(self) -> int:
        return len(self._held)

    def push(self, t_ns: int, kind: str, payload: Any) -> list[Sample]:
        """Add a sample; return the samples to process now, in order."""
        out: list[Sample] = []
        if kind == self.clock_kind:
            # held samples stamped before the clock sample go first ...
            out.extend(self._release(lambda t: t < t_ns))
            out.append((t_ns, kind, payload))
            # ... and those with the same stamp right after it (replay merge order)
            out.extend(self._release(lambda t: t <= t_ns))
            if self.last_clock_ns is None or t_ns > self.last_clock_ns:
                self.last_clock_ns = t_ns
            return out
        if self.last_clock_ns is not None and t_ns <= self.last_clock_ns:
            out.append((t_ns, kind, payload))
        else:
            heapq.heappush(self._held, (t_ns, next(self._seq), kind, payload))
        out.extend(self._release(lambda t: t <= t_ns - self.max_hold_ns))
        return out

    def flush(self) -> list[Sample]:
        """Release every held sample in stamp order."""
        return self._release(lambda _t: True)

    def _release(self, due: Any) -> list[Sample]:
        out: list[Sample] = []
        while self._held and due(self._held[0][0]):
            t_ns, _, kind, payload = heapq.heappop(self._held)
            out.append((t_ns, kind, payload))
        return out
