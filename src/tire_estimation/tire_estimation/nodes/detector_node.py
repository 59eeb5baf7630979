"""detector_node: thin rclpy adapter over the core ``DeflationMonitor`` (the same front-end of
the CUSUM detector that the estimation pipeline runs in a replay).

Subscribes ``/tire_estimation/tire_radii`` (TireRadii) and ``/tire_estimation/odometry``
(nav_msgs/Odometry: speed from ``twist.linear.x``; braking = deceleration between odometry
samples at least ``braking_window_s`` apart above ``braking_decel_m_s2``). Publishes
``/tire_estimation/deflation`` (DeflationStatus) for every accepted TireRadii and
``/diagnostics`` (one status per wheel plus one for the detector). Service ``~/recalibrate``
(std_srvs/Trigger) forgets the calibration and the latched alarms.

The calibration, CUSUM sums and latched alarms persist across restarts in ``persistence_file``,
keyed by vehicle name and ``tire_set_id``, only under an explicit vehicle identity
(``vehicle_file`` or a ``vehicle.name`` other than the default) and only when they changed.
Bad input never stops the node: it is dropped, counted by kind and shown on ``/diagnostics``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from std_srvs.srv import Trigger

from tire_estimation.core.clock import ClockGuard
from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.monitor import DeflationMonitor
from tire_estimation.core.deflation.status import DeflationStatusData, RadiusErrors
from tire_estimation.core.vehicle import load_vehicle_yaml
from tire_estimation.errors import InputError
from tire_estimation.node_config import DetectorNodeOptions
from tire_estimation.nodes import conversions as conv
from tire_estimation.nodes.common import (
    NodeState,
    declare_specs,
    explicit_identity,
    reject_undeclared_overrides,
    spin_node,
)
from tire_estimation.nodes.detector_diagnostics import wheel_status
from tire_estimation.nodes.lifecycle import BAD_INPUT, ManagedNode
from tire_estimation.params import (
    ParameterSpec,
    build_config,
    detector_sections,
    parameter_specs,
)
from tire_estimation.persistence import Identity
from tire_estimation_msgs.msg import DeflationStatus, TireRadii, WheelDeflation

DETECTOR_PREFIX = "detector"


class DetectorNode(ManagedNode):
    """ROS wrapper: parameters -> DeflationDetectorConfig, TireRadii/Odometry -> detector. A
    lifecycle node: configure builds everything below, inputs are processed and outputs
    published only while active (``autostart``: both at start)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__("detector_node", **kwargs)
        self._declare_parameters()
        self.start()

    def _configure(self) -> None:
        for prefix, cls, _ in detector_sections()[:2]:  # node options and vehicle identity
            build_config(cls, prefix, self._values(parameter_specs(cls, prefix)))
        self.config = build_config(
            DeflationDetectorConfig, DETECTOR_PREFIX, self._values(self._specs)
        )
        options = build_config(DetectorNodeOptions, "", self._values(self._node_specs))
        vehicle_name, nominal_radius_m = self._vehicle()
        # the nominal radius (with a vehicle file) bounds the radius errors of a restored state
        self.monitor = DeflationMonitor(self.config, options, nominal_radius_m)
        self.detector = self.monitor.detector
        self.received: Counter[str] = Counter()
        self.dropped: Counter[str] = Counter()
        self.events = self.monitor.events
        # stamps that jump: a far one is held, a run of agreeing ones makes a new clock; the
        # detector runs on the guard's continuous time, published stamps on the topics' clock
        self._stamps: ClockGuard[Callable[[int], None]] = ClockGuard()
        self._last_radii_ns: int | None = None  # guard time of the last TireRadii
        self._last_radii_clock_ns = 0  # node clock when it arrived
        self._last_status: DeflationStatusData | None = None

        self._identity = Identity(vehicle_name, self.get_parameter("tire_set_id").value)
        self.state_file = NodeState(
            self,
            self.get_parameter("persistence_file").value,
            self._identity,
            explicit_identity(self.get_parameter("vehicle_file").value, vehicle_name),
            self.detector,
            "detector state",
        )

        # the guarded callbacks (public: tests feed long sequences without DDS)
        self.on_tire_radii = self._guard("tire_radii", self._on_radii)
        self.on_odometry = self._guard("odometry", self._on_odometry)
        self.create_subscription(TireRadii, "tire_estimation/tire_radii", self.on_tire_radii, 50)
        self.create_subscription(Odometry, "tire_estimation/odometry", self.on_odometry, 50)
        self.pub_status = self.create_lifecycle_publisher(
            DeflationStatus, "tire_estimation/deflation", 10
        )
        self.pub_diag = self.create_lifecycle_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_service(Trigger, "~/recalibrate", self._on_recalibrate)
        self.create_timer(self.get_parameter("diagnostics_period_s").value, self.publish_diag)
        period = self.get_parameter("persistence_period_s").value
        if self.state_file.path is not None and period > 0:
            self.create_timer(period, self._save)
        self.get_logger().info(
            f"detector_node up: vehicle {self._identity.vehicle_name!r}, tire set "
            f"{self._identity.tire_set_id!r}, calibration {self.detector.calibration_state.name}; "
            f"{self.state_file.note}"
        )

    # --- parameters -------------------------------------------------------------------------
    def _declare_parameters(self) -> None:
        sections = detector_sections()
        for prefix, cls, _ in sections[:2]:
            specs = parameter_specs(cls, prefix)
            declare_specs(self, specs)
        self._node_specs = parameter_specs(sections[0][1], sections[0][0])
        self._specs = parameter_specs(DeflationDetectorConfig, DETECTOR_PREFIX)
        declare_specs(self, self._specs)
        reject_undeclared_overrides(self)

    def _values(self, specs: Sequence[ParameterSpec]) -> dict[str, Any]:
        return {
            s.name: self.get_parameter(s.name).value for s in specs if self.has_parameter(s.name)
        }

    def _vehicle(self) -> tuple[str, float | None]:
        """The vehicle's name and, from a vehicle file, its nominal tyre radius (m)."""
        path = self.get_parameter("vehicle_file").value
        if path:
            vehicle = load_vehicle_yaml(Path(path).expanduser())
            return vehicle.name, vehicle.nominal_tire_radius_m
        return str(self.get_parameter("vehicle.name").value), None

    # --- persistence ------------------------------------------------------------------------
    def _save(self) -> None:
        """Write the state when it changed since it was restored or saved."""
        if not self.state_file.save():
            self.dropped["persistence_write"] += 1

    def save_on_shutdown(self) -> None:
        """Write the calibration and alarms (when the node deactivates, cleans up or stops);
        log why nothing is written."""
        if not self.state_file.save_on_shutdown():
            self.dropped["persistence_write"] += 1

    def _on_recalibrate(self, _: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.detector.recalibrate()
        self._save()
        self._last_status = self.detector.status()
        if self._last_radii_ns is not None:
            self.pub_status.publish(self._status_msg(self._last_status))
        response.success = True
        response.message = "deflation detector recalibration started; alarms cleared"
        self.get_logger().info(response.message)
        return response

    # --- inputs -----------------------------------------------------------------------------
    def _guard(self, stream: str, handler: Callable[[Any], None]) -> Callable[[Any], None]:
        """Wrap a callback: count the message, drop and count bad input, never raise."""

        def callback(msg: Any) -> None:
            if not self.accept(stream):
                return
            try:
                handler(msg)
            except BAD_INPUT as exc:
                self.drop(stream, exc)

        return callback

    def _admit(self, stream: str, t_ns: int, apply: Callable[[int], None]) -> None:
        """Through the clock guard: apply what it releases, each at its guard time."""
        for u_ns, apply_at in self._stamps.admit(stream, t_ns, apply):
            try:
                apply_at(u_ns)
            except InputError as exc:
                self.dropped[f"{stream}:{exc.kind}"] += 1
        if self._stamps.dropped[stream]:
            self.dropped[f"{stream}:clock_jump"] = self._stamps.dropped[stream]

    def _on_odometry(self, msg: Odometry) -> None:
        speed_m_s = float(msg.twist.twist.linear.x)
        self._admit(
            "odometry",
            conv.stamp_ns(msg.header),
            lambda t_ns: self.monitor.on_odometry(t_ns, speed_m_s),
        )

    def _on_radii(self, msg: TireRadii) -> None:
        names = list(msg.wheel_names)
        errors_m = list(msg.radius_error_m)
        stds_m = list(msg.radius_error_std_m)
        active = list(msg.active)
        self._admit(
            "tire_radii",
            conv.stamp_ns(msg.header),
            lambda t_ns: self._radii_at(RadiusErrors(t_ns, names, errors_m, stds_m, active)),
        )

    def _radii_at(self, radii: RadiusErrors) -> None:
        t_ns = radii.t_ns
        step = self.monitor.on_radii(radii)
        if step is None:
            return
        status = step.status
        self._last_radii_ns = t_ns
        self._last_radii_clock_ns = self.get_clock().now().nanoseconds
        self._last_status = status
        self.pub_status.publish(self._status_msg(status))
        for wheel in step.new_alarms:
            change = status.wheel(wheel).radius_change_m
            self.get_logger().error(
                f"tyre deflation alarm on {wheel}: radius {1e3 * change:.2f} mm smaller than "
                "calibrated"
            )
        common = status.common
        if step.new_common_alarm and common is not None:
            self.get_logger().error(
                "tyre deflation alarm, tyre not identified (common channel): mean radius of "
                f"{', '.join(common.wheel_names)} {1e3 * common.radius_change_m:.2f} mm smaller "
                "than calibrated"
            )
        if step.new_alarms or step.new_common_alarm or step.calibration_changed:
            self._save()

    # --- outputs ----------------------------------------------------------------------------
    def _status_msg(self, status: DeflationStatusData) -> DeflationStatus:
        msg = DeflationStatus()
        # the detector's time is the guard's; the message carries the topics' clock
        offset_ns = self._stamps.offset_ns("tire_radii")
        if status.t_ns is not None:
            conv.ns_to_stamp(status.t_ns - offset_ns, msg.header.stamp)
        msg.header.frame_id = "base_link"
        msg.calibration_state = int(status.calibration_state)
        msg.calibration_progress = float(status.calibration_progress)
        msg.calibrated_driving_time_s = float(status.calibrated_driving_time_s)
        msg.any_alarm = bool(status.any_alarm)
        for w in status.wheels:
            entry = WheelDeflation()
            entry.wheel_name = w.wheel_name
            entry.level = int(w.level)
            entry.radius_change_m = float(w.radius_change_m)
            entry.cusum = float(w.cusum_m)
            entry.threshold = float(w.threshold_m)
            entry.alarm = bool(w.alarm)
            entry.alarm_time_s = 0.0 if w.alarm_t_ns is None else (w.alarm_t_ns - offset_ns) * 1e-9
            msg.wheels.append(entry)
        return msg

    def _now_stamp_ns(self) -> int | None:
        """The present on the clock of the radius stamps: last stamp + time since its arrival."""
        if self._last_radii_ns is None:
            return None
        elapsed = self.get_clock().now().nanoseconds - self._last_radii_clock_ns
        return self._last_radii_ns + max(0, elapsed)

    def publish_diag(self) -> None:
        """Publish /diagnostics (timer callback; public so tests can trigger it)."""
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status = self.diagnostic_statuses()
        self.pub_diag.publish(arr)

    def diagnostic_statuses(self) -> list[DiagnosticStatus]:
        """One status for the detector and one per wheel it monitors."""
        now = self._now_stamp_ns()
        status = self.detector.check_stale(now) if now is not None else self.detector.status()
        hw = self._identity.vehicle_name
        main = DiagnosticStatus(name="tire_estimation: deflation detector", hardware_id=hw)
        calib = status.calibration_state.name.lower()
        if self._last_radii_ns is None:
            main.level, main.message = DiagnosticStatus.WARN, "waiting for tire radii"
        elif now is not None and now - self._last_radii_ns > self.config.stale_timeout_s * 1e9:
            main.level, main.message = DiagnosticStatus.STALE, "tire radii stopped arriving"
        else:
            main.level = DiagnosticStatus.OK
            main.message = f"calibration {calib} ({100 * status.calibration_progress:.0f} %)"
        alarmed = [w.wheel_name for w in status.wheels if w.alarm]
        if alarmed:
            main.message += f"; deflation alarm on {', '.join(alarmed)}"
        if status.common is not None and status.common.alarm:
            main.message += "; deflation alarm, tyre not identified (common channel)"
        dropped = dict(self.dropped)
        for kind, count in self.detector.dropped.items():
            dropped[f"tire_radii:{kind}"] = dropped.get(f"tire_radii:{kind}", 0) + count
        if dropped:
            main.message += f"; {sum(dropped.values())} input messages dropped"
        values = {
            "calibration_state": calib,
            "calibration_progress": f"{status.calibration_progress:.3f}",
            "calibrated_driving_time_s": f"{status.calibrated_driving_time_s:.1f}",
            "calibration_required_s": f"{self.config.calibration_time_s:.1f}",
            "speed_m_s": "unknown"
            if self.monitor.speed_m_s is None
            else f"{self.monitor.speed_m_s:.2f}",
            "braking": str(self.monitor.braking).lower(),
            "tire_set_id": self._identity.tire_set_id,
            "persistence": self.state_file.note,
        }
        if status.common is not None:
            values["common.radius_change_m"] = f"{status.common.radius_change_m:.6f}"
            values["common.cusum"] = f"{status.common.cusum_m:.6f}"
            values["common.threshold"] = f"{status.common.threshold_m:.6f}"
            values["common.alarm"] = str(status.common.alarm).lower()
        for stream in ("tire_radii", "odometry"):
            values[f"received.{stream}"] = str(self.received.get(stream, 0))
        for key, count in sorted(self.events.items()):
            values[f"events.{key}"] = str(count)
        for key, count in sorted(dropped.items()):
            values[f"dropped.{key}"] = str(count)
        main.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        statuses = [main]
        statuses.extend(wheel_status(w, now, hw) for w in status.wheels)
        return statuses


def main(args: list[str] | None = None) -> None:
    """Console script ``detector_node`` (``ros2 run tire_estimation detector_node``)."""
    spin_node("detector_node", DetectorNode, args)


if __name__ == "__main__":
    main()
