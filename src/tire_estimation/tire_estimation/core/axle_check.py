"""Can the two wheels of an axle be told apart? A check on the wheel speeds against the gyro.

The radius model reads the heading change from the difference of the rear wheel speeds (eq. 6b:
``r = ((r0 + d4) w4 - (r0 + d3) w3) / l_T``), so a split of the two radii is learned from turns.
In a turn with yaw rate ``r`` the two wheels of an axle differ by about ``|r| l_T / r0`` rad/s.
When they report the same speed through the turns (a locked axle or spool, one sensor's signal
copied to both sides, a dead sensor held at the other's value), the split is unobservable: only
the axle's common radius is. This check counts the turning samples (``|gyro z|`` at least
``min_yaw_rate_rad_s`` at ``min_speed_m_s`` or more) in which an axle's speed difference is
below ``equal_fraction`` of the expected one, over the last ``window`` turning samples.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

from tire_estimation.core.validation import require_positive, require_range
from tire_estimation.core.vehicle import VehicleParams

#: axle name -> (left, right) index in the wheel-speed vector (fl, fr, rl, rr)
AXLES = {"front": (0, 1), "rear": (2, 3)}


@dataclass(frozen=True)
class AxleCheckConfig:
    """Thresholds of :class:`AxleCheck`.

    Attributes:
        min_yaw_rate_rad_s: a sample counts as turning from this gyro yaw rate, rad/s.
            Default 0.05 (a 400 m radius at 20 m/s).
        min_speed_m_s: and from this speed, m/s. Default 2.
        equal_fraction: the two wheels count as equal when their difference is below this share
            of the difference the turn implies, 1. Default 0.2.
        window: turning samples the verdict looks back on. Default 1000 (10 s at 100 Hz).
        min_turning: turning samples needed before a verdict. Default 300.
        unobservable_share: share of equal samples from which the split is unobservable, 1.
            Default 0.9.
    """

    min_yaw_rate_rad_s: float = 0.05
    min_speed_m_s: float = 2.0
    equal_fraction: float = 0.2
    window: int = 1000
    min_turning: int = 300
    unobservable_share: float = 0.9

    def __post_init__(self) -> None:
        require_positive("min_yaw_rate_rad_s", self.min_yaw_rate_rad_s)
        require_positive("min_speed_m_s", self.min_speed_m_s)
        require_range("equal_fraction", self.equal_fraction, 0.0, 1.0)
        require_positive("window", self.window)
        require_positive("min_turning", self.min_turning)
        require_range("unobservable_share", self.unobservable_share, 0.0, 1.0)


@dataclass(frozen=True)
class AxleStatus:
    """One axle's verdict.

    Attributes:
        axle: ``front`` or ``rear``.
        split_observable: True, False, or None (not enough turning samples yet, or no gyro).
        turning_samples: turning samples seen so far.
        equal_share: share of equal speeds among the last ``window`` turning samples.
        reason: the verdict in words.
    """

    axle: str
    split_observable: bool | None
    turning_samples: int
    equal_share: float
    reason: str


class AxleCheck:
    """Counts, per axle, turning samples in which the two wheels report the same speed."""

    def __init__(self, vehicle: VehicleParams, config: AxleCheckConfig | None = None) -> None:
        self.config = config or AxleCheckConfig()
        # |w_left - w_right| per unit yaw rate: l_T / r0, s (eq. 6b)
        self._gain_s = vehicle.track_width_m / vehicle.nominal_tire_radius_m
        self._radius_m = vehicle.nominal_tire_radius_m
        self._yaw_rate: float | None = None
        self._equal = {axle: deque(maxlen=self.config.window) for axle in AXLES}
        self._turning = dict.fromkeys(AXLES, 0)

    def on_imu(self, gyro_rad_s: Any) -> None:
        """The latest gyro yaw rate (z), rad/s."""
        self._yaw_rate = float(gyro_rad_s[2])

    def on_wheel_speeds(self, wheel_speed_rad_s: Any) -> None:
        """One wheel-speed sample (fl, fr, rl, rr), rad/s; NaN for a wheel not reported."""
        r = self._yaw_rate
        c = self.config
        if r is None or abs(r) < c.min_yaw_rate_rad_s:
            return
        expected = abs(r) * self._gain_s
        for axle, (i, j) in AXLES.items():
            wl, wr = float(wheel_speed_rad_s[i]), float(wheel_speed_rad_s[j])
            if not (math.isfinite(wl) and math.isfinite(wr)):
                continue
            if 0.5 * (wl + wr) * self._radius_m < c.min_speed_m_s:
                continue
            self._turning[axle] += 1
            self._equal[axle].append(abs(wl - wr) < c.equal_fraction * expected)

    def status(self, axle: str) -> AxleStatus:
        """The verdict on ``axle`` (``front`` or ``rear``)."""
        c = self.config
        seen = self._equal[axle]
        share = sum(seen) / len(seen) if seen else 0.0
        n = self._turning[axle]
        if self._yaw_rate is None:
            return AxleStatus(axle, None, n, share, "unknown: no gyro yaw rate")
        if len(seen) < c.min_turning:
            return AxleStatus(axle, None, n, share, f"unknown: {n} turning samples so far")
        if share >= c.unobservable_share:
            return AxleStatus(
                axle,
                False,
                n,
                share,
                f"unobservable: both wheels turn at the same speed in {100 * share:.0f} % of the "
                "turns (locked axle or spool, or one signal copied to both sides); only the "
                "axle's common radius is observable",
            )
        return AxleStatus(axle, True, n, share, "observable")
