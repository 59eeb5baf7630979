"""Husky converter: small synthetic ROS 1 bags written with rosbags, plus the real bag."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from tire_estimation.bag.reader import read_bag
from tire_estimation.bag.typestore import get_typestore as contract_typestore
from tire_estimation.cli import main
from tire_estimation.convert.common import ConvertError
from tire_estimation.convert.husky import (
    EFFECTIVE_SEPARATION_M,
    FIX_TOPIC,
    IMU_TO_BASE,
    IMU_TOPIC,
    NOMINAL_WHEEL_RADIUS_M,
    ODOM_TOPIC,
    HuskyOptions,
    convert_husky,
    husky_vehicle,
    pose_increment_velocities,
    side_speeds_m_s,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError

REAL_DATA = Path("/work/shared/data/husky_robot_localization")
T0_NS = 1_432_235_498_000_000_000
DT_NS = 100_000_000
V_M_S, W_RAD_S = 1.0, 0.2
LAT0, LON0 = 42.3758, -71.1474


def _header(store: object, t_ns: int, frame: str, seq: int) -> object:
    types = store.types  # type: ignore[attr-defined]
    stamp = types["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    return types["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame)


def _odometry(store: object, t_ns: int, seq: int, x: float, y: float, yaw: float) -> object:
    t = store.types  # type: ignore[attr-defined]
    vec = t["geometry_msgs/msg/Vector3"]
    pose = t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=t["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        ),
    )
    twist = t["geometry_msgs/msg/Twist"](
        linear=vec(x=V_M_S, y=0.0, z=0.0), angular=vec(x=0.0, y=0.0, z=W_RAD_S)
    )
    cov = np.diag([1e-3] * 5 + [3e-2]).reshape(36)
    return t["nav_msgs/msg/Odometry"](
        header=_header(store, t_ns, "odom", seq),
        child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov),
    )


def _imu(store: object, t_ns: int, seq: int, gyro_imu: np.ndarray, acc_imu: np.ndarray) -> object:
    t = store.types  # type: ignore[attr-defined]
    vec = t["geometry_msgs/msg/Vector3"]
    return t["sensor_msgs/msg/Imu"](
        header=_header(store, t_ns, "imu_link", seq),
        orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.full(9, 1e-3),
        angular_velocity=vec(x=gyro_imu[0], y=gyro_imu[1], z=gyro_imu[2]),
        angular_velocity_covariance=np.full(9, 4e-4),
        linear_acceleration=vec(x=acc_imu[0], y=acc_imu[1], z=acc_imu[2]),
        linear_acceleration_covariance=np.full(9, 1e-2),
    )


def _fix(store: object, t_ns: int, seq: int, lat: float, status: int) -> object:
    t = store.types  # type: ignore[attr-defined]
    nav_status = t["sensor_msgs/msg/NavSatStatus"](status=status, service=1)
    return t["sensor_msgs/msg/NavSatFix"](
        header=_header(store, t_ns, "/gps", seq),
        status=nav_status,
        latitude=lat,
        longitude=LON0,
        altitude=7.0,
        position_covariance=np.diag([0.64, 0.64, 2.56]).reshape(9),
        position_covariance_type=1,
    )


def make_bag(
    root: Path, *, n_odom: int = 31, skip: tuple[str, ...] = (), no_fix_at: int = 3
) -> Path:
    """A steady left turn (1 m/s, 0.2 rad/s): odometry integrated as diff_drive_controller
    does (arcs), IMU in imu_link axes, GNSS at 2.5 Hz with one fix without a fix status."""
    store = get_typestore(Stores.ROS1_NOETIC)
    folder = root / "husky"
    folder.mkdir()
    path = folder / "test1.bag"
    # base_link gyro (0, 0, w), specific force (0, v w, g) seen by the rotated IMU
    gyro_imu = IMU_TO_BASE.T @ np.array([0.0, 0.0, W_RAD_S])
    acc_imu = IMU_TO_BASE.T @ np.array([0.0, V_M_S * W_RAD_S, 9.81])
    msgs: list[tuple[int, str, str, object]] = []
    x = y = 0.0
    yaw = 0.3
    for k in range(n_odom):
        t_ns = T0_NS + k * DT_NS
        if k > 0:  # exact arc over the cycle (diff_drive_controller's integrateExact)
            radius = V_M_S / W_RAD_S
            new_yaw = yaw + W_RAD_S * DT_NS * 1e-9
            x += radius * (math.sin(new_yaw) - math.sin(yaw))
            y += -radius * (math.cos(new_yaw) - math.cos(yaw))
            yaw = new_yaw
        msgs.append(
            (t_ns, ODOM_TOPIC, "nav_msgs/msg/Odometry", _odometry(store, t_ns, k, x, y, yaw))
        )
    for k in range(3 * (n_odom - 1) + 1):
        t_ns = T0_NS + k * DT_NS // 3 - 5_000_000
        msgs.append(
            (t_ns, IMU_TOPIC, "sensor_msgs/msg/Imu", _imu(store, t_ns, k, gyro_imu, acc_imu))
        )
    for k in range((n_odom - 1) // 4 + 1):
        t_ns = T0_NS + k * 400_000_000 + 1_000_000
        status = -1 if k == no_fix_at else 1
        fix = _fix(store, t_ns, k, LAT0 + 1e-5 * k, status)
        msgs.append((t_ns, FIX_TOPIC, "sensor_msgs/msg/NavSatFix", fix))
    with Ros1Writer(path) as writer:
        conns = {}
        for topic, msgtype in (
            (ODOM_TOPIC, "nav_msgs/msg/Odometry"),
            (IMU_TOPIC, "sensor_msgs/msg/Imu"),
            (FIX_TOPIC, "sensor_msgs/msg/NavSatFix"),
        ):
            if topic not in skip:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
        for t_ns, topic, msgtype, msg in sorted(msgs, key=lambda m: m[0]):
            if topic in conns:
                writer.write(conns[topic], t_ns, store.serialize_ros1(msg, msgtype))
    return folder


def test_side_speeds_from_a_known_turn(tmp_path: Path) -> None:
    bag = convert_husky(make_bag(tmp_path), tmp_path / "bag")
    data = read_bag(bag)
    assert set(data.topics) == {"/vehicle/wheel_speeds", "/imu/data", "/gnss/fix"}
    assert data.steering is None and data.reference_odometry is None
    ws = data.wheel_speeds
    # v_l = 1 - 0.2 x 1.07025 / 2 = 0.892975 m/s, v_r = 1.107025 m/s; / 0.17775 m
    left, right = 0.892975 / 0.17775, 1.107025 / 0.17775
    assert ws.wheel_speed_rad_s.shape == (30, 4)
    assert np.allclose(ws.wheel_speed_rad_s, [left, right, left, right], rtol=1e-9)
    # stamps: the middles of the 100 ms odometry cycles, in ns
    assert ws.t_ns[0] == T0_NS + 50_000_000
    assert np.all(np.diff(ws.t_ns) == DT_NS)


def test_wheel_names_on_the_message(tmp_path: Path) -> None:
    bag = convert_husky(make_bag(tmp_path), tmp_path / "bag")
    store = contract_typestore()
    with Reader(bag) as reader:
        conn = next(c for c in reader.connections if c.topic == "/vehicle/wheel_speeds")
        _, stamp, raw = next(reader.messages(connections=[conn]))
        msg = store.deserialize_cdr(raw, conn.msgtype)
    assert list(msg.name) == ["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
    assert msg.velocity[0] == msg.velocity[2] < msg.velocity[1] == msg.velocity[3]
    assert stamp == T0_NS + 50_000_000 == msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_twist_source_uses_message_stamps(tmp_path: Path) -> None:
    opts = HuskyOptions(source="twist")
    data = read_bag(convert_husky(make_bag(tmp_path), tmp_path / "bag", options=opts))
    ws = data.wheel_speeds
    assert ws.t_ns.size == 31 and ws.t_ns[0] == T0_NS
    assert np.allclose(ws.wheel_speed_rad_s[:, 0], 0.892975 / 0.17775)


def test_imu_rotated_into_base_link(tmp_path: Path) -> None:
    data = read_bag(convert_husky(make_bag(tmp_path), tmp_path / "bag"))
    imu = data.imu
    assert imu.t_ns.size == 91 and imu.t_ns[0] == T0_NS - 5_000_000
    assert np.allclose(imu.angular_velocity_rad_s, [0.0, 0.0, W_RAD_S], atol=1e-12)
    assert np.allclose(imu.linear_acceleration_m_s2, [0.0, V_M_S * W_RAD_S, 9.81], atol=1e-12)


def test_gnss_copied_and_no_fix_dropped(tmp_path: Path) -> None:
    bag = convert_husky(make_bag(tmp_path), tmp_path / "bag")
    data = read_bag(bag)
    g = data.gnss
    assert g.t_ns.size == 7  # 8 fixes, the one with STATUS_NO_FIX dropped
    assert g.t_ns[0] == T0_NS + 1_000_000
    assert np.allclose(g.position_covariance_m2, np.diag([0.64, 0.64, 2.56]))
    assert g.lat_deg[3] == pytest.approx(LAT0 + 4e-5)
    store = contract_typestore()
    with Reader(bag) as reader:
        conn = next(c for c in reader.connections if c.topic == "/gnss/fix")
        _, _, raw = next(reader.messages(connections=[conn]))
        msg = store.deserialize_cdr(raw, conn.msgtype)
    assert msg.header.frame_id == "gnss_antenna" and msg.position_covariance_type == 1
    info = yaml.safe_load((bag / "conversion.yaml").read_text())
    assert info["dropped_rows"]["fix_without_fix_or_finite_position"] == 1
    assert info["frame_ids"][ODOM_TOPIC] == ["odom -> base_link"]


def test_vehicle_description(tmp_path: Path) -> None:
    bag = convert_husky(make_bag(tmp_path), tmp_path / "bag")
    vehicle = read_bag(bag).vehicle
    assert vehicle == husky_vehicle()
    assert vehicle.track_width_m == pytest.approx(1.875 * 0.5708)
    assert vehicle.nominal_tire_radius_m == 0.17775 == NOMINAL_WHEEL_RADIUS_M
    assert vehicle.drive == "all" and vehicle.wheelbase_m == 0.512
    assert vehicle.gnss_antenna_position_m == (0.0, 0.0, 0.0)
    assert vehicle.imu_position_m == pytest.approx((0.256, -0.3, 0.52 + 0.17775 - 0.03282))
    assert vehicle.mass_kg == pytest.approx(33.455 + 4 * 2.637)
    assert 0.0 < vehicle.cg_to_rear_axle_m < 0.256 < vehicle.cg_to_front_axle_m
    assert VehicleParams.from_dict(vehicle.to_dict()) == vehicle
    text = (bag / "vehicle.yaml").read_text()
    assert "wheel_separation_multiplier 1.875" in text and "UNKNOWN" in text


def test_imu_to_base_is_the_test_launch_transform() -> None:
    # static_transform_publisher yaw -pi/2, pitch 0, roll pi/2 (base_link -> imu_link)
    expected = Rotation.from_euler("ZYX", [-math.pi / 2, 0.0, math.pi / 2]).as_matrix()
    assert np.allclose(IMU_TO_BASE, expected, atol=1e-12)
    assert np.allclose(IMU_TO_BASE @ IMU_TO_BASE.T, np.eye(3)) and np.linalg.det(IMU_TO_BASE) == 1


def test_side_speeds_invert_the_controller() -> None:
    v = np.array([1.0, 0.5, 0.0, -0.3])
    w = np.array([0.2, -0.4, 0.5, 0.0])
    left, right = side_speeds_m_s(v, w, EFFECTIVE_SEPARATION_M)
    assert np.allclose(0.5 * (left + right), v)
    assert np.allclose((right - left) / EFFECTIVE_SEPARATION_M, w)
    assert left[2] == pytest.approx(-0.5 * 1.07025 / 2)


def test_pose_increments_invert_arcs_and_straight_lines() -> None:
    t_ns = np.array([0, 100_000_000, 200_000_000, 300_000_000], dtype=np.int64)
    # an arc of 0.1 m at 0.5 rad over the first cycle, then 0.2 m straight, then a pivot
    yaw = np.array([0.0, 0.5, 0.5, 0.7])
    r = 0.1 / 0.5
    p1 = np.array([r * math.sin(0.5), r * (1.0 - math.cos(0.5))])
    p2 = p1 + 0.2 * np.array([math.cos(0.5), math.sin(0.5)])
    pos = np.array([[0.0, 0.0], p1, p2, p2])
    t_mid, v, w = pose_increment_velocities(t_ns, pos, yaw)
    assert t_mid.tolist() == [50_000_000, 150_000_000, 250_000_000]
    assert np.allclose(v, [1.0, 2.0, 0.0], atol=1e-12)
    assert np.allclose(w, [5.0, 0.0, 2.0])


def test_bad_options() -> None:
    with pytest.raises(ConfigError, match=r"husky\.source"):
        HuskyOptions(source="cmd_vel")
    with pytest.raises(ConfigError, match="effective_separation_m"):
        HuskyOptions(effective_separation_m=0.0)


def test_missing_inputs(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ConvertError, match=r"missing folder .*nowhere"):
        convert_husky(tmp_path / "nowhere", tmp_path / "bag")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ConvertError, match=r"missing file .*test1\.bag"):
        convert_husky(tmp_path / "empty", tmp_path / "bag")
    folder = make_bag(tmp_path, skip=(FIX_TOPIC,))
    with pytest.raises(ConvertError, match="no topic /fix"):
        convert_husky(folder, tmp_path / "bag")
    (folder / "test1.bag").write_bytes(b"not a bag")
    with pytest.raises(ConvertError, match="cannot read"):
        convert_husky(folder, tmp_path / "bag")
    rc = main(["convert", "husky", str(tmp_path / "nope"), "--out", str(tmp_path / "b")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "nope" in err
    assert not (tmp_path / "bag").exists()


def test_cli_writes_the_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = make_bag(tmp_path)
    (folder / "README.md").write_text("licence text")
    out = tmp_path / "cli_bag"
    assert main(["convert", "husky", str(folder), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert (out / "SOURCE_README.md").read_text() == "licence text"
    assert "convert husky" in (out / "ATTRIBUTION.md").read_text()
    assert main(["convert", "husky", str(folder), "--out", str(out)]) == 2  # exists


@pytest.mark.skipif(not (REAL_DATA / "test1.bag").is_file(), reason="Husky test1.bag not present")
def test_real_bag(tmp_path: Path) -> None:
    bag = convert_husky(REAL_DATA, tmp_path / "bag")
    data = read_bag(bag)
    counts = {k: v.count for k, v in data.topics.items()}
    assert counts == {"/vehicle/wheel_speeds": 3951, "/imu/data": 11865, "/gnss/fix": 989}
    for stream in (data.wheel_speeds, data.imu, data.gnss):
        assert np.all(np.diff(stream.t_ns) > 0)
    ws = data.wheel_speeds.wheel_speed_rad_s
    assert np.array_equal(ws[:, 0], ws[:, 2]) and np.array_equal(ws[:, 1], ws[:, 3])
    checks = yaml.safe_load((bag / "conversion.yaml").read_text())["checks"]
    # b_eff reconstructs whole-millimetre side travels (the MCU's resolution) in every cycle
    assert checks["side_travel_whole_mm_fraction"] == 1.0
    # the twist is the 10-cycle rolling mean of the pose increments
    assert checks["twist_minus_10_cycle_mean_of_pose_increments"]["speed_rms_m_s"] < 0.005
    assert 0.95 < checks["gyro_z_vs_odometry_yaw_rate"]["gain"] < 1.02
    assert checks["gyro_z_vs_odometry_yaw_rate"]["corr"] > 0.8
    assert checks["accel_y_vs_speed_times_yaw_rate"]["gain"] > 0.5
    assert checks["accel_x_vs_speed_derivative"]["gain"] > 0.3
    assert 9.7 < checks["accel_at_standstill_m_s2"][2] < 9.9  # +g on base_link z
    assert 350.0 < checks["distance_m"] < 370.0
    assert checks["gnss_horizontal_std_m"][1] == pytest.approx(0.8)
