"""StampMerge: windows of sorted streams in, blocks in stamp order out; late rows counted."""

from __future__ import annotations

import numpy as np

from tire_estimation.bag import topics as tp
from tire_estimation.bag.reader import ReadLog
from tire_estimation.bag.stamp_merge import StampMerge, join
from tire_estimation.sim.streams import SteeringStream, WheelSpeedStream

S = 1_000_000_000


def _steer(*t_s: float) -> SteeringStream:
    t = np.asarray([round(x * S) for x in t_s], dtype=np.int64)
    return SteeringStream(t, t * 1e-12)


def _wheels(*t_s: float) -> WheelSpeedStream:
    t = np.asarray([round(x * S) for x in t_s], dtype=np.int64)
    return WheelSpeedStream(t, np.tile(t[:, None] * 1e-9, (1, 4)))


def _stamps(blocks: list[dict], name: str) -> list[float]:
    return [float(t) / S for b in blocks if name in b for t in b[name].t_ns]


def test_join_keeps_the_first_of_a_repeated_stamp_and_counts_it() -> None:
    first, then = _steer(1, 2, 3), _steer(2.5, 3, 4)
    then = SteeringStream(then.t_ns, np.array([9.0, 9.0, 9.0]))
    joined, dropped = join(first, then)
    assert dropped == 1
    np.testing.assert_array_equal(joined.t_ns, np.array([1, 2, 2.5, 3, 4]) * S)
    assert joined.angle_rad[3] == first.angle_rad[2]  # the first window's row at t = 3 s


def test_blocks_follow_in_stamp_order_across_windows() -> None:
    log = ReadLog()
    merge = StampMerge(horizon_ns=1 * S, max_pending_rows=1000, log=log)
    blocks = []
    # wheel speeds run 0.5 s behind the steering in the file; both may come a little late
    merge.add({"steering": _steer(1, 2, 3, 4), "wheel_speeds": _wheels(0.5, 1.5, 2.5)})
    blocks.append(merge.release({"steering", "wheel_speeds"}))
    merge.add({"steering": _steer(3.5, 5, 6), "wheel_speeds": _wheels(2.7, 3.5, 4.5, 5.5)})
    blocks.append(merge.release({"steering", "wheel_speeds"}))
    blocks.append(merge.release(None))
    # first release: below min(4 - 1, 2.5 - 1) = 1.5 s; then below min(6, 5.5) - 1 = 4.5 s
    assert _stamps(blocks[:1], "steering") == [1.0]
    assert _stamps(blocks[:1], "wheel_speeds") == [0.5]
    assert max(_stamps(blocks[1:2], "steering")) < 4.5 <= min(_stamps(blocks[2:], "steering"))
    assert _stamps(blocks, "steering") == [1, 2, 3, 3.5, 4, 5, 6]
    assert _stamps(blocks, "wheel_speeds") == [0.5, 1.5, 2.5, 2.7, 3.5, 4.5, 5.5]
    assert not log.dropped
    assert log.notes == [f"{tp.STEERING}: messages were not in header-stamp order; sorted"]


def test_rows_behind_what_was_released_are_dropped_and_counted() -> None:
    log = ReadLog()
    merge = StampMerge(horizon_ns=1 * S, max_pending_rows=1000, log=log)
    merge.add({"steering": _steer(1, 2, 3, 4, 5)})
    released = merge.release({"steering"})
    assert _stamps([released], "steering") == [1, 2, 3]
    merge.add({"steering": _steer(2, 3, 3.5, 6)})  # 2 s: too late; 3 s: a repeat of the last
    rest = merge.release(None)
    assert _stamps([rest], "steering") == [3.5, 4, 5, 6]
    assert log.dropped == {"steering:out_of_order": 1, "steering:duplicate": 1}


def test_a_stream_that_ended_or_pauses_does_not_hold_the_others() -> None:
    log = ReadLog()
    merge = StampMerge(horizon_ns=1 * S, max_pending_rows=6, log=log)
    merge.add({"steering": _steer(1, 2), "wheel_speeds": _wheels(1, 2, 3, 4, 5, 6, 7, 8)})
    # steering has no messages to come: only the wheel speeds' horizon counts
    block = merge.release({"wheel_speeds"})
    assert _stamps([block], "steering") == [1, 2]
    assert _stamps([block], "wheel_speeds") == [1, 2, 3, 4, 5, 6]
    # steering still open but silent: the rows held stay within max_pending_rows
    merge.add({"wheel_speeds": _wheels(*range(9, 20))})
    block = merge.release({"wheel_speeds", "steering"})
    assert merge.pending_rows() <= 6
    assert _stamps([block], "wheel_speeds")[0] == 7.0
