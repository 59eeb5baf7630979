"""Core estimates -> output messages of the estimator node (REP-103/105)."""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState, NavSatFix
from std_msgs.msg import Float64

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.lateral.estimate import LateralEstimate
from tire_estimation.core.radius.estimator import RadiusEstimate
from tire_estimation.core.radius.wheel_odometry import CorrectedTwist, EffectiveRadii
from tire_estimation.core.stiffness.estimator import StiffnessEstimate
from tire_estimation.core.wheels import CONTRACT_NAMES, WHEELS, Names
from tire_estimation.nodes.conversions import ns_to_stamp
from tire_estimation_msgs.msg import LateralState, TireRadii, TireStiffness

_STATE = {
    "initializing": TireRadii.STATE_INITIALIZING,
    "running": TireRadii.STATE_RUNNING,
    "paused": TireRadii.STATE_PAUSED,
}
_LINEARITY = {
    "unknown": LateralState.LINEARITY_UNKNOWN,
    "linear": LateralState.LINEARITY_LINEAR,
    "nonlinear": LateralState.LINEARITY_NONLINEAR,
}
#: rows/columns of x, y and yaw in the REP-103 6x6 covariance order (x, y, z, roll, pitch, yaw)
_PLANAR = (0, 1, 5)
#: twist covariance of the odometry: speed (0.1 m/s)^2, lateral and vertical speed (0.1 m/s)^2
#: (planar, non-holonomic), roll/pitch rates unknown, yaw rate (0.01 rad/s)^2
_TWIST_COV = np.diag([0.01, 0.01, 0.01, 1e6, 1e6, 1e-4]).reshape(36)
#: variance of what the corrected wheel odometry does not measure (vy, vz, roll and pitch rate)
UNMEASURED_VAR = 1e6

#: the 6x6 pose covariance of the odometry without its planar block: z, roll, pitch unknown
_POSE_COV_UNKNOWN = (0.0,) * 14 + (1e6,) + (0.0,) * 6 + (1e6,) + (0.0,) * 6 + (1e6,) + (0.0,) * 7
#: the 6x6 covariance of the corrected twist without its (vx, yaw rate) block
_TWIST_UNMEASURED = tuple(
    UNMEASURED_VAR if i == j and i not in (0, 5) else 0.0 for i in range(6) for j in range(6)
)

M = TypeVar("M")


def _embedded(block: object, axes: tuple[int, ...], base: tuple[float, ...]) -> list[float]:
    """The row-major 6x6 covariance ``base`` with ``block`` (len(axes) square) at the rows and
    columns ``axes``: plain floats (cheaper than a NumPy scatter for 36 values)."""
    cov = list(base)
    rows = np.asarray(block, dtype=float).tolist()
    for a, row in zip(axes, rows, strict=True):
        for b, value in zip(axes, row, strict=True):
            cov[6 * a + b] = value
    return cov


def _stamped(msg: M, t_ns: int, frame_id: str) -> M:
    """``msg`` with its header's stamp ``t_ns`` and ``frame_id``."""
    ns_to_stamp(t_ns, msg.header.stamp)
    msg.header.frame_id = frame_id
    return msg


def odometry_msg(est: RadiusEstimate, t_ns: int, names: Names = CONTRACT_NAMES) -> Odometry:
    """Pose of base_link in ``map`` (planar: z, roll, pitch unknown), twist in base_link (the
    frames as ``names`` calls them)."""
    msg = _stamped(Odometry(), t_ns, names.map_frame)
    msg.child_frame_id = names.base_frame
    east, north, yaw = (float(v) for v in est.pose)
    msg.pose.pose.position.x = east
    msg.pose.pose.position.y = north
    # quaternion of a rotation about z by yaw: (0, 0, sin(yaw / 2), cos(yaw / 2))
    msg.pose.pose.orientation.z = math.sin(0.5 * yaw)
    msg.pose.pose.orientation.w = math.cos(0.5 * yaw)
    msg.pose.covariance = _embedded(est.pose_cov, _PLANAR, _POSE_COV_UNKNOWN)
    msg.twist.twist.linear.x = float(est.speed_m_s)
    msg.twist.twist.angular.z = float(est.yaw_rate_rad_s)
    msg.twist.covariance = _TWIST_COV
    return msg


def radii_msg(
    est: RadiusEstimate, t_ns: int, nominal_radius_m: float, names: Names = CONTRACT_NAMES
) -> TireRadii:
    """Per-wheel radius error (estimate minus nominal) with its std."""
    msg = _stamped(TireRadii(), t_ns, names.base_frame)
    msg.nominal_radius_m = float(nominal_radius_m)
    msg.wheel_names = list(est.wheels)
    msg.radius_error_m = [float(v) for v in est.radius_error_m]
    msg.radius_error_std_m = [float(v) for v in est.radius_error_std_m]
    msg.radius_noise_std_m = [float(v) for v in est.radius_noise_std_m]
    msg.active = [bool(v) for v in est.active]
    msg.effective_sample_size = float(est.n_eff)
    msg.state = _STATE.get(est.state, TireRadii.STATE_INITIALIZING)
    msg.state_reason = str(est.state_reason)
    return msg


def twist_msg(twist: CorrectedTwist, names: Names = CONTRACT_NAMES) -> TwistWithCovarianceStamped:
    """Wheel odometry corrected with the learned radii, in base_link: vx and yaw rate with
    their (2, 2) covariance at (x, x), (x, yaw), (yaw, yaw) of the 6x6 twist covariance; the
    other components are not measured (0 with variance :data:`UNMEASURED_VAR`)."""
    msg = _stamped(TwistWithCovarianceStamped(), twist.t_ns, names.base_frame)
    msg.twist.twist.linear.x = float(twist.vx_m_s)
    msg.twist.twist.angular.z = float(twist.yaw_rate_rad_s)
    msg.twist.covariance = _embedded(twist.covariance, (0, 5), _TWIST_UNMEASURED)
    return msg


def wheel_radii_msg(radii: EffectiveRadii, t_ns: int, names: Names = CONTRACT_NAMES) -> JointState:
    """Per wheel (``name``): ``position`` = effective rolling radius, m (as on
    ``/truth/wheel_radii``); ``effort`` = radius multiplier, effective over nominal radius, 1
    (``diff_drive_controller``'s ``*_wheel_radius_multiplier``); ``velocity`` empty. Wheels
    carry the robot's joint names (``names``)."""
    msg = _stamped(JointState(), t_ns, names.base_frame)
    own = dict(zip(WHEELS, names.wheels, strict=True))
    msg.name = [own.get(w, w) for w in radii.wheels]
    msg.position = [float(v) for v in radii.radius_m]
    msg.effort = [float(v) for v in radii.multiplier]
    return msg


def speed_scale_msg(radii: EffectiveRadii) -> Float64:
    """The speed scale factor: mean rear effective radius over the nominal radius, 1."""
    return Float64(data=float(radii.speed_scale_factor))


def stiffness_msg(
    est: StiffnessEstimate, t_ns: int, names: Names = CONTRACT_NAMES
) -> TireStiffness:
    """Learned axle stiffness, its std, the nominal values and the IMU biases."""
    msg = _stamped(TireStiffness(), t_ns, names.base_frame)
    msg.names = list(est.names)
    msg.stiffness = [float(v) for v in est.stiffness]
    msg.stiffness_std = [float(v) for v in est.stiffness_std]
    msg.nominal = [float(v) for v in est.nominal]
    msg.active = bool(est.active)
    msg.reason = "" if est.reason == "excited" else str(est.reason)
    msg.gyro_bias_rad_s = [float(v) for v in est.gyro_bias_rad_s]
    msg.accel_bias_m_s2 = [float(v) for v in est.accel_bias_m_s2]
    msg.effective_sample_size = float(est.n_eff)
    return msg


def lateral_msg(est: LateralEstimate, t_ns: int, names: Names = CONTRACT_NAMES) -> LateralState:
    """Lateral state of base_link; ``source`` names the estimator."""
    msg = _stamped(LateralState(), t_ns, names.base_frame)
    msg.source = str(est.source)
    msg.longitudinal_velocity_m_s = float(est.vx_m_s)
    msg.lateral_velocity_m_s = float(est.vy_m_s)
    msg.yaw_rate_rad_s = float(est.yaw_rate_rad_s)
    msg.sideslip_rad = float(est.sideslip_rad)
    msg.covariance = np.asarray(est.covariance, dtype=float).ravel().tolist()
    msg.axle_lateral_force_n = [float(v) for v in est.axle_lateral_force_n]
    msg.linearity = _LINEARITY.get(est.linearity, LateralState.LINEARITY_UNKNOWN)
    return msg


def datum_msg(datum: LocalTangentPlane, t_ns: int, names: Names = CONTRACT_NAMES) -> NavSatFix:
    """The origin of the pose's ENU frame (``map``, as ``names`` calls it): latitude,
    longitude (deg) and ellipsoidal height (m) of the first GNSS fix; covariance unknown."""
    msg = _stamped(NavSatFix(), t_ns, names.map_frame)
    msg.latitude = float(datum.origin_lat_deg)
    msg.longitude = float(datum.origin_lon_deg)
    msg.altitude = float(datum.origin_alt_m)
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_UNKNOWN
    return msg
