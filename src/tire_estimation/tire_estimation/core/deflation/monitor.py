"""The deflation detector's front-end: published radii and odometry in, detector status out.

The detector node and the estimation pipeline feed the same object: the speed and the braking
flag come from the odometry stream (``twist.linear.x``; braking = deceleration between odometry
samples at least ``braking_window_s`` apart above ``braking_decel_m_s2``), the radius estimates
from the radii stream, and :class:`~.detector.DeflationDetector` runs on
them. Bad input raises :class:`~tire_estimation.errors.InputError` for the caller to count.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.detector import DeflationDetector
from tire_estimation.core.deflation.status import (
    CalibrationState,
    DeflationStatusData,
    RadiusErrors,
)
from tire_estimation.core.validation import (
    Checked,
    Positive,
)
from tire_estimation.errors import InputError


@dataclass(frozen=True)
class MonitorConfig(Checked):
    """How the monitor derives speed and braking from the odometry stream.

    Attributes:
        braking_decel_m_s2: deceleration above which the car counts as braking, m/s^2.
            Default 1.
        braking_window_s: odometry span over which the deceleration is taken, s. Default 0.5.
        odometry_timeout_s: a speed older than this (against the radius stamp) is unknown, s.
            Default 1.
    """

    braking_decel_m_s2: Positive = 1.0
    braking_window_s: Positive = 0.5
    odometry_timeout_s: Positive = 1.0


@dataclass(frozen=True)
class MonitorStep:
    """What one accepted radius estimate changed.

    Attributes:
        status: the detector's status after the step.
        new_alarms: wheels whose alarm was raised by this step.
        new_common_alarm: the common channel's vehicle-level alarm was raised by this step.
        calibration_changed: the calibration state changed.
    """

    status: DeflationStatusData
    new_alarms: tuple[str, ...]
    new_common_alarm: bool
    calibration_changed: bool


class DeflationMonitor:
    """Speed and braking from odometry, radii into the CUSUM detector.

    Args:
        detector: the detector configuration.
        config: how speed and braking are taken from the odometry.
        nominal_tire_radius_m: the vehicle's nominal tyre radius when known (bounds the radius
            errors of a restored detector state), m.
    """

    def __init__(
        self,
        detector: DeflationDetectorConfig,
        config: MonitorConfig | None = None,
        nominal_tire_radius_m: float | None = None,
    ) -> None:
        self.config = config or MonitorConfig()
        self.detector = DeflationDetector(detector, nominal_tire_radius_m)
        #: events that are not drops (e.g. ``radii_without_odometry``)
        self.events: Counter[str] = Counter()
        self._window_ns = int(self.config.braking_window_s * 1e9)
        self._timeout_ns = int(self.config.odometry_timeout_s * 1e9)
        self.odometry_t_ns: int | None = None
        self.speed_m_s: float | None = None
        self.braking = False
        self._brake_ref: tuple[int, float] | None = None

    def on_odometry(self, t_ns: int, speed_m_s: float) -> None:
        """One odometry sample: its stamp and forward speed, m/s."""
        speed = float(speed_m_s)
        if not math.isfinite(speed):
            raise InputError("nan", "odometry speed is not finite")
        last = self.odometry_t_ns
        if last is not None and t_ns <= last:
            raise InputError("out_of_order", "odometry stamp is not newer than the last one")
        if last is not None and t_ns - last > self._timeout_ns:
            self._brake_ref = None  # a gap: restart the deceleration estimate
            self.braking = False
        ref = self._brake_ref
        if ref is None:
            self._brake_ref = (t_ns, speed)
        elif t_ns - ref[0] >= self._window_ns:
            # deceleration over the window: (v_ref - v) / (t - t_ref)
            decel = (ref[1] - speed) / ((t_ns - ref[0]) * 1e-9)
            self.braking = decel > self.config.braking_decel_m_s2
            self._brake_ref = (t_ns, speed)
        self.odometry_t_ns = t_ns
        self.speed_m_s = speed

    def on_radii(self, radii: RadiusErrors) -> MonitorStep | None:
        """One radius estimate; None when the detector did not accept it (counted there)."""
        speed = self.speed_m_s
        t_ns = radii.t_ns
        if self.odometry_t_ns is None or abs(t_ns - self.odometry_t_ns) > self._timeout_ns:
            speed = None
            self.events["radii_without_odometry"] += 1
        det = self.detector
        before = det.calibration_state
        alarms_before, common_before = det.latched_alarms()
        status = det.step(radii, speed, self.braking)
        if not status.accepted:
            return None
        new_alarms = tuple(
            w.wheel_name for w in status.wheels if w.alarm and w.wheel_name not in alarms_before
        )
        common = status.common
        new_common = common is not None and common.alarm and not common_before
        return MonitorStep(
            status=status,
            new_alarms=new_alarms,
            new_common_alarm=new_common,
            calibration_changed=status.calibration_state != before,
        )

    @property
    def calibration_state(self) -> CalibrationState:
        """The detector's calibration state."""
        return self.detector.calibration_state
