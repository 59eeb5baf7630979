"""Front and rear wheel names exchanged, told from the turns.

A wheel-speed driver that publishes the rear wheels' speeds under the front wheels' names (and
the front under the rear: a CAN decoding with the axles in the other order) leaves every check
on one axle satisfied: the steered front wheels' difference follows the gyro about as well as
the rear's. The estimator would learn the front tyres' radii as the rear ones, with the steering
geometry and a front drive's traction slip in them.

The axles differ in a turn. The rear axle's centre moves along the car; the front axle's centre
runs on a wider circle, ``v_f = v_r sqrt(1 + (L kappa)^2)`` (bicycle model, ``L`` the
wheelbase, ``kappa = r / v_r`` the curvature from the gyro's yaw rate ``r``), so
``v_f / v_r - 1`` is about ``x = (L r / v_r)^2 / 2``. Per bin of :data:`BIN_S` seconds the front
wheels' mean speed over the rear wheels' minus one, ``y``, is fitted by least squares to
``y = c_0 + s x + c_1 a_y^2 + c_2 a_x``: ``c_0`` the two axles' radius ratio, ``a_y^2``
(``a_y = v_r r``) what the tyres' slip angles change at speed, ``a_x`` (the IMU's) a driven
axle's traction slip. ``s`` is about +1 wired right and about -1 with the names exchanged (``y``
is then ``v_r / v_f - 1``). A highway's curves keep ``x`` below 1e-3, where ``s`` is not resolved
(standard error 1.7-3.4 on 5-min simulated drives) and nothing is decided; in town, with turns of
10-20 m, a few minutes resolve it (simulated `city` and `slow` drives: ``s`` 0.95-0.98 wired
right, -0.89 to -0.92 exchanged, standard error 0.01-0.03 in 5 min).

Decided once, when ``|s|`` is at least :data:`MIN_ABS_SLOPE`, at least :data:`T_DECIDE`
standard errors from 0, with a standard error of at most :data:`MAX_SLOPE_SE`: a negative
``s`` is an exchange (:attr:`AxleOrder.exchanged`; the estimator exchanges the axles back and
learns again from the prior), a positive one confirms the order and the fit stops. Two chained
wheels per side (a skid-steer robot whose driver writes one speed for both) give ``y = 0`` and
no decision; without the front wheels or the gyro nothing is fitted.
"""

from __future__ import annotations

import math

import numpy as np

#: length of a bin, s
BIN_S = 1.0

#: a bin counts while the rear axle moves at this speed or more, m/s
MIN_SPEED_M_S = 2.0

#: fewest bins before a decision
MIN_BINS = 60

#: largest standard error of ``s`` for a decision
MAX_SLOPE_SE = 0.2

#: ``|s|`` over its standard error needed for a decision
T_DECIDE = 5.0

#: smallest ``|s|`` that decides (the kinematic signal is about 1)
MIN_ABS_SLOPE = 0.5


class AxleOrder:
    """Fits the front wheels' speed over the rear wheels' against the turns (module
    docstring) and decides once whether the axles' names are exchanged."""

    def __init__(self, wheelbase_m: float, radius_m: float) -> None:
        self._wheelbase_m = wheelbase_m
        self._radius_m = radius_m
        #: the front and rear names arrive exchanged: the estimator exchanges them back
        self.exchanged = False
        #: None until decided, then the slope ``s`` it was decided on
        self.slope: float | None = None
        # the open bin: [front speed, rear speed, yaw rate, a_x] sums, samples, first stamp
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._count = 0
        self._t0_ns: int | None = None
        # normal equations of [1, x, a_y^2, a_x] -> y
        self._xtx = np.zeros((4, 4))
        self._xty = np.zeros(4)
        self._yty = 0.0
        self._n = 0

    @property
    def decided(self) -> bool:
        """Whether the order is decided (exchanged or confirmed)."""
        return self.slope is not None

    def add(
        self, t_ns: int, wheel_speed_rad_s: list[float], yaw_rate_rad_s: float, accel_x_m_s2: float
    ) -> bool:
        """One wheel-speed sample (fl, fr, rl, rr; rad/s, as the estimator rewired it) with the
        latest yaw rate (rad/s) and longitudinal specific force (m/s^2); True when it decides
        that the axles are exchanged."""
        if self.slope is not None:
            return False
        fl, fr, rl, rr = wheel_speed_rad_s
        front, rear = 0.5 * (fl + fr), 0.5 * (rl + rr)
        if not (math.isfinite(front) and math.isfinite(rear)):
            return False
        if self._t0_ns is None:
            self._t0_ns = t_ns
        sums = self._sums
        sums[0] += front
        sums[1] += rear
        sums[2] += yaw_rate_rad_s
        sums[3] += accel_x_m_s2
        self._count += 1
        if (t_ns - self._t0_ns) * 1e-9 < BIN_S:
            return False
        front, rear, r, a_x = (v / self._count for v in sums)
        self._sums = [0.0, 0.0, 0.0, 0.0]
        self._count = 0
        self._t0_ns = None
        speed_m_s = rear * self._radius_m
        if speed_m_s < MIN_SPEED_M_S or front <= 0.0:
            return False
        # v_f / v_r - 1 = sqrt(1 + (L kappa)^2) - 1 ~ (L r / v_r)^2 / 2
        x = 0.5 * (self._wheelbase_m * r / speed_m_s) ** 2
        row = np.array([1.0, x, (speed_m_s * r) ** 2, a_x])
        y = front / rear - 1.0
        self._xtx += np.outer(row, row)
        self._xty += row * y
        self._yty += y * y
        self._n += 1
        return self._decide()

    def _decide(self) -> bool:
        """The slope and its standard error from the normal equations; True on an exchange."""
        if self._n < MIN_BINS:
            return False
        # pseudo-inverse: a column without spread (no a_x reported) drops out of the fit
        inv = np.linalg.pinv(self._xtx, rcond=1e-12)
        beta = inv @ self._xty
        rss = self._yty - float(beta @ self._xty)
        if not rss > 0.0:
            return False  # y fitted exactly (chained wheels): nothing to tell
        se = math.sqrt(rss / (self._n - 4) * inv[1, 1])
        s = float(beta[1])
        if not (se <= MAX_SLOPE_SE and abs(s) >= MIN_ABS_SLOPE and abs(s) >= T_DECIDE * se):
            return False
        self.slope = s
        self.exchanged = s < 0.0
        return self.exchanged
