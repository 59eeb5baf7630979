"""Message <-> core conversions for the nodes (duck-typed: no message imports needed here).

Each ``*_from_msg`` returns a typed sample of :mod:`tire_estimation.core.samples` (checked
there) or raises :class:`InputError` with a stable ``kind`` that the node counts and reports on
``/diagnostics`` as ``dropped.<stream>:<kind>``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tire_estimation.core.input_checks import unique_names
from tire_estimation.core.samples import (
    GnssFix,
    GnssVelocity,
    ImuSample,
    MeasuredVelocity,
    Steering,
    TireForces,
    WheelSpeeds,
)
from tire_estimation.core.wheels import CONTRACT_NAMES, Names
from tire_estimation.errors import InputError


def stamp_ns(header: Any) -> int:
    """Header stamp as integer nanoseconds; a zero stamp is rejected (no measurement time)."""
    t_ns = int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    if t_ns <= 0:
        raise InputError("no_stamp", "header stamp is zero")
    return t_ns


def ns_to_stamp(t_ns: int, stamp: Any) -> Any:
    """Fill a builtin_interfaces/Time from integer nanoseconds and return it."""
    stamp.sec, stamp.nanosec = divmod(int(t_ns), 1_000_000_000)
    return stamp


def wheel_speeds_from_msg(msg: Any, joints: Names = CONTRACT_NAMES) -> WheelSpeeds:
    """JointState -> :class:`WheelSpeeds` (NaN for a wheel the message does not name).

    Names are matched, not positions (contract), against ``joints.wheels`` (the robot's own
    names for ``wheel_fl`` ... ``wheel_rr``). Unknown names are ignored if at least one known
    wheel is present; a message with no known wheel raises ``unknown_wheel`` (naming the
    expected names), one that names a wheel twice ``duplicate_wheel``.
    """
    t_ns = stamp_ns(msg.header)
    names = list(msg.name)
    velocity = list(msg.velocity)
    if not names or not velocity:
        raise InputError("empty", "wheel speed JointState has no names or no velocities")
    if len(names) != len(velocity):
        raise InputError(
            "wrong_length",
            f"wheel speed JointState has {len(names)} names but {len(velocity)} velocities",
        )
    index = joints.wheel_index
    unique_names(names, index, "duplicate_wheel")
    # floats in a list, one array made by the sample's check: cheaper than array item writes
    out = [math.nan] * 4
    known = 0
    for name, value in zip(names, velocity, strict=True):
        idx = index.get(name)
        if idx is None:
            continue
        out[idx] = float(value)
        known += 1
    if known == 0:
        raise InputError(
            "unknown_wheel", f"no known wheel name in {names}; expected {joints.wheels}"
        )
    if any(map(math.isinf, out)) or any(map(math.isnan, velocity)):
        raise InputError("nan", "a wheel speed is not finite")
    return WheelSpeeds.checked(t_ns, out)


def steering_from_msg(msg: Any, joints: Names = CONTRACT_NAMES) -> Steering:
    """JointState with ``joints.steering`` (contract ``front_wheel_angle``) -> :class:`Steering`
    (named twice: ``duplicate_joint``)."""
    t_ns = stamp_ns(msg.header)
    names = list(msg.name)
    position = list(msg.position)
    if len(names) != len(position):
        raise InputError(
            "wrong_length",
            f"steering JointState has {len(names)} names but {len(position)} positions",
        )
    unique_names(names, (joints.steering,), "duplicate_joint")
    for name, value in zip(names, position, strict=True):
        if name == joints.steering:
            return Steering.checked(t_ns, value)
    raise InputError("unknown_joint", f"no '{joints.steering}' in steering names {names}")


def imu_from_msg(msg: Any) -> ImuSample:
    """Imu -> :class:`ImuSample`."""
    t_ns = stamp_ns(msg.header)
    w = msg.angular_velocity
    a = msg.linear_acceleration
    return ImuSample.checked(t_ns, [w.x, w.y, w.z], [a.x, a.y, a.z])


def velocity_from_msg(msg: Any) -> MeasuredVelocity:
    """TwistWithCovarianceStamped in base_link -> :class:`MeasuredVelocity`.

    Another frame raises ``wrong_frame`` (an empty frame id is taken as base_link).
    """
    t_ns = stamp_ns(msg.header)
    frame = str(msg.header.frame_id)
    if frame not in ("base_link", ""):
        raise InputError("wrong_frame", f"/vehicle/velocity must be in base_link, got {frame!r}")
    return MeasuredVelocity.checked(t_ns, msg.twist.twist.linear.x)


def gnss_velocity_from_msg(msg: Any) -> GnssVelocity:
    """TwistWithCovarianceStamped of ``/gnss/velocity`` (ENU, contract) -> :class:`GnssVelocity`
    (covariance None when all zero).

    The frame id is not an axis convention for GNSS drivers (many put the antenna's frame
    there while reporting ENU); only ``base_link`` (body axes) is refused with ``wrong_frame``.
    """
    t_ns = stamp_ns(msg.header)
    if str(msg.header.frame_id) == "base_link":
        raise InputError("wrong_frame", "/gnss/velocity must be in ENU, got base_link")
    lin = msg.twist.twist.linear
    cov = np.asarray(msg.twist.covariance, dtype=float).reshape(6, 6)[:3, :3]
    return GnssVelocity.checked(t_ns, [lin.x, lin.y, lin.z], cov.copy())


def gnss_from_msg(msg: Any) -> GnssFix:
    """NavSatFix -> :class:`GnssFix` (:meth:`GnssFix.from_navsat`, the bag reader's check).

    A fix with status STATUS_NO_FIX (-1) raises ``no_fix``; STATUS_UNKNOWN (-2, the message
    default, left by many drivers) is accepted. Covariance type 0 (unknown) gives None so the
    estimator applies its configured default; with any other type a covariance that is not
    finite, not symmetric or not positive semi-definite raises ``bad_covariance`` (all zero is
    read as not reported). A NaN altitude (none reported) is kept.
    """
    return GnssFix.from_navsat(
        stamp_ns(msg.header),
        msg.status.status,
        msg.latitude,
        msg.longitude,
        msg.altitude,
        msg.position_covariance,
        msg.position_covariance_type,
    )


def tire_forces_from_msg(msg: Any, joints: Names = CONTRACT_NAMES) -> TireForces:
    """TireForces message -> :class:`TireForces` sample, arrays in WHEELS order.

    Wheels absent from the message are invalid; unknown names are ignored; mismatched array
    lengths raise ``wrong_length``; no known wheel raises ``unknown_wheel``, a wheel named twice
    ``duplicate_wheel``.
    """
    t_ns = stamp_ns(msg.header)
    names = list(msg.wheel_names)
    cols = [list(msg.fx_n), list(msg.fy_n), list(msg.fz_n), list(msg.valid)]
    if any(len(c) != len(names) for c in cols):
        raise InputError(
            "wrong_length",
            f"TireForces has {len(names)} names but {[len(c) for c in cols]} values",
        )
    index = joints.wheel_index
    unique_names(names, index, "duplicate_wheel")
    fx, fy, fz = [0.0] * 4, [0.0] * 4, [0.0] * 4
    valid = [False] * 4
    known = 0
    for k, name in enumerate(names):
        idx = index.get(name)
        if idx is None:
            continue
        known += 1
        fx[idx], fy[idx], fz[idx] = float(cols[0][k]), float(cols[1][k]), float(cols[2][k])
        valid[idx] = bool(cols[3][k])
    if known == 0:
        raise InputError(
            "unknown_wheel", f"no known wheel name in {names}; expected {joints.wheels}"
        )
    return TireForces.checked(t_ns, fx, fy, fz, valid)
