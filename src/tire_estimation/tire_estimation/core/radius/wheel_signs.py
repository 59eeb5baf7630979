"""Wheels whose speed arrives with its sign reversed, told from the motion the GNSS shows.

A wheel-speed driver may report one side's wheels with the opposite sign (a motor or encoder
mounted mirrored, a joint axis pointing the other way), or every wheel negative when rolling
forward. With a mirrored side the rear wheels' mean speed reads about zero and their difference
reads as a turn on the spot: the pose cannot follow the fixes and nothing is learned.

The wheel speeds alone cannot tell a mirrored side from a robot turning on the spot; the
receiver can. While it moves at :data:`MIN_SPEED_M_S` or more (its Doppler speed, or without
one the distance between fixes :data:`SPEED_BASELINE_S` apart), each wheel that turns at half
that speed or more counts the time it turns forward (positive) and backward (negative). After
:data:`DECIDE_S` seconds of such motion a wheel that turned backward for at least
:data:`REVERSED_SHARE` of them is reversed: the estimator negates its speed from then on
(:meth:`WheelSigns.correct`), and the replay and ``/diagnostics`` report it. Vehicles drive
forward most of the time: a drive that backs up for nine tenths of its first 20 s of motion at
1 m/s or more would be read as reversed wiring. Each wheel is decided once; a wheel still
undecided after :data:`GIVE_UP_FACTOR` times that much motion (not reported, standing still
in a lost signal) stays as it is and the counting stops.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.wheels import WHEELS

#: the receiver's speed at which the wheels' signs are counted, m/s
MIN_SPEED_M_S = 1.0

#: a wheel's sign is counted while it turns at this share of the receiver's speed or more
MIN_SPEED_SHARE = 0.5

#: seconds of counted motion after which a wheel is decided, s
DECIDE_S = 20.0

#: the counting stops after this many times ``DECIDE_S`` of motion
GIVE_UP_FACTOR = 5.0

#: a wheel is reversed when it turned backward for this share of the counted time or more
REVERSED_SHARE = 0.9

#: without a Doppler velocity, the speed is the distance between fixes this far apart, s,
#: taken when it is at least :data:`SPEED_MIN_STDS` times the fixes' std
SPEED_BASELINE_S = 5.0
SPEED_MIN_STDS = 5.0

#: a receiver speed older than this is not used, s
SPEED_MAX_AGE_S = 2.0

#: longest interval one wheel-speed sample stands for, s
_MAX_DT_S = 0.1


class WheelSigns:
    """The sign of each wheel's speed (fl, fr, rl, rr) against the receiver's motion."""

    def __init__(self, nominal_radius_m: float) -> None:
        self._radius_m = nominal_radius_m
        #: per wheel: its speed arrives negative when rolling forward (negated since)
        self.reversed = [False] * 4
        #: every wheel decided: nothing more is counted
        self.settled = False
        #: any wheel reversed (the estimator corrects its input while this is true)
        self.any_reversed = False
        self._decided = [False] * 4
        self._forward_s = [0.0] * 4
        self._backward_s = [0.0] * 4
        self._factors = np.ones(4)
        self._speed: tuple[int, float] | None = None  # (t_ns, m/s)
        self._velocity_t_ns: int | None = None
        self._fixes: deque[tuple[int, float, float]] = deque()
        self._last_t_ns: int | None = None
        self._moving_s = 0.0

    def on_velocity(self, t_ns: int, east_m_s: float, north_m_s: float) -> None:
        """The receiver's horizontal Doppler velocity, m/s."""
        if self.settled:
            return
        self._velocity_t_ns = t_ns
        self._speed = (t_ns, math.hypot(east_m_s, north_m_s))

    def on_fix(self, t_ns: int, east_m: float, north_m: float, std_m: float) -> None:
        """A fix in the local ENU frame and its horizontal std (used while no velocity is
        fresh)."""
        if self.settled:
            return
        fixes = self._fixes
        fixes.append((t_ns, east_m, north_m))
        baseline_ns = int(SPEED_BASELINE_S * 1e9)
        while len(fixes) > 1 and t_ns - fixes[1][0] >= baseline_ns:
            fixes.popleft()
        t0, e0, n0 = fixes[0]
        v_t = self._velocity_t_ns
        if t_ns - t0 < baseline_ns or (v_t is not None and t_ns - v_t <= 1e9 * SPEED_MAX_AGE_S):
            return
        distance_m = math.hypot(east_m - e0, north_m - n0)
        # a distance within the fixes' noise says the receiver stands, not how fast it moves
        speed = distance_m / ((t_ns - t0) * 1e-9) if distance_m >= SPEED_MIN_STDS * std_m else 0.0
        self._speed = (t_ns, speed)

    def add(self, t_ns: int, wheel_speed_rad_s: list[float]) -> bool:
        """One wheel-speed sample (fl, fr, rl, rr), rad/s, as it arrived (NaN: not reported).
        True when a wheel was found reversed at this sample (the estimator's input changes:
        what it took from the earlier samples is to be forgotten)."""
        last, self._last_t_ns = self._last_t_ns, t_ns
        speed = self._speed
        if self.settled or last is None or speed is None:
            return False
        speed_t_ns, speed_m_s = speed
        if speed_m_s < MIN_SPEED_M_S or (t_ns - speed_t_ns) * 1e-9 > SPEED_MAX_AGE_S:
            return False
        found = False
        dt_s = min(max((t_ns - last) * 1e-9, 0.0), _MAX_DT_S)
        w_min = MIN_SPEED_SHARE * speed_m_s / self._radius_m
        self._moving_s += dt_s
        for k, w in enumerate(wheel_speed_rad_s):
            if self._decided[k]:
                continue
            if w >= w_min:
                self._forward_s[k] += dt_s
            elif w <= -w_min:
                self._backward_s[k] += dt_s
            total = self._forward_s[k] + self._backward_s[k]
            if total >= DECIDE_S:
                self._decided[k] = True
                if self._backward_s[k] >= REVERSED_SHARE * total:
                    self.reversed[k] = True
                    self._factors[k] = -1.0
                    self.any_reversed = found = True
        self.settled = all(self._decided) or self._moving_s >= GIVE_UP_FACTOR * DECIDE_S
        if found:
            self._fixes.clear()  # the estimator's origin starts again
        return found

    @property
    def reversed_wheels(self) -> list[str]:
        """The names of the reversed wheels (fl, fr, rl, rr order)."""
        return [name for name, rev in zip(WHEELS, self.reversed, strict=True) if rev]

    def correct(self, wheel_speed_rad_s: F64) -> F64:
        """The wheel speeds (4,) with the reversed wheels negated (a new array)."""
        return wheel_speed_rad_s * self._factors
