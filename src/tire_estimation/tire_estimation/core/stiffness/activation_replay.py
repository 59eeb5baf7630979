"""Learning from the onset of an excitation: rewind a filter and replay its inputs.

The stiffness estimators learn only once the excitation measure over a sliding window passes
its threshold (Berntorp & Di Cairano 2018, Sec. V). On a snow sine drive the RMS steering angle
over 1 s reaches 0.003 rad about 0.25 s after the steering starts; until then the particles'
lateral speed runs on the prior stiffness, and from a prior at 150 % of the truth the filter's
vY is off by +0.0045 m/s when learning starts (40 % of the true vY RMS over the next 0.5 s;
docs/stiffness_limits.md, "What limits Algorithm 1 on snow"). The rear cornering stiffness
then needs seconds to come down. Not in the paper.

:class:`ActivationReplay` keeps copies of the filter taken while it does not learn, every
``horizon_s / 10``, and the inputs of every step since the oldest copy that is still needed
(at least ``horizon_s`` back). On the step on which learning starts,
:meth:`ActivationReplay.rewind` hands back the newest copy taken before the first kept step that
was itself excited (the front-end's test, e.g. ``|delta| >= activation_steer_rad``), and the
steps after the copy; the front-end swaps the copy in and runs those steps again with learning
on, then the new step. The filter so learns from the onset of the excitation, at most
``horizon_s`` (plus one copy interval) back, and not from the straight driving before it:
learning there would only apply the forgetting of the statistics to steps that carry no
information (on an asphalt drive from 75 % a fixed 1 s replay, with 0.7 s of it straight, ended
one run of 50 at -8.8 %). What was published before stays as it was.

Experimental and off by default (``activation_replay_s`` 0): on 200 snow and 100 asphalt drives
the replay from the onset settles the rear a little more often but ends more tanh runs above
3 % (docs/results.md section 6, the table of options).

The front-end decides what a step holds (an opaque record); this module only keeps them in
order. Copies are deep copies except for the objects named in ``shared`` (the random
generator, the read-only configuration), which the copy keeps by reference.
"""

from __future__ import annotations

import copy
from collections import deque
from collections.abc import Callable, Iterable
from typing import Generic, TypeVar

T = TypeVar("T")
R = TypeVar("R")

#: copies per horizon: the oldest copy kept is between ``horizon_s`` and ``1.1 horizon_s`` old,
#: and a rewind starts at most ``horizon_s / 10`` before the first excited step
SNAPSHOTS_PER_HORIZON = 10


class ActivationReplay(Generic[T, R]):
    """Copies of a filter of type ``T`` and the step records ``R`` after them.

    Args:
        horizon_s: how far back copies and steps are kept (a rewind goes back at most this
            plus one copy interval), s (0 switches the replay off: nothing is kept and
            :meth:`rewind` returns ``None``).
        shared: objects the copies share with the live filter instead of copying them.
    """

    def __init__(self, horizon_s: float, shared: Iterable[object] = ()) -> None:
        if not horizon_s >= 0.0:
            raise ValueError(f"horizon_s must be >= 0, got {horizon_s!r}")
        self.horizon_ns = round(horizon_s * 1e9)
        self.interval_ns = self.horizon_ns // SNAPSHOTS_PER_HORIZON
        self._shared = tuple(shared)
        self._snapshots: deque[tuple[int, T]] = deque()
        self._steps: deque[tuple[int, R]] = deque()

    @property
    def enabled(self) -> bool:
        """A rewind can go back (``horizon_s`` > 0)."""
        return self.horizon_ns > 0

    @property
    def snapshot_count(self) -> int:
        """Number of copies kept."""
        return len(self._snapshots)

    @property
    def step_count(self) -> int:
        """Number of step records kept."""
        return len(self._steps)

    def clear(self) -> None:
        """Forget every copy and step (filter re-initialized, or learning on)."""
        self._snapshots.clear()
        self._steps.clear()

    def record(self, t_ns: int, step: R, filt: T) -> None:
        """Keep ``step`` (stamp ``t_ns``, non-decreasing), which ``filt`` has just run without
        learning; copy ``filt`` when the newest copy is ``horizon_s / 10`` old or there is none.
        """
        if not self.enabled:
            return
        self._steps.append((t_ns, step))
        if not self._snapshots or t_ns - self._snapshots[-1][0] >= self.interval_ns:
            memo = {id(obj): obj for obj in self._shared}
            self._snapshots.append((t_ns, copy.deepcopy(filt, memo)))
        # keep the newest copy at or before t - horizon, and everything after it
        while len(self._snapshots) > 1 and self._snapshots[1][0] <= t_ns - self.horizon_ns:
            self._snapshots.popleft()
        first = self._snapshots[0][0]
        while self._steps and self._steps[0][0] <= first:
            self._steps.popleft()

    def rewind(self, excited: Callable[[R], bool] | None = None) -> tuple[T, list[R]] | None:
        """The newest copy taken before the first kept step for which ``excited`` holds (the
        oldest copy when ``excited`` is None or that step is older than every copy) and the
        steps after the copy, oldest first; ``None`` if there is no copy or no excited step.
        Forgets everything either way."""
        onset = None
        for t, step in self._steps:
            if excited is None or excited(step):
                onset = t
                break
        if not self._snapshots or onset is None:
            self.clear()
            return None
        start, filt = self._snapshots[0]
        for t, snap in self._snapshots:
            if t >= onset:
                break
            start, filt = t, snap
        steps = [s for t, s in self._steps if t > start]
        self.clear()
        return filt, steps


__all__ = ["SNAPSHOTS_PER_HORIZON", "ActivationReplay"]
