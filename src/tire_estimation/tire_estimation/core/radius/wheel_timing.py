"""The time a wheel-speed sample describes, and its compensation.

A wheel speed is a mean over the sample period that ends at its stamp: an ABS unit times the
edges of a toothed ring over its last period ``T`` and reports ``(count - 1) pitch / span``, a
drive controller differences its encoder counts once per period. The value describes the wheel
about ``T / 2`` before the stamp, and while the wheel accelerates at ``alpha`` it reads
``alpha T / 2`` slow (fast while braking). A radius estimate takes the shortfall for a larger
tyre wherever acceleration and braking are not weighed alike (the braking gate, the GNSS
velocity's acceleration gate): on the simulator's slow drive at 100 Hz the rear wheels measure
0.24 % too little distance while accelerating and, less the brake slip, 0.07 % too much
while braking (``evaluation/slow_study.py``'s ``odometry_bias_pct``).

The compensation is the first-order extrapolation to the stamp, ``omega + alpha T / 2``, with
``alpha`` the low-passed derivative of the wheel's own speed and ``T`` the median interval of
the wheel-speed stamps: nothing to configure, and a sensor with a longer delay is
under-compensated (one stamped at the middle of its period would be over-compensated by
``T / 2``; ABS units and drive controllers stamp the end). At low speed an edge-timed unit
holds its last value until the next tooth (a lag up to one tooth period); that part is not
modelled.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

import numpy as np

from tire_estimation.core.arrays import F64

#: time constant of the low-pass derivative of each wheel speed, s
ALPHA_TIME_CONSTANT_S = 0.1

#: intervals the sample period is the median of
PERIOD_WINDOW = 64

#: intervals needed before the first compensation (and between two updates of the median)
PERIOD_MIN_INTERVALS = 16


class WheelSpeedTiming:
    """Compensates the half-period lag of wheel speeds (module docstring)."""

    def __init__(self) -> None:
        #: ``T``, the median wheel-speed sample period, s (0 until known)
        self.sample_period_s = 0.0
        self._intervals: deque[float] = deque(maxlen=PERIOD_WINDOW)
        self._since_median = 0
        self._t_ns: int | None = None
        self._prev: list[float] = [0.0] * 4
        self._alpha = [0.0] * 4

    @property
    def lag_s(self) -> float:
        """The compensated lag ``T / 2``, s."""
        return 0.5 * self.sample_period_s

    def compensate(self, t_ns: int, ws: F64, max_gap_s: float) -> F64:
        """The wheel speeds ``ws`` (4,) rad/s stamped ``t_ns`` as at ``t_ns``:
        ``ws + alpha T / 2``. After a gap longer than ``max_gap_s`` the derivative restarts
        from 0."""
        vals = ws.tolist()
        dt = 0.0 if self._t_ns is None else (t_ns - self._t_ns) * 1e-9
        if 0.0 < dt <= max_gap_s:
            self._note_interval(dt)
            # first-order low-pass of d omega / dt (a wheel not reported, NaN, adds nothing)
            k = dt / (ALPHA_TIME_CONSTANT_S + dt)
            alpha = self._alpha
            for i in range(4):
                rate = (vals[i] - self._prev[i]) / dt
                if math.isfinite(rate):
                    alpha[i] += k * (rate - alpha[i])
        else:
            self._alpha = [0.0] * 4
        self._t_ns = t_ns
        self._prev = vals
        lag = self.lag_s
        if lag == 0.0:
            return ws
        # omega(t) = omega(t - T/2) + alpha T/2: the first-order step from the window's centre
        # to its end
        return np.array([w + a * lag for w, a in zip(vals, self._alpha, strict=True)])

    def _note_interval(self, dt: float) -> None:
        self._intervals.append(dt)
        self._since_median += 1
        if self._since_median >= PERIOD_MIN_INTERVALS:
            self._since_median = 0
            self.sample_period_s = median(self._intervals)
