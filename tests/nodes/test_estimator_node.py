"""estimator_node: parameters, bad input never kills it, persistence, reset, diagnostics."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros

WHEELS = ["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
LAT0, LON0 = 58.4, 15.6


@pytest.fixture
def ros() -> Any:
    (rclpy,) = import_ros("rclpy")
    context = rclpy.Context()
    rclpy.init(context=context)
    yield rclpy, context
    rclpy.shutdown(context=context)


def _node(ros: Any, tmp_path: Path, **params: Any) -> Any:
    _rclpy, context = ros
    from rclpy.parameter import Parameter

    from tire_estimation.nodes.estimator_node import EstimatorNode

    values = {
        "persistence_file": str(tmp_path / "radii.json"),
        "radius.n_particles": 200,
        "vehicle.name": "test_car",
        **params,
    }
    overrides = [Parameter(k, value=v) for k, v in values.items()]
    return EstimatorNode(context=context, parameter_overrides=overrides)


def _callbacks(node: Any) -> dict[str, Any]:
    return {sub.topic_name: sub.callback for sub in node.subscriptions}


def _wheels(t_ns: int, speeds: list[float], names: list[str] | None = None) -> Any:
    from sensor_msgs.msg import JointState

    msg = JointState()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.name = names if names is not None else list(WHEELS)
    msg.velocity = [float(v) for v in speeds]
    return msg


def _fix(t_ns: int, east_m: float, north_m: float) -> Any:
    from sensor_msgs.msg import NavSatFix

    from tire_estimation.core.geodesy import LocalTangentPlane

    lat, lon, alt = LocalTangentPlane(LAT0, LON0, 100.0).to_lla(east_m, north_m, 0.0)
    msg = NavSatFix()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.latitude, msg.longitude, msg.altitude = float(lat), float(lon), float(alt)
    msg.position_covariance = [2.25, 0, 0, 0, 2.25, 0, 0, 0, 4.0]
    msg.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return msg


def _drive(cb: dict[str, Any], t0_ns: int, seconds: float, speed_m_s: float = 20.0) -> int:
    """Straight drive east at constant speed: wheel speeds at 100 Hz, GNSS at 10 Hz."""
    omega = speed_m_s / 0.31
    t_ns = t0_ns
    for k in range(int(seconds * 100)):
        t_ns = t0_ns + k * 10_000_000
        cb["/vehicle/wheel_speeds"](_wheels(t_ns, [omega] * 4))
        if k % 10 == 0:
            east = speed_m_s * (t_ns - 1_000_000_000_000) * 1e-9
            cb["/gnss/fix"](_fix(t_ns, east, 0.0))
    return t_ns


def _diag_values(node: Any) -> dict[str, str]:
    statuses = node.diagnostic_statuses()
    return {kv.key: kv.value for kv in statuses[0].values}


def test_parameters_map_onto_config_and_reject_bad_values(ros: Any, tmp_path: Path) -> None:
    from tire_estimation.errors import ConfigError

    node = _node(ros, tmp_path, **{"radius.n_particles": 123, "vehicle.track_width_m": 1.6})
    assert node.config.n_particles == 123
    assert node.vehicle.track_width_m == pytest.approx(1.6)
    described = node.describe_parameters(["radius.n_particles"])[0]
    assert "particles" in described.description
    node.destroy_node()
    with pytest.raises(ConfigError, match="n_particles"):
        _node(ros, tmp_path, **{"radius.n_particles": 1})


def test_bad_input_is_dropped_counted_and_reported(ros: Any, tmp_path: Path) -> None:
    node = _node(ros, tmp_path)
    cb = _callbacks(node)
    t0 = 1_000_000_000_000
    t = _drive(cb, t0, 30.0)
    good = node.estimator.estimate()
    assert good.state in ("running", "paused")

    from sensor_msgs.msg import JointState, NavSatFix

    cb["/vehicle/wheel_speeds"](_wheels(t + 10_000_000, [math.nan] * 4))  # NaN
    cb["/vehicle/wheel_speeds"](_wheels(t - 500_000_000, [64.5] * 4))  # out of order
    cb["/vehicle/wheel_speeds"](_wheels(t, [64.5] * 4))  # duplicate stamp
    cb["/vehicle/wheel_speeds"](JointState())  # no stamp at all
    cb["/vehicle/wheel_speeds"](_wheels(t + 15_000_000, [], names=[]))  # empty
    cb["/vehicle/wheel_speeds"](_wheels(t + 20_000_000, [1.0, 2.0], names=WHEELS))  # length
    cb["/vehicle/wheel_speeds"](_wheels(t + 30_000_000, [1.0], names=["wheel_xx"]))  # unknown
    cb["/vehicle/wheel_speeds"](_wheels(t + 40_000_000, [math.inf] * 4))  # inf
    jump = _fix(t + 50_000_000, 20.0 * 30.0 + 500.0, 0.0)  # 500 m GNSS jump
    cb["/gnss/fix"](jump)
    no_fix = _fix(t + 60_000_000, 0.0, 0.0)
    no_fix.status.status = NavSatFix().status.STATUS_NO_FIX
    cb["/gnss/fix"](no_fix)
    # fixes stamped ahead of the last wheel speed wait until the wheel speeds are 50 ms
    # (reorder_delay_s) past them, then are used in stamp order
    cb["/vehicle/wheel_speeds"](_wheels(t + 70_000_000, [64.5] * 4))
    assert len(node.pipeline.buffer) > 0
    cb["/vehicle/wheel_speeds"](_wheels(t + 130_000_000, [64.5] * 4))

    values = _diag_values(node)
    dropped = {k: int(v) for k, v in values.items() if k.startswith("dropped.")}
    assert dropped.get("dropped.wheel_speeds:no_stamp") == 1
    assert dropped.get("dropped.wheel_speeds:empty") == 1
    assert dropped.get("dropped.wheel_speeds:wrong_length") == 1
    assert dropped.get("dropped.wheel_speeds:unknown_wheel") == 1
    assert dropped.get("dropped.gnss_fix:no_fix") == 1
    assert dropped.get("dropped.wheel_speeds:nan") == 2  # NaN and inf samples
    # dropped by the radius estimator, with their stream too
    assert not any(".core." in k for k in dropped)
    late = dropped.get("dropped.wheel_speeds:out_of_order", 0)
    assert late + dropped.get("dropped.wheel_speeds:duplicate", 0) >= 2
    assert dropped.get("dropped.gnss_fix:outlier", 0) >= 1

    # a gap of ten minutes, then driving on: still finite, still running
    t = _drive(cb, t + 600_000_000_000, 20.0)
    est = node.estimator.estimate()
    assert np.all(np.isfinite(est.radius_error_m))
    assert np.all(np.isfinite(est.pose)) and np.all(np.isfinite(est.pose_cov))
    assert int(values["received.wheel_speeds"]) >= 3000
    node.destroy_node()


def test_radii_persist_across_restarts_and_reset_forgets(ros: Any, tmp_path: Path) -> None:
    node = _node(ros, tmp_path)
    cb = _callbacks(node)
    _drive(cb, 1_000_000_000_000, 20.0)
    learned = node.estimator.state_dict()
    # a distinctive learned stiffness (the straight test drive does not excite it)
    stiff = node.stiffness.state_dict()
    stiff["mean"] = [1.0e3, -4.0e3, 2.5e3]
    node.stiffness.load_state_dict(stiff)
    node.save_on_shutdown()
    node.destroy_node()
    assert (tmp_path / "radii.json").is_file()

    again = _node(ros, tmp_path)
    assert "radius restored" in again.state_file.note
    assert "stiffness restored" in again.state_file.note
    restored = again.estimator.state_dict()
    assert restored.keys() == learned.keys()
    np.testing.assert_allclose(restored["rear"]["mean_m"], learned["rear"]["mean_m"], atol=1e-5)
    np.testing.assert_allclose(again.stiffness.state_dict()["mean"], stiff["mean"], rtol=0.05)
    # without the stiffness MPF the radii still load and the saved stiffness is kept
    no_stiff = _node(ros, tmp_path, stiffness_enabled=False)
    assert "radius restored" in no_stiff.state_file.note
    no_stiff.save_on_shutdown()
    no_stiff.destroy_node()
    kept = _node(ros, tmp_path)
    np.testing.assert_allclose(kept.stiffness.state_dict()["mean"], stiff["mean"], rtol=0.05)
    kept.destroy_node()
    other = _node(ros, tmp_path, tire_set_id="winter")
    assert "tire set" in other.state_file.note
    other.destroy_node()

    from std_srvs.srv import Trigger

    response = again._on_reset(Trigger.Request(), Trigger.Response())
    assert response.success
    assert not (tmp_path / "radii.json").exists()
    est = again.estimator.estimate()
    assert np.allclose(est.radius_error_m, 0.0, atol=1e-12)
    again.destroy_node()


def _corrupt_files(good: dict[str, Any]) -> dict[str, str]:
    """Persistence files that crashed the node at start or left its filter NaN or absurd."""

    def payload(state: Any) -> str:
        return json.dumps(
            {"format_version": 1, "vehicle_name": "test_car", "tire_set_id": "default",
             "saved_unix_s": 1.7e9, "state": state}
        )  # fmt: skip

    zero_noise = copy.deepcopy(good)
    zero_noise["radius"]["rear"]["noise_cov_m2"] = [[0.0, 0.0], [0.0, 0.0]]
    far = copy.deepcopy(good)
    far["radius"]["rear"]["mean_m"] = [0.1, -0.1]
    text = payload(good)
    return {
        "deep nesting": '{"state": ' + "[" * 100_000 + "]" * 100_000 + "}",
        "500-digit integer": text.replace('"dof": 10.0', '"dof": ' + "9" * 500, 1),
        "zero noise covariance": payload(zero_noise),
        "radius errors of +-100 mm": payload(far),
    }


@pytest.mark.parametrize(
    "corruption",
    ["deep nesting", "500-digit integer", "zero noise covariance", "radius errors of +-100 mm"],
)
def test_a_corrupt_persistence_file_is_rejected_and_the_node_publishes_finite_radii(
    ros: Any, tmp_path: Path, corruption: str
) -> None:
    probe = _node(ros, tmp_path, persistence_file="")
    good = probe._learned.state_dict()
    probe.destroy_node()
    assert '"dof": 10.0' in json.dumps(good)
    (tmp_path / "radii.json").write_text(_corrupt_files(good)[corruption])
    node = _node(ros, tmp_path)  # starts: no RecursionError / OverflowError
    assert "rejected" in node.state_file.note and "radius restored" not in node.state_file.note
    assert "rejected" in _diag_values(node)["persistence"]
    published: list[Any] = []
    node.pub_radii.publish = published.append  # capture instead of DDS
    _drive(_callbacks(node), 1_000_000_000_000, 20.0)
    from tire_estimation_msgs.msg import TireRadii

    running = [m for m in published if m.state == TireRadii.STATE_RUNNING]
    assert running, "the estimator never ran"
    for msg in running:
        assert all(math.isfinite(v) and abs(v) < 0.0155 for v in msg.radius_error_m)
        assert all(0.0 < v < 0.01 for v in msg.radius_error_std_m)  # not the NaN fallback
    st = node.estimator.mpf.stats
    assert all(np.all(np.isfinite(a)) for a in (st.mean, st.scale, st.gamma, st.dof))
    node.destroy_node()


def test_tire_forces_drive_the_lateral_state(ros: Any, tmp_path: Path) -> None:
    from tire_estimation.bag.messages import joint_state
    from tire_estimation.sim import simulate
    from tire_estimation_msgs.msg import LateralState, TireForces

    node = _node(ros, tmp_path)
    published: list[Any] = []
    node.pub_lateral.publish = published.append  # capture instead of DDS (tested elsewhere)
    cb = _callbacks(node)
    res = simulate("lane_change", seed=1, minutes=0.3)
    events = []
    ws, st, tf = res.wheel_speeds, res.steering, res.tire_forces
    for i, t in enumerate(ws.t_ns.tolist()):
        events.append((t, 0, i))
    for i, t in enumerate(st.t_ns.tolist()):
        events.append((t, 1, i))
    for i, t in enumerate(tf.t_ns.tolist()):
        events.append((t, 2, i))
    for t, kind, i in sorted(events):
        if kind == 0:
            cb["/vehicle/wheel_speeds"](_wheels(t, ws.wheel_speed_rad_s[i].tolist()))
        elif kind == 1:
            msg = joint_state(t, ["front_wheel_angle"], position=[float(st.angle_rad[i])])
            cb["/vehicle/steering"](_to_ros_joint(msg))
        else:
            m = TireForces()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(t, 1_000_000_000)
            m.wheel_names = ["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
            m.fx_n, m.fy_n, m.fz_n = (tf.fx_n[i].tolist(), tf.fy_n[i].tolist(),
                                      tf.fz_n[i].tolist())  # fmt: skip
            m.valid = tf.valid[i].tolist()
            cb["/vehicle/tire_forces"](m)
    bad = TireForces()
    bad.header.stamp.sec = 2_000_000_000
    bad.wheel_names = ["wheel_fl"]
    bad.fx_n = [1.0, 2.0]
    cb["/vehicle/tire_forces"](bad)
    assert node.dropped["tire_forces:wrong_length"] == 1
    assert len(published) > 500
    last = published[-1]
    assert last.source == "tyre_force_kf"
    assert last.linearity in (LateralState.LINEARITY_LINEAR, LateralState.LINEARITY_NONLINEAR)
    # against truth: vy within 0.2 m/s at the last estimate
    k = int(
        np.searchsorted(res.truth.t_ns, last.header.stamp.sec * 10**9 + last.header.stamp.nanosec)
    )
    k = min(k, res.truth.t_ns.size - 1)
    assert abs(last.lateral_velocity_m_s - res.truth.velocity_m_s[k, 1]) < 0.2
    assert abs(last.yaw_rate_rad_s - res.truth.yaw_rate_rad_s[k]) < 0.05
    status = next(
        st
        for st in node.diagnostic_statuses()
        if st.name == "tire_estimation: tyre-force lateral KF"
    )
    values = {kv.key: kv.value for kv in status.values}
    assert status.message.startswith("running (")
    assert int(values["received.tire_forces"]) == tf.t_ns.size + 1
    assert values["linearity"] in ("linear", "nonlinear")
    node.destroy_node()


def _to_ros_joint(msg: Any) -> Any:
    from sensor_msgs.msg import JointState

    out = JointState()
    out.header.stamp.sec, out.header.stamp.nanosec = msg.header.stamp.sec, msg.header.stamp.nanosec
    out.name = list(msg.name)
    out.position = [float(v) for v in msg.position]
    return out


def _imu_msg(t_ns: int, gyro: Any, acc: Any) -> Any:
    from sensor_msgs.msg import Imu

    m = Imu()
    m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    m.header.frame_id = "base_link"
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = (float(v) for v in gyro)
    a = m.linear_acceleration
    a.x, a.y, a.z = (float(v) for v in acc)
    return m


def test_stiffness_estimator_publishes_stiffness_and_lateral_state(
    ros: Any, tmp_path: Path
) -> None:
    from tire_estimation.bag.messages import joint_state
    from tire_estimation.sim import simulate

    node = _node(ros, tmp_path, **{"stiffness.n_particles": 100})
    stiffness: list[Any] = []
    lateral: list[Any] = []
    node.pub_stiffness.publish = stiffness.append  # capture instead of DDS
    node.pub_lateral.publish = lateral.append
    cb = _callbacks(node)
    res = simulate("lane_change", seed=1, minutes=0.3)
    ws, st, imu = res.wheel_speeds, res.steering, res.imu
    events = [(t, 0, i) for i, t in enumerate(ws.t_ns.tolist())]
    events += [(t, 1, i) for i, t in enumerate(st.t_ns.tolist())]
    events += [(t, 2, i) for i, t in enumerate(imu.t_ns.tolist())]
    for t, kind, i in sorted(events):
        if kind == 0:
            cb["/vehicle/wheel_speeds"](_wheels(t, ws.wheel_speed_rad_s[i].tolist()))
        elif kind == 1:
            msg = joint_state(t, ["front_wheel_angle"], position=[float(st.angle_rad[i])])
            cb["/vehicle/steering"](_to_ros_joint(msg))
        else:
            cb["/imu/data"](
                _imu_msg(t, imu.angular_velocity_rad_s[i], imu.linear_acceleration_m_s2[i])
            )
    # bad input on the new streams is dropped and counted
    t_end = int(imu.t_ns[-1])
    cb["/imu/data"](_imu_msg(t_end + 10_000_000, [0.0, 0.0, math.nan], [0.0, 0.0, 9.8]))
    assert node.dropped["imu:nan"] == 1
    # about 10 Hz over the 18 s drive (header time)
    assert 150 <= len(stiffness) <= 190
    last = stiffness[-1]
    assert list(last.names) == ["cx_front", "cy_front", "cy_rear"]
    assert all(np.isfinite(last.stiffness)) and all(s > 0 for s in last.stiffness_std)
    assert last.nominal[1] == pytest.approx(node.vehicle.cornering_stiffness_front_n_rad)
    # no tyre forces: the lateral state comes from the stiffness MPF, in base_link
    assert lateral and all(m.source == "stiffness_mpf" for m in lateral)
    msg = lateral[-1]
    t_msg = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    k = min(int(np.searchsorted(res.truth.t_ns, t_msg)), res.truth.t_ns.size - 1)
    assert abs(msg.lateral_velocity_m_s - res.truth.velocity_m_s[k, 1]) < 0.2
    assert abs(msg.yaw_rate_rad_s - res.truth.yaw_rate_rad_s[k]) < 0.02
    cov = np.asarray(msg.covariance).reshape(3, 3)
    assert np.allclose(cov, cov.T) and np.all(np.linalg.eigvalsh(cov) >= -1e-12)
    status = next(
        st
        for st in node.diagnostic_statuses()
        if st.name == "tire_estimation: stiffness estimator"
    )
    values = {kv.key: kv.value for kv in status.values}
    assert status.message in ("learning", "holding: no lateral excitation")
    assert float(values["cy_front"]) == pytest.approx(float(last.stiffness[1]), rel=0.05)
    # Algorithm 1 from the start (first_learning: mpf): no grid to hand over or drop
    assert (values["grid_handovers"], values["grid_rejections"]) == ("0", "0")
    node.destroy_node()


def test_stiffness_runs_on_measured_velocity_without_wheel_speeds(
    ros: Any, tmp_path: Path
) -> None:
    from geometry_msgs.msg import TwistWithCovarianceStamped

    from tire_estimation.bag.messages import joint_state

    node = _node(ros, tmp_path, **{"stiffness.n_particles": 50})
    cb = _callbacks(node)
    t0 = 1_000_000_000_000

    def vel(t_ns: int, vx: float, frame: str = "base_link") -> Any:
        m = TwistWithCovarianceStamped()
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
        m.header.frame_id = frame
        m.twist.twist.linear.x = vx
        return m

    for k in range(300):  # 3 s at 100 Hz, straight at 20 m/s
        t = t0 + k * 10_000_000
        cb["/vehicle/velocity"](vel(t, 20.0))
        cb["/vehicle/steering"](
            _to_ros_joint(joint_state(t, ["front_wheel_angle"], position=[0.0]))
        )
        cb["/imu/data"](_imu_msg(t, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81]))
    cb["/vehicle/velocity"](vel(t0 + 4_000_000_000, 20.0, frame="map"))
    assert node.dropped["velocity:wrong_frame"] == 1
    # no wheel-speed clock: samples are released 0.5 s behind the newest (ordering.py)
    assert node.stiffness is not None and node.stiffness.mpf.initialized
    est = node.stiffness.estimate()
    assert est.vx_m_s == pytest.approx(20.0, abs=0.5)
    assert not est.active and est.reason == "no lateral excitation"
    node.destroy_node()


def _gnss_velocity(t_ns: int, east_m_s: float, north_m_s: float, frame: str = "map") -> Any:
    from geometry_msgs.msg import TwistWithCovarianceStamped

    msg = TwistWithCovarianceStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    msg.header.frame_id = frame
    msg.twist.twist.linear.x, msg.twist.twist.linear.y = float(east_m_s), float(north_m_s)
    cov = [0.0] * 36
    cov[0] = cov[7] = 0.01
    cov[14] = 0.04
    msg.twist.covariance = cov
    return msg


def test_gnss_velocity_is_subscribed_used_and_bad_ones_are_counted(
    ros: Any, tmp_path: Path
) -> None:
    """``radius.gnss_velocity_enabled``: /gnss/velocity re-weights the particles; a velocity in
    base_link axes and a NaN one are dropped and reported. On by default; off: no
    subscription."""
    node = _node(ros, tmp_path, **{"radius.gnss_velocity_enabled": False})
    assert "/gnss/velocity" not in _callbacks(node)
    node.destroy_node()
    node = _node(ros, tmp_path)
    cb = _callbacks(node)
    t0 = 1_000_000_000_000
    omega = 20.0 / 0.31
    t_ns = t0
    for k in range(3000):  # 30 s east at 20 m/s, fix and velocity at 10 Hz
        t_ns = t0 + k * 10_000_000
        cb["/vehicle/wheel_speeds"](_wheels(t_ns, [omega] * 4))
        if k % 10 == 0:
            cb["/gnss/fix"](_fix(t_ns, 20.0 * k * 0.01, 0.0))
            cb["/gnss/velocity"](_gnss_velocity(t_ns, 20.0, 0.0))
    assert node.estimator.velocity_updates > 100
    cb["/gnss/velocity"](_gnss_velocity(t_ns + 1_000_000, 20.0, 0.0, frame="base_link"))
    cb["/gnss/velocity"](_gnss_velocity(t_ns + 2_000_000, math.nan, 0.0))
    cb["/vehicle/wheel_speeds"](_wheels(t_ns + 10_000_000, [omega] * 4))
    values = _diag_values(node)
    assert values["dropped.gnss_velocity:wrong_frame"] == "1"
    assert values["dropped.gnss_velocity:nan"] == "1"
    assert int(values["received.gnss_velocity"]) == 302
    assert int(values["gnss_velocity.updates"]) == node.estimator.velocity_updates > 100
    assert values["gnss_velocity.skipped_accelerating"] == "0"  # constant speed
    # no IMU to check the altitude's grade against: no grade correction, and said so
    assert values["road_grade.source"] == "none" and values["road_grade_deg"] == "0.00"
    assert int(values["road_grade.fixes.none"]) > 200
    # half the 10 ms wheel-speed period is brought back before the prediction
    assert values["wheel_speeds.lag_ms"] == "5.0"
    # a constant speed holds no value at the tooth rate: no ABS pitch read off
    assert values["wheel_speeds.teeth"] == "0"
    # a front-driven car (the default vehicle): no traction slip on the rear wheels
    assert "drive_slip.source" not in values
    # the GNSS speed agrees with the wheels': no rescaling of the radii
    assert values["speed_scale.rescales"] == "0"
    # 30 s of fixes as accurate as stated: their covariance is used as it is
    assert values["gnss.covariance_scale"] == "1"
    # straight driving tells neither the axles nor the gyro's sign: nothing is rewired
    assert values["gyro.yaw_reversed"] == "false" and values["axle.rear.swapped"] == "false"
    assert values["wheels.sign_reversed"] == "none"
    assert values["axle.front_rear_exchanged"] == "false"
    assert values["road_grade.imu_offset_deg"] == "0.00"
    # constant speed, no IMU: the IMU's mounting is never decided
    assert values["imu.mounting_yaw_deg"] == "checking" and values["imu.rotated"] == "false"
    est = node.estimator.estimate()
    # 30 s of straight driving: filter seeds 0-5 end at 0.14-0.56 mm (the common mode of the
    # two radii, which a straight drive observes weakly); 1 mm catches a velocity misuse
    assert np.all(np.abs(est.radius_error_m) < 1e-3), est.radius_error_m
    node.destroy_node()


def test_each_wheel_says_whether_it_learns_and_why_not(ros: Any, tmp_path: Path) -> None:
    """Below the speed floor (1 m/s) the wheels' statuses warn that the radius is not learned
    yet (the published value is the prior); above it they learn and count the time learned."""
    from diagnostic_msgs.msg import DiagnosticStatus

    node = _node(ros, tmp_path, persistence_file="")
    cb = _callbacks(node)
    t = _drive(cb, 1_000_000_000_000, 40.0, speed_m_s=0.8)

    def wheels() -> dict[str, Any]:
        return {s.name: s for s in node.diagnostic_statuses() if s.name.endswith(("_rl", "_rr"))}

    slow = wheels()
    assert len(slow) == 2
    for st in slow.values():
        assert st.level == DiagnosticStatus.WARN and st.message == "not learned yet: low speed"
        assert {kv.key: kv.value for kv in st.values}["learned_s"] == "0.0"
    t = _drive(cb, t + 10_000_000, 20.0, speed_m_s=20.0)
    for st in wheels().values():
        assert st.level == DiagnosticStatus.OK and st.message == "learning"
        assert float({kv.key: kv.value for kv in st.values}["learned_s"]) > 5.0
    # the rear-left sensor reads 0 while the others turn: that wheel warns, both hold
    omega = 20.0 / 0.31
    for k in range(1, 51):  # 0.5 s, longer than the reorder delay
        tk = t + k * 10_000_000
        cb["/vehicle/wheel_speeds"](_wheels(tk, [omega, omega, 0.0, omega]))
        if k % 10 == 0:
            cb["/gnss/fix"](_fix(tk, 20.0 * (tk - 1_000_000_000_000) * 1e-9, 0.0))
    lost = wheels()
    assert lost["tire_estimation: wheel_rl"].level == DiagnosticStatus.WARN
    assert lost["tire_estimation: wheel_rl"].message == (
        "holding: wheel_rl signal lost; wheel-speed signal lost"
    )
    assert lost["tire_estimation: wheel_rr"].level == DiagnosticStatus.OK
    assert lost["tire_estimation: wheel_rr"].message == "holding: wheel_rl signal lost"
    node.destroy_node()


def test_a_rear_driven_vehicle_reports_the_slip_of_its_rear_wheels(
    ros: Any, tmp_path: Path
) -> None:
    """``vehicle.drive: rear``: the traction slip is removed from the rear wheel speeds (the
    prior from the mass and the stiffness until the regression has enough straight driving)
    and ``/diagnostics`` says where it came from."""
    node = _node(ros, tmp_path, persistence_file="", **{"vehicle.drive": "rear"})
    _drive(_callbacks(node), 1_000_000_000_000, 10.0)
    values = _diag_values(node)
    assert values["drive_slip.source"] == "prior"
    # m / C_x (c_rr g + rho C_d A v^2 / (2 m)) at 20 m/s on the default car: 0.23 %
    assert float(values["drive_slip.mean_pct"]) == pytest.approx(0.23, abs=0.02)
    node.destroy_node()


def test_corrected_twist_wheel_radii_and_speed_scale_go_with_every_radii_message(
    ros: Any, tmp_path: Path
) -> None:
    """``/tire_estimation/twist`` (base_link, vx and yaw rate with their covariance),
    ``/tire_estimation/wheel_radii`` (position = effective radius, effort = multiplier) and
    ``/tire_estimation/speed_scale_factor`` are published with each TireRadii."""
    node = _node(ros, tmp_path, persistence_file="")
    topics = {
        "twist": node.pub_twist,
        "wheel_radii": node.pub_wheel_radii,
        "speed_scale_factor": node.pub_speed_scale,
        "tire_radii": node.pub_radii,
    }
    assert {k: p.topic_name for k, p in topics.items()} == {
        k: f"/tire_estimation/{k}" for k in topics
    }
    published: dict[str, list[Any]] = {k: [] for k in topics}
    for key, pub in topics.items():
        pub.publish = published[key].append  # capture instead of DDS
    _drive(_callbacks(node), 1_000_000_000_000, 20.0, speed_m_s=15.0)
    n = len(published["tire_radii"])
    assert 190 <= n <= 200  # 10 Hz over 20 s of header time
    assert all(len(published[k]) == n for k in topics)
    nominal = node.vehicle.nominal_tire_radius_m
    for twist, joints, scale, radii in zip(*published.values(), strict=True):
        assert twist.header == joints.header == radii.header
        assert twist.header.frame_id == "base_link"
        assert list(joints.name) == list(radii.wheel_names) == ["wheel_rl", "wheel_rr"]
        effective = [nominal + e for e in radii.radius_error_m]
        np.testing.assert_allclose(joints.position, effective, rtol=1e-12)
        np.testing.assert_allclose(joints.effort, np.array(effective) / nominal, rtol=1e-12)
        assert len(joints.velocity) == 0
        assert scale.data == pytest.approx(np.mean(effective) / nominal, rel=1e-12)
    last = published["twist"][-1]
    # eq. (6) with the wheel speeds of the drive and the learned radii
    omega = 15.0 / 0.31
    learned = published["wheel_radii"][-1].position
    assert last.twist.twist.linear.x == pytest.approx(0.5 * omega * sum(learned), rel=1e-9)
    assert last.twist.twist.angular.z == pytest.approx(
        omega * (learned[1] - learned[0]) / node.vehicle.track_width_m, abs=1e-9
    )
    cov = np.asarray(last.twist.covariance).reshape(6, 6)
    # vx and yaw rate measured (the straight drive's constant wheel speeds have no noise, so
    # the floors and the radius uncertainty remain); the rest not measured
    assert 0.05**2 <= cov[0, 0] < 0.1**2 and 0.03**2 <= cov[5, 5] < 0.05**2
    assert cov[0, 5] == cov[5, 0]
    assert all(cov[i, i] == 1e6 for i in (1, 2, 3, 4))
    node.destroy_node()


def test_no_vehicle_identity_means_no_persistence(ros: Any, tmp_path: Path) -> None:
    """Without a vehicle file and with the default vehicle name the node neither restores nor
    saves: two vehicles left at the defaults would share one file."""
    path = tmp_path / "radii.json"
    named = _node(ros, tmp_path, **{"vehicle.name": "vehicle"})
    assert "no vehicle identity" in named.state_file.note
    assert "no vehicle identity" in _diag_values(named)["persistence"]
    _drive(_callbacks(named), 1_000_000_000_000, 20.0)
    named.save_on_shutdown()
    assert not path.exists()
    named.destroy_node()
    # a saved state of the default identity is not restored either
    saved = {"format_version": 1, "vehicle_name": "vehicle", "tire_set_id": "default"}
    path.write_text(json.dumps({**saved, "saved_unix_s": 1.7e9, "state": {}}))
    again = _node(ros, tmp_path, **{"vehicle.name": "vehicle"})
    assert "no vehicle identity" in again.state_file.note
    again.destroy_node()


def test_an_untouched_prior_is_never_saved(ros: Any, tmp_path: Path) -> None:
    """A node with nothing learned does not write its prior at the save period or at
    shutdown, nor after a reset; once it learned, it saves."""
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import Trigger

    _rclpy, context = ros
    path = tmp_path / "radii.json"
    node = _node(ros, tmp_path, persistence_period_s=0.1)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    for _ in range(10):  # about 0.5 s: several save periods
        executor.spin_once(timeout_sec=0.05)
    node.save_on_shutdown()
    assert not path.exists()
    _drive(_callbacks(node), 1_000_000_000_000, 20.0)
    node.save_on_shutdown()
    assert path.is_file()
    node._on_reset(Trigger.Request(), Trigger.Response())
    assert not path.exists()
    node.save_on_shutdown()
    assert not path.exists()
    executor.remove_node(node)
    executor.shutdown()
    node.destroy_node()


def test_the_robot_localization_example_fuses_the_twist_the_node_publishes(
    ros: Any, tmp_path: Path
) -> None:
    import yaml

    root = Path(__file__).resolve().parents[2]
    example = root / "src/tire_estimation/config/ekf_wheel_odometry.yaml"
    params = yaml.safe_load(example.read_text())["ekf_filter_node"]["ros__parameters"]
    node = _node(ros, tmp_path, persistence_file="")
    assert params["twist0"] == node.pub_twist.topic_name == "/tire_estimation/twist"
    # the twist's frame, and only its measured components: vx (6) and yaw rate (11)
    assert params["base_link_frame"] == "base_link" and params["world_frame"] == "odom"
    config = params["twist0_config"]
    assert len(config) == 15 and [i for i, on in enumerate(config) if on] == [6, 11]
    assert "ekf_wheel_odometry.yaml" in (root / "docs/robot_localization.md").read_text()
    node.destroy_node()


def test_the_datum_of_the_pose_is_published_once_with_the_map_frame(
    ros: Any, tmp_path: Path
) -> None:
    """The ENU origin (the first fix) goes out on tire_estimation/datum, framed as the robot
    names its map frame; other nodes can then place the pose on the globe."""
    node = _node(ros, tmp_path, name_remaps=["map=odom"], stiffness_enabled=False)
    datums: list[Any] = []
    node.pub_datum.publish = datums.append
    _drive(_callbacks(node), 1_000_000_000_000, 5.0)
    assert len(datums) == 1
    d = datums[0]
    assert d.header.frame_id == "odom"
    assert d.latitude == pytest.approx(LAT0, abs=1e-7)
    assert d.longitude == pytest.approx(LON0, abs=1e-7)
    assert d.header.stamp.sec == 1000
    node.destroy_node()


def test_a_gnss_clock_offset_is_reported_on_diagnostics(ros: Any, tmp_path: Path) -> None:
    """The node's clock check (core/clock_check.py, decided over the first minutes) is on the
    radius estimator's status: "checking" until decided, then the lag; an offset is a WARN
    that says what to fix."""
    from diagnostic_msgs.msg import DiagnosticStatus

    node = _node(ros, tmp_path)
    assert node.clock_check in node.pipeline.observers
    assert _diag_values(node)["clock.gnss_lag_s"] == "checking"
    node.clock_check.result = {"lag_s": 0.0, "correlation": 0.99, "offset": False}
    assert _diag_values(node)["clock.gnss_lag_s"] == "0.00"
    node.clock_check.result = {"lag_s": 18.02, "correlation": 0.99, "offset": True}
    main = node.diagnostic_statuses()[0]
    assert main.level == DiagnosticStatus.WARN
    assert "GNSS stamps +18.0 s off the wheel speeds' clock" in main.message
    assert {kv.key: kv.value for kv in main.values}["clock.gnss_lag_s"] == "18.02"
    node.destroy_node()
