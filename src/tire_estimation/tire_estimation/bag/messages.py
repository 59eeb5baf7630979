"""Build ROS-typed message objects (``rosbags`` dataclasses) from plain numbers and arrays.

Used by the bag writer (generic path) and by anything that publishes contract messages. Times are
integer nanoseconds; every angle is in rad, every length in m, every force in N (SI throughout).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from tire_estimation.bag import topics as tp
from tire_estimation.bag.typestore import get_typestore

_NS_PER_S = 1_000_000_000

#: ``sensor_msgs/NavSatStatus`` values used by the writer.
NAVSAT_STATUS_FIX = 0
NAVSAT_SERVICE_GPS = 1
#: ``sensor_msgs/NavSatFix.position_covariance_type`` for a full ENU covariance.
COVARIANCE_TYPE_KNOWN = 3
#: Variance (rad^2/s^2) written for the unmeasured angular part of ``/gnss/velocity``.
UNKNOWN_ANGULAR_VARIANCE = 1e6


def _types() -> dict[str, Any]:
    return get_typestore().types


def _f64(values: ArrayLike, size: int | None = None) -> NDArray[np.float64]:
    arr = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
    if size is not None and arr.size != size:
        raise ValueError(f"expected {size} numbers, got {arr.size}")
    return arr


def stamp_to_ns(stamp: Any) -> int:
    """``builtin_interfaces/Time`` (``sec``, ``nanosec``) to integer nanoseconds."""
    return int(stamp.sec) * _NS_PER_S + int(stamp.nanosec)


def ns_to_stamp(t_ns: int) -> Any:
    """Integer nanoseconds to ``builtin_interfaces/Time`` (``sec`` floor, ``nanosec`` < 1e9)."""
    sec, nanosec = divmod(int(t_ns), _NS_PER_S)
    if not -(2**31) <= sec < 2**31:
        raise ValueError(f"time {t_ns} ns does not fit builtin_interfaces/Time")
    return _types()["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)


def header(t_ns: int, frame_id: str) -> Any:
    """``std_msgs/Header`` with the measurement time ``t_ns`` (ns)."""
    return _types()["std_msgs/msg/Header"](stamp=ns_to_stamp(t_ns), frame_id=frame_id)


def vector3(xyz: ArrayLike) -> Any:
    """``geometry_msgs/Vector3`` from three numbers."""
    x, y, z = (float(v) for v in _f64(xyz, 3))
    return _types()["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def quaternion(xyzw: ArrayLike) -> Any:
    """``geometry_msgs/Quaternion`` from (x, y, z, w)."""
    x, y, z, w = (float(v) for v in _f64(xyzw, 4))
    return _types()["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)


def yaw_to_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation by ``yaw_rad`` (rad, counter-clockwise) about z."""
    half = 0.5 * float(yaw_rad)
    return (0.0, 0.0, math.sin(half), math.cos(half))


def joint_state(
    t_ns: int,
    names: Sequence[str],
    *,
    position: ArrayLike = (),
    velocity: ArrayLike = (),
    effort: ArrayLike = (),
    frame_id: str = tp.BASE_LINK,
) -> Any:
    """``sensor_msgs/JointState`` (position rad or m, velocity rad/s, effort N or N m)."""
    return _types()[tp.JOINT_STATE](
        header=header(t_ns, frame_id),
        name=list(names),
        position=_f64(position),
        velocity=_f64(velocity),
        effort=_f64(effort),
    )


def imu(
    t_ns: int,
    angular_velocity_rad_s: ArrayLike,
    linear_acceleration_m_s2: ArrayLike,
    *,
    gyro_std_rad_s: float = 0.0,
    accel_std_m_s2: float = 0.0,
    frame_id: str = tp.BASE_LINK,
) -> Any:
    """``sensor_msgs/Imu`` without orientation (``orientation_covariance[0] = -1``).

    Covariances are diagonal: ``gyro_std_rad_s**2`` (rad^2/s^2) and ``accel_std_m_s2**2``
    (m^2/s^4).
    """
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0
    return _types()[tp.IMU](
        header=header(t_ns, frame_id),
        orientation=quaternion((0.0, 0.0, 0.0, 1.0)),
        orientation_covariance=no_orientation,
        angular_velocity=vector3(angular_velocity_rad_s),
        angular_velocity_covariance=np.diag([float(gyro_std_rad_s) ** 2] * 3).reshape(9),
        linear_acceleration=vector3(linear_acceleration_m_s2),
        linear_acceleration_covariance=np.diag([float(accel_std_m_s2) ** 2] * 3).reshape(9),
    )


def nav_sat_fix(
    t_ns: int,
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    covariance_enu_m2: ArrayLike,
    *,
    frame_id: str = tp.GNSS_FRAME,
    covariance_type: int = COVARIANCE_TYPE_KNOWN,
) -> Any:
    """``sensor_msgs/NavSatFix`` with status FIX (GPS); covariance 3x3 ENU m^2, row-major."""
    status = _types()["sensor_msgs/msg/NavSatStatus"](
        status=NAVSAT_STATUS_FIX, service=NAVSAT_SERVICE_GPS
    )
    return _types()[tp.NAV_SAT_FIX](
        header=header(t_ns, frame_id),
        status=status,
        latitude=float(lat_deg),
        longitude=float(lon_deg),
        altitude=float(alt_m),
        position_covariance=_f64(covariance_enu_m2, 9),
        position_covariance_type=int(covariance_type),
    )


def twist_with_covariance_stamped(
    t_ns: int,
    linear_m_s: ArrayLike,
    linear_covariance_m2_s2: ArrayLike,
    *,
    frame_id: str = tp.MAP,
) -> Any:
    """``geometry_msgs/TwistWithCovarianceStamped`` of a Doppler velocity (m/s, ENU axes).

    The 6x6 covariance holds ``linear_covariance_m2_s2`` (3x3) top-left; the angular part is not
    measured (zero twist, variance :data:`UNKNOWN_ANGULAR_VARIANCE`).
    """
    cov = np.zeros((6, 6))
    cov[:3, :3] = _f64(linear_covariance_m2_s2, 9).reshape(3, 3)
    cov[3:, 3:] = np.eye(3) * UNKNOWN_ANGULAR_VARIANCE
    types = _types()
    twist = types["geometry_msgs/msg/Twist"](
        linear=vector3(linear_m_s), angular=vector3((0.0, 0.0, 0.0))
    )
    return types[tp.TWIST_WITH_COVARIANCE_STAMPED](
        header=header(t_ns, frame_id),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=twist, covariance=cov.reshape(36)
        ),
    )


def odometry(
    t_ns: int,
    position_m: ArrayLike,
    orientation_xyzw: ArrayLike,
    linear_m_s: ArrayLike,
    angular_rad_s: ArrayLike,
    *,
    pose_covariance: ArrayLike | None = None,
    twist_covariance: ArrayLike | None = None,
    frame_id: str = tp.MAP,
    child_frame_id: str = tp.BASE_LINK,
) -> Any:
    """``nav_msgs/Odometry``: pose (m, quaternion) in ``frame_id``, twist in ``child_frame_id``.

    Covariances are 6x6 row-major (m^2, rad^2 / m^2/s^2, rad^2/s^2); zero when not given.
    """
    types = _types()
    pose = types["geometry_msgs/msg/Pose"](
        position=types["geometry_msgs/msg/Point"](*(float(v) for v in _f64(position_m, 3))),
        orientation=quaternion(orientation_xyzw),
    )
    twist = types["geometry_msgs/msg/Twist"](
        linear=vector3(linear_m_s), angular=vector3(angular_rad_s)
    )
    pcov = np.zeros(36) if pose_covariance is None else _f64(pose_covariance, 36)
    tcov = np.zeros(36) if twist_covariance is None else _f64(twist_covariance, 36)
    return types[tp.ODOMETRY](
        header=header(t_ns, frame_id),
        child_frame_id=child_frame_id,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=pcov),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=tcov),
    )


def tire_forces(
    t_ns: int,
    wheel_names: Sequence[str],
    fx_n: ArrayLike,
    fy_n: ArrayLike,
    fz_n: ArrayLike,
    valid: ArrayLike,
    *,
    frame_id: str = tp.BASE_LINK,
) -> Any:
    """``tire_estimation_msgs/TireForces`` (forces in N in each wheel's frame)."""
    n = len(wheel_names)
    return _types()[tp.TIRE_FORCES](
        header=header(t_ns, frame_id),
        wheel_names=list(wheel_names),
        fx_n=_f64(fx_n, n),
        fy_n=_f64(fy_n, n),
        fz_n=_f64(fz_n, n),
        valid=np.ascontiguousarray(valid, dtype=np.bool_).reshape(n),
    )
