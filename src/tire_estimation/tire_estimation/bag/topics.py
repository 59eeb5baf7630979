"""Contract v1 topic names, message type names and frame ids (see /work/shared/contract.md)."""

from __future__ import annotations

from typing import Final

# --- message types (rosbags / ROS 2 names) ---
JOINT_STATE: Final = "sensor_msgs/msg/JointState"
IMU: Final = "sensor_msgs/msg/Imu"
NAV_SAT_FIX: Final = "sensor_msgs/msg/NavSatFix"
TWIST_WITH_COVARIANCE_STAMPED: Final = "geometry_msgs/msg/TwistWithCovarianceStamped"
ODOMETRY: Final = "nav_msgs/msg/Odometry"
DIAGNOSTIC_ARRAY: Final = "diagnostic_msgs/msg/DiagnosticArray"
TIRE_FORCES: Final = "tire_estimation_msgs/msg/TireForces"
TIRE_RADII: Final = "tire_estimation_msgs/msg/TireRadii"
TIRE_STIFFNESS: Final = "tire_estimation_msgs/msg/TireStiffness"
DEFLATION_STATUS: Final = "tire_estimation_msgs/msg/DeflationStatus"
WHEEL_DEFLATION: Final = "tire_estimation_msgs/msg/WheelDeflation"
LATERAL_STATE: Final = "tire_estimation_msgs/msg/LateralState"

# --- input topics (subscribed by the estimator node) ---
WHEEL_SPEEDS: Final = "/vehicle/wheel_speeds"
STEERING: Final = "/vehicle/steering"
IMU_DATA: Final = "/imu/data"
GNSS_FIX: Final = "/gnss/fix"
GNSS_VELOCITY: Final = "/gnss/velocity"
TIRE_FORCES_TOPIC: Final = "/vehicle/tire_forces"
#: Project-defined input (not in contract v1): measured body velocity of base_link in base_link
#: axes (``TwistWithCovarianceStamped``; ``linear.x`` is used), for data without wheel speeds.
VEHICLE_VELOCITY: Final = "/vehicle/velocity"

# --- output topics ---
OUT_ODOMETRY: Final = "/tire_estimation/odometry"
OUT_TIRE_RADII: Final = "/tire_estimation/tire_radii"
OUT_TIRE_STIFFNESS: Final = "/tire_estimation/tire_stiffness"
OUT_LATERAL_STATE: Final = "/tire_estimation/lateral_state"
OUT_DEFLATION: Final = "/tire_estimation/deflation"
DIAGNOSTICS: Final = "/diagnostics"

# --- ground truth and reference (evaluation bags only; never subscribed by the nodes) ---
TRUTH_FIX: Final = "/truth/fix"
TRUTH_ODOMETRY: Final = "/truth/odometry"
TRUTH_WHEEL_RADII: Final = "/truth/wheel_radii"
TRUTH_TIRE_PRESSURE: Final = "/truth/tire_pressure"
TRUTH_TIRE_STIFFNESS: Final = "/truth/tire_stiffness"
REFERENCE_ODOMETRY: Final = "/reference/odometry"
#: Project-defined reference: measured lateral state at the CG (JointState ``position`` by name,
#: :data:`REFERENCE_LATERAL_NAMES`: m/s, m/s, rad, rad/s).
REFERENCE_LATERAL_STATE: Final = "/reference/lateral_state"
REFERENCE_LATERAL_NAMES: Final[tuple[str, str, str, str]] = (
    "vx_cg",
    "vy_cg",
    "sideslip_cg",
    "yaw_rate",
)

#: Names on ``/truth/tire_stiffness`` in the order of ``TruthStream.stiffness`` columns.
STIFFNESS_NAMES: Final[tuple[str, str, str]] = ("cx_front", "cy_front", "cy_rear")
#: The same and ``cx_rear`` (``TruthStream.cx_rear_n``; the estimate of a rear-driven vehicle),
#: the names the replay reads from ``/truth/tire_stiffness``.
TRUTH_STIFFNESS_NAMES: Final[tuple[str, ...]] = (*STIFFNESS_NAMES, "cx_rear")

#: Message type of every contract topic.
TOPIC_TYPES: Final[dict[str, str]] = {
    WHEEL_SPEEDS: JOINT_STATE,
    STEERING: JOINT_STATE,
    IMU_DATA: IMU,
    GNSS_FIX: NAV_SAT_FIX,
    GNSS_VELOCITY: TWIST_WITH_COVARIANCE_STAMPED,
    TIRE_FORCES_TOPIC: TIRE_FORCES,
    OUT_ODOMETRY: ODOMETRY,
    OUT_TIRE_RADII: TIRE_RADII,
    OUT_TIRE_STIFFNESS: TIRE_STIFFNESS,
    OUT_LATERAL_STATE: LATERAL_STATE,
    OUT_DEFLATION: DEFLATION_STATUS,
    DIAGNOSTICS: DIAGNOSTIC_ARRAY,
    TRUTH_FIX: NAV_SAT_FIX,
    TRUTH_ODOMETRY: ODOMETRY,
    TRUTH_WHEEL_RADII: JOINT_STATE,
    TRUTH_TIRE_PRESSURE: JOINT_STATE,
    TRUTH_TIRE_STIFFNESS: JOINT_STATE,
    REFERENCE_ODOMETRY: ODOMETRY,
    VEHICLE_VELOCITY: TWIST_WITH_COVARIANCE_STAMPED,
    REFERENCE_LATERAL_STATE: JOINT_STATE,
}

INPUT_TOPICS: Final = (
    WHEEL_SPEEDS,
    STEERING,
    IMU_DATA,
    GNSS_FIX,
    GNSS_VELOCITY,
    TIRE_FORCES_TOPIC,
    VEHICLE_VELOCITY,
)
#: The sample stream (``core.samples`` ``KIND``, the key of the drop counters) of each input
#: topic.
INPUT_STREAMS: Final[dict[str, str]] = {
    WHEEL_SPEEDS: "wheel_speeds",
    STEERING: "steering",
    IMU_DATA: "imu",
    GNSS_FIX: "gnss_fix",
    GNSS_VELOCITY: "gnss_velocity",
    TIRE_FORCES_TOPIC: "tire_forces",
    VEHICLE_VELOCITY: "velocity",
}
TRUTH_TOPICS: Final = (
    TRUTH_FIX,
    TRUTH_ODOMETRY,
    TRUTH_WHEEL_RADII,
    TRUTH_TIRE_PRESSURE,
    TRUTH_TIRE_STIFFNESS,
)
REFERENCE_TOPICS: Final = (REFERENCE_ODOMETRY, REFERENCE_LATERAL_STATE)

# --- frame ids ---
BASE_LINK: Final = "base_link"
MAP: Final = "map"
#: Frame of ``/gnss/fix`` (the antenna; its position in base_link is in vehicle.yaml).
GNSS_FRAME: Final = "gnss_antenna"
