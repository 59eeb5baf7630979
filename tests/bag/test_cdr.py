"""Bulk CDR encoder/decoder against rosbags' own serializer and deserializer."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.bag import cdr
from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag.typestore import get_typestore


def _deflation(n_wheels: int, t_ns: int = 5) -> object:
    types = get_typestore().types
    wheel = types[tp.WHEEL_DEFLATION]
    wheels = [
        wheel(
            wheel_name=f"wheel_{k}ä",
            level=k % 4,
            radius_change_m=0.001 * k,
            cusum=0.5 + k,
            threshold=0.25,
            alarm=bool(k % 2),
            alarm_time_s=1.5 * k,
        )
        for k in range(n_wheels)
    ]
    return types[tp.DEFLATION_STATUS](
        header=mb.header(t_ns, "base_link"),
        calibration_state=2,
        calibration_progress=0.75,
        calibrated_driving_time_s=123.5,
        wheels=wheels,
        any_alarm=n_wheels > 1,
    )


def _samples() -> list[tuple[str, object]]:
    rng = np.random.default_rng(3)
    types = get_typestore().types
    lateral = types[tp.LATERAL_STATE](
        header=mb.header(9, "base_link"),
        source="stiffness_mpf",
        longitudinal_velocity_m_s=20.0,
        lateral_velocity_m_s=-0.3,
        yaw_rate_rad_s=0.1,
        sideslip_rad=-0.015,
        covariance=rng.normal(size=9),
        axle_lateral_force_n=np.array([1000.0, -2000.0]),
        linearity=1,
    )
    return [
        (tp.JOINT_STATE, mb.joint_state(1_700_000_000_999_999_999, ["a", "bb"], velocity=[1, 2])),
        (tp.JOINT_STATE, mb.joint_state(3, [], frame_id="")),
        (tp.JOINT_STATE, mb.joint_state(3, ["x"], position=[0.5], effort=[2.0])),
        (tp.IMU, mb.imu(5, rng.normal(size=3), rng.normal(size=3), gyro_std_rad_s=0.1)),
        (tp.NAV_SAT_FIX, mb.nav_sat_fix(5, 48.1, 11.5, 500.0, rng.normal(size=9))),
        (
            tp.ODOMETRY,
            mb.odometry(
                7,
                rng.normal(size=3),
                mb.yaw_to_quaternion(0.3),
                rng.normal(size=3),
                rng.normal(size=3),
                pose_covariance=rng.normal(size=36),
            ),
        ),
        (
            tp.TWIST_WITH_COVARIANCE_STAMPED,
            mb.twist_with_covariance_stamped(5, [1, 2, 3], np.eye(3)),
        ),
        (
            tp.TIRE_FORCES,
            mb.tire_forces(5, ["wheel_fl", "wheel_rr"], [1, 2], [3, 4], [5, 6], [True, False]),
        ),
        (tp.DEFLATION_STATUS, _deflation(0)),
        (tp.DEFLATION_STATUS, _deflation(3)),
        (tp.LATERAL_STATE, lateral),
    ]


def _assert_flat_equal(a: dict, b: dict) -> None:
    assert set(a) == set(b)
    for key, value in a.items():
        if isinstance(value, (str, tuple)):
            assert value == b[key], key
        else:
            assert np.asarray(value).dtype == np.asarray(b[key]).dtype, key
            np.testing.assert_array_equal(value, b[key], err_msg=key)


def _batch_row(batches: list[cdr.Batch], i: int) -> dict:
    for b in batches:
        hit = np.flatnonzero(b.index == i)
        if hit.size:
            row = {k: v[hit[0]] for k, v in b.arrays.items()}
            row.update(b.strings)
            return row
    raise AssertionError(f"message {i} missing from batches")


@pytest.mark.parametrize("case", range(11))
def test_walk_matches_rosbags_on_every_field(case: int) -> None:
    store = get_typestore()
    msgtype, msg = _samples()[case]
    raw = bytes(store.serialize_cdr(msg, msgtype))
    batches = cdr.decode(store, msgtype, [raw, raw])
    assert [b.fast for b in batches] == [True]
    generic = cdr.flatten(store, msgtype, store.deserialize_cdr(raw, msgtype))
    _assert_flat_equal(_batch_row(batches, 1), generic)


@pytest.mark.parametrize("case", range(11))
def test_encoder_is_byte_identical_to_rosbags(case: int) -> None:
    store = get_typestore()
    msgtype, msg = _samples()[case]
    raw = bytes(store.serialize_cdr(msg, msgtype))
    rows = cdr.Encoder(store, msgtype, msg).encode(2, {})
    assert rows[1].tobytes() == raw


def test_encoder_values_land_in_the_right_fields() -> None:
    store = get_typestore()
    template = mb.imu(0, [0, 0, 0], [0, 0, 0], gyro_std_rad_s=0.01)
    rows = cdr.Encoder(store, tp.IMU, template).encode(
        2,
        {
            "header.stamp.sec": [1, 2],
            "header.stamp.nanosec": [3, 999_999_999],
            "angular_velocity.y": [0.25, -0.5],
            "linear_acceleration.z": 9.81,
        },
    )
    msg = store.deserialize_cdr(rows[1].tobytes(), tp.IMU)
    assert mb.stamp_to_ns(msg.header.stamp) == 2_999_999_999
    assert msg.angular_velocity.y == -0.5
    assert msg.linear_acceleration.z == 9.81
    assert msg.angular_velocity_covariance[4] == pytest.approx(1e-4)
    with pytest.raises(KeyError):
        cdr.Encoder(store, tp.IMU, template).encode(1, {"no_such.field": 1.0})


def test_mixed_layouts_and_big_endian_fall_back_and_agree() -> None:
    store = get_typestore()
    msgs = [
        mb.joint_state(1, ["wheel_fl", "wheel_fr"], velocity=[1.0, 2.0]),
        mb.joint_state(2, ["wheel_fr", "wheel_fl"], velocity=[3.0, 4.0]),  # same length
        mb.joint_state(3, ["wheel_fl", "wheel_fr", "x"], velocity=[5.0, 6.0, 7.0]),
        mb.joint_state(4, ["wheel_fl", "wheel_fr"], velocity=[8.0, 9.0]),
    ]
    raws = [bytes(store.serialize_cdr(m, tp.JOINT_STATE)) for m in msgs]
    raws.append(bytes(store.serialize_cdr(msgs[0], tp.JOINT_STATE, little_endian=False)))
    fast = cdr.decode(store, tp.JOINT_STATE, raws)
    generic = cdr.decode(store, tp.JOINT_STATE, raws, fast=False)
    assert sorted(np.concatenate([b.index for b in fast]).tolist()) == [0, 1, 2, 3, 4]
    assert [b.fast for b in fast].count(False) == 1  # only the big-endian one
    for i in range(len(raws)):
        _assert_flat_equal(_batch_row(fast, i), _batch_row(generic, i))
    assert _batch_row(fast, 1)["name"] == ("wheel_fr", "wheel_fl")
    np.testing.assert_array_equal(_batch_row(fast, 3)["velocity"], [8.0, 9.0])


def test_undecodable_message_raises_bag_error() -> None:
    from tire_estimation.errors import BagError

    store = get_typestore()
    raw = bytes(store.serialize_cdr(mb.joint_state(1, ["a"], velocity=[1.0]), tp.JOINT_STATE))
    with pytest.raises(BagError, match="JointState"):
        cdr.decode(store, tp.JOINT_STATE, [raw[:-9]])
