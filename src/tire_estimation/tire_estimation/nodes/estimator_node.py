"""estimator_node: thin rclpy adapter over the core estimators.

Subscribes (contract v1): ``/vehicle/wheel_speeds``, ``/vehicle/steering``, ``/imu/data``,
``/gnss/fix`` and, when present, ``/vehicle/tire_forces`` and ``/vehicle/velocity``
(project-defined: measured vx for vehicles without wheel speeds), and ``/gnss/velocity`` (the
receiver's Doppler velocity) with the parameter ``radius.gnss_velocity_enabled``. Publishes
``/tire_estimation/odometry`` and ``/tire_estimation/tire_radii`` (tire-radius MPF,
:class:`~tire_estimation.core.radius_estimator.RadiusEstimator`),
``/tire_estimation/tire_stiffness`` (stiffness MPF,
:class:`~tire_estimation.core.stiffness_estimator.StiffnessEstimator`, on IMU + steering +
speed), ``/tire_estimation/lateral_state`` (tyre-force Kalman filter,
:class:`~tire_estimation.core.tyre_force_kf.TyreForceEstimator`, while tyre forces arrive; else
the stiffness MPF's lateral state) and ``/diagnostics``. Services: ``~/reset``
(std_srvs/Trigger) forgets the learned radii and stiffness.

The node converts messages, hands them to the same core object the bag replay drives, and
publishes what the core estimates. Bad input never stops it: the sample is dropped, counted by
kind and shown on ``/diagnostics``.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState, NavSatFix
from std_srvs.srv import Trigger

from tire_estimation.core.config import RadiusEstimatorConfig
from tire_estimation.core.ordering import StampOrderedDispatcher
from tire_estimation.core.radius_estimator import RadiusEstimator
from tire_estimation.core.stiffness_config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness_estimator import StiffnessEstimate, StiffnessEstimator
from tire_estimation.core.tyre_force_kf import TyreForceEstimator, TyreForceKFConfig
from tire_estimation.core.vehicle import VehicleParams, load_vehicle_yaml
from tire_estimation.errors import InputError, TireEstimationError
from tire_estimation.node_config import EstimatorNodeOptions
from tire_estimation.nodes import conversions as conv
from tire_estimation.nodes.common import declare_specs, restore_state, save_state_of, spin_node
from tire_estimation.params import (
    ParameterSpec,
    build_config,
    estimator_sections,
    parameter_specs,
)
from tire_estimation.persistence import Identity, LearnedState, delete_state
from tire_estimation_msgs.msg import LateralState, TireForces, TireRadii, TireStiffness

SECTIONS = estimator_sections()
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


#: Seed-sequence key of the stiffness MPF's generator (``default_rng([radius.seed, key])``), as in
#: the replay, so a live run and a replay draw the same numbers.
STIFFNESS_RNG_KEY = 1
#: The stiffness MPF publishes the lateral state only when the tyre-force KF has not for this
#: long (header time), ns.
TYRE_FORCE_PRIORITY_NS = 500_000_000

#: rows/columns of x, y and yaw in the REP-103 6x6 covariance order (x, y, z, roll, pitch, yaw)
_PLANAR = (0, 1, 5)
#: twist covariance of the odometry: speed (0.1 m/s)^2, lateral and vertical speed (0.1 m/s)^2
#: (planar, non-holonomic), roll/pitch rates unknown, yaw rate (0.01 rad/s)^2
_TWIST_COV = np.diag([0.01, 0.01, 0.01, 1e6, 1e6, 1e-4]).reshape(36)


#: input streams reported on /diagnostics (rate and count)
INPUT_STREAMS = ("wheel_speeds", "steering", "imu", "gnss_fix", "gnss_velocity", "tire_forces")


def _yaw_to_quaternion(yaw_rad: float) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a rotation about z by ``yaw_rad``."""
    return 0.0, 0.0, math.sin(0.5 * yaw_rad), math.cos(0.5 * yaw_rad)


class EstimatorNode(Node):
    """ROS wrapper: parameters -> config dataclasses, messages -> core calls, core -> messages."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("estimator_node", **kwargs)
        self._declare_parameters()
        self.options = build_config(EstimatorNodeOptions, "", self._values(self._specs[""]))
        self.vehicle = self._load_vehicle()
        self.config = self._load_config()
        rng = np.random.default_rng(self.config.seed)
        self.estimator = RadiusEstimator(self.config, self.vehicle, rng)
        self.dispatcher = StampOrderedDispatcher("wheel_speeds")
        self.lateral: TyreForceEstimator | None = None
        if self.options.tyre_force_enabled:
            tyre_cfg = build_config(
                TyreForceKFConfig, "tyre_force", self._values(self._specs["tyre_force"])
            )
            self.lateral = TyreForceEstimator(tyre_cfg, self.vehicle)
        self._last_lateral_pub_ns = 0
        self._last_tyre_force_pub_ns: int | None = None
        self._lateral_period_ns = int(self.options.lateral_publish_period_s * 1e9)
        self.stiffness: StiffnessEstimator | None = None
        if self.options.stiffness_enabled:
            stiff_cfg = build_config(
                StiffnessEstimatorConfig, "stiffness", self._values(self._specs["stiffness"])
            )
            stiff_rng = np.random.default_rng([self.config.seed, STIFFNESS_RNG_KEY])
            self.stiffness = StiffnessEstimator(stiff_cfg, self.vehicle, stiff_rng)
        self._last_stiffness_pub_ns = 0
        self._stiffness_period_ns = int(self.options.stiffness_publish_period_s * 1e9)

        self.dropped: Counter[str] = Counter()
        self.received: Counter[str] = Counter()
        self._rate_window: Counter[str] = Counter()
        self._rate_t0 = time.monotonic()
        self._input_rates_hz: dict[str, float] = {}
        self._last_radii_pub_ns = 0
        self._last_odom_pub_ns = 0
        self._radii_period_ns = int(self.options.radii_publish_period_s * 1e9)
        self._odom_period_ns = int(self.options.odometry_publish_period_s * 1e9)
        self._persist_note = "persistence disabled"
        self._identity = Identity(self.vehicle.name, self.options.tire_set_id)
        self._persist_path = self._persistence_path()
        self._restore()

        sensor_qos: QoSProfile = (
            qos_profile_sensor_data
            if self.options.sensor_qos == "sensor_data"
            else QoSProfile(depth=100)
        )
        self.create_subscription(
            JointState,
            "/vehicle/wheel_speeds",
            self._guard("wheel_speeds", self._on_wheels),
            sensor_qos,
        )
        self.create_subscription(
            JointState, "/vehicle/steering", self._guard("steering", self._on_steering), sensor_qos
        )
        self.create_subscription(Imu, "/imu/data", self._guard("imu", self._on_imu), sensor_qos)
        self.create_subscription(
            NavSatFix, "/gnss/fix", self._guard("gnss_fix", self._on_gnss), sensor_qos
        )
        if self.config.gnss_velocity_enabled:
            self.create_subscription(
                TwistWithCovarianceStamped,
                "/gnss/velocity",
                self._guard("gnss_velocity", self._on_gnss_velocity),
                sensor_qos,
            )
        if self.stiffness is not None:
            self.create_subscription(
                TwistWithCovarianceStamped,
                "/vehicle/velocity",
                self._guard("velocity", self._on_velocity),
                sensor_qos,
            )
        if self.lateral is not None:
            self.create_subscription(
                TireForces,
                "/vehicle/tire_forces",
                self._guard("tire_forces", self._on_tire_forces),
                sensor_qos,
            )
        self.pub_lateral = self.create_publisher(
            LateralState, "/tire_estimation/lateral_state", 10
        )
        self.pub_stiffness = self.create_publisher(
            TireStiffness, "/tire_estimation/tire_stiffness", 10
        )
        self.pub_odom = self.create_publisher(Odometry, "/tire_estimation/odometry", 10)
        self.pub_radii = self.create_publisher(TireRadii, "/tire_estimation/tire_radii", 10)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_timer(self.options.diagnostics_period_s, self._publish_diag)
        period = self.options.persistence_period_s
        if self._persist_path is not None and period > 0:
            self.create_timer(period, self._save)
        self.get_logger().info(
            f"estimator_node up: vehicle {self.vehicle.name!r}, {self.config.n_particles} "
            f"particles, wheels {self.config.wheels}; {self._persist_note}"
        )

    # --- parameters -------------------------------------------------------------------------
    def _declare_parameters(self) -> None:
        self._specs = {prefix: parameter_specs(cls, prefix) for prefix, cls, _ in SECTIONS}
        for specs in self._specs.values():
            declare_specs(self, specs)

    def _values(self, specs: Sequence[ParameterSpec]) -> dict[str, Any]:
        return {
            s.name: self.get_parameter(s.name).value for s in specs if self.has_parameter(s.name)
        }

    def _load_vehicle(self) -> VehicleParams:
        if self.options.vehicle_file:
            return load_vehicle_yaml(Path(self.options.vehicle_file).expanduser())
        return build_config(VehicleParams, "vehicle", self._values(self._specs["vehicle"]))

    def _load_config(self) -> RadiusEstimatorConfig:
        return build_config(RadiusEstimatorConfig, "radius", self._values(self._specs["radius"]))

    # --- persistence ------------------------------------------------------------------------
    def _persistence_path(self) -> Path | None:
        text = self.options.persistence_file
        return Path(text).expanduser() if text else None

    def _restore(self) -> None:
        # one file for the learned radii and (when the stiffness MPF runs) the learned
        # stiffness; each part is restored or rejected on its own
        self._learned = LearnedState({"radius": self.estimator, "stiffness": self.stiffness})
        note = restore_state(self._persist_path, self._identity, self._learned, "estimates")
        if self._persist_path is not None:
            summary = self._learned.summary()
            self._persist_note = f"{note} ({summary})" if summary else note

    def _save(self) -> None:
        if not save_state_of(self, self._persist_path, self._identity, self._learned, "estimates"):
            self.dropped["persistence_write"] += 1

    def _on_reset(self, _: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.estimator.reset()
        if self.stiffness is not None:
            self.stiffness.reset()
        if self._persist_path is not None:
            delete_state(self._persist_path)
        response.success = True
        response.message = "learned tire radii and stiffness reset to the prior"
        self.get_logger().info(response.message)
        return response

    def save_on_shutdown(self) -> None:
        """Write the learned radii and stiffness (called when the node stops)."""
        self._save()

    # --- inputs -----------------------------------------------------------------------------
    def _guard(self, stream: str, handler: Callable[[Any], None]) -> Callable[[Any], None]:
        """Wrap a callback: count the message, drop and count bad input, never raise."""

        def callback(msg: Any) -> None:
            self.received[stream] += 1
            self._rate_window[stream] += 1
            try:
                handler(msg)
            except InputError as exc:
                self.dropped[f"{stream}:{exc.kind}"] += 1
            except (TireEstimationError, ValueError, TypeError, AttributeError) as exc:
                self.dropped[f"{stream}:invalid"] += 1
                self.get_logger().warning(
                    f"dropped a {stream} message: {exc}", throttle_duration_sec=5.0
                )

        return callback

    def _on_wheels(self, msg: JointState) -> None:
        t_ns, speeds = conv.wheel_speeds_from_msg(msg)
        self._dispatch(t_ns, "wheel_speeds", speeds)

    def _on_steering(self, msg: JointState) -> None:
        t_ns, angle = conv.steering_from_msg(msg)
        self._dispatch(t_ns, "steering", angle)

    def _on_imu(self, msg: Imu) -> None:
        t_ns, gyro, acc = conv.imu_from_msg(msg)
        self._dispatch(t_ns, "imu", (gyro, acc))

    def _on_gnss(self, msg: NavSatFix) -> None:
        t_ns, lat, lon, alt, cov = conv.gnss_from_msg(msg)
        self._dispatch(t_ns, "gnss_fix", (lat, lon, alt, cov))

    def _on_gnss_velocity(self, msg: TwistWithCovarianceStamped) -> None:
        t_ns, vel, cov = conv.gnss_velocity_from_msg(msg)
        self._dispatch(t_ns, "gnss_velocity", (vel, cov))

    def _on_velocity(self, msg: TwistWithCovarianceStamped) -> None:
        t_ns, vx = conv.velocity_from_msg(msg)
        self._dispatch(t_ns, "velocity", vx)

    def _on_tire_forces(self, msg: TireForces) -> None:
        t_ns, fx, fy, fz, valid = conv.tire_forces_from_msg(msg)
        self._dispatch(t_ns, "tire_forces", (fx, fy, fz, valid))

    def _dispatch(self, t_ns: int, kind: str, payload: Any) -> None:
        """Hand samples to the core estimators in header-stamp order (see core.ordering)."""
        lateral, stiffness = self.lateral, self.stiffness
        for t, k, value in self.dispatcher.push(t_ns, kind, payload):
            if k == "wheel_speeds":
                self.estimator.on_wheel_speeds(t, value)
                if lateral is not None:
                    lateral.on_wheel_speeds(t, value)
                if stiffness is not None:
                    stiffness.on_wheel_speeds(t, value)
                self._publish(t)
            elif k == "steering":
                self.estimator.on_steering(t, value)
                if lateral is not None:
                    lateral.on_steering(t, value)
                if stiffness is not None:
                    stiffness.on_steering(t, value)
            elif k == "imu":
                self.estimator.on_imu(t, value[0], value[1])
                if lateral is not None:
                    lateral.on_imu(t, value[0], value[1])
                if stiffness is not None:
                    stiffness.on_imu(t, value[0], value[1])
                    self._publish_stiffness(stiffness, t)
            elif k == "gnss_velocity":
                self.estimator.on_gnss_velocity(t, value[0], value[1])
            elif k == "velocity":
                if stiffness is not None:
                    stiffness.on_velocity(t, value)
            elif k == "tire_forces":
                if lateral is not None:
                    est = lateral.on_tire_forces(t, *value)
                    if est is not None:
                        self._last_tyre_force_pub_ns = t
                        self._publish_lateral(est, t)
            else:
                self.estimator.on_gnss_fix(t, *value)

    def _publish_stiffness(self, stiffness: StiffnessEstimator, t_ns: int) -> None:
        """TireStiffness at its period and, while the tyre-force KF is silent, LateralState."""
        if not stiffness.mpf.initialized:
            return
        stiff_due = t_ns - self._last_stiffness_pub_ns >= self._stiffness_period_ns
        last_tf = self._last_tyre_force_pub_ns
        lateral_due = (
            last_tf is None or t_ns - last_tf > TYRE_FORCE_PRIORITY_NS
        ) and t_ns - self._last_lateral_pub_ns >= self._lateral_period_ns
        if not (stiff_due or lateral_due):
            return
        est = stiffness.estimate()
        if stiff_due:
            self._last_stiffness_pub_ns = t_ns
            self.pub_stiffness.publish(self._stiffness_msg(est, t_ns))
        if lateral_due:
            self._last_lateral_pub_ns = t_ns
            self.pub_lateral.publish(self._stiffness_lateral_msg(est, t_ns))

    def _stiffness_msg(self, est: StiffnessEstimate, t_ns: int) -> TireStiffness:
        msg = TireStiffness()
        conv.ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = "base_link"
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

    def _stiffness_lateral_msg(self, est: StiffnessEstimate, t_ns: int) -> LateralState:
        """The stiffness MPF's CG state moved to base_link: vy_b = vy_cg - lr r (REP-103)."""
        lr = self.vehicle.lr_m
        msg = LateralState()
        conv.ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = "base_link"
        msg.source = "stiffness_mpf"
        vy_b = est.vy_m_s - lr * est.yaw_rate_rad_s
        msg.longitudinal_velocity_m_s = float(est.vx_m_s)
        msg.lateral_velocity_m_s = float(vy_b)
        msg.yaw_rate_rad_s = float(est.yaw_rate_rad_s)
        msg.sideslip_rad = float(math.atan2(vy_b, max(est.vx_m_s, 1e-3)))
        # covariance of J [vx, vy_cg, r] with J = [[1, 0, 0], [0, 1, -lr], [0, 0, 1]]
        jac = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -lr], [0.0, 0.0, 1.0]])
        cov = jac @ np.asarray(est.covariance, dtype=float) @ jac.T
        msg.covariance = [float(v) for v in cov.ravel()]
        msg.axle_lateral_force_n = [0.0, 0.0]
        msg.linearity = LateralState.LINEARITY_UNKNOWN
        return msg

    def _publish_lateral(self, est: Any, t_ns: int) -> None:
        if t_ns - self._last_lateral_pub_ns < self._lateral_period_ns:
            return
        self._last_lateral_pub_ns = t_ns
        msg = LateralState()
        conv.ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = "base_link"
        msg.source = str(est.source)
        msg.longitudinal_velocity_m_s = float(est.vx_m_s)
        msg.lateral_velocity_m_s = float(est.vy_m_s)
        msg.yaw_rate_rad_s = float(est.yaw_rate_rad_s)
        msg.sideslip_rad = float(est.sideslip_rad)
        msg.covariance = [float(v) for v in np.asarray(est.covariance, dtype=float).ravel()]
        msg.axle_lateral_force_n = [float(v) for v in est.axle_lateral_force_n]
        msg.linearity = _LINEARITY.get(est.linearity, LateralState.LINEARITY_UNKNOWN)
        self.pub_lateral.publish(msg)

    # --- outputs ----------------------------------------------------------------------------
    def _publish(self, t_ns: int) -> None:
        """Publish odometry and radii when their periods (in header time) have elapsed."""
        odom_due = t_ns - self._last_odom_pub_ns >= self._odom_period_ns
        radii_due = t_ns - self._last_radii_pub_ns >= self._radii_period_ns
        if not (odom_due or radii_due):
            return
        est = self.estimator.estimate()
        if odom_due:
            self._last_odom_pub_ns = t_ns
            if est.state != "initializing":
                self.pub_odom.publish(self._odometry(est, t_ns))
        if radii_due:
            self._last_radii_pub_ns = t_ns
            self.pub_radii.publish(self._radii(est, t_ns))

    def _odometry(self, est: Any, t_ns: int) -> Odometry:
        msg = Odometry()
        conv.ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = "map"
        msg.child_frame_id = "base_link"
        east, north, yaw = (float(v) for v in est.pose)
        msg.pose.pose.position.x = east
        msg.pose.pose.position.y = north
        qx, qy, qz, qw = _yaw_to_quaternion(yaw)
        msg.pose.pose.orientation.x = qx
        msg.pose.pose.orientation.y = qy
        msg.pose.pose.orientation.z = qz
        msg.pose.pose.orientation.w = qw
        cov = np.zeros((6, 6))
        # REP-103 6x6 order (x, y, z, roll, pitch, yaw); z/roll/pitch are not estimated (planar)
        cov[np.ix_(_PLANAR, _PLANAR)] = est.pose_cov
        cov[2, 2] = cov[3, 3] = cov[4, 4] = 1e6
        msg.pose.covariance = cov.reshape(36)
        msg.twist.twist.linear.x = float(est.speed_m_s)
        msg.twist.twist.angular.z = float(est.yaw_rate_rad_s)
        msg.twist.covariance = _TWIST_COV
        return msg

    def _radii(self, est: Any, t_ns: int) -> TireRadii:
        msg = TireRadii()
        conv.ns_to_stamp(t_ns, msg.header.stamp)
        msg.header.frame_id = "base_link"
        msg.nominal_radius_m = float(self.vehicle.nominal_tire_radius_m)
        msg.wheel_names = list(est.wheels)
        msg.radius_error_m = [float(v) for v in est.radius_error_m]
        msg.radius_error_std_m = [float(v) for v in est.radius_error_std_m]
        msg.radius_noise_std_m = [float(v) for v in est.radius_noise_std_m]
        msg.active = [bool(v) for v in est.active]
        msg.effective_sample_size = float(est.n_eff)
        msg.state = _STATE.get(est.state, TireRadii.STATE_INITIALIZING)
        msg.state_reason = str(est.state_reason)
        return msg

    def _publish_diag(self) -> None:
        now = time.monotonic()
        span = max(now - self._rate_t0, 1e-3)
        self._input_rates_hz = {k: v / span for k, v in self._rate_window.items()}
        self._rate_window.clear()
        self._rate_t0 = now
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = self.diagnostic_statuses()
        self.pub_diag.publish(arr)

    def diagnostic_statuses(self) -> list[DiagnosticStatus]:
        """One status for the estimator and one per wheel it covers."""
        est = self.estimator.estimate()
        core_dropped = dict(getattr(self.estimator, "stats", {}) or {})
        statuses: list[DiagnosticStatus] = []
        main = DiagnosticStatus()
        main.name = "tire_estimation: radius estimator"
        main.hardware_id = self.vehicle.name
        if est.state == "running":
            main.level, main.message = DiagnosticStatus.OK, "running"
        elif est.state == "paused":
            main.level, main.message = DiagnosticStatus.WARN, f"paused: {est.state_reason}"
        else:
            main.level, main.message = DiagnosticStatus.WARN, f"initializing: {est.state_reason}"
        values = {
            "state": est.state,
            "reason": est.state_reason,
            "effective_sample_size": f"{float(est.n_eff):.1f}",
            "resample_count": str(int(est.resample_count)),
            "particles": str(self.config.n_particles),
            "persistence": self._persist_note,
        }
        if self.config.gnss_velocity_enabled:
            # velocities received minus these: dropped, gated, or while paused / initializing
            values["gnss_velocity.updates"] = str(int(self.estimator.velocity_updates))
            values["gnss_velocity.skipped_accelerating"] = str(
                int(self.estimator.velocity_skipped_accel)
            )
        for stream in INPUT_STREAMS:
            values[f"rate_hz.{stream}"] = f"{self._input_rates_hz.get(stream, 0.0):.1f}"
            values[f"received.{stream}"] = str(self.received.get(stream, 0))
        for key, count in sorted(self.dropped.items()):
            values[f"dropped.{key}"] = str(count)
        for key, count in sorted(core_dropped.items()):
            values[f"dropped.core.{key}"] = str(count)
        if any(self.dropped.values()) and main.level == DiagnosticStatus.OK:
            main.message = f"running; {sum(self.dropped.values())} input samples dropped"
        main.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        statuses.append(main)
        for i, wheel in enumerate(est.wheels):
            st = DiagnosticStatus()
            st.name = f"tire_estimation: {wheel}"
            st.hardware_id = self.vehicle.name
            active = bool(est.active[i])
            st.level = DiagnosticStatus.OK
            st.message = "learning" if active else "holding"
            st.values = [
                KeyValue(key="radius_error_mm", value=f"{1e3 * float(est.radius_error_m[i]):.3f}"),
                KeyValue(
                    key="radius_error_std_mm",
                    value=f"{1e3 * float(est.radius_error_std_m[i]):.3f}",
                ),
                KeyValue(
                    key="radius_noise_std_mm",
                    value=f"{1e3 * float(est.radius_noise_std_m[i]):.4f}",
                ),
                KeyValue(key="active", value=str(active).lower()),
            ]
            statuses.append(st)
        if self.stiffness is not None:
            statuses.append(self._stiffness_status())
        if self.lateral is not None:
            statuses.append(self._tyre_force_status())
        return statuses

    def _tyre_force_status(self) -> DiagnosticStatus:
        """Status of the tyre-force lateral KF: waiting for forces, or running with its relay."""
        lateral = self.lateral
        assert lateral is not None
        st = DiagnosticStatus()
        st.name = "tire_estimation: tyre-force lateral KF"
        st.hardware_id = self.vehicle.name
        est = lateral.estimate()
        received = self.received.get("tire_forces", 0)
        if received == 0:
            st.level, st.message = DiagnosticStatus.OK, "idle: no tyre forces received"
        elif est.linearity == "unknown":
            st.level, st.message = DiagnosticStatus.WARN, "initializing"
        else:
            st.level, st.message = DiagnosticStatus.OK, f"running ({est.linearity})"
        values = {
            "linearity": str(est.linearity),
            "received.tire_forces": str(received),
            "lateral_velocity_m_s": f"{float(est.vy_m_s):.3f}",
            "yaw_rate_rad_s": f"{float(est.yaw_rate_rad_s):.4f}",
            "virtual_sensor_method": lateral.config.virtual_sensor_method,
        }
        for key, count in sorted(lateral.stats.items()):
            values[f"dropped.core.{key}"] = str(count)
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        return st

    def _stiffness_status(self) -> DiagnosticStatus:
        """Status of the stiffness MPF: learning or holding and why, N_eff, estimates, drops."""
        stiffness = self.stiffness
        assert stiffness is not None
        st = DiagnosticStatus()
        st.name = "tire_estimation: stiffness estimator"
        st.hardware_id = self.vehicle.name
        est = stiffness.estimate()
        if not stiffness.mpf.initialized:
            st.level, st.message = DiagnosticStatus.WARN, f"initializing: {est.reason}"
        else:
            st.level = DiagnosticStatus.OK
            st.message = "learning" if est.active else f"holding: {est.reason}"
        values = {
            "active": str(bool(est.active)).lower(),
            "reason": est.reason,
            "effective_sample_size": f"{float(est.n_eff):.1f}",
            "resample_count": str(int(stiffness.mpf.resample_count)),
            "activation_replays": str(stiffness.replay_count),
            "activation_restarts": str(stiffness.restart_count),
            "grid_handovers": str(stiffness.handover_count),
            "grid_rejections": str(stiffness.grid_rejection_count),
            "particles": str(stiffness.config.n_particles),
            "gyro_bias_z_rad_s": f"{float(est.gyro_bias_rad_s[2]):.5f}",
            "received.velocity": str(self.received.get("velocity", 0)),
        }
        for name, c, s in zip(est.names, est.stiffness, est.stiffness_std, strict=True):
            values[name] = f"{float(c):.0f}"
            values[f"{name}_std"] = f"{float(s):.0f}"
        for key, count in sorted(stiffness.stats.items()):
            values[f"dropped.core.{key}"] = str(count)
        st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        return st


def main(args: list[str] | None = None) -> None:
    """Console script ``estimator_node`` (``ros2 run tire_estimation estimator_node``)."""
    spin_node("estimator_node", EstimatorNode, args)


if __name__ == "__main__":
    main()
