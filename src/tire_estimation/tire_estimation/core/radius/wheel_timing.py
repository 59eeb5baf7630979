"""The time a wheel-speed sample describes, its compensation, and the speeds at a given time.

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
``T / 2``; ABS units and drive controllers stamp the end).

At low speed an edge-timed unit sees fewer than two edges per period: it reports the speed of
the last tooth interval ``pitch / gap`` and holds it until the next edge. That value describes
the wheel at the interval's middle, on average one tooth period ``tau = pitch / omega`` before
the stamp (exactly ``tau`` for ``T / 2 <= tau``: with one or two edges in the window the two
cases weigh to it), so the lag is ``max(T / 2, tau)``: 27 ms at 1.5 m/s on a 0.31 m tyre with
48 teeth, where ``T / 2`` is 5 ms at 100 Hz. The pitch comes from the
data: a held value changes only when a tooth passes, once per ``tau``, so over the samples of
the hold regime the wheel angle they span over the changes they show is the pitch. The samples
are binned by their angle ``omega dt`` (octaves from :data:`PITCH_BIN_BASE_RAD`); a bin whose
share of changed values is below :data:`HOLD_CHANGE_SHARE` is in the hold regime, and the pitch
is taken once two such bins, each with :data:`PITCH_MIN_CHANGES` changes, agree within
:data:`PITCH_AGREEMENT` (a wheel speed quantized in value repeats too, but not at a rate
proportional to the speed), and a bin of samples that turn the wheel by more than that pitch
shows a new value nearly every time (:data:`AT_SPEED_CHANGE_SHARE`). Until then, or when no
bin is in the hold regime (a drive controller's encoder, an ABS unit at speed), the lag is
``T / 2``.

Where one instant's speed is compared with another sensor's (a GNSS Doppler velocity) it is
read off a line through the samples of the :data:`FIT_WINDOW_S` before that instant
(:func:`speeds_at`): a single sample carries its tooth's pitch error for as long as the tooth
takes to pass.
"""

from __future__ import annotations

import itertools
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

#: lower edge of the first bin of a sample's wheel angle ``omega dt``, rad; the bins are
#: octaves, :data:`PITCH_BINS` of them (to 0.64 rad: 64 rad/s at 100 Hz)
PITCH_BIN_BASE_RAD = 0.005
PITCH_BINS = 7
PITCH_TOP_RAD = PITCH_BIN_BASE_RAD * 2**PITCH_BINS

#: share of changed values below which a bin is in the hold regime (at most one edge per
#: sample period: the share is ``omega dt / pitch``)
HOLD_CHANGE_SHARE = 0.6

#: changes a hold bin needs before it counts, and the largest ratio of two bins' pitches that
#: still agree
PITCH_MIN_CHANGES = 100
PITCH_AGREEMENT = 1.25

#: the pitch found must lie between these, rad (a ring of 200 to 24 teeth; ABS rings and
#: magnetic encoders have about 40 to 100)
MIN_PITCH_RAD = 2.0 * math.pi / 200
MAX_PITCH_RAD = 2.0 * math.pi / 24

#: ... and a bin of samples turning the wheel by more than that pitch must show a changed value
#: in this share of them at least (past the hold regime every sample sees its own edges)
AT_SPEED_CHANGE_SHARE = 0.9

#: the tooth-period lag is not taken beyond this, s (a wheel turning four teeth a second)
MAX_TOOTH_LAG_S = 0.25

#: samples between two looks at the bins
PITCH_CHECK_SAMPLES = 200

#: window of the line the wheel speeds are read off at a GNSS velocity's time, s, and the
#: samples it needs (fewer, as at 10 Hz: interpolation)
FIT_WINDOW_S = 0.2
FIT_MIN_SAMPLES = 5


class WheelSpeedTiming:
    """Compensates the lag of wheel speeds: half a sample period, a tooth period at low speed
    (module docstring)."""

    def __init__(self) -> None:
        #: ``T``, the median wheel-speed sample period, s (0 until known)
        self.sample_period_s = 0.0
        #: the tooth pitch found in the hold regime, rad (0 until found)
        self.tooth_pitch_rad = 0.0
        self._intervals: deque[float] = deque(maxlen=PERIOD_WINDOW)
        self._since_median = 0
        self._t_ns: int | None = None
        self._prev: list[float] = [0.0] * 4
        self._alpha = [0.0] * 4
        # per angle bin: samples, their summed angle (rad), changed values
        self._bin_n = [0] * PITCH_BINS
        self._bin_angle = [0.0] * PITCH_BINS
        self._bin_changes = [0] * PITCH_BINS
        self._since_check = 0

    @property
    def lag_s(self) -> float:
        """The half-period lag ``T / 2``, s (at speed; a tooth period where that is longer)."""
        return 0.5 * self.sample_period_s

    def compensate(self, t_ns: int, ws: F64, max_gap_s: float) -> F64:
        """The wheel speeds ``ws`` (4,) rad/s stamped ``t_ns`` as at ``t_ns``:
        ``ws + alpha max(T / 2, pitch / |omega|)``. After a gap longer than ``max_gap_s`` the
        derivative restarts from 0."""
        vals = ws.tolist()
        dt = 0.0 if self._t_ns is None else (t_ns - self._t_ns) * 1e-9
        if 0.0 < dt <= max_gap_s:
            self._note_interval(dt)
            if not self.tooth_pitch_rad:
                self._note_changes(vals, dt)
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
        pitch = self.tooth_pitch_rad
        if not pitch:
            # omega(t) = omega(t - T/2) + alpha T/2: the first-order step from the window's
            # centre to its end
            return np.array([w + a * lag for w, a in zip(vals, self._alpha, strict=True)])
        # held at low speed: omega(t) = omega(t - tau) + alpha tau, tau = pitch / |omega|
        return np.array(
            [
                w + a * max(lag, min(pitch / abs(w), MAX_TOOTH_LAG_S) if w else lag)
                for w, a in zip(vals, self._alpha, strict=True)
            ]
        )

    def _note_interval(self, dt: float) -> None:
        self._intervals.append(dt)
        self._since_median += 1
        if self._since_median >= PERIOD_MIN_INTERVALS:
            self._since_median = 0
            self.sample_period_s = median(self._intervals)

    def _note_changes(self, vals: list[float], dt: float) -> None:
        """Bins each moving wheel's angle over the interval and whether its value changed."""
        prev = self._prev
        # past the last bin (and NaN) nothing is binned: one comparison per wheel at speed
        top = PITCH_TOP_RAD / dt
        for i in range(4):
            w = vals[i]
            if not 0.0 < abs(w) < top or not prev[i]:
                continue
            angle = abs(w) * dt
            # octave of the angle: frexp gives angle / base = m 2^e, 0.5 <= m < 1
            b = math.frexp(angle / PITCH_BIN_BASE_RAD)[1] - 1
            if 0 <= b < PITCH_BINS:
                self._bin_n[b] += 1
                self._bin_angle[b] += angle
                self._bin_changes[b] += w != prev[i]
        self._since_check += 1
        if self._since_check >= PITCH_CHECK_SAMPLES:
            self._since_check = 0
            self.tooth_pitch_rad = hold_pitch(self._bin_n, self._bin_angle, self._bin_changes)


def hold_pitch(counts: list[int], angles: list[float], changes: list[int]) -> float:
    """The tooth pitch the hold regime's bins show, rad (0: not shown).

    ``counts``, ``angles``, ``changes``: per angle bin the samples, their summed angle
    ``omega dt`` (rad) and how many changed value. In the hold regime one value per tooth:
    ``E[changes] = sum(omega dt) / pitch``."""
    hold = [
        (angles[b], changes[b])
        for b in range(len(counts))
        if changes[b] >= PITCH_MIN_CHANGES and changes[b] < HOLD_CHANGE_SHARE * counts[b]
    ]
    for (a1, c1), (a2, c2) in itertools.pairwise(hold):
        lo, hi = sorted((a1 / c1, a2 / c2))
        # pitch = sum(omega dt) / changes over the two bins
        pitch = (a1 + a2) / (c1 + c2)
        if hi <= PITCH_AGREEMENT * lo and MIN_PITCH_RAD <= pitch <= MAX_PITCH_RAD:
            at_speed = any(
                counts[b] >= PITCH_MIN_CHANGES
                and angles[b] >= pitch * counts[b]
                and changes[b] >= AT_SPEED_CHANGE_SHARE * counts[b]
                for b in range(len(counts))
            )
            return pitch if at_speed else 0.0
    return 0.0


def speeds_at(x_s: float, rel_s: F64, speeds: F64) -> tuple[F64, float]:
    """The wheel speeds at ``x_s`` from a line fitted to the samples of the
    :data:`FIT_WINDOW_S` before it, and the variance of their sum there.

    ``rel_s`` (n,): the samples' times, s, increasing; ``speeds`` (n, k): their speeds, rad/s.
    One sample holds its sensor's error for as long as a tooth takes to pass (1 % of the speed
    with a pitch error of 1e-3 rad on a 48-tooth ring), and a GNSS velocity compared with it
    takes that error whole; the line averages it over the window. With fewer than
    :data:`FIT_MIN_SAMPLES` samples in the window: linear interpolation, variance 0."""
    win = (rel_s >= x_s - FIT_WINDOW_S) & (rel_s <= x_s + 1e-9)
    n = int(win.sum())
    if n < FIT_MIN_SAMPLES:
        return np.array([np.interp(x_s, rel_s, speeds[:, j]) for j in range(speeds.shape[1])]), 0.0
    d = rel_s[win] - x_s
    y = speeds[win]
    d_mean = float(d.mean())
    sxx = float(((d - d_mean) ** 2).sum())
    # least squares y = a + b d: b = S_dy / S_dd, a = y_mean - b d_mean (the value at x_s)
    y_mean = y.mean(axis=0)
    slope = ((d - d_mean) @ (y - y_mean)) / sxx
    value = y_mean - slope * d_mean
    res = y - (value + np.outer(d, slope))
    # var(a) = s^2 (1 / n + d_mean^2 / S_dd), s^2 = sum(res^2) / (n - 2), per wheel
    var = (res**2).sum(axis=0) / (n - 2) * (1.0 / n + d_mean**2 / sxx)
    return value, float(var.sum())
