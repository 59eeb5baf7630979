"""read_bag: round trip, name matching, fast vs generic, metadata and errors."""

from __future__ import annotations

import shutil
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from tests.bag.synthetic import START_NS, make_result
from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag.reader import BagData, TopicInfo, read_bag
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.bag.writer import sim_topic_series
from tire_estimation.core.vehicle import VehicleParams, dump_vehicle_yaml
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import BagError, VehicleConfigError
from tire_estimation.sim.streams import SimResult


@pytest.fixture(scope="module")
def data(bag: Path) -> BagData:
    return read_bag(bag)


def _eq(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape
    np.testing.assert_array_equal(a, b)


def test_input_streams_round_trip_exactly(data: BagData, result: SimResult) -> None:
    assert data.wheel_speeds is not None and data.steering is not None and data.imu is not None
    _eq(data.wheel_speeds.t_ns, result.wheel_speeds.t_ns)
    _eq(data.wheel_speeds.wheel_speed_rad_s, result.wheel_speeds.wheel_speed_rad_s)
    _eq(data.steering.t_ns, result.steering.t_ns)
    _eq(data.steering.angle_rad, result.steering.angle_rad)
    _eq(data.imu.t_ns, result.imu.t_ns)
    _eq(data.imu.angular_velocity_rad_s, result.imu.angular_velocity_rad_s)
    _eq(data.imu.linear_acceleration_m_s2, result.imu.linear_acceleration_m_s2)
    assert data.imu.gyro_noise_std_rad_s == pytest.approx(0.002, rel=1e-12)
    assert data.imu.accel_noise_std_m_s2 == pytest.approx(0.05, rel=1e-12)
    g, rg = data.gnss, result.gnss
    assert g is not None
    for name in ("t_ns", "lat_deg", "lon_deg", "alt_m", "position_covariance_m2"):
        _eq(getattr(g, name), getattr(rg, name))
    _eq(g.velocity_enu_m_s, rg.velocity_enu_m_s)
    _eq(g.velocity_covariance_m2_s2, rg.velocity_covariance_m2_s2)
    f, rf = data.tire_forces, result.tire_forces
    assert f is not None and rf is not None
    for name in ("t_ns", "fx_n", "fy_n", "fz_n", "valid"):
        _eq(getattr(f, name), getattr(rf, name))
    assert data.notes == ()


def test_truth_round_trip(data: BagData, result: SimResult) -> None:
    tr = result.truth
    fix = data.truth_fix
    assert fix is not None
    _eq(fix.t_ns, tr.t_ns)
    _eq(fix.lat_deg, tr.lat_deg)
    _eq(fix.alt_m, tr.alt_m)
    odo = data.truth_odometry
    assert odo is not None
    assert (odo.frame_id, odo.child_frame_id) == ("map", "base_link")
    _eq(odo.t_ns, tr.t_ns)
    _eq(odo.position_m, tr.position_enu_m)
    _eq(odo.linear_velocity_m_s[:, :2], tr.velocity_m_s)
    _eq(odo.angular_velocity_rad_s[:, 2], tr.yaw_rate_rad_s)
    np.testing.assert_allclose(odo.yaw_rad, tr.yaw_rad, atol=1e-12)
    radii = data.truth_wheel_radii
    assert radii is not None and radii.names == WHEELS
    rows = np.searchsorted(tr.t_ns, radii.t_ns)
    _eq(tr.t_ns[rows], radii.t_ns)
    _eq(radii.values, tr.wheel_radius_m[rows])
    stiff = data.truth_stiffness
    assert stiff is not None and stiff.names == tp.TRUTH_STIFFNESS_NAMES
    _eq(stiff.values[0, :3], tr.stiffness[0])
    # this truth has no rear-axle Cx: read as NaN (not scored)
    assert tr.cx_rear_n is None and np.isnan(stiff.values[:, 3]).all()
    pressure = data.truth_tire_pressure
    assert pressure is not None
    assert pressure.values[-1, 2] == 150_000.0 and pressure.values[0, 2] == 230_000.0


def test_metadata(data: BagData, bag: Path, result: SimResult) -> None:
    assert data.path == bag
    assert data.vehicle == result.vehicle
    assert data.start_ns == min(result.wheel_speeds.t_ns[0], result.truth.t_ns[0]) >= START_NS
    last = max(
        result.wheel_speeds.t_ns[-1],
        result.imu.t_ns[-1],
        result.steering.t_ns[-1],
        result.truth.t_ns[-1],
    )
    assert data.duration_s == pytest.approx((last - data.start_ns) * 1e-9, abs=1e-9)
    assert data.events == result.events
    assert (data.scenario, data.seed) == ("synthetic", 1)
    assert data.topics[tp.WHEEL_SPEEDS].count == len(result.wheel_speeds.t_ns)
    assert data.topics[tp.IMU_DATA].msgtype == tp.IMU
    assert data.reference_odometry is None
    assert data.t_s(np.array([data.start_ns + 1_500_000_000]))[0] == pytest.approx(1.5)


def test_fast_and_generic_reading_agree(bag: Path, data: BagData) -> None:
    generic = read_bag(bag, fast=False)
    for name in (
        "wheel_speeds",
        "steering",
        "imu",
        "gnss",
        "tire_forces",
        "truth_fix",
        "truth_odometry",
        "truth_wheel_radii",
        "truth_tire_pressure",
        "truth_stiffness",
    ):
        a, b = getattr(data, name), getattr(generic, name)
        for field in a.__dataclass_fields__:
            va, vb = getattr(a, field), getattr(b, field)
            if isinstance(va, np.ndarray):
                assert va.dtype == vb.dtype, (name, field)
                np.testing.assert_array_equal(va, vb, err_msg=f"{name}.{field}")
            else:
                assert va == vb, (name, field)


def test_topic_selection(bag: Path) -> None:
    data = read_bag(bag, topics=[tp.IMU_DATA], require=[tp.IMU_DATA, tp.WHEEL_SPEEDS])
    assert data.imu is not None
    assert data.wheel_speeds is None and data.truth_odometry is None
    assert tp.WHEEL_SPEEDS in data.topics
    with pytest.raises(BagError, match="cannot decode topic /diagnostics"):
        read_bag(bag, topics=["/diagnostics"])


def _write_custom_bag(path: Path, messages: list[tuple[str, str, int, object]]) -> Path:
    store = get_typestore()
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns: dict[str, object] = {}
    for topic, msgtype, t_ns, msg in messages:
        if topic not in conns:
            conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
        writer.write(conns[topic], t_ns, store.serialize_cdr(msg, msgtype))
    writer.close()
    dump_vehicle_yaml(VehicleParams(), path / "vehicle.yaml")
    return path


def test_joint_state_names_permuted_unknown_and_missing(tmp_path: Path) -> None:
    ws = tp.WHEEL_SPEEDS
    js = tp.JOINT_STATE
    bag = _write_custom_bag(
        tmp_path / "perm",
        [
            (ws, js, 10, mb.joint_state(10, WHEELS, velocity=[1.0, 2.0, 3.0, 4.0])),
            (
                ws,
                js,
                20,
                mb.joint_state(
                    20,
                    ["wheel_rr", "wheel_fl", "wheel_rl", "wheel_fr"],
                    velocity=[14.0, 11.0, 13.0, 12.0],
                ),
            ),
            (
                ws,
                js,
                30,
                mb.joint_state(
                    30, ["wheel_rl", "engine", "wheel_fr"], velocity=[23.0, 999.0, 22.0]
                ),
            ),
            (ws, js, 40, mb.joint_state(40, ["wheel_fl"], position=[5.0])),  # no velocity
            (
                tp.STEERING,
                js,
                15,
                mb.joint_state(15, ["other", "front_wheel_angle"], position=[9.0, 0.1]),
            ),
        ],
    )
    for fast in (True, False):
        data = read_bag(bag, fast=fast)
        assert data.wheel_speeds is not None and data.steering is not None
        _eq(data.wheel_speeds.t_ns, np.array([10, 20, 30, 40]))
        expected = np.array(
            [
                [1.0, 2.0, 3.0, 4.0],
                [11.0, 12.0, 13.0, 14.0],
                [np.nan, 22.0, 23.0, np.nan],
                [np.nan, np.nan, np.nan, np.nan],
            ]
        )
        _eq(data.wheel_speeds.wheel_speed_rad_s, expected)
        _eq(data.steering.angle_rad, np.array([0.1]))


def test_tire_forces_subset_and_stamp_order(tmp_path: Path) -> None:
    tf = tp.TIRE_FORCES_TOPIC
    msgs = [
        (
            tf,
            tp.TIRE_FORCES,
            100,
            mb.tire_forces(200, ["wheel_rl", "wheel_rr"], [1, 2], [3, 4], [5, 6], [True, False]),
        ),
        (
            tf,
            tp.TIRE_FORCES,
            101,
            mb.tire_forces(100, WHEELS, [1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12], [True] * 4),
        ),
        (
            tf,
            tp.TIRE_FORCES,
            102,
            mb.tire_forces(100, WHEELS, [0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0], [False] * 4),
        ),
    ]
    data = read_bag(_write_custom_bag(tmp_path / "tf", msgs))
    forces = data.tire_forces
    assert forces is not None
    _eq(forces.t_ns, np.array([100, 200]))  # sorted by stamp, repeated stamp dropped
    _eq(forces.fx_n[0], np.array([1.0, 2.0, 3.0, 4.0]))
    _eq(forces.fz_n[1], np.array([np.nan, np.nan, 5.0, 6.0]))
    _eq(forces.valid, np.array([[True] * 4, [False, False, True, False]]))
    assert any("repeated header stamp" in n for n in data.notes)
    assert any("not in header-stamp order" in n for n in data.notes)


def test_sqlite3_bag_is_read_through_rosbags(tmp_path: Path) -> None:
    small = make_result(2.0, seed=4, with_forces=False, with_velocity=False)
    store = get_typestore()
    path = tmp_path / "sq"
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.SQLITE3)
    writer.open()
    for series in sim_topic_series(small):
        conn = writer.add_connection(series.topic, series.msgtype, typestore=store)
        for t, raw in zip(series.t_ns.tolist(), series.serialize(), strict=True):
            writer.write(conn, t, raw)
    writer.close()
    dump_vehicle_yaml(small.vehicle, tmp_path / "vehicle.yaml")  # next to the bag
    data = read_bag(path)
    assert data.vehicle == small.vehicle
    assert data.tire_forces is None and data.gnss is not None
    assert data.gnss.velocity_enu_m_s is None
    _eq(data.wheel_speeds.wheel_speed_rad_s, small.wheel_speeds.wheel_speed_rad_s)


# ----------------------------------------------------------------------------- errors


def test_missing_path(tmp_path: Path) -> None:
    with pytest.raises(BagError, match=r"bag not found: .*nope"):
        read_bag(tmp_path / "nope")


def test_directory_that_is_not_a_bag(tmp_path: Path) -> None:
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(BagError, match="not a rosbag2 bag"):
        read_bag(tmp_path)


def _copy(bag: Path, tmp_path: Path) -> Path:
    dst = tmp_path / bag.name
    shutil.copytree(bag, dst)
    return dst


@pytest.mark.parametrize("fast", [True, False])
def test_truncated_mcap(bag: Path, tmp_path: Path, fast: bool) -> None:
    dst = _copy(bag, tmp_path)
    mcap = dst / f"{dst.name}.mcap"
    content = mcap.read_bytes()
    mcap.write_bytes(content[: len(content) // 2])
    with pytest.raises(BagError, match="cannot read bag") as info:
        read_bag(dst, fast=fast)
    assert "\n" not in str(info.value)


def test_corrupt_chunk(bag: Path, tmp_path: Path) -> None:
    dst = _copy(bag, tmp_path)
    mcap = dst / f"{dst.name}.mcap"
    content = bytearray(mcap.read_bytes())
    mid = len(content) // 3
    content[mid : mid + 64] = b"\xff" * 64
    mcap.write_bytes(bytes(content))
    with pytest.raises(BagError, match="cannot read bag"):
        read_bag(dst)


def test_missing_required_topic(bag: Path) -> None:
    with pytest.raises(BagError, match="required topic /reference/odometry"):
        read_bag(bag, require=[tp.WHEEL_SPEEDS, tp.REFERENCE_ODOMETRY])


def test_vehicle_from_custom_data_then_missing(bag: Path, tmp_path: Path) -> None:
    dst = _copy(bag, tmp_path)
    (dst / "vehicle.yaml").unlink()
    assert read_bag(dst, topics=[]).vehicle.name == "test_car"  # metadata custom data
    meta = dst / "metadata.yaml"
    meta.write_text(meta.read_text().replace("tire_estimation.vehicle", "other.key"))
    with pytest.raises(BagError, match=r"no vehicle\.yaml"):
        read_bag(dst, topics=[])


def test_absurd_vehicle_yaml_names_the_field(bag: Path, tmp_path: Path) -> None:
    dst = _copy(bag, tmp_path)
    path = dst / "vehicle.yaml"
    path.write_text(path.read_text().replace("mass_kg: 1500.0", "mass_kg: -3.0"))
    with pytest.raises(VehicleConfigError, match=r"vehicle\.mass_kg"):
        read_bag(dst, topics=[])


def test_wrong_topic_type(tmp_path: Path) -> None:
    bag = _write_custom_bag(
        tmp_path / "wrong", [(tp.IMU_DATA, tp.JOINT_STATE, 1, mb.joint_state(1, ["a"]))]
    )
    with pytest.raises(BagError, match="/imu/data has type sensor_msgs/msg/JointState"):
        read_bag(bag)


def test_topics_chosen_from_the_bags_topic_list(bag: Path) -> None:
    seen: dict[str, int] = {}

    def choose(infos: Mapping[str, TopicInfo]) -> list[str]:
        seen.update({name: info.count for name, info in infos.items()})
        return [t for t in (tp.IMU_DATA, tp.TRUTH_ODOMETRY) if infos[t].count > 0][:1]

    data = read_bag(bag, topics=choose)
    assert seen[tp.IMU_DATA] > 0 and seen[tp.TRUTH_ODOMETRY] > 0
    assert data.imu is not None and data.imu.t_ns.size == seen[tp.IMU_DATA]
    assert data.truth_odometry is None and data.wheel_speeds is None
    with pytest.raises(BagError, match="cannot decode topic /not/a/topic"):
        read_bag(bag, topics=lambda infos: ["/not/a/topic"])


def _fix(t_ns: int, alt: float, cov: list[float], cov_type: int, status: int = 0) -> object:
    msg = mb.nav_sat_fix(t_ns, 58.4, 15.6, alt, cov, covariance_type=cov_type)
    msg.status.status = status
    return msg


def test_bad_input_messages_are_dropped_and_counted_as_the_node_does(tmp_path: Path) -> None:
    """The checks of the node's conversions: a fix with a bad covariance or without a fix is
    dropped and counted (before the repeated stamps, as the node checks each message as it
    comes); with covariance type unknown its covariance is not read; a NaN altitude is kept; a
    wheel or joint named twice, a repeated stamp and a bad velocity are dropped."""
    nan = float("nan")
    good = [2.25, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 4.0]
    known, fix, js = mb.COVARIANCE_TYPE_KNOWN, tp.NAV_SAT_FIX, tp.JOINT_STATE
    twice = [*WHEELS, "wheel_rl"]
    vel = tp.TWIST_WITH_COVARIANCE_STAMPED
    bag = _write_custom_bag(
        tmp_path / "bad",
        [
            (tp.GNSS_FIX, fix, 10, _fix(10, 80.0, good, known)),
            (tp.GNSS_FIX, fix, 11, _fix(10, 80.0, good, known)),  # repeated stamp
            (tp.GNSS_FIX, fix, 20, _fix(20, 80.0, [nan, *good[1:]], known)),
            (tp.GNSS_FIX, fix, 30, _fix(30, 80.0, [*good[:8], -4.0], known)),
            (tp.GNSS_FIX, fix, 40, _fix(40, 80.0, [nan] * 9, 0)),  # type unknown
            (tp.GNSS_FIX, fix, 50, _fix(50, nan, good, known)),  # no altitude
            (tp.GNSS_FIX, fix, 60, _fix(60, 80.0, good, known, status=-1)),  # STATUS_NO_FIX
            (tp.GNSS_FIX, fix, 61, _fix(60, 80.0, good, known)),  # after a refused one: used
            (tp.WHEEL_SPEEDS, js, 10, mb.joint_state(10, WHEELS, velocity=[1.0] * 4)),
            (tp.WHEEL_SPEEDS, js, 20, mb.joint_state(20, twice, velocity=[1.0] * 5)),
            (tp.STEERING, js, 10, mb.joint_state(10, ["front_wheel_angle"] * 2, position=[0, 0])),
            (tp.GNSS_VELOCITY, vel, 10, mb.twist_with_covariance_stamped(10, [1, 0, 0], good)),
            (
                tp.GNSS_VELOCITY,
                vel,
                20,
                mb.twist_with_covariance_stamped(20, [1, 0, 0], [nan] * 9),
            ),
        ],
    )
    for fast in (True, False):
        data = read_bag(bag, fast=fast)
        assert data.dropped == {
            "gnss_fix:bad_covariance": 2,
            "gnss_fix:duplicate": 1,
            "gnss_fix:no_fix": 1,
            "gnss_velocity:bad_covariance": 1,
            "steering:duplicate_joint": 1,
            "wheel_speeds:duplicate_wheel": 1,
        }
        g = data.gnss
        assert g is not None and data.wheel_speeds is not None and data.steering is not None
        _eq(g.t_ns, np.array([10, 40, 50, 60]))
        _eq(g.alt_m, np.array([80.0, 80.0, nan, 80.0]))
        _eq(g.position_covariance_m2[1], np.zeros((3, 3)))  # not reported: the default
        _eq(g.position_covariance_m2[2], np.reshape(good, (3, 3)))
        _eq(data.wheel_speeds.t_ns, np.array([10]))
        assert data.steering.t_ns.size == 0
        assert data.gnss_velocity is not None
        _eq(data.gnss_velocity.t_ns, np.array([10]))
