"""detector_node: calibration, alarm on the deflated wheel, latching, recalibration, bad input.

Long sequences go straight into the node's guarded callbacks; the outputs, a malformed message
and the ``~/recalibrate`` service go over DDS.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros

S = 1_000_000_000
T0 = 1_000 * S
REAR = ["wheel_rl", "wheel_rr"]
MU_CAL = [0.3e-3, -0.2e-3]


def _params(parameter_cls: Any, tmp_path: Path, **extra: Any) -> list[Any]:
    values: dict[str, Any] = {
        "persistence_file": str(tmp_path / "deflation.json"),
        "vehicle.name": "test_car",
        "tire_set_id": "summer",
        "diagnostics_period_s": 0.2,
        "detector.calibration_time_s": 20.0,
        "detector.calibration_average_s": 5.0,
        "detector.lowpass_time_constant_s": 1.0,
        "detector.rate_limit_m_s": 0.0,
        "detector.reference_sample_period_s": 1.0,
        "detector.adaptive_threshold": False,
    }
    values.update(extra)
    return [parameter_cls(k, value=v) for k, v in values.items()]


class Feeder:
    """Builds stamped Odometry + TireRadii pairs at 10 Hz."""

    def __init__(self, msg_mod: Any, odom_cls: Any) -> None:
        self.msg_mod, self.odom_cls = msg_mod, odom_cls
        self.t_ns = T0

    def stamp(self, header: Any) -> None:
        header.stamp.sec, header.stamp.nanosec = divmod(self.t_ns, S)

    def odometry(self, speed: float = 20.0) -> Any:
        msg = self.odom_cls()
        self.stamp(msg.header)
        msg.twist.twist.linear.x = speed
        return msg

    def radii(self, mu: list[float], names: list[str] | None = None) -> Any:
        msg = self.msg_mod.TireRadii()
        self.stamp(msg.header)
        msg.wheel_names = names if names is not None else list(REAR)
        msg.radius_error_m = list(mu)
        msg.radius_error_std_m = [2e-4] * len(mu)
        msg.radius_noise_std_m = [1e-5] * len(mu)
        msg.active = [True] * len(mu)
        msg.state = self.msg_mod.TireRadii.STATE_RUNNING
        return msg

    def drive(self, node: Any, seconds: float, mu: list[float], speed: float = 20.0) -> None:
        for _ in range(round(seconds * 10)):
            self.t_ns += S // 10
            node.on_odometry(self.odometry(speed))
            node.on_tire_radii(self.radii(mu))


def _spin_until(executor: Any, cond: Callable[[], bool], timeout_s: float = 8.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not cond() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    return cond()


def _diag_values(status: Any) -> dict[str, str]:
    return {kv.key: kv.value for kv in status.values}


def _by_name(statuses: list[Any]) -> dict[str, Any]:
    return {s.name: s for s in statuses}


def test_detector_node_alarm_latch_recalibrate_and_bad_input(tmp_path: Path) -> None:
    rclpy, msg_mod, executors, nav_msgs, diag_msgs, std_srvs, rclpy_parameter, node_mod = (
        import_ros(
            "rclpy",
            "tire_estimation_msgs.msg",
            "rclpy.executors",
            "nav_msgs.msg",
            "diagnostic_msgs.msg",
            "std_srvs.srv",
            "rclpy.parameter",
            "tire_estimation.nodes.detector_node",
        )
    )
    parameter_cls = rclpy_parameter.Parameter
    level_byte = diag_msgs.DiagnosticStatus
    wheel_diag = "tire_estimation: deflation wheel_rl"
    other_diag = "tire_estimation: deflation wheel_rr"
    main_diag = "tire_estimation: deflation detector"
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = node_mod.DetectorNode(
            context=context, parameter_overrides=_params(parameter_cls, tmp_path)
        )
        helper = rclpy.create_node("detector_test_helper", context=context)
        statuses: list[Any] = []
        diags: list[Any] = []
        helper.create_subscription(
            msg_mod.DeflationStatus, "/tire_estimation/deflation", statuses.append, 50
        )
        helper.create_subscription(diag_msgs.DiagnosticArray, "/diagnostics", diags.append, 50)
        pub_radii = helper.create_publisher(msg_mod.TireRadii, "/tire_estimation/tire_radii", 50)
        pub_odom = helper.create_publisher(nav_msgs.Odometry, "/tire_estimation/odometry", 50)
        client = helper.create_client(std_srvs.Trigger, "/detector_node/recalibrate")
        executor = executors.SingleThreadedExecutor(context=context)
        executor.add_node(node)
        executor.add_node(helper)
        feed = Feeder(msg_mod, nav_msgs.Odometry)

        # --- calibration: braking and slow driving do not count ----------------------------------
        feed.drive(node, 5.0, MU_CAL, speed=5.0)  # 18 km/h
        for _ in range(20):  # 2 s of hard braking inside the window (20 -> 14 m/s)
            feed.t_ns += S // 10
            node.on_odometry(feed.odometry(20.0 - 3.0 * (feed.t_ns - T0 - 5 * S) / S))
            node.on_tire_radii(feed.radii(MU_CAL))
        status = node.detector.status()
        assert status.calibrated_driving_time_s < 0.6  # only the braking-window lag
        feed.drive(node, 21.0, MU_CAL)
        assert node.detector.status().calibration_state == 2  # DONE
        rl = node.detector.status().wheel("wheel_rl")
        assert rl.calibrated_radius_error_m == pytest.approx(MU_CAL[0])

        # --- deflation of wheel_rl: 2 mm smaller -------------------------------------------------
        deflated = [MU_CAL[0] - 2e-3, MU_CAL[1]]
        levels = []
        for _ in range(100):
            feed.drive(node, 0.1, deflated)
            by_name = _by_name(node.diagnostic_statuses())
            levels.append(by_name[wheel_diag].level)
            assert by_name[other_diag].level == level_byte.OK
            if node.detector.status().any_alarm:
                break
        assert level_byte.WARN in levels, "no WARN before the alarm"
        assert levels[-1] == level_byte.ERROR
        st = node.detector.status()
        assert st.wheel("wheel_rl").alarm and not st.wheel("wheel_rr").alarm
        assert (tmp_path / "deflation.json").is_file()  # saved when the alarm latched

        # --- latch: tyre back at its calibrated radius, g decays, alarm stays --------------------
        feed.drive(node, 30.0, MU_CAL)
        rl = node.detector.status().wheel("wheel_rl")
        assert rl.cusum_m == 0.0 and rl.alarm

        # --- restart: the latched alarm is restored for the same vehicle and tyre set ------------
        again = node_mod.DetectorNode(
            context=context,
            namespace="restarted",
            parameter_overrides=_params(parameter_cls, tmp_path),
        )
        assert again.detector.status().wheel("wheel_rl").alarm
        again.destroy_node()
        other_set = node_mod.DetectorNode(
            context=context,
            namespace="other_set",
            parameter_overrides=_params(parameter_cls, tmp_path, tire_set_id="winter"),
        )
        assert other_set.detector.status().calibration_state == 0  # NOT_STARTED
        other_set.destroy_node()

        # --- over DDS: a good sample, then malformed ones ----------------------------------------
        feed.t_ns += S // 10
        pub_odom.publish(feed.odometry())
        _spin_until(executor, lambda: node.received["odometry"] > 0)
        pub_radii.publish(feed.radii(MU_CAL))
        good_stamp = feed.t_ns

        def stamped(t_ns: int) -> list[Any]:
            return [s for s in statuses if s.header.stamp.sec * S + s.header.stamp.nanosec == t_ns]

        assert _spin_until(executor, lambda: bool(stamped(good_stamp)))
        got = stamped(good_stamp)[0]
        assert got.any_alarm
        wheels = {w.wheel_name: w for w in got.wheels}
        assert (
            wheels["wheel_rl"].alarm and wheels["wheel_rl"].level == wheels["wheel_rl"].LEVEL_ALARM
        )
        assert not wheels["wheel_rr"].alarm and wheels["wheel_rr"].level == 0
        assert got.calibration_state == got.CALIBRATION_DONE
        assert wheels["wheel_rl"].threshold == pytest.approx(9e-3)
        assert wheels["wheel_rl"].alarm_time_s > T0 / S

        n_received = node.received["tire_radii"]
        feed.t_ns += S // 10
        bad_len = feed.radii(MU_CAL)
        bad_len.radius_error_std_m = [2e-4]  # mismatched array lengths
        pub_radii.publish(bad_len)
        bad_stamps = [feed.t_ns]
        feed.t_ns += S // 10
        pub_radii.publish(feed.radii([math.nan, MU_CAL[1]]))
        bad_stamps.append(feed.t_ns)
        assert _spin_until(executor, lambda: node.received["tire_radii"] == n_received + 2)

        def diag_shows_drops() -> bool:
            for arr in diags:
                main = _by_name(list(arr.status)).get(main_diag)
                if main is None:
                    continue
                v = _diag_values(main)
                if (
                    v.get("dropped.tire_radii:wrong_length") == "1"
                    and v.get("dropped.tire_radii:nan") == "1"
                ):
                    return True
            return False

        assert _spin_until(executor, diag_shows_drops), "drops not reported on /diagnostics"
        assert not any(stamped(t) for t in bad_stamps)  # nothing published for dropped input
        arr = diags[-1]
        by_name = _by_name(list(arr.status))
        assert by_name[wheel_diag].level == level_byte.ERROR
        wv = _diag_values(by_name[wheel_diag])
        assert wv["calibrated"] == "true" and wv["alarm"] == "true"
        assert float(wv["threshold_mm"]) == pytest.approx(9.0)
        assert float(wv["time_since_calibration_s"]) > 30.0
        assert {"radius_change_mm", "cusum_g_mm"} <= set(wv)

        # --- ~/recalibrate clears the alarm ------------------------------------------------------
        assert client.wait_for_service(timeout_sec=5.0)
        future = client.call_async(std_srvs.Trigger.Request())
        assert _spin_until(executor, future.done)
        assert future.result().success
        assert _spin_until(executor, lambda: statuses[-1].calibration_state == 0)
        assert not statuses[-1].any_alarm
        by_name = _by_name(node.diagnostic_statuses())
        assert by_name[wheel_diag].level == level_byte.OK
        assert _diag_values(by_name[wheel_diag])["calibrated"] == "false"

        # --- estimates stop: STALE ---------------------------------------------------------------
        node._last_radii_clock_ns -= 10 * S  # pretend the last estimate arrived 10 s ago
        by_name = _by_name(node.diagnostic_statuses())
        assert by_name[wheel_diag].level == level_byte.STALE
        assert by_name[main_diag].level == level_byte.STALE

        executor.shutdown()
        helper.destroy_node()
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_detector_node_reports_a_common_channel_alarm(tmp_path: Path) -> None:
    """An equal loss on both wheels: no wheel alarms (relative test), the common channel does;
    any_alarm, the main diagnostic status and the persisted state show it."""
    rclpy, msg_mod, nav_msgs, rclpy_parameter, node_mod = import_ros(
        "rclpy",
        "tire_estimation_msgs.msg",
        "nav_msgs.msg",
        "rclpy.parameter",
        "tire_estimation.nodes.detector_node",
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        params = _params(
            rclpy_parameter.Parameter,
            tmp_path,
            **{
                "detector.common_mode_fraction": 1.0,
                "detector.common_channel": True,
                "detector.common_drift_m": 0.4e-3,
                "detector.common_threshold_m": 5e-3,
                "detector.common_lowpass_time_constant_s": 0.0,
                "detector.common_calibration_average_s": 5.0,
            },
        )
        node = node_mod.DetectorNode(context=context, parameter_overrides=params)
        feed = Feeder(msg_mod, nav_msgs.Odometry)
        feed.drive(node, 21.0, MU_CAL)
        assert node.detector.status().calibration_state == 2  # DONE
        start_ns = feed.t_ns
        # both tyres 1.5 mm smaller: G grows by (1.5 - 0.4) mm x 0.1 s / 1 s = 0.11 mm per
        # sample, passes 5 mm on the 46th sample (4.6 s) and reaches 6.6 mm after 6 s
        feed.drive(node, 6.0, [MU_CAL[0] - 1.5e-3, MU_CAL[1] - 1.5e-3])
        st = node.detector.status()
        assert st.common is not None and st.common.alarm and st.any_alarm
        assert st.common.alarm_t_ns == start_ns + 46 * S // 10
        assert st.common.cusum_m == pytest.approx(6.6e-3, rel=1e-9)
        assert not any(w.alarm for w in st.wheels)
        diag = {s.name: s for s in node.diagnostic_statuses()}
        main = diag["tire_estimation: deflation detector"]
        assert "deflation alarm, tyre not identified" in main.message
        values = _diag_values(main)
        assert values["common.alarm"] == "true"
        assert float(values["common.threshold"]) == pytest.approx(5e-3)
        assert (tmp_path / "deflation.json").is_file()  # saved when the common alarm latched
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def _detector_file(calibrated_m: str, g_m: str) -> str:
    """A saved detector state whose rear-left wheel is calibrated at ``calibrated_m`` with the
    CUSUM sum ``g_m`` (JSON number texts)."""
    wheel = (
        '{"calib_time_s": 20.0, "calib_sum_w": 5.0, "calib_sum_wx": 0.0, '
        f'"calibrated_m": {calibrated_m}, "calibration_t_ns": {T0}, "common_sum_w": 0.0, '
        '"common_sum_wx": 0.0, "common_calibrated_m": null, "lp_m": 0.0, "xbar_m": 0.0, '
        f'"raw_m": 0.0, "g_m": {g_m}, "threshold_m": 0.009, "alarm_t_ns": null, '
        '"last_estimate_m": 0.0}'
    )
    return (
        '{"format_version": 1, "vehicle_name": "test_car", "tire_set_id": "summer", '
        '"state": {"version": 1, "driving_time_s": 30.0, "t_last_ns": null, '
        f'"wheels": {{"wheel_rl": {wheel}}}}}}}'
    )


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (_detector_file("0.0", "9" * 500), "500 digits"),  # crashed the node at start
        (_detector_file("0.5", "1e29"), "calibrated_m=0.5"),  # restored and published
    ],
    ids=["500-digit integer", "calibrated 0.5 m, CUSUM 1e29 m"],
)
def test_detector_node_starts_on_a_corrupt_file_and_publishes_finite_status(
    tmp_path: Path, content: str, reason: str
) -> None:
    rclpy, msg_mod, nav_msgs, rclpy_parameter, node_mod = import_ros(
        "rclpy",
        "tire_estimation_msgs.msg",
        "nav_msgs.msg",
        "rclpy.parameter",
        "tire_estimation.nodes.detector_node",
    )
    (tmp_path / "deflation.json").write_text(content)
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = node_mod.DetectorNode(
            context=context, parameter_overrides=_params(rclpy_parameter.Parameter, tmp_path)
        )
        assert node.state_file.note.startswith("rejected") and reason in node.state_file.note
        main = _by_name(node.diagnostic_statuses())["tire_estimation: deflation detector"]
        assert _diag_values(main)["persistence"] == node.state_file.note
        assert node.detector.calibration_state.name == "NOT_STARTED"
        published: list[Any] = []
        node.pub_status.publish = published.append  # capture instead of DDS
        Feeder(msg_mod, nav_msgs.Odometry).drive(node, 5.0, MU_CAL)
        assert len(published) == 50
        for msg in published:
            assert not msg.any_alarm and msg.calibration_state != 2  # not DONE
            for w in msg.wheels:
                values = (w.radius_change_m, w.cusum, w.threshold)
                assert all(math.isfinite(v) and abs(v) < 0.1 for v in values)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_detector_node_survives_stamps_that_jump(tmp_path: Path) -> None:
    """One TireRadii two hours ahead is dropped and counted; a clock stepped back ten minutes
    is adopted: calibration goes on and the published stamps follow the topics' clock."""
    rclpy, msg_mod, nav_msgs, rclpy_parameter, node_mod = import_ros(
        "rclpy",
        "tire_estimation_msgs.msg",
        "nav_msgs.msg",
        "rclpy.parameter",
        "tire_estimation.nodes.detector_node",
    )
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        node = node_mod.DetectorNode(
            context=context,
            parameter_overrides=_params(rclpy_parameter.Parameter, tmp_path, **{
                "detector.calibration_time_s": 600.0,
                "detector.calibration_average_s": 60.0,
            }),
        )  # fmt: skip
        published: list[Any] = []
        node.pub_status.publish = published.append
        feed = Feeder(msg_mod, nav_msgs.Odometry)
        feed.drive(node, 5.0, MU_CAL)
        driven_s = node.detector.status().calibrated_driving_time_s
        assert driven_s > 3.0

        future = feed.radii(MU_CAL)
        future.header.stamp.sec += 7200
        node.on_tire_radii(future)
        feed.drive(node, 5.0, MU_CAL)
        assert node.dropped["tire_radii:clock_jump"] == 1
        assert node.detector.status().calibrated_driving_time_s == pytest.approx(
            driven_s + 5.0, abs=0.3
        )

        feed.t_ns -= 600 * S  # the clock steps back ten minutes
        feed.drive(node, 5.0, MU_CAL)
        assert node.detector.status().calibrated_driving_time_s == pytest.approx(
            driven_s + 10.0, abs=1.0
        )
        last = published[-1].header.stamp
        assert last.sec * S + last.nanosec == feed.t_ns
        node.destroy_node()
    finally:
        rclpy.shutdown(context=context)


def test_detector_node_persists_only_a_changed_state_of_a_named_vehicle(tmp_path: Path) -> None:
    """The default vehicle name (no vehicle file) turns persistence off; a named vehicle's
    node writes nothing until its state changed, then saves at shutdown."""
    rclpy, msg_mod, nav_msgs, rclpy_parameter, node_mod = import_ros(
        "rclpy",
        "tire_estimation_msgs.msg",
        "nav_msgs.msg",
        "rclpy.parameter",
        "tire_estimation.nodes.detector_node",
    )
    path = tmp_path / "deflation.json"
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        params = _params(rclpy_parameter.Parameter, tmp_path, **{"vehicle.name": "vehicle"})
        unnamed = node_mod.DetectorNode(context=context, parameter_overrides=params)
        assert "no vehicle identity" in unnamed.state_file.note
        Feeder(msg_mod, nav_msgs.Odometry).drive(unnamed, 5.0, MU_CAL)
        unnamed.save_on_shutdown()
        assert not path.exists()
        unnamed.destroy_node()

        named = node_mod.DetectorNode(
            context=context, parameter_overrides=_params(rclpy_parameter.Parameter, tmp_path)
        )
        named.save_on_shutdown()  # nothing changed: the prior is not written
        assert not path.exists()
        Feeder(msg_mod, nav_msgs.Odometry).drive(named, 5.0, MU_CAL)
        named.save_on_shutdown()
        assert path.is_file()
        named.destroy_node()
    finally:
        rclpy.shutdown(context=context)
