"""The bag player publishes every message of the chosen topics and ``/clock`` at the bag time,
thinned to one per ``clock_period_s`` of bag time."""

from __future__ import annotations

from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.sim import simulate

    result = simulate("robustness", seed=3, minutes=0.05)
    return write_sim_bag(result, tmp_path_factory.mktemp("bags") / "short")


def _play(bag: Path, **kwargs: Any) -> tuple[int, list[int], list[int]]:
    """Play ``bag`` unpaced; the published count, the /clock stamps and the message stamps
    (log time), captured instead of sent."""
    (rclpy,) = import_ros("rclpy")
    from rosbags.rosbag2 import Reader

    from tire_estimation.bag.topics import INPUT_TOPICS
    from tire_estimation.nodes.bag_player import BagPlayer

    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic in INPUT_TOPICS]
        stamps = [t for _, t, _ in reader.messages(connections=conns)]
    context = rclpy.Context()
    rclpy.init(context=context)
    clocks: list[int] = []
    try:
        player = BagPlayer(bag, context=context)
        player.clock_pub.publish = lambda msg: clocks.append(
            msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        )
        published = player.play(rate=0.0, **kwargs)
        player.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    return published, clocks, stamps


def test_clock_is_published_once_per_period_of_bag_time(short_bag: Path) -> None:
    published, clocks, stamps = _play(short_bag)
    assert published == len(stamps) > 500
    # the first message's time first, then at least 10 ms apart, each a message's stamp
    assert clocks[0] == stamps[0]
    gaps = [b - a for a, b in pairwise(clocks)]
    assert min(gaps) >= 10_000_000
    assert set(clocks) <= set(stamps)
    # one /clock per 10 ms of bag time: about a fifth of the messages
    span_s = (stamps[-1] - stamps[0]) * 1e-9
    assert len(clocks) == pytest.approx(span_s / 0.01, abs=2)
    assert len(clocks) < published / 4


def test_clock_period_zero_publishes_a_clock_before_every_message(short_bag: Path) -> None:
    published, clocks, stamps = _play(short_bag, clock_period_s=0.0)
    assert clocks == stamps and published == len(stamps)
