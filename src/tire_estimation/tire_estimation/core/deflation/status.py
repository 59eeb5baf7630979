"""What the deflation detector takes and reports: a radius estimate in, per-wheel and
common-channel status out (these mirror ``TireRadii.msg``, ``WheelDeflation.msg`` and
``DeflationStatus.msg``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntEnum

#: wheel name of a common-channel alarm in :attr:`.trace.TraceResult.alarms` (names no tyre)
ALL_WHEELS = "all_wheels"


@dataclass(frozen=True)
class RadiusErrors:
    """One radius estimate of the wheels, as the radius estimator publishes it.

    Attributes:
        t_ns: stamp, ns.
        wheel_names: the wheels of the estimate.
        radius_error_m: mu per wheel, effective minus nominal radius, m.
        radius_error_std_m: reported std of mu per wheel, m.
        active: per wheel, whether the estimator is learning it.
    """

    t_ns: int
    wheel_names: Sequence[str]
    radius_error_m: Sequence[float]
    radius_error_std_m: Sequence[float]
    active: Sequence[bool]


class CalibrationState(IntEnum):
    """Calibration phase; values equal the ``DeflationStatus.CALIBRATION_*`` constants."""

    NOT_STARTED = 0
    IN_PROGRESS = 1
    DONE = 2


class Level(IntEnum):
    """Per-wheel level; values equal the ``WheelDeflation.LEVEL_*`` constants."""

    OK = 0
    WARN = 1
    ALARM = 2
    STALE = 3


@dataclass(frozen=True)
class WheelDeflationData:
    """Detector state of one wheel (mirrors ``WheelDeflation.msg``)."""

    wheel_name: str
    level: Level
    radius_change_m: float  # filtered xbar: calibrated minus current (positive = smaller tyre)
    raw_radius_change_m: float  # unfiltered x of the last detection step
    cusum_m: float
    threshold_m: float
    alarm: bool
    alarm_t_ns: int | None
    calibrated: bool
    calibrated_radius_error_m: float | None
    calibration_t_ns: int | None
    calibration_progress: float
    last_estimate_t_ns: int | None


@dataclass(frozen=True)
class CommonChannelData:
    """State of the common-mode channel (all covered wheels together; vehicle level)."""

    wheel_names: tuple[str, ...]  # the wheels of the last update
    radius_change_m: float  # filtered mean decrease since calibration (positive = smaller)
    raw_radius_change_m: float  # unfiltered mean decrease of the last update
    cusum_m: float
    threshold_m: float
    alarm: bool
    alarm_t_ns: int | None


@dataclass(frozen=True)
class DeflationStatusData:
    """Detector output for one instant (mirrors ``DeflationStatus.msg``)."""

    t_ns: int | None
    accepted: bool  # False when the sample handed to step() was dropped
    calibration_state: CalibrationState
    calibration_progress: float
    calibrated_driving_time_s: float
    wheels: tuple[WheelDeflationData, ...]
    any_alarm: bool  # a wheel's alarm or the common channel's
    common: CommonChannelData | None = None  # None unless config.common_channel

    def wheel(self, name: str) -> WheelDeflationData:
        """Entry of wheel ``name`` (KeyError when the detector has not seen it)."""
        for w in self.wheels:
            if w.wheel_name == name:
                return w
        raise KeyError(name)
