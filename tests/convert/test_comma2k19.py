"""comma2k19 converter: synthetic segments in the on-disk layout, plus the real segment."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest
import yaml
from scipy.spatial.transform import Rotation

from tire_estimation.bag.reader import read_bag
from tire_estimation.cli import main
from tire_estimation.convert.comma2k19 import (
    RAV4_NOMINAL_RADIUS_M,
    Comma2k19Options,
    convert_comma2k19,
    tire_radius_m,
)
from tire_estimation.convert.common import ConvertError
from tire_estimation.errors import TireEstimationError

REAL_SEGMENT = Path("/work/shared/data/comma2k19/rav4_2018-08-02--08-34-47_seg40")
LAT0, LON0, ALT0 = 37.7, -122.47, 30.0
#: No lever arm: the device sits at the base_link origin in the synthetic segments.
OPTS = Comma2k19Options(device_position_m=(0.0, 0.0, 0.0))


def _save(root: Path, folder: str, t: np.ndarray, value: np.ndarray) -> None:
    d = root / folder
    d.mkdir(parents=True, exist_ok=True)
    for name, arr in (("t", t), ("value", value)):
        with (d / name).open("wb") as fh:  # no extension, like the dataset
            np.save(fh, arr)


def make_segment(
    root: Path,
    *,
    heading_deg: float = 30.0,
    speed: float = 10.0,
    accel_fwd: float = 0.0,
    yaw_rate: float = 0.0,
    steer_deg: float = 0.0,
    mount_yaw_deg: float = 0.0,
    mount_pitch_deg: float = 0.0,
    duration: float = 4.0,
) -> Path:
    """A straight (or turning) drive on level ground; device axes [forward, right, down]."""
    seg = root / "seg"
    t0 = 1000.0
    # device attitude relative to the vehicle: yaw left by mount_yaw, pitch down by mount_pitch
    r_veh_dev_flu = Rotation.from_euler(
        "zy", [mount_yaw_deg, mount_pitch_deg], degrees=True
    ).as_matrix()
    frd = np.diag([1.0, -1.0, -1.0])
    r_veh_dev = r_veh_dev_flu @ frd  # device FRD -> vehicle FLU

    tp_ = t0 + np.arange(0.0, duration, 0.05)
    s = tp_ - t0
    yaw = math.radians(90.0 - heading_deg) + yaw_rate * s
    v = speed + accel_fwd * s
    dist = speed * s + 0.5 * accel_fwd * s**2
    if yaw_rate == 0.0:
        east = dist * math.cos(yaw[0])
        north = dist * math.sin(yaw[0])
    else:  # integrate numerically
        ve, vn = v * np.cos(yaw), v * np.sin(yaw)
        east = np.r_[0, np.cumsum(0.5 * (ve[1:] + ve[:-1]) * np.diff(s))]
        north = np.r_[0, np.cumsum(0.5 * (vn[1:] + vn[:-1]) * np.diff(s))]
    x, y, z = pymap3d.enu2ecef(east, north, np.zeros_like(s), LAT0, LON0, ALT0)
    ve, vn = v * np.cos(yaw), v * np.sin(yaw)
    vx, vy, vz = pymap3d.enu2uvw(ve, vn, np.zeros_like(s), LAT0, LON0)
    la, lo = math.radians(LAT0), math.radians(LON0)
    r_enu_ecef = np.array(
        [
            [-math.sin(lo), math.cos(lo), 0.0],
            [-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la)],
            [math.cos(la) * math.cos(lo), math.cos(la) * math.sin(lo), math.sin(la)],
        ]
    )
    r_enu_veh = Rotation.from_euler("z", yaw[:, None]).as_matrix()
    r_ecef_dev = r_enu_ecef.T @ r_enu_veh @ r_veh_dev
    q = Rotation.from_matrix(r_ecef_dev).as_quat()[:, [3, 0, 1, 2]]  # w, x, y, z
    (seg / "global_pose").mkdir(parents=True)
    for name, arr in (
        ("frame_times", tp_),
        ("frame_positions", np.column_stack([x, y, z])),
        ("frame_velocities", np.column_stack([vx, vy, vz])),
        ("frame_orientations", q),
    ):
        with (seg / "global_pose" / name).open("wb") as fh:
            np.save(fh, arr)

    tc = t0 + np.arange(0.0, duration, 0.01)
    sc = tc - t0
    vc = speed + accel_fwd * sc
    wheels = np.column_stack([vc, vc * 1.01, vc * 0.99, vc * 1.02])  # distinct per wheel
    _save(seg, "processed_log/CAN/wheel_speed", tc, wheels)
    _save(seg, "processed_log/CAN/steering_angle", tc, np.full(len(tc), steer_deg))
    # specific force and rate in vehicle FLU, then to device FRD
    f_veh = np.column_stack([np.full(len(tc), accel_fwd), vc * yaw_rate, np.full(len(tc), 9.81)])
    w_veh = np.column_stack([np.zeros((len(tc), 2)), np.full(len(tc), yaw_rate)])
    _save(seg, "processed_log/IMU/accelerometer", tc, f_veh @ r_veh_dev)
    _save(seg, "processed_log/IMU/gyro", tc, w_veh @ r_veh_dev)

    tg = t0 + np.arange(0.05, duration, 0.1)
    sg = tg - t0
    eg, ng = np.interp(sg, s, east), np.interp(sg, s, north)
    lat, lon, alt = pymap3d.enu2geodetic(eg, ng, np.zeros_like(sg), LAT0, LON0, ALT0)
    gnss = np.column_stack(
        [
            lat,
            lon,
            np.interp(sg, s, v),
            (1.5e9 + sg) * 1e3,
            alt,
            np.full(len(tg), heading_deg),
        ]
    )
    _save(seg, "processed_log/GNSS/live_gnss_ublox", tg, gnss)
    return seg


def test_tire_radius_of_rav4_size() -> None:
    unloaded, rolling = tire_radius_m(225, 65, 17)
    assert unloaded == pytest.approx(0.5 * (17 * 0.0254 + 2 * 0.225 * 0.65))
    assert rolling == pytest.approx(3.05 * 2 * unloaded / (2 * math.pi))
    assert abs(RAV4_NOMINAL_RADIUS_M - 0.3516) < 1e-4


def test_forward_acceleration_and_axes(tmp_path: Path) -> None:
    seg = make_segment(tmp_path, accel_fwd=1.5, steer_deg=29.0)
    bag = convert_comma2k19(seg, tmp_path / "bag", options=OPTS)
    data = read_bag(bag)
    acc = data.imu.linear_acceleration_m_s2
    assert np.allclose(acc.mean(axis=0), [1.5, 0.0, 9.81], atol=1e-6)  # forward, left, up
    # wheel names: columns fl, fr, rl, rr of the CAN array, divided by the nominal radius
    ws = data.wheel_speeds.wheel_speed_rad_s
    v0 = 10.0
    assert np.allclose(ws[0] * RAV4_NOMINAL_RADIUS_M, [v0, 1.01 * v0, 0.99 * v0, 1.02 * v0])
    assert data.steering.angle_rad[0] == pytest.approx(math.radians(29.0) / 14.5)
    ref = data.reference_odometry
    assert np.allclose(ref.position_m[0], 0.0, atol=1e-9)
    assert np.allclose(ref.yaw_rad, math.radians(60.0), atol=1e-6)  # heading 30 deg -> ENU 60
    assert np.allclose(ref.linear_velocity_m_s[:, 1:], 0.0, atol=1e-6)
    assert np.allclose(np.diff(ref.linear_velocity_m_s[:, 0]), 1.5 * 0.05, atol=1e-6)


def test_left_turn_signs(tmp_path: Path) -> None:
    seg = make_segment(tmp_path, yaw_rate=0.2, steer_deg=45.0)
    data = read_bag(convert_comma2k19(seg, tmp_path / "bag", options=OPTS))
    gyro = data.imu.angular_velocity_rad_s
    acc = data.imu.linear_acceleration_m_s2
    assert np.allclose(gyro[:, 2], 0.2, atol=1e-9)  # counter-clockwise seen from above
    assert np.all(acc[:, 1] > 1.9)  # centripetal: towards the left (+y)
    assert np.all(data.steering.angle_rad > 0)
    ref = data.reference_odometry
    assert np.allclose(ref.angular_velocity_rad_s[:, 2], 0.2, atol=1e-3)
    assert np.all(np.diff(ref.yaw_rad) > 0)


def test_mounting_rotation_is_removed(tmp_path: Path) -> None:
    seg = make_segment(tmp_path, accel_fwd=1.0, mount_yaw_deg=2.0, mount_pitch_deg=4.0)
    bag = convert_comma2k19(seg, tmp_path / "bag", options=OPTS)
    data = read_bag(bag)
    assert np.allclose(data.imu.linear_acceleration_m_s2, [1.0, 0.0, 9.81], atol=1e-6)
    assert np.allclose(data.reference_odometry.linear_velocity_m_s[:, 1:], 0.0, atol=1e-6)
    mount = yaml.safe_load((bag / "conversion.yaml").read_text())["device_mount"]
    assert mount["yaw_deg"] == pytest.approx(2.0, abs=1e-6)
    assert mount["pitch_deg"] == pytest.approx(4.0, abs=1e-6)


def test_gnss_fix_and_velocity(tmp_path: Path) -> None:
    seg = make_segment(tmp_path, heading_deg=30.0)
    data = read_bag(convert_comma2k19(seg, tmp_path / "bag", options=OPTS))
    g = data.gnss
    raw = np.load(seg / "processed_log/GNSS/live_gnss_ublox/value")
    t_raw = np.load(seg / "processed_log/GNSS/live_gnss_ublox/t")
    assert np.array_equal(g.t_ns, np.rint(t_raw * 1e9).astype(np.int64))
    assert np.allclose(g.lat_deg, raw[:, 0]) and np.allclose(g.lon_deg, raw[:, 1])
    assert np.allclose(g.alt_m, raw[:, 4])
    assert np.allclose(g.position_covariance_m2[0], np.diag([1.5**2, 1.5**2, 3.0**2]))
    # bearing 30 deg clockwise from north: east = v sin 30, north = v cos 30
    assert np.allclose(g.velocity_enu_m_s[0, :2], [5.0, 10.0 * math.cos(math.radians(30))])


def test_reference_origin_recorded(tmp_path: Path) -> None:
    seg = make_segment(tmp_path)
    lever = Comma2k19Options(device_position_m=(1.5, 0.0, 1.2))
    bag = convert_comma2k19(seg, tmp_path / "bag", options=lever)
    info = yaml.safe_load((bag / "conversion.yaml").read_text())
    origin = info["reference_origin"]
    # base_link is 1.5 m behind and 1.2 m below the device (heading 30 deg from north)
    e, n, u = pymap3d.geodetic2enu(
        origin["lat_deg"], origin["lon_deg"], origin["alt_m"], LAT0, LON0, ALT0
    )
    assert [e, n, u] == pytest.approx(
        [-1.5 * math.sin(math.radians(30)), -1.5 * math.cos(math.radians(30)), -1.2], abs=1e-3
    )
    data = read_bag(bag)
    assert np.allclose(data.reference_odometry.position_m[0], 0.0, atol=1e-9)
    custom = yaml.safe_load(data.custom_data["tire_estimation.reference_origin_lla"])
    assert custom == pytest.approx([origin["lat_deg"], origin["lon_deg"], origin["alt_m"]])


def test_missing_folder_is_one_line_error(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    seg = make_segment(tmp_path)
    for name in ("t", "value"):
        (seg / "processed_log/CAN/steering_angle" / name).unlink()
    (seg / "processed_log/CAN/steering_angle").rmdir()
    with pytest.raises(ConvertError, match=r"missing folder .*steering_angle"):
        convert_comma2k19(seg, tmp_path / "bag")
    assert issubclass(ConvertError, TireEstimationError)
    rc = main(["convert", "comma2k19", str(tmp_path / "nope"), "--out", str(tmp_path / "b")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "nope" in err
    assert not (tmp_path / "bag").exists()


@pytest.mark.skipif(not REAL_SEGMENT.is_dir(), reason="comma2k19 example segment not present")
def test_real_segment(tmp_path: Path) -> None:
    bag = convert_comma2k19(REAL_SEGMENT, tmp_path / "bag")
    data = read_bag(bag)
    counts = {k: v.count for k, v in data.topics.items()}
    assert counts == {
        "/vehicle/wheel_speeds": 4974,
        "/vehicle/steering": 4974,
        "/imu/data": 6256,
        "/gnss/fix": 579,
        "/gnss/velocity": 579,
        "/reference/odometry": 1200,
    }
    for stream in (data.wheel_speeds, data.steering, data.imu, data.gnss):
        assert np.all(np.diff(stream.t_ns) > 0)
    ref = data.reference_odometry
    assert np.all(np.diff(ref.t_ns) > 0)
    assert np.allclose(ref.position_m[0], 0.0, atol=1e-6)
    vx = np.interp(data.wheel_speeds.t_ns, ref.t_ns, ref.linear_velocity_m_s[:, 0])
    ratio = data.wheel_speeds.wheel_speed_rad_s * data.vehicle.nominal_tire_radius_m / vx[:, None]
    assert np.all(np.abs(np.median(ratio, axis=0) - 1.0) < 0.03)
    acc = data.imu.linear_acceleration_m_s2
    assert 9.5 < acc[:, 2].mean() < 9.9  # +g on z in base_link
    assert abs(acc[:, 0].mean()) < 0.2  # mounting pitch removed (about -0.6 without)
    assert np.abs(ref.linear_velocity_m_s[:, 1]).max() < 0.2  # no sideslip on the highway
    # steering positive to the left <-> yaw rate positive (left)
    yaw_rate = np.interp(data.steering.t_ns, data.imu.t_ns, data.imu.angular_velocity_rad_s[:, 2])
    assert np.corrcoef(data.steering.angle_rad, yaw_rate)[0, 1] > 0.3
    assert (bag / "LICENSE").is_file() and (bag / "ATTRIBUTION.md").is_file()


def test_lever_arm_moves_twist_to_base_link(tmp_path: Path) -> None:
    # the synthetic device has no lateral velocity; the rear axle 1.5 m behind it in a left
    # turn at 0.2 rad/s moves to the right at 0.3 m/s
    seg = make_segment(tmp_path, yaw_rate=0.2)
    lever = Comma2k19Options(device_position_m=(1.5, 0.0, 0.0))
    data = read_bag(convert_comma2k19(seg, tmp_path / "bag", options=lever))
    vy = data.reference_odometry.linear_velocity_m_s[:, 1]
    assert np.allclose(vy, -0.3, atol=2e-3)
