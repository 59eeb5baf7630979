"""Can the two wheels of an axle be told apart? A check on the wheel speeds against the gyro.

The radius estimator owns one (:attr:`RadiusEstimator.axles`): while the rear axle is locked it
takes the heading change from the gyro instead of the rear wheels.

The radius model reads the heading change from the difference of the rear wheel speeds (eq. 6b:
``r = ((r0 + d4) w4 - (r0 + d3) w3) / l_T``), so a split of the two radii is learned from turns.
In a turn with yaw rate ``r`` the right wheel of an axle turns faster than the left by about
``x = r l_T / r0`` rad/s. When the two report the same speed through the turns (a locked axle
or spool, one sensor's signal copied to both sides, a dead sensor held at the other's value),
the split is unobservable: only the axle's common radius is. At ``min_speed_m_s`` or more the
check fits the measured difference ``y = w_right - w_left`` by least squares (exponential
forgetting over ``memory`` samples) to ``y = slope x + c w``, where ``w`` is the axle's mean
wheel speed and ``c w`` the difference a left-right radius split makes: ``slope`` is about 1 on
a free axle and about 0 on a locked one (wheel-speed noise does not bias it). A verdict needs
the turns to carry information: ``sum x_perp^2`` (``x`` without its part along ``w``) at least
that of ``min_turning`` samples at ``min_yaw_rate_rad_s``.
"""

from __future__ import annotations

import math
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
        min_yaw_rate_rad_s: a sample counts as turning from this gyro yaw rate, rad/s; also
            the yaw rate of the information needed for a verdict. Default 0.05 (a 400 m
            radius at 20 m/s).
        min_speed_m_s: samples below this speed are left out, m/s. Default 2.
        memory: time constant of the fit's forgetting, samples. Default 6000 (60 s at 100 Hz).
        min_turning: the information needed for a verdict, in turning samples at
            ``min_yaw_rate_rad_s``. Default 300.
        locked_slope: the split is unobservable while the fitted slope is below this, 1.
            Default 0.2.
    """

    min_yaw_rate_rad_s: float = 0.05
    min_speed_m_s: float = 2.0
    memory: int = 6000
    min_turning: int = 300
    locked_slope: float = 0.2

    def __post_init__(self) -> None:
        require_positive("min_yaw_rate_rad_s", self.min_yaw_rate_rad_s)
        require_positive("min_speed_m_s", self.min_speed_m_s)
        require_positive("memory", self.memory)
        require_positive("min_turning", self.min_turning)
        require_range("locked_slope", self.locked_slope, 0.0, 1.0)


@dataclass(frozen=True)
class AxleStatus:
    """One axle's verdict.

    Attributes:
        axle: ``front`` or ``rear``.
        split_observable: True, False, or None (not enough turning samples yet, or no gyro).
        turning_samples: turning samples seen so far.
        slope: the fitted slope of the measured on the expected speed difference (1 free,
            0 locked); NaN before the turns carry information.
        reason: the verdict in words.
    """

    axle: str
    split_observable: bool | None
    turning_samples: int
    slope: float
    reason: str


class AxleCheck:
    """Fits, per axle, the wheel-speed difference to the one the gyro implies."""

    def __init__(self, vehicle: VehicleParams, config: AxleCheckConfig | None = None) -> None:
        self.config = config or AxleCheckConfig()
        # w_right - w_left per unit yaw rate: l_T / r0, s (eq. 6b)
        self._gain_s = vehicle.track_width_m / vehicle.nominal_tire_radius_m
        self._radius_m = vehicle.nominal_tire_radius_m
        self._forget = 1.0 - 1.0 / self.config.memory
        # information needed: min_turning samples of x = min_yaw_rate l_T / r0
        self._min_info = (
            self.config.min_turning * (self.config.min_yaw_rate_rad_s * self._gain_s) ** 2
        )
        self._yaw_rate: float | None = None
        # discounted sums of x^2, x w, w^2, x y, w y per axle
        self._sums = {axle: [0.0] * 5 for axle in AXLES}
        self._turning = dict.fromkeys(AXLES, 0)
        # the slope of the last verdict, kept while the recent turns carry too little
        # information (a straight stretch does not undo what the turns showed)
        self._decided: dict[str, float] = {}

    def on_imu(self, gyro_rad_s: Any) -> None:
        """The latest gyro yaw rate (z), rad/s."""
        self._yaw_rate = float(gyro_rad_s[2])

    def on_wheel_speeds(self, wheel_speed_rad_s: Any) -> None:
        """One wheel-speed sample (fl, fr, rl, rr), rad/s; NaN for a wheel not reported."""
        r = self._yaw_rate
        if r is None:
            return
        c = self.config
        lam = self._forget
        x = r * self._gain_s
        turning = abs(r) >= c.min_yaw_rate_rad_s
        for axle, (i, j) in AXLES.items():
            wl, wr = float(wheel_speed_rad_s[i]), float(wheel_speed_rad_s[j])
            if not (math.isfinite(wl) and math.isfinite(wr)):
                continue
            w = 0.5 * (wl + wr)
            if w * self._radius_m < c.min_speed_m_s:
                continue
            y = wr - wl
            self._turning[axle] += turning
            s = self._sums[axle]
            s[0] = lam * s[0] + x * x
            s[1] = lam * s[1] + x * w
            s[2] = lam * s[2] + w * w
            s[3] = lam * s[3] + x * y
            s[4] = lam * s[4] + w * y

    def _info(self, axle: str) -> float:
        sxx, sxw, sww = self._sums[axle][:3]
        # sum of x_perp^2: the information on the slope once the split term is fitted
        return sxx - sxw * sxw / sww if sww > 0.0 else 0.0

    def slope(self, axle: str) -> float:
        """Least-squares slope of the measured on the expected difference (split fitted), or
        the slope of the last verdict while the recent turns carry too little information."""
        sxx, sxw, sww, sxy, swy = self._sums[axle]
        det = sxx * sww - sxw * sxw
        if det <= 0.0 or self._info(axle) < self._min_info:
            return self._decided.get(axle, math.nan)
        # normal equations of y = slope x + c w: slope = (sww sxy - sxw swy) / det
        slope = (sww * sxy - sxw * swy) / det
        self._decided[axle] = slope
        return slope

    def locked(self, axle: str) -> bool:
        """True when ``axle``'s split is unobservable (:meth:`status` says False)."""
        return bool(self.slope(axle) < self.config.locked_slope)

    def status(self, axle: str) -> AxleStatus:
        """The verdict on ``axle`` (``front`` or ``rear``)."""
        slope = self.slope(axle)
        n = self._turning[axle]
        if self._yaw_rate is None:
            return AxleStatus(axle, None, n, slope, "unknown: no gyro yaw rate")
        if math.isnan(slope):
            return AxleStatus(axle, None, n, slope, f"unknown: too few turns ({n} samples)")
        if self.locked(axle):
            return AxleStatus(
                axle,
                False,
                n,
                slope,
                f"unobservable: both wheels turn alike in the turns (slope {slope:.2f} of the "
                "difference the gyro implies: a locked axle or spool, or one signal copied to "
                "both sides); only the axle's common radius is observable",
            )
        return AxleStatus(axle, True, n, slope, f"observable (slope {slope:.2f})")
