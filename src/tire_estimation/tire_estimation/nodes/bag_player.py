"""bag_player: publish a rosbag2 bag's messages over DDS with ``/clock`` (no ros2cli needed).

``ros2 bag play`` is not installable from PyPI; this small player reads the raw CDR of each
message with ``rosbags`` and publishes the bytes unchanged (``Publisher.publish(bytes)``), in
log-time order, paced by ``rate`` (0 = as fast as possible). ``/clock`` follows the bag time so
nodes with ``use_sim_time:=true`` see the recorded time: it is published before the first
message and then before each message at least ``clock_period_s`` of bag time after the last
``/clock`` (default :data:`CLOCK_PERIOD_S`; 0: before every message).
"""

from __future__ import annotations

import argparse
import importlib
import sys
import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rosbags.rosbag2 import Reader
from rosgraph_msgs.msg import Clock

from tire_estimation.bag import topics
from tire_estimation.errors import BagError

#: Topics played by default: the estimator's inputs (never the truth).
DEFAULT_TOPICS = topics.INPUT_TOPICS
#: bag time between two ``/clock`` messages, s: 100 Hz, as often as the fastest input stream
#: (a ``/clock`` per message would double what a subscribing node has to take in)
CLOCK_PERIOD_S = 0.01


def message_class(msgtype: str) -> type:
    """``pkg/msg/Name`` -> the generated Python class (``pkg.msg.Name``)."""
    pkg, kind, name = msgtype.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


class BagPlayer(Node):
    """Publishes chosen topics of a bag; call :meth:`play` to run to the end."""

    def __init__(self, bag: Path, topics: Iterable[str] = DEFAULT_TOPICS, **kwargs: Any) -> None:
        super().__init__("bag_player", **kwargs)
        self.bag = Path(bag)
        if not self.bag.exists():
            raise BagError(f"no bag at {self.bag}")
        self.topics = tuple(topics)
        self.clock_pub = self.create_publisher(Clock, "/clock", 10)
        self.publishers_by_topic: dict[str, Any] = {}
        self.published = 0

    def play(
        self,
        rate: float = 1.0,
        qos: QoSProfile = qos_profile_sensor_data,
        progress: bool = False,
        clock_period_s: float = CLOCK_PERIOD_S,
    ) -> int:
        """Publish every message of the chosen topics; return how many were published
        (``progress``: a progress bar on stderr; ``clock_period_s``: bag time between two
        ``/clock`` messages, 0 for one before every message)."""
        try:
            reader = Reader(self.bag)
            reader.open()
        except Exception as exc:  # rosbags raises several types for unreadable bags
            raise BagError(f"cannot open bag {self.bag}: {exc}") from exc
        try:
            conns = [c for c in reader.connections if c.topic in self.topics]
            for conn in conns:
                if conn.topic not in self.publishers_by_topic:
                    self.publishers_by_topic[conn.topic] = self.create_publisher(
                        message_class(conn.msgtype), conn.topic, qos
                    )
            bar = None
            if progress:
                from tqdm import tqdm

                total = sum(c.msgcount for c in conns)
                bar = tqdm(total=total, unit="msg", unit_scale=True, desc="play", file=sys.stderr)
            wall0: float | None = None
            bag0 = 0
            clock = Clock()
            clock_period_ns = round(clock_period_s * 1e9)
            next_clock_ns = -1
            publish_clock = self.clock_pub.publish
            publish = {topic: pub.publish for topic, pub in self.publishers_by_topic.items()}
            monotonic = time.monotonic
            for conn, t_ns, raw in reader.messages(connections=conns):
                if wall0 is None:
                    wall0, bag0 = monotonic(), t_ns
                if rate > 0:
                    delay = (t_ns - bag0) * 1e-9 / rate - (monotonic() - wall0)
                    if delay > 0:
                        time.sleep(delay)
                if t_ns >= next_clock_ns:
                    clock.clock.sec, clock.clock.nanosec = divmod(t_ns, 1_000_000_000)
                    publish_clock(clock)
                    next_clock_ns = t_ns + clock_period_ns
                publish[conn.topic](bytes(raw))
                self.published += 1
                if bar is not None and self.published % 1000 == 0:
                    bar.update(1000)
            if bar is not None:
                bar.close()
        finally:
            reader.close()
        return self.published


def main(argv: Sequence[str] | None = None) -> None:
    """Console script ``bag_player BAG [--rate R] [--topic T ...]``."""
    parser = argparse.ArgumentParser(prog="bag_player", description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path)
    parser.add_argument("--rate", type=float, default=1.0, help="speed-up; 0 = no pacing")
    parser.add_argument("--topic", action="append", help="topic to play (default: inputs)")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    args, ros_args = parser.parse_known_args(argv)
    rclpy.init(args=ros_args)
    try:
        player = BagPlayer(args.bag, args.topic or DEFAULT_TOPICS)
        time.sleep(0.5)  # let discovery match subscribers before the first message
        count = player.play(rate=args.rate, progress=not args.no_progress)
        print(f"bag_player: published {count} messages from {args.bag}")
        player.destroy_node()
    except BagError as exc:
        print(f"bag_player: error: {exc}")
        raise SystemExit(2) from exc
    except KeyboardInterrupt:
        pass
    finally:
        if rclpy.ok():
            rclpy.shutdown()


if __name__ == "__main__":
    main()
