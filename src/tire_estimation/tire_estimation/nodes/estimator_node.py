"""estimator_node: parameters, message conversions and publishing around the core pipeline.

Subscribes (contract v1) ``/vehicle/wheel_speeds``, ``/vehicle/steering``, ``/imu/data``,
``/gnss/fix``, ``/gnss/velocity`` (with ``radius.gnss_velocity_enabled``), and, with their
estimators on, ``/vehicle/tire_forces`` and ``/vehicle/velocity`` (project-defined: measured vx
for vehicles without wheel speeds). Every message becomes a typed sample
(:mod:`tire_estimation.nodes.conversions`) pushed into the
:class:`~tire_estimation.core.pipeline.EstimationPipeline` that the bag replay and the campaigns
drive too; what the pipeline outputs is published on ``/tire_estimation/odometry``,
``/tire_estimation/tire_radii``, ``/tire_estimation/tire_stiffness`` and
``/tire_estimation/lateral_state``, with ``/diagnostics``. With every radii message go the
outputs for the rest of a ROS stack (``WheelOdometryOutput``,
:mod:`tire_estimation.core.radius.wheel_odometry`):
``/tire_estimation/twist`` (wheel odometry corrected with the learned radii, with its
covariance), ``/tire_estimation/wheel_radii`` (effective radius and multiplier per wheel) and
``/tire_estimation/speed_scale_factor``. Service ``~/reset`` (std_srvs/Trigger) forgets the
learned radii and stiffness.

The learned state persists only under an explicit vehicle identity (``vehicle_file`` or a
``vehicle.name`` other than the default): without one the node neither restores nor saves, and
it never saves a state it has not changed since it started, restored or was reset.

Bad input never stops the node: the message is dropped, counted as ``<stream>:<kind>`` and
shown on ``/diagnostics``.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import Imu, JointState, NavSatFix
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from tire_estimation.core.clock import ClockGuardConfig
from tire_estimation.core.clock_check import LeadingClockCheck
from tire_estimation.core.lateral.tyre_force_kf import TyreForceKFConfig
from tire_estimation.core.pipeline import (
    EstimationPipeline,
    LateralOutput,
    OdometryOutput,
    Output,
    PipelineConfig,
    RadiiOutput,
    StiffnessOutput,
    WheelOdometryOutput,
)
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.samples import Sample
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams, load_vehicle_yaml
from tire_estimation.node_config import EstimatorNodeOptions, periods_of
from tire_estimation.nodes import conversions as conv
from tire_estimation.nodes import estimator_diagnostics, messages
from tire_estimation.nodes.common import (
    NodeState,
    declare_specs,
    explicit_identity,
    parameter_values,
    reject_undeclared_overrides,
    spin_node,
)
from tire_estimation.nodes.lifecycle import BAD_INPUT, ManagedNode
from tire_estimation.params import ParameterSpec, build_config, estimator_sections, parameter_specs
from tire_estimation.persistence import Identity, LearnedState
from tire_estimation_msgs.msg import LateralState, TireForces, TireRadii, TireStiffness

SECTIONS = estimator_sections()


class EstimatorNode(ManagedNode):
    """ROS wrapper: parameters -> pipeline configuration, messages -> samples, outputs ->
    messages. A lifecycle node: configure builds everything below, inputs are processed and
    outputs published only while active (``autostart``: both at start)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("estimator_node", **kwargs)
        self._specs = {prefix: parameter_specs(cls, prefix) for prefix, cls, _ in SECTIONS}
        for specs in self._specs.values():
            declare_specs(self, specs)
        reject_undeclared_overrides(self)
        self.start()

    def _configure(self) -> None:
        self.options = build_config(EstimatorNodeOptions, "", self._values(""))
        self.vehicle = self._load_vehicle()
        self.config = build_config(RadiusEstimatorConfig, "radius", self._values("radius"))
        opts = self.options
        self.pipeline = EstimationPipeline(
            PipelineConfig(
                seed=self.config.seed,
                radius=self.config,
                stiffness=build_config(
                    StiffnessEstimatorConfig, "stiffness", self._values("stiffness")
                )
                if opts.stiffness_enabled
                else None,
                tyre_force=build_config(
                    TyreForceKFConfig, "tyre_force", self._values("tyre_force")
                )
                if opts.tyre_force_enabled
                else None,
                periods=periods_of(opts),
                reorder_delay_s=opts.reorder_delay_s,
                clock=ClockGuardConfig(max_jump_s=opts.max_clock_jump_s),
            ),
            self.vehicle,
        )
        # the GNSS stamps against the wheel speeds' clock over the first minutes
        self.clock_check = LeadingClockCheck(self.vehicle.nominal_tire_radius_m)
        self.pipeline.add_observers(self.clock_check)
        self.estimator = self.pipeline.radius
        self.stiffness = self.pipeline.stiffness
        self.lateral = self.pipeline.tyre_force
        self.dropped: Counter[str] = Counter()
        self.received: Counter[str] = Counter()
        self._rate_window: Counter[str] = Counter()
        self._rate_t0 = time.monotonic()
        self._input_rates_hz: dict[str, float] = {}
        self._identity = Identity(self.vehicle.name, opts.tire_set_id)
        # one file for the learned radii and (when the stiffness MPF runs) the learned
        # stiffness; each part is restored or rejected on its own
        self._learned = LearnedState({"radius": self.estimator, "stiffness": self.stiffness})
        self.state_file = NodeState(
            self,
            opts.persistence_file,
            self._identity,
            explicit_identity(opts.vehicle_file, self.vehicle.name),
            self._learned,
            "estimates",
        )

        qos = (
            qos_profile_sensor_data if opts.sensor_qos == "sensor_data" else QoSProfile(depth=100)
        )
        # the robot's own joint and frame names (parameter name_remaps)
        names = self.names = opts.names
        subs: list[tuple[type, str, str, Callable[[Any], Sample]]] = [
            (
                JointState,
                "vehicle/wheel_speeds",
                "wheel_speeds",
                partial(conv.wheel_speeds_from_msg, joints=names),
            ),
            (
                JointState,
                "vehicle/steering",
                "steering",
                partial(conv.steering_from_msg, joints=names),
            ),
            (Imu, "imu/data", "imu", conv.imu_from_msg),
            (NavSatFix, "gnss/fix", "gnss_fix", conv.gnss_from_msg),
        ]
        if self.config.gnss_velocity_enabled:
            subs.append(
                (TwistWithCovarianceStamped, "gnss/velocity", "gnss_velocity",
                 conv.gnss_velocity_from_msg)
            )  # fmt: skip
        if self.stiffness is not None:
            subs.append(
                (TwistWithCovarianceStamped, "vehicle/velocity", "velocity",
                 conv.velocity_from_msg)
            )  # fmt: skip
        if self.lateral is not None:
            subs.append(
                (
                    TireForces,
                    "vehicle/tire_forces",
                    "tire_forces",
                    partial(conv.tire_forces_from_msg, joints=names),
                )
            )
        for msg_type, topic, stream, convert in subs:
            self.create_subscription(msg_type, topic, self._callback(stream, convert), qos)
        self.pub_lateral = self.create_lifecycle_publisher(
            LateralState, "tire_estimation/lateral_state", 10
        )
        self.pub_stiffness = self.create_lifecycle_publisher(
            TireStiffness, "tire_estimation/tire_stiffness", 10
        )
        self.pub_odom = self.create_lifecycle_publisher(Odometry, "tire_estimation/odometry", 10)
        self.pub_radii = self.create_lifecycle_publisher(
            TireRadii, "tire_estimation/tire_radii", 10
        )
        self.pub_twist = self.create_lifecycle_publisher(
            TwistWithCovarianceStamped, "tire_estimation/twist", 10
        )
        self.pub_wheel_radii = self.create_lifecycle_publisher(
            JointState, "tire_estimation/wheel_radii", 10
        )
        self.pub_speed_scale = self.create_lifecycle_publisher(
            Float64, "tire_estimation/speed_scale_factor", 10
        )
        # the ENU origin of the pose (the first fix), latched for late subscribers
        self.pub_datum = self.create_lifecycle_publisher(
            NavSatFix,
            "tire_estimation/datum",
            QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL),
        )
        self._datum: Any = None
        self.pub_diag = self.create_lifecycle_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_timer(opts.diagnostics_period_s, self._publish_diag)
        if self.state_file.path is not None and opts.persistence_period_s > 0:
            self.create_timer(opts.persistence_period_s, self._save)
        self.get_logger().info(
            f"estimator_node up: vehicle {self.vehicle.name!r}, {self.config.n_particles} "
            f"particles, wheels {self.config.wheels}; {self.state_file.note}"
        )

    # --- parameters -------------------------------------------------------------------------
    def _values(self, prefix: str) -> dict[str, Any]:
        specs: Sequence[ParameterSpec] = self._specs[prefix]
        return parameter_values(self, specs)

    def _load_vehicle(self) -> VehicleParams:
        if self.options.vehicle_file:
            return load_vehicle_yaml(Path(self.options.vehicle_file).expanduser())
        return build_config(VehicleParams, "vehicle", self._values("vehicle"))

    # --- persistence ------------------------------------------------------------------------
    def _save(self) -> None:
        """Write the learned state when it changed since it was restored, saved or reset."""
        if not self.state_file.save():
            self.dropped["persistence_write"] += 1

    def _on_reset(self, _: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.pipeline.reset()
        self.state_file.reset()
        response.success = True
        response.message = "learned tire radii and stiffness reset to the prior"
        self.get_logger().info(response.message)
        return response

    def save_on_shutdown(self) -> None:
        """Write the learned radii and stiffness (when the node deactivates, cleans up or
        stops); log why nothing is written."""
        if not self.state_file.save_on_shutdown():
            self.dropped["persistence_write"] += 1

    # --- inputs -----------------------------------------------------------------------------
    def _callback(self, stream: str, convert: Callable[[Any], Sample]) -> Callable[[Any], None]:
        """Count the message, convert it, push it; drop and count bad input, never raise."""

        def callback(msg: Any) -> None:
            if not self.accept(stream):
                return
            self._rate_window[stream] += 1
            try:
                sample = convert(msg)
                outputs = self.pipeline.push(sample)
            except BAD_INPUT as exc:
                self.drop(stream, exc)
                return
            self._publish(outputs)
            datum = self.estimator.datum if self.estimator is not None else None
            if datum is not None and datum is not self._datum:
                self._datum = datum
                self.pub_datum.publish(messages.datum_msg(datum, sample.t_ns, self.names))

        return callback

    # --- outputs ----------------------------------------------------------------------------
    def _publish(self, outputs: list[Output]) -> None:
        names = self.names
        for out in outputs:
            if type(out) is OdometryOutput:
                self.pub_odom.publish(messages.odometry_msg(out.estimate, out.t_ns, names))
            elif type(out) is RadiiOutput:
                nominal = self.vehicle.nominal_tire_radius_m
                self.pub_radii.publish(messages.radii_msg(out.estimate, out.t_ns, nominal, names))
            elif type(out) is WheelOdometryOutput:
                self.pub_twist.publish(messages.twist_msg(out.twist, names))
                self.pub_wheel_radii.publish(messages.wheel_radii_msg(out.radii, out.t_ns, names))
                self.pub_speed_scale.publish(messages.speed_scale_msg(out.radii))
            elif type(out) is StiffnessOutput:
                self.pub_stiffness.publish(messages.stiffness_msg(out.estimate, out.t_ns, names))
            elif type(out) is LateralOutput:
                self.pub_lateral.publish(messages.lateral_msg(out.estimate, out.t_ns, names))

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

    def diagnostic_statuses(self) -> list[Any]:
        """One status per estimator and one per wheel the radius estimator covers."""
        return estimator_diagnostics.statuses(
            self.pipeline,
            self.vehicle.name,
            self.received,
            self.dropped,
            self._input_rates_hz,
            self.state_file.note,
            self.clock_check.result,
        )


def main(args: list[str] | None = None) -> None:
    """Console script ``estimator_node`` (``ros2 run tire_estimation estimator_node``)."""
    spin_node("estimator_node", EstimatorNode, args)


if __name__ == "__main__":
    main()
