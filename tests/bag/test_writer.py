"""write_sim_bag: layout on disk, metadata, serialization paths, reduced-rate truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader

from tests.bag.synthetic import make_result
from tire_estimation.bag import topics as tp
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.bag.writer import reduced_rate_rows, sim_topic_series, write_sim_bag
from tire_estimation.core.vehicle import load_vehicle_yaml
from tire_estimation.errors import BagError
from tire_estimation.sim.streams import SimResult


def test_fast_serialization_is_byte_identical(result: SimResult) -> None:
    for series in sim_topic_series(result):
        fast = series.serialize(fast=True)
        generic = series.serialize(fast=False)
        assert len(fast) == len(generic) == len(series.t_ns)
        for i in (0, 1, len(fast) // 2, len(fast) - 1):
            assert bytes(fast[i]) == generic[i], (series.topic, i)
        assert all(bytes(a) == b for a, b in zip(fast, generic, strict=True)), series.topic


def test_bag_directory_contents(bag: Path, result: SimResult) -> None:
    names = sorted(p.name for p in bag.iterdir())
    assert names == ["metadata.yaml", "sim_config.yaml", "synthetic.mcap", "vehicle.yaml"]
    assert not [p for p in bag.parent.iterdir() if p.name.startswith(".")]  # no staging left
    assert load_vehicle_yaml(bag / "vehicle.yaml") == result.vehicle
    cfg = yaml.safe_load((bag / "sim_config.yaml").read_text())
    assert cfg["scenario"] == "synthetic" and cfg["seed"] == 1
    assert cfg["events"] == [
        {"t_s": 10.0, "kind": "pressure_step", "detail": {"wheel": "wheel_rl", "to_pa": 150000.0}}
    ]
    assert cfg["config"] == {"gnss": {"rate_hz": 10.0}, "noise": 0.5, "wheels": ["a", "b"]}
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    custom = meta["custom_data"]
    assert custom["tire_estimation.scenario"] == "synthetic"
    assert custom["tire_estimation.seed"] == "1"
    assert yaml.safe_load(custom["tire_estimation.vehicle"])["vehicle"]["name"] == "test_car"
    assert meta["storage_identifier"] == "mcap"


def test_rosbags_reads_stamps_equal_log_times(bag: Path, result: SimResult) -> None:
    store = get_typestore()
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert counts[tp.WHEEL_SPEEDS] == len(result.wheel_speeds.t_ns)
        assert counts[tp.GNSS_VELOCITY] == len(result.gnss.t_ns)
        assert counts[tp.TRUTH_ODOMETRY] == len(result.truth.t_ns)
        assert reader.start_time == min(result.wheel_speeds.t_ns[0], result.truth.t_ns[0])
        previous = 0
        for conn, log_ns, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            assert msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec == log_ns
            assert log_ns >= previous
            previous = log_ns


def test_imu_and_fix_fields(bag: Path, result: SimResult) -> None:
    store = get_typestore()
    with Reader(bag) as reader:
        conns = {c.topic: c for c in reader.connections}
        first = {}
        for conn, _, raw in reader.messages([conns[tp.IMU_DATA], conns[tp.GNSS_FIX]]):
            first.setdefault(conn.topic, store.deserialize_cdr(raw, conn.msgtype))
    imu = first[tp.IMU_DATA]
    assert imu.orientation_covariance[0] == -1.0
    assert imu.angular_velocity_covariance[8] == pytest.approx(0.002**2)
    assert imu.linear_acceleration_covariance[4] == pytest.approx(0.05**2)
    fix = first[tp.GNSS_FIX]
    assert fix.position_covariance_type == 3 and fix.status.status == 0
    np.testing.assert_array_equal(
        fix.position_covariance, result.gnss.position_covariance_m2[0].reshape(9)
    )


def test_reduced_rate_rows_keeps_changes_and_1hz() -> None:
    t = np.arange(0, 5_000_000_000, 10_000_000, dtype=np.int64)  # 100 Hz, 5 s
    values = np.zeros((t.size, 2))
    values[237:, 1] = 1.0  # step at 2.37 s
    values[:, 0] = np.arange(t.size) * 1e-9  # drift far below the tolerance
    rows = reduced_rate_rows(t, values, 1e-3)
    assert 237 in rows.tolist()
    assert rows.tolist()[:2] == [0, 100]
    assert rows[-1] == t.size - 1
    held = values[rows[np.searchsorted(rows, np.arange(t.size), side="right") - 1]]
    assert np.all(np.abs(held - values) <= 1e-3)
    assert np.all(np.diff(t[rows]) <= 1_000_000_000)
    assert len(rows) < 10


def test_truth_pressure_step_is_published_at_the_step(bag: Path, result: SimResult) -> None:
    series = {s.topic: s for s in sim_topic_series(result)}
    pressure = series[tp.TRUTH_TIRE_PRESSURE]
    step_t = result.truth.t_ns[len(result.truth.t_ns) // 2]
    assert step_t in pressure.t_ns.tolist()
    assert len(pressure.t_ns) < len(result.truth.t_ns) // 10


def test_existing_target(tmp_path: Path, result: SimResult) -> None:
    small = make_result(2.0, seed=5)
    out = write_sim_bag(small, tmp_path / "b")
    with pytest.raises(BagError, match="exists"):
        write_sim_bag(small, out)
    write_sim_bag(result, out, overwrite=True)
    with Reader(out) as reader:
        assert reader.message_count > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b"]
    other = tmp_path / "not_a_bag"
    other.mkdir()
    (other / "precious.txt").write_text("keep")
    with pytest.raises(BagError, match="not a bag"):
        write_sim_bag(small, other, overwrite=True)
    assert (other / "precious.txt").exists()


def test_failed_write_leaves_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from tire_estimation.bag import writer as writer_mod

    def boom(*args: object, **kwargs: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(writer_mod, "dump_vehicle_yaml", boom)
    with pytest.raises(BagError, match="disk full"):
        write_sim_bag(make_result(1.0), tmp_path / "b")
    assert list(tmp_path.iterdir()) == []


def test_compression_smaller_and_readable(tmp_path: Path) -> None:
    small = make_result(5.0, seed=2)
    plain = write_sim_bag(small, tmp_path / "plain", compression=False)
    packed = write_sim_bag(small, tmp_path / "packed", compression=True)
    size_plain = (plain / "plain.mcap").stat().st_size
    size_packed = (packed / "packed.mcap").stat().st_size
    assert size_packed < 0.7 * size_plain
    store = get_typestore()
    with Reader(plain) as a, Reader(packed) as b:
        msgs_a = [(c.topic, t, bytes(d)) for c, t, d in a.messages()]
        msgs_b = [(c.topic, t, bytes(d)) for c, t, d in b.messages()]
    assert msgs_a == msgs_b
    last = store.deserialize_cdr(msgs_b[-1][2], tp.TOPIC_TYPES[msgs_b[-1][0]])
    assert last.header.stamp.sec > 0
