"""Type store (custom messages) and message helpers."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag import typestore
from tire_estimation.errors import BagError

CUSTOM = [
    tp.TIRE_RADII,
    tp.TIRE_STIFFNESS,
    tp.DEFLATION_STATUS,
    tp.WHEEL_DEFLATION,
    tp.TIRE_FORCES,
    tp.LATERAL_STATE,
]


def test_custom_types_registered_with_hash() -> None:
    store = typestore.get_typestore()
    assert typestore.get_typestore() is store
    for name in CUSTOM:
        assert name in store.types
        assert store.hash_rihs01(name).startswith("RIHS01_")
    fields = dict(store.fielddefs[tp.DEFLATION_STATUS][1])
    assert fields["wheels"][1][0][1] == tp.WHEEL_DEFLATION
    msgdef, _ = store.generate_msgdef(tp.DEFLATION_STATUS, ros_version=2)
    assert "MSG: tire_estimation_msgs/WheelDeflation" in msgdef


def test_msg_dir_prefers_ament_prefix_path(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    share = tmp_path / "share" / "tire_estimation_msgs" / "msg"
    shutil.copytree(typestore.find_msg_dir(), share)
    monkeypatch.setenv("AMENT_PREFIX_PATH", f"/nonexistent:{tmp_path}")
    assert typestore.find_msg_dir() == share


def test_msg_dir_missing_is_bag_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(tmp_path))
    monkeypatch.setattr(typestore, "__file__", str(tmp_path / "a" / "b" / "c" / "typestore.py"))
    with pytest.raises(BagError, match="tire_estimation_msgs"):
        typestore.find_msg_dir()


@pytest.mark.parametrize("t_ns", [0, 1, 999_999_999, 1_000_000_000, 1_700_000_000_123_456_789, -1])
def test_stamp_round_trip(t_ns: int) -> None:
    stamp = mb.ns_to_stamp(t_ns)
    assert 0 <= stamp.nanosec < 1_000_000_000
    assert mb.stamp_to_ns(stamp) == t_ns


def test_yaw_quaternion() -> None:
    x, y, z, w = mb.yaw_to_quaternion(math.pi / 2)
    assert (x, y) == (0.0, 0.0)
    assert z == pytest.approx(math.sqrt(0.5)) and w == pytest.approx(math.sqrt(0.5))


def test_imu_builder_covariances() -> None:
    msg = mb.imu(5, [1, 2, 3], [4, 5, 6], gyro_std_rad_s=0.1, accel_std_m_s2=0.2)
    assert msg.orientation_covariance[0] == -1.0
    np.testing.assert_allclose(msg.angular_velocity_covariance.reshape(3, 3), np.eye(3) * 0.01)
    np.testing.assert_allclose(msg.linear_acceleration_covariance.reshape(3, 3), np.eye(3) * 0.04)
    assert msg.header.frame_id == "base_link"


def test_bag_typestore_from_the_bags_schemas(bag: Path) -> None:
    from tire_estimation.bag.mcap_raw import read_mcap

    raw = read_mcap(bag / f"{bag.name}.mcap", tp.TOPIC_TYPES)
    schemas = tuple(sorted({(m.msgtype, *m.schema) for m in raw.values()}))
    assert {enc for _, enc, _ in schemas} == {"ros2msg"}
    store = typestore.bag_typestore(schemas)
    full = typestore.get_typestore()
    assert store is not full
    for name, _, _ in schemas:  # same definitions as the Jazzy store, dependencies included
        assert store.fielddefs[name] == full.fielddefs[name]
        assert store.hash_rihs01(name) == full.hash_rihs01(name)
    assert typestore.bag_typestore(schemas) is store  # cached


@pytest.mark.parametrize(
    "schemas",
    [
        (),
        (("sensor_msgs/msg/Imu", "ros2idl", "module sensor_msgs { };"),),
        (("sensor_msgs/msg/Imu", "ros2msg", ""),),
        (("sensor_msgs/msg/Imu", "ros2msg", "this is not a message definition ]["),),
        (("sensor_msgs/msg/Imu", "ros2msg", "std_msgs/Header header\nfloat64 x"),),  # no Header
    ],
)
def test_bag_typestore_falls_back_to_the_full_store(
    schemas: tuple[tuple[str, str, str], ...],
) -> None:
    assert typestore.bag_typestore(schemas) is typestore.get_typestore()
