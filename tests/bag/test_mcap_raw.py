"""mcap_raw: the MessageIndex path agrees with the record walk; a bad index falls back."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from tire_estimation.bag import mcap_raw
from tire_estimation.bag import topics as tp
from tire_estimation.bag.mcap_raw import RawMessages, read_mcap

TOPICS = tuple(tp.TOPIC_TYPES)


def _mcap(bag: Path) -> Path:
    return bag / f"{bag.name}.mcap"


def _payloads(msgs: RawMessages) -> list[bytes]:
    if msgs.rows is not None:
        return [r.tobytes() for r in msgs.rows]
    assert msgs.data is not None
    return list(msgs.data)


def _assert_same(a: dict[str, RawMessages], b: dict[str, RawMessages]) -> None:
    assert a.keys() == b.keys()
    for topic in a:
        assert a[topic].msgtype == b[topic].msgtype, topic
        assert a[topic].schema == b[topic].schema, topic
        np.testing.assert_array_equal(a[topic].log_ns, b[topic].log_ns, err_msg=topic)
        assert _payloads(a[topic]) == _payloads(b[topic]), topic


def _walked(path: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, RawMessages]:
    with monkeypatch.context() as m:
        m.setattr(mcap_raw._Scanner, "_indexed", lambda self, inner, index: False)
        return read_mcap(path, TOPICS)


def _read_recording_index_use(
    path: Path, monkeypatch: pytest.MonkeyPatch
) -> tuple[dict[str, RawMessages], list[bool]]:
    """read_mcap, with the result of every ``_indexed`` call (True: the index path was taken)."""
    used: list[bool] = []
    original = mcap_raw._Scanner._indexed

    def spy(self: mcap_raw._Scanner, inner: bytes, index: list[tuple[int, bytes]]) -> bool:
        used.append(original(self, inner, index))
        return used[-1]

    with monkeypatch.context() as m:
        m.setattr(mcap_raw._Scanner, "_indexed", spy)
        return read_mcap(path, TOPICS), used


def _index_records(content: bytes) -> list[int]:
    """Positions of the top-level MessageIndex records of an MCAP file."""
    pos, found = len(mcap_raw.MAGIC), []
    while pos < len(content) - len(mcap_raw.MAGIC):
        op, length = struct.unpack_from("<BQ", content, pos)
        if op == mcap_raw.OP_MESSAGE_INDEX:
            found.append(pos)
        if op == mcap_raw.OP_DATA_END:
            break
        pos += 9 + length
    return found


def _without_index_records(bag: Path, dst: Path, step: int = 1) -> bytes:
    """Write the bag's MCAP file to ``dst`` without every ``step``-th MessageIndex record."""
    content = _mcap(bag).read_bytes()
    out, last = bytearray(), 0
    for pos in _index_records(content)[::step]:
        (length,) = struct.unpack_from("<Q", content, pos + 1)
        out += content[last:pos]
        last = pos + 9 + length
    out += content[last:]
    dst.write_bytes(bytes(out))
    return bytes(out)


def test_index_path_equals_record_walk(bag: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = _mcap(bag)
    assert _index_records(path.read_bytes()), "the writer's bags carry MessageIndex records"
    fast = read_mcap(path, TOPICS)
    _assert_same(fast, _walked(path, monkeypatch))
    assert fast[tp.WHEEL_SPEEDS].rows is not None  # one length per topic: a 2-D array
    assert len(fast[tp.WHEEL_SPEEDS]) == fast[tp.WHEEL_SPEEDS].rows.shape[0] > 100
    assert fast[tp.IMU_DATA].schema[0] == "ros2msg"
    assert "geometry_msgs/Quaternion orientation" in fast[tp.IMU_DATA].schema[1]


def test_index_path_is_used(bag: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _, used = _read_recording_index_use(_mcap(bag), monkeypatch)
    assert used and all(used)


@pytest.mark.parametrize("delta", [1, -1, 10**6])
def test_wrong_index_offset_falls_back_to_the_walk(
    bag: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, delta: int
) -> None:
    content = bytearray(_mcap(bag).read_bytes())
    first = _index_records(bytes(content))[0]
    # record: opcode, length u64, channel u16, byte length u32, then (log_time, offset) pairs
    at = first + 15 + 8
    (offset,) = struct.unpack_from("<Q", content, at)
    struct.pack_into("<Q", content, at, max(offset + delta, 0))
    bad = tmp_path / "bad_index.mcap"
    bad.write_bytes(bytes(content))
    got, used = _read_recording_index_use(bad, monkeypatch)
    assert used[0] is False and all(used[1:])  # only the chunk with the bad entry is walked
    _assert_same(got, read_mcap(_mcap(bag), TOPICS))


def test_without_index_records_the_walk_reads_everything(bag: Path, tmp_path: Path) -> None:
    stripped = tmp_path / "no_index.mcap"
    assert not _index_records(_without_index_records(bag, stripped))
    _assert_same(read_mcap(stripped, TOPICS), read_mcap(_mcap(bag), TOPICS))


def test_topics_not_asked_for_are_not_returned(bag: Path) -> None:
    got = read_mcap(_mcap(bag), [tp.IMU_DATA, "/not/in/the/bag"])
    assert list(got) == [tp.IMU_DATA]


def test_channel_missing_from_the_index_is_found_by_the_walk(
    bag: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Index records for some channels only: the others' messages lie in the gaps between the
    indexed ones; the walk of the gaps finds them, in file order with the indexed ones."""
    partial = tmp_path / "partial_index.mcap"
    _without_index_records(bag, partial, step=3)  # drop every third index record
    got, used = _read_recording_index_use(partial, monkeypatch)
    assert used and all(used)  # the index path ran on every chunk
    _assert_same(got, read_mcap(_mcap(bag), TOPICS))


def test_several_files_are_joined_in_order(bag: Path) -> None:
    from tire_estimation.bag.reader import read_raw_fast

    one = read_raw_fast(bag, [_mcap(bag)], TOPICS)
    two = read_raw_fast(bag, [_mcap(bag), _mcap(bag)], TOPICS)
    for topic, raw in one.items():
        assert raw.rows is not None and two[topic].rows is not None, topic
        np.testing.assert_array_equal(two[topic].rows, np.concatenate([raw.rows, raw.rows]))
        np.testing.assert_array_equal(two[topic].log_ns, np.tile(raw.log_ns, 2))
        assert two[topic].schema == raw.schema
