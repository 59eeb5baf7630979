"""Typed sensor samples: what every source (node, bag, simulator) hands to the pipeline.

One frozen dataclass per input stream of the contract. Time is integer nanoseconds of
measurement (header stamp); vectors are in ``base_link`` axes (REP-103) unless named ``_enu``;
per-wheel arrays have 4 entries in the order of :data:`~tire_estimation.core.wheels.WHEELS`.

A sample is checked once, where it enters the package: :meth:`checked` of each type raises
:class:`~tire_estimation.errors.InputError` with a stable ``kind`` (``no_stamp``, ``nan``,
``wrong_shape``, ``out_of_range``, ``bad_covariance``, ...) that the caller counts as
``dropped.<stream>:<kind>``. The node's conversions and the bag reader check the GNSS samples
with the same methods (:meth:`GnssFix.from_navsat`, :meth:`GnssVelocity.checked`); for the
high-rate streams the bag reader and the simulator build samples with the plain constructor
and the estimators' own checks drop and count bad values under the same names.

``KIND`` names the stream (the key of the drop counters and of ``/diagnostics``);
``PRIORITY`` orders samples of equal stamp: the speeds and steering an IMU sample belongs to
come before it, a fix before its Doppler velocity, and all of them before the tyre forces and
the measured velocity of the same instant.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import checked_covariance
from tire_estimation.errors import InputError

#: largest wheel angular speed accepted, rad/s (about 1300 km/h on a 0.35 m tyre)
MAX_WHEEL_SPEED_RAD_S = 1000.0
#: largest steering angle accepted, rad
MAX_STEERING_RAD = 1.2
#: largest angular rate accepted, rad/s (2000 deg/s, the widest range of common MEMS gyros)
MAX_ANGULAR_RATE_RAD_S = 35.0
#: largest specific force accepted, m/s^2 (about 20 g, beyond common MEMS ranges of 16 g)
MAX_ACCELERATION_M_S2 = 200.0
#: largest GNSS velocity accepted, m/s (720 km/h)
MAX_GNSS_SPEED_M_S = 200.0
#: the NavSatFix covariance types (unknown, approximated, diagonal known, known)
NAVSAT_COVARIANCE_TYPES = frozenset({0, 1, 2, 3})
#: largest altitude of a GNSS fix accepted, m (above or below the WGS-84 ellipsoid)
MAX_ABS_ALTITUDE_M = 1e5
#: ``sensor_msgs/NavSatFix.COVARIANCE_TYPE_UNKNOWN``: the position covariance is not reported
COVARIANCE_TYPE_UNKNOWN = 0
#: ``sensor_msgs/NavSatStatus.STATUS_NO_FIX``
STATUS_NO_FIX = -1


def _stamp(t_ns: object) -> int:
    if isinstance(t_ns, bool) or not isinstance(t_ns, (int, np.integer)):
        raise InputError("bad_stamp", f"stamp must be integer nanoseconds, got {t_ns!r}")
    if t_ns <= 0:
        raise InputError("no_stamp", "stamp is zero or negative")
    return int(t_ns)


def _vector(values: object, n: int, what: str) -> F64:
    try:
        arr = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError("bad_value", f"{what}: {exc}") from exc
    if arr.size != n:
        raise InputError("wrong_shape", f"{what} needs {n} values, got {arr.size}")
    return arr


def _finite_vector(values: object, n: int, what: str, max_abs: float, unit: str) -> F64:
    """``n`` finite values (else ``nan``) within +-``max_abs`` (else ``out_of_range``)."""
    arr = _vector(values, n, what)
    # (the few values as floats: cheaper than NumPy's reductions on a short vector; a sum is
    # finite when every value is, one that overflows is checked value by value)
    vals = arr.tolist()
    total = sum(vals)
    if total - total != 0.0 and not all(map(math.isfinite, vals)):
        raise InputError("nan", f"{what} is not finite")
    if max(map(abs, vals)) > max_abs:
        raise InputError("out_of_range", f"|{what}| above {max_abs} {unit}")
    return arr


def _finite_scalar(value: object, what: str) -> float:
    """A number (else ``bad_value``) that is finite (else ``nan``)."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise InputError("bad_value", f"{what}: {exc}") from exc
    if not math.isfinite(x):
        raise InputError("nan", f"{what} is not finite")
    return x


@dataclass(frozen=True, slots=True)
class WheelSpeeds:
    """Wheel angular speeds (4,) rad/s, positive rolling forward; NaN for a wheel not reported."""

    KIND: ClassVar[str] = "wheel_speeds"
    PRIORITY: ClassVar[int] = 0
    t_ns: int
    wheel_speed_rad_s: F64

    @classmethod
    def checked(cls, t_ns: object, wheel_speed_rad_s: object) -> WheelSpeeds:
        """Validated sample: at least one finite wheel, all within +-1000 rad/s."""
        ws = _vector(wheel_speed_rad_s, 4, "wheel speeds")
        finite = ws[np.isfinite(ws)]
        if finite.size == 0:
            raise InputError("nan", "no finite wheel speed")
        if np.any(np.isinf(ws)) or np.any(np.abs(finite) > MAX_WHEEL_SPEED_RAD_S):
            raise InputError("out_of_range", f"wheel speed beyond 1000 rad/s: {ws.tolist()}")
        return cls(_stamp(t_ns), ws)


@dataclass(frozen=True, slots=True)
class Steering:
    """Mean road-wheel steer angle, rad, positive to the left."""

    KIND: ClassVar[str] = "steering"
    PRIORITY: ClassVar[int] = 1
    t_ns: int
    angle_rad: float

    @classmethod
    def checked(cls, t_ns: object, angle_rad: object) -> Steering:
        """Validated sample: finite, within +-1.2 rad."""
        angle = _finite_scalar(angle_rad, "steering angle")
        if abs(angle) > MAX_STEERING_RAD:
            raise InputError("out_of_range", f"steering angle {angle} rad")
        return cls(_stamp(t_ns), angle)


@dataclass(frozen=True, slots=True)
class ImuSample:
    """Gyro (3,) rad/s and specific force (3,) m/s^2 (about +9.81 z at rest), base_link axes."""

    KIND: ClassVar[str] = "imu"
    PRIORITY: ClassVar[int] = 2
    t_ns: int
    angular_velocity_rad_s: F64
    linear_acceleration_m_s2: F64

    @classmethod
    def checked(
        cls, t_ns: object, angular_velocity_rad_s: object, linear_acceleration_m_s2: object
    ) -> ImuSample:
        """Validated sample: two finite 3-vectors within the ranges of MEMS sensors."""
        gyro = _finite_vector(
            angular_velocity_rad_s, 3, "angular velocity", MAX_ANGULAR_RATE_RAD_S, "rad/s"
        )
        acc = _finite_vector(
            linear_acceleration_m_s2, 3, "linear acceleration", MAX_ACCELERATION_M_S2, "m/s^2"
        )
        return cls(_stamp(t_ns), gyro, acc)


@dataclass(frozen=True, slots=True)
class GnssFix:
    """WGS-84 antenna position and its ENU covariance (3, 3) m^2 (None: not reported);
    ``alt_m`` NaN when the receiver reports no altitude."""

    KIND: ClassVar[str] = "gnss_fix"
    PRIORITY: ClassVar[int] = 3
    t_ns: int
    lat_deg: float
    lon_deg: float
    alt_m: float
    covariance_m2: F64 | None

    @classmethod
    def checked(
        cls, t_ns: object, lat_deg: float, lon_deg: float, alt_m: float, covariance_m2: object
    ) -> GnssFix:
        """Validated sample: finite latitude and longitude in range; a covariance that is given
        must be a finite, symmetric, positive semi-definite matrix whose horizontal block is
        positive definite (else ``bad_covariance``). A non-finite altitude is kept as NaN: not
        reported (the ROS convention for a fix without altitude); the radius estimator then uses
        the fix without it and counts ``no_altitude``."""
        lat, lon, alt = float(lat_deg), float(lon_deg), float(alt_m)
        if not (math.isfinite(lat) and math.isfinite(lon)):
            raise InputError("nan", "GNSS latitude or longitude not finite")
        if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
            raise InputError("out_of_range", f"GNSS lat/lon out of range: {lat}, {lon}")
        if not math.isfinite(alt):
            alt = math.nan
        elif abs(alt) > MAX_ABS_ALTITUDE_M:
            raise InputError("out_of_range", f"GNSS altitude out of range: {alt}")
        return cls(
            _stamp(t_ns), lat, lon, alt, checked_covariance(covariance_m2, "fix covariance")
        )

    @classmethod
    def from_navsat(
        cls,
        t_ns: object,
        status: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float,
        covariance_m2: object,
        covariance_type: int,
    ) -> GnssFix:
        """The fields of a ``sensor_msgs/NavSatFix`` as a checked sample (node and bag reader).

        Status ``STATUS_NO_FIX`` raises ``no_fix`` (``STATUS_UNKNOWN``, -2, the message default
        many drivers leave, is accepted). With ``COVARIANCE_TYPE_UNKNOWN`` the covariance is not
        read (None: the estimator's configured default); any other type must carry a valid one
        (:meth:`checked`; all zero is read as not reported)."""
        if int(status) == STATUS_NO_FIX:
            raise InputError("no_fix", "NavSatFix status reports no fix")
        if int(covariance_type) not in NAVSAT_COVARIANCE_TYPES:
            raise InputError("bad_covariance", f"unknown covariance type {int(covariance_type)}")
        cov = None if int(covariance_type) == COVARIANCE_TYPE_UNKNOWN else covariance_m2
        return cls.checked(t_ns, lat_deg, lon_deg, alt_m, cov)


@dataclass(frozen=True, slots=True)
class GnssVelocity:
    """The receiver's Doppler velocity (3,) m/s in ENU, covariance (3, 3) (None: not given)."""

    KIND: ClassVar[str] = "gnss_velocity"
    PRIORITY: ClassVar[int] = 4
    t_ns: int
    velocity_enu_m_s: F64
    covariance_m2_s2: F64 | None

    @classmethod
    def checked(cls, t_ns: object, velocity_enu_m_s: object, covariance: object) -> GnssVelocity:
        """Validated sample: a finite 3-vector; a covariance as for :meth:`GnssFix.checked`
        (all zero: not given)."""
        v = _finite_vector(velocity_enu_m_s, 3, "GNSS velocity", MAX_GNSS_SPEED_M_S, "m/s")
        return cls(_stamp(t_ns), v, checked_covariance(covariance, "velocity covariance"))


@dataclass(frozen=True, slots=True)
class TireForces:
    """Measured tyre forces (4,) N per wheel in the wheel's frame; ``valid`` (4,) bool."""

    KIND: ClassVar[str] = "tire_forces"
    PRIORITY: ClassVar[int] = 5
    t_ns: int
    fx_n: F64
    fy_n: F64
    fz_n: F64
    valid: NDArray[np.bool_]

    @classmethod
    def checked(
        cls, t_ns: object, fx_n: object, fy_n: object, fz_n: object, valid: object
    ) -> TireForces:
        """Validated sample: four 4-vectors; a wheel with a non-finite force is not valid."""
        fx = _vector(fx_n, 4, "fx")
        fy = _vector(fy_n, 4, "fy")
        fz = _vector(fz_n, 4, "fz")
        ok = np.asarray(valid, dtype=bool).reshape(-1)
        if ok.size != 4:
            raise InputError("wrong_shape", f"valid needs 4 values, got {ok.size}")
        ok = ok & np.isfinite(fx) & np.isfinite(fy) & np.isfinite(fz)
        return cls(_stamp(t_ns), fx, fy, fz, ok)


@dataclass(frozen=True, slots=True)
class MeasuredVelocity:
    """Measured longitudinal speed of base_link, m/s (vehicles without wheel speeds)."""

    KIND: ClassVar[str] = "velocity"
    PRIORITY: ClassVar[int] = 6
    t_ns: int
    vx_m_s: float

    @classmethod
    def checked(cls, t_ns: object, vx_m_s: object) -> MeasuredVelocity:
        """Validated sample: a finite speed."""
        return cls(_stamp(t_ns), _finite_scalar(vx_m_s, "velocity"))


Sample = (
    WheelSpeeds | Steering | ImuSample | GnssFix | GnssVelocity | TireForces | MeasuredVelocity
)
#: every sample type, in priority order
SAMPLE_TYPES: tuple[type, ...] = (
    WheelSpeeds,
    Steering,
    ImuSample,
    GnssFix,
    GnssVelocity,
    TireForces,
    MeasuredVelocity,
)
#: the stream names (``KIND``) in priority order
STREAMS: tuple[str, ...] = tuple(t.KIND for t in SAMPLE_TYPES)


def order_key(sample: Sample) -> tuple[int, int]:
    """``(stamp, priority)``: the order in which the pipeline processes samples."""
    return sample.t_ns, sample.PRIORITY


def merge(streams: Iterable[Iterable[Sample]]) -> Iterator[Sample]:
    """Merge per-stream sample sequences, each in strictly increasing stamp order, into one in
    :func:`order_key` order (lazy)."""
    keyed = [((s.t_ns, s.PRIORITY, s) for s in stream) for stream in streams]
    # the keys of two samples are never equal (one priority per stream, stamps increase
    # within a stream), so the samples themselves are never compared
    return (entry[2] for entry in heapq.merge(*keyed))
