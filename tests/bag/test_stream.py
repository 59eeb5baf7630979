"""stream_bag: the blocks of a bag read window by window give the samples, streams and drop
counts of the whole bag read at once (read_bag); a message too late to be ordered is counted."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag.reader import BagData, read_bag
from tire_estimation.bag.stamp_merge import row_fields
from tire_estimation.bag.stream import stream_bag
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.core.vehicle import VehicleParams, dump_vehicle_yaml
from tire_estimation.core.wheels import WHEELS
from tire_estimation.sources import bag_samples

ROOT = Path(__file__).resolve().parents[2]
S = 1_000_000_000


def _same_sample(a: Any, b: Any) -> bool:
    if type(a) is not type(b):
        return False
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            if x is None or y is None or not np.array_equal(x, y, equal_nan=True):
                return False
        elif x != y and not (x != x and y != y):  # NaN == NaN here
            return False
    return True


def _assert_same_as_whole(path: Path, window_s: float, fast: bool = True) -> list[BagData]:
    whole = read_bag(path, fast=fast)
    stream = stream_bag(path, window_s=window_s, fast=fast)
    blocks = list(stream.blocks())
    expected = list(bag_samples(whole))
    got = list(itertools.chain.from_iterable(bag_samples(b) for b in blocks))
    assert len(got) == len(expected) > 0
    assert all(_same_sample(a, b) for a, b in zip(got, expected, strict=True))
    for name in ("truth_fix", "truth_odometry", "truth_wheel_radii", "truth_stiffness"):
        ref = getattr(whole, name)
        parts = [getattr(b, name) for b in blocks if getattr(b, name) is not None]
        if ref is None:
            assert not parts, name
            continue
        for col in row_fields(ref):
            joined = np.concatenate([getattr(p, col) for p in parts])
            np.testing.assert_array_equal(joined, getattr(ref, col), err_msg=f"{name}.{col}")
    assert stream.dropped == whole.dropped
    return blocks


@pytest.mark.parametrize("fast", [True, False])
def test_blocks_are_the_whole_bag(bag: Path, fast: bool) -> None:
    blocks = _assert_same_as_whole(bag, window_s=1.0, fast=fast)
    assert len(blocks) >= 3
    starts = [min(int(s.t_ns[0]) for s in _streams(b)) for b in blocks]
    assert starts == sorted(starts)


def test_the_bundled_measured_bag_streams_as_a_whole() -> None:
    blocks = _assert_same_as_whole(ROOT / "bags" / "comma2k19_rav4_seg40", window_s=5.0)
    assert len(blocks) >= 3


def _streams(block: BagData) -> list[Any]:
    return [
        getattr(block, f.name)
        for f in dataclasses.fields(block)
        if hasattr(getattr(block, f.name), "t_ns")
    ]


def _wheel_bag(path: Path, stamps_and_logs: list[tuple[float, float]]) -> Path:
    """A bag of wheel speeds with the given (stamp, log time) pairs, s."""
    store = get_typestore()
    writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conn = writer.add_connection(tp.WHEEL_SPEEDS, tp.JOINT_STATE, typestore=store)
    for k, (stamp_s, log_s) in enumerate(sorted(stamps_and_logs, key=lambda x: x[1])):
        msg = mb.joint_state(round(stamp_s * S), WHEELS, velocity=[float(k)] * 4)
        writer.write(conn, round(log_s * S), store.serialize_cdr(msg, tp.JOINT_STATE))
    writer.close()
    dump_vehicle_yaml(VehicleParams(), path / "vehicle.yaml")
    return path


def test_late_messages_within_the_horizon_are_ordered_beyond_it_counted(tmp_path: Path) -> None:
    rows = [(1.0 + k / 10, 1.0 + k / 10) for k in range(600)]  # 60 s at 10 Hz
    rows.append((30.05, 33.0))  # logged 3 s late: put in order
    rows.append((20.0, 36.0))  # a repeat of a stamp 16 s back: beyond the horizon
    rows.append((40.0, 40.05))  # a repeat of the previous stamp: a duplicate
    bag = _wheel_bag(tmp_path / "late", rows)
    whole = read_bag(bag, fast=False)
    stream = stream_bag(bag, window_s=2.0, fast=False)
    blocks = list(stream.blocks())
    assert len(blocks) > 10
    t = np.concatenate([b.wheel_speeds.t_ns for b in blocks if b.wheel_speeds is not None])
    np.testing.assert_array_equal(t, whole.wheel_speeds.t_ns)  # 30.05 s in its place
    assert whole.dropped == {"wheel_speeds:duplicate": 2}
    # 20 s arrives after the rows up to about 26 s are released: too late to order
    assert stream.dropped == {"wheel_speeds:duplicate": 1, "wheel_speeds:out_of_order": 1}
