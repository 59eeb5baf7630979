"""Revs 250 LM converter: a synthetic export in the text layout, plus the real data."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader

from tire_estimation.bag.reader import read_bag
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.convert.common import ConvertError
from tire_estimation.convert.revs250lm import (
    LATERAL_NAMES,
    REFERENCE_LATERAL,
    VEHICLE_VELOCITY,
    convert_revs250lm,
)

REAL_DATA = Path("/work/shared/data/revs_250lm")


def make_export(root: Path, n: int = 300, yaw_rate: float = 0.3) -> Path:
    """A steady left turn at 20 m/s with 0.5 m/s lateral velocity at the CG."""
    d = root / "revs"
    d.mkdir()
    t = 150.0 + 0.01 * np.arange(n)
    vx, vy = np.full(n, 20.0), np.full(n, 0.5)
    cols = {
        "t": t,
        "vx": vx,
        "vy": vy,
        "yawRate": np.full(n, yaw_rate),
        "axCG": np.full(n, 0.4),
        "ayCG": vx * yaw_rate,
        "delta": np.full(n, 0.05),
        "beta_true": np.arctan(vy / vx),
    }
    for name, arr in cols.items():
        np.savetxt(d / f"{name}.txt", arr)
    return d


def test_signs_and_topics(tmp_path: Path) -> None:
    bag = convert_revs250lm(make_export(tmp_path), tmp_path / "bag")
    data = read_bag(bag)
    assert set(data.topics) == {
        "/vehicle/steering",
        "/imu/data",
        VEHICLE_VELOCITY,
        "/reference/odometry",
        REFERENCE_LATERAL,
    }
    assert data.wheel_speeds is None and data.gnss is None
    assert np.allclose(data.steering.angle_rad, 0.05)
    assert np.allclose(data.imu.angular_velocity_rad_s, [0.0, 0.0, 0.3])
    assert np.allclose(data.imu.linear_acceleration_m_s2, [0.4, 6.0, 9.80665])
    ref = data.reference_odometry
    lr = data.vehicle.cg_to_rear_axle_m
    assert np.allclose(ref.linear_velocity_m_s, [20.0, 0.5 - lr * 0.3, 0.0])
    assert np.allclose(ref.angular_velocity_rad_s[:, 2], 0.3)
    assert np.allclose(ref.position_m[0], 0.0) and np.all(np.diff(ref.yaw_rad) > 0)
    assert ref.pose_covariance[0, 0, 0] >= 1e6  # dead-reckoned pose marked unmeasured
    assert data.start_ns == 150_000_000_000 and np.all(np.diff(ref.t_ns) == 10_000_000)


def test_velocity_input_and_lateral_reference(tmp_path: Path) -> None:
    bag = convert_revs250lm(make_export(tmp_path), tmp_path / "bag")
    store = get_typestore()
    with Reader(bag) as reader:
        conns = {c.topic: c for c in reader.connections}
        msgs = {}
        for conn, _, raw in reader.messages(
            connections=[conns[VEHICLE_VELOCITY], conns[REFERENCE_LATERAL]]
        ):
            msgs.setdefault(conn.topic, store.deserialize_cdr(raw, conn.msgtype))
    vel = msgs[VEHICLE_VELOCITY]
    assert vel.header.frame_id == "base_link"
    assert vel.twist.twist.linear.x == 20.0
    assert vel.twist.covariance[7] >= 1e4  # lateral not an input
    lat = msgs[REFERENCE_LATERAL]
    assert tuple(lat.name) == LATERAL_NAMES
    assert lat.position[:2].tolist() == [20.0, 0.5]
    assert lat.position[2] == pytest.approx(math.atan2(0.5, 20.0))


def test_missing_file_and_folder(tmp_path: Path) -> None:
    d = make_export(tmp_path)
    (d / "delta.txt").unlink()
    with pytest.raises(ConvertError, match=r"missing file .*delta\.txt"):
        convert_revs250lm(d, tmp_path / "bag")
    with pytest.raises(ConvertError, match=r"missing folder .*nowhere"):
        convert_revs250lm(tmp_path / "nowhere", tmp_path / "bag")


@pytest.mark.skipif(not REAL_DATA.is_dir(), reason="Revs 250 LM export not present")
def test_real_export(tmp_path: Path) -> None:
    bag = convert_revs250lm(REAL_DATA, tmp_path / "bag")
    data = read_bag(bag)
    assert all(info.count == 55001 for info in data.topics.values())
    assert np.all(np.diff(data.imu.t_ns) > 0)
    info = yaml.safe_load((bag / "conversion.yaml").read_text())["checks"]
    assert info["max_abs_beta_true_minus_atan2_vy_vx_rad"] < 1e-6
    assert abs(info["ay_minus_dvy_dt_plus_vx_r_mean_m_s2"]) < 0.1
    assert info["corr_delta_yaw_rate"] > 0.9
    assert (bag / "LICENSE-of-source-repo").is_file()
