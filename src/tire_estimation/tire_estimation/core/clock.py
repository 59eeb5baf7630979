"""Stamps that jump: a sample far from the others is held; a run that agrees makes a new clock.

Every stream is expected to run on one clock. A sample whose stamp lies more than
``max_jump_ns`` before or after the newest accepted stamp (the guard's *present*) is held as
*suspect*:

* when the stream's next sample is consistent again, the held ones were outliers (one
  message stamped two hours ahead): they are dropped and counted;
* when ``confirm_samples`` suspects of one stream agree with each other (each within
  ``max_jump_ns`` of the one before), the stream has a new clock and it is adopted:

  - if they lie ahead and no stream delivered a consistent sample meanwhile, every stream
    went silent and came back later (a pause in a recording): the present moves forward,
    the stamps are kept, the estimators see the gap;
  - if they lie behind and no stream delivered meanwhile (a clock stepped back), the stream
    gets the offset that puts its first suspect right after the present: the estimators see
    one continuous time;
  - if the other streams went on (one stream's clock jumped), the offset puts the newest
    suspect, which just arrived, at the present.

  Other streams whose held suspects agree with a new offset take it at once.

Released samples carry the guard's *internal* stamp ``t + offset``; :meth:`ClockGuard.offset_ns`
maps an output made from them back to the stream's own clock. On data without jumps every
offset stays 0 and every sample passes at once, unchanged.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Generic, TypeVar

from tire_estimation.core.validation import require_positive

T = TypeVar("T")

#: internal stamp of a re-timed stream's first sample after the present, ns
STEP_AFTER_PRESENT_NS = 1


@dataclass(frozen=True)
class ClockGuardConfig:
    """How far a stamp may be from the present before it is suspect, and how many agreeing
    suspects make a new clock.

    Attributes:
        max_jump_s: a stamp more than this before or after the newest accepted stamp is
            suspect, s. Default 5.
        confirm_samples: suspects of one stream, each within ``max_jump_s`` of the one
            before, that make a new clock. Default 5.
    """

    max_jump_s: float = 5.0
    confirm_samples: int = 5

    def __post_init__(self) -> None:
        require_positive("max_clock_jump_s", self.max_jump_s)
        if isinstance(self.confirm_samples, bool) or not isinstance(self.confirm_samples, int):
            raise TypeError(f"confirm_samples must be an int, got {self.confirm_samples!r}")
        require_positive("confirm_samples", self.confirm_samples)


class ClockGuard(Generic[T]):
    """Per-stream clock offsets in front of the ordering; ``admit`` returns what may go on.

    Args:
        config: tolerance and confirmation length.
    """

    def __init__(self, config: ClockGuardConfig | None = None) -> None:
        cfg = config or ClockGuardConfig()
        self.config = cfg
        self._tol_ns = round(cfg.max_jump_s * 1e9)
        self._confirm = cfg.confirm_samples
        #: newest accepted internal stamp (None before the first sample)
        self.present_ns: int | None = None
        self._offset: dict[str, int] = {}
        self._held: dict[str, list[tuple[int, T]]] = {}
        # accepted samples so far, and their count when each stream's run of suspects began
        self._accepted = 0
        self._run_began_at: dict[str, int] = {}
        # offset most recently adopted by a re-timed stream (other streams may share it)
        self._candidate_ns: int | None = None
        #: suspects dropped as outliers, per stream
        self.dropped: Counter[str] = Counter()
        #: new clocks adopted, per stream
        self.jumps: Counter[str] = Counter()

    def offset_ns(self, stream: str) -> int:
        """Internal stamp minus the stream's own stamp (0 until its clock jumped)."""
        return self._offset.get(stream, 0)

    def drop_counts(self) -> dict[str, int]:
        """The dropped outliers as ``<stream>:clock_jump`` counters."""
        return {f"{stream}:clock_jump": n for stream, n in self.dropped.items() if n}

    def held(self) -> int:
        """Number of suspects held."""
        return sum(len(run) for run in self._held.values())

    def discard_held(self) -> None:
        """Drop and count every held suspect (the end of a recording)."""
        for stream in self._held:
            self._drop_held(stream)

    def admit_now(self, stream: str, t_ns: int) -> int | None:
        """The internal stamp of a sample of ``stream`` stamped ``t_ns`` that goes on at once
        and alone (near the present, nothing held on its stream), accepted as :meth:`admit`
        accepts it; None, with nothing changed, for any other sample (give it to
        :meth:`admit`)."""
        present = self.present_ns
        if present is None:
            return None
        u_ns = t_ns + self._offset.get(stream, 0)
        tol = self._tol_ns
        if present - tol <= u_ns <= present + tol and not self._held.get(stream):
            if u_ns > present:
                self.present_ns = u_ns
            self._accepted += 1
            return u_ns
        return None

    def admit(self, stream: str, t_ns: int, item: T) -> list[tuple[int, T]]:
        """Take one sample of ``stream`` stamped ``t_ns``; return ``(internal stamp, item)`` of
        every sample that may go on now (this one, or held ones a new clock released)."""
        present = self.present_ns
        u_ns = t_ns + self._offset.get(stream, 0)
        if present is None:
            self.present_ns = u_ns
            self._accepted += 1
            return [(u_ns, item)]
        tol = self._tol_ns
        if present - tol <= u_ns <= present + tol:
            return self._accept(stream, u_ns, item)
        cand = self._candidate_ns
        held = self._held.get(stream)
        if (
            cand is not None
            and held
            and cand != self._offset.get(stream, 0)
            and all(present - tol <= t + cand <= present + tol for t, _ in (*held, (t_ns, item)))
        ):
            # two or more samples of this stream made the jump another stream already made (one
            # alone may be an outlier that happens to match)
            self._offset[stream] = cand
            released = self._take_held(stream, cand)
            released.extend(self._accept(stream, t_ns + cand, item))
            return released
        run = self._held.setdefault(stream, [])
        if run and not -tol <= t_ns - run[-1][0] <= tol:
            self._drop_held(stream)
        if not run:
            self._run_began_at[stream] = self._accepted
        run.append((t_ns, item))
        if len(run) < self._confirm:
            return []
        return self._adopt(stream)

    # ------------------------------------------------------------------ internals
    def _accept(self, stream: str, u_ns: int, item: T) -> list[tuple[int, T]]:
        released: list[tuple[int, T]] = []
        if self._held.get(stream):
            # the stream is back on its clock: what it held were outliers
            self._drop_held(stream)
        assert self.present_ns is not None
        if u_ns > self.present_ns:
            self.present_ns = u_ns
        self._accepted += 1
        released.append((u_ns, item))
        return released

    def _drop_held(self, stream: str) -> None:
        run = self._held.get(stream)
        if run:
            self.dropped[stream] += len(run)
            run.clear()

    def _take_held(self, stream: str, offset_ns: int) -> list[tuple[int, T]]:
        run = self._held.get(stream) or []
        out = [(t + offset_ns, item) for t, item in run]
        run.clear()
        return out

    def _adopt(self, stream: str) -> list[tuple[int, T]]:
        """A run of agreeing suspects: the stream's new clock."""
        run = self._held[stream]
        present = self.present_ns
        assert present is not None
        offset = self._offset.get(stream, 0)
        first_ns = run[0][0]
        silent = self._accepted == self._run_began_at.get(stream, -1)
        if not silent:
            # the other streams went on: the newest suspect, just arrived, is the present;
            # the older ones keep their spacing (and may be late for the ordering)
            offset = present - run[-1][0]
        elif first_ns + offset <= present:
            # every stream stepped back: one continuous time, the first suspect right after
            # the present
            offset = present + STEP_AFTER_PRESENT_NS - first_ns
        # else every stream went silent and came back later: a pause, the stamps are kept
        if offset != self._offset.get(stream, 0):
            self._offset[stream] = offset
            self._candidate_ns = offset
        self.jumps[stream] += 1
        released = self._take_held(stream, offset)
        self._accepted += len(released)
        # streams whose suspects now agree with the present (their offset or the new one)
        self.present_ns = max(present, max(u for u, _ in released))
        tol = self._tol_ns
        for other, held in self._held.items():
            if other == stream or not held:
                continue
            last_ns = held[-1][0]
            own = self._offset.get(other, 0)
            if abs(last_ns + own - self.present_ns) <= tol:
                released.extend(self._take_held(other, own))
            elif abs(last_ns + offset - self.present_ns) <= tol:
                self._offset[other] = offset
                released.extend(self._take_held(other, offset))
        self.present_ns = max(present, max(u for u, _ in released))
        released.sort(key=lambda entry: entry[0])
        return released
