"""Sampled sensor and truth streams: what a simulation produces and a bag writer consumes.

Every stream holds ``t_ns`` (int64 nanoseconds of measurement time, strictly increasing, shaped
``(M,)``) and arrays whose first axis is ``M``. Per-wheel arrays have last axis 4 in the order of
:data:`tire_estimation.core.wheels.WHEELS` (fl, fr, rl, rr). Vectors are in ``base_link`` axes
(x forward, y left, z up) unless named ``_enu``. These types carry no ROS dependency; the bag
layer turns them into messages.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64, I64
from tire_estimation.core.vehicle import VehicleParams

BOOL = NDArray[np.bool_]


def _check(name: str, t_ns: I64, **arrays: NDArray[Any]) -> None:
    if t_ns.ndim != 1:
        raise ValueError(f"{name}.t_ns must be 1-D, got shape {t_ns.shape}")
    if t_ns.size > 1 and not np.all(np.diff(t_ns) > 0):
        raise ValueError(f"{name}.t_ns must be strictly increasing")
    for key, arr in arrays.items():
        if arr is not None and arr.shape[0] != t_ns.shape[0]:
            raise ValueError(f"{name}.{key} has {arr.shape[0]} rows but t_ns has {t_ns.shape[0]}")


@dataclass(frozen=True)
class WheelSpeedStream:
    """ABS wheel speeds. ``wheel_speed_rad_s``: (M, 4), positive when rolling forward."""

    t_ns: I64
    wheel_speed_rad_s: F64

    def __post_init__(self) -> None:
        _check("wheel_speeds", self.t_ns, wheel_speed_rad_s=self.wheel_speed_rad_s)


@dataclass(frozen=True)
class SteeringStream:
    """Mean road-wheel steer angle ``angle_rad``: (M,), positive to the left."""

    t_ns: I64
    angle_rad: F64

    def __post_init__(self) -> None:
        _check("steering", self.t_ns, angle_rad=self.angle_rad)


@dataclass(frozen=True)
class SpeedStream:
    """Measured longitudinal speed of ``base_link``, ``vx_m_s``: (M,), m/s (no wheel speeds)."""

    t_ns: I64
    vx_m_s: F64

    def __post_init__(self) -> None:
        _check("speed", self.t_ns, vx_m_s=self.vx_m_s)


@dataclass(frozen=True)
class ImuStream:
    """IMU in ``base_link`` axes.

    Gyro (M, 3) rad/s; specific force (M, 3) m/s^2 (+9.81 z at rest).
    """

    t_ns: I64
    angular_velocity_rad_s: F64
    linear_acceleration_m_s2: F64
    gyro_noise_std_rad_s: float = 0.0
    accel_noise_std_m_s2: float = 0.0

    def __post_init__(self) -> None:
        _check(
            "imu",
            self.t_ns,
            angular_velocity_rad_s=self.angular_velocity_rad_s,
            linear_acceleration_m_s2=self.linear_acceleration_m_s2,
        )


@dataclass(frozen=True)
class GnssStream:
    """GNSS antenna fixes.

    WGS-84 ``lat_deg``, ``lon_deg``, ``alt_m`` (M,) (NaN: no altitude reported) and ENU
    covariance (M, 3, 3) m^2 (all zero: not reported).

    ``velocity_enu_m_s`` (M, 3) and ``velocity_covariance_m2_s2`` (M, 3, 3) are the optional
    Doppler velocity (None when the receiver does not report it).
    """

    t_ns: I64
    lat_deg: F64
    lon_deg: F64
    alt_m: F64
    position_covariance_m2: F64
    velocity_enu_m_s: F64 | None = None
    velocity_covariance_m2_s2: F64 | None = None

    def __post_init__(self) -> None:
        _check(
            "gnss",
            self.t_ns,
            lat_deg=self.lat_deg,
            lon_deg=self.lon_deg,
            alt_m=self.alt_m,
            position_covariance_m2=self.position_covariance_m2,
            velocity_enu_m_s=self.velocity_enu_m_s,
            velocity_covariance_m2_s2=self.velocity_covariance_m2_s2,
        )


@dataclass(frozen=True)
class GnssVelocityStream:
    """The receiver's Doppler velocity on its own stamps: ``velocity_enu_m_s`` (M, 3) m/s and
    ``covariance_m2_s2`` (M, 3, 3) (all zero: not reported)."""

    t_ns: I64
    velocity_enu_m_s: F64
    covariance_m2_s2: F64

    def __post_init__(self) -> None:
        _check(
            "gnss_velocity",
            self.t_ns,
            velocity_enu_m_s=self.velocity_enu_m_s,
            covariance_m2_s2=self.covariance_m2_s2,
        )


@dataclass(frozen=True)
class TireForceStream:
    """Measured tyre forces (M, 4) N in each wheel's frame; ``valid`` (M, 4) marks real sensors."""

    t_ns: I64
    fx_n: F64
    fy_n: F64
    fz_n: F64
    valid: BOOL

    def __post_init__(self) -> None:
        _check(
            "tire_forces",
            self.t_ns,
            fx_n=self.fx_n,
            fy_n=self.fy_n,
            fz_n=self.fz_n,
            valid=self.valid,
        )


@dataclass(frozen=True)
class TruthStream:
    """True state of ``base_link``.

    Position: WGS-84 (``lat_deg``, ``lon_deg``, ``alt_m``) and ENU ``position_enu_m`` (M, 3) from
    the origin of the run; ``yaw_rad`` (M,) heading of x in ENU (0 = east, counter-clockwise);
    ``velocity_m_s`` (M, 2) [vx, vy] in base_link; ``yaw_rate_rad_s`` (M,);
    ``acceleration_m_s2`` (M, 2) [ax, ay] in base_link (kinematic, without gravity);
    ``wheel_radius_m`` (M, 4) effective rolling radius; ``tire_pressure_pa`` (M, 4);
    ``stiffness`` (M, 3) [cx_front N/unit slip, cy_front N/rad, cy_rear N/rad] (axle values);
    ``cx_rear_n`` (M,) the rear axle's longitudinal stiffness, N/unit slip (None: not known).
    """

    t_ns: I64
    lat_deg: F64
    lon_deg: F64
    alt_m: F64
    position_enu_m: F64
    yaw_rad: F64
    velocity_m_s: F64
    yaw_rate_rad_s: F64
    acceleration_m_s2: F64
    wheel_radius_m: F64
    tire_pressure_pa: F64
    stiffness: F64
    cx_rear_n: F64 | None = None

    def __post_init__(self) -> None:
        _check(
            "truth",
            self.t_ns,
            lat_deg=self.lat_deg,
            lon_deg=self.lon_deg,
            alt_m=self.alt_m,
            position_enu_m=self.position_enu_m,
            yaw_rad=self.yaw_rad,
            velocity_m_s=self.velocity_m_s,
            yaw_rate_rad_s=self.yaw_rate_rad_s,
            acceleration_m_s2=self.acceleration_m_s2,
            wheel_radius_m=self.wheel_radius_m,
            tire_pressure_pa=self.tire_pressure_pa,
            stiffness=self.stiffness,
            cx_rear_n=self.cx_rear_n,
        )


@dataclass(frozen=True)
class SimEvent:
    """Something a scenario did at a time, e.g. a pressure step (recorded in bag metadata)."""

    t_s: float
    kind: str
    detail: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SimResult:
    """Everything one simulated drive produced.

    ``origin_lla`` is the WGS-84 (lat deg, lon deg, alt m) of the ENU origin (first truth fix).
    ``config`` is a YAML-serializable record of the scenario and sensor settings used.
    """

    scenario: str
    seed: int
    vehicle: VehicleParams
    origin_lla: tuple[float, float, float]
    wheel_speeds: WheelSpeedStream
    steering: SteeringStream
    imu: ImuStream
    gnss: GnssStream
    truth: TruthStream
    tire_forces: TireForceStream | None = None
    events: tuple[SimEvent, ...] = ()
    config: dict[str, Any] = field(default_factory=dict)

    @property
    def duration_s(self) -> float:
        """Time from the first to the last truth sample, s."""
        return float(self.truth.t_ns[-1] - self.truth.t_ns[0]) * 1e-9
