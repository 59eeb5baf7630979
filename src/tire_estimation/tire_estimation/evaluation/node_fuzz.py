"""Bad messages and clock faults into the nodes' callbacks, against a clean run of the same bag.

The estimator node is fed a bag's input messages in log order through its subscription
callbacks (no DDS), with bad messages of :data:`MUTATIONS` mixed in at seeded places and the
clock faults of :data:`CLOCK_FAULTS` applied one a minute; the detector node is fed what the
estimator publishes, with bad ones of its own. The same bag runs once clean. Counted: escaped
exceptions (crashes), published messages with a non-finite number, and the radius error of
the faulted run against the clean one 60 s after each clock fault.

    python -m tire_estimation.evaluation.node_fuzz bags/ece_r64_6min --bad 10000

ends with one line per figure and exit 1 when a crash, a non-finite output or a missed
recovery (more than 1 mm 60 s after a fault) occurred.
"""

from __future__ import annotations

import argparse
import math
import tempfile
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bag import topics as tp

HOUR_NS = 3600 * 1_000_000_000
S_NS = 1_000_000_000
#: a clock fault must be recovered from (radii within this of the clean run) after RECOVERY_S
RECOVERY_TOLERANCE_M = 1e-3
RECOVERY_S = 60.0
#: the faulted run publishes at least this share of the clean run's messages on every topic
MIN_PUBLISHED_SHARE = 0.95

Mutation = Callable[[Any, np.random.Generator], None]


# --------------------------------------------------------------------------- bad messages
def _stamp(msg: Any, t_ns: int) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(max(t_ns, 0), S_NS)


def _t_ns(msg: Any) -> int:
    return int(msg.header.stamp.sec) * S_NS + int(msg.header.stamp.nanosec)


def _set_array(name: str, make: Callable[[int, np.random.Generator], list[float]]) -> Mutation:
    def mutate(msg: Any, rng: np.random.Generator) -> None:
        setattr(msg, name, make(len(getattr(msg, name)), rng))

    return mutate


def _one(value: float) -> Callable[[int, np.random.Generator], list[float]]:
    def make(n: int, rng: np.random.Generator) -> list[float]:
        out = [1.0] * max(n, 1)
        out[int(rng.integers(len(out)))] = value
        return out

    return make


def _length(k: int) -> Callable[[int, np.random.Generator], list[float]]:
    return lambda _n, rng: [float(v) for v in rng.normal(30.0, 1.0, k)]


def _attr(path: str, value: Any) -> Mutation:
    *parents, last = path.split(".")

    def mutate(msg: Any, _rng: np.random.Generator) -> None:
        obj = msg
        for p in parents:
            obj = getattr(obj, p)
        setattr(obj, last, value)

    return mutate


def _shift(seconds: float) -> Mutation:
    return lambda msg, _rng: _stamp(msg, _t_ns(msg) + round(seconds * S_NS))


def _zero_stamp(msg: Any, _rng: np.random.Generator) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0


def _cov(index: int, value: float) -> Callable[[Any, str], Mutation]:
    def factory(_msg: Any, name: str) -> Mutation:
        def mutate(msg: Any, _rng: np.random.Generator) -> None:
            *parents, last = name.split(".")
            obj = msg
            for p in parents:
                obj = getattr(obj, p)
            cov = list(getattr(obj, last))
            cov[index] = value
            setattr(obj, last, cov)

        return mutate

    return factory


_COMMON: dict[str, Mutation] = {
    "zero_stamp": _zero_stamp,
    "stamp_2h_ahead": _shift(7200.0),
    "stamp_2h_behind": _shift(-7200.0),
    "stamp_1s_behind": _shift(-1.0),
    "frame_1mb": _attr("header.frame_id", "x" * 1_000_000),
}

_JOINT: dict[str, Mutation] = {
    "velocity_nan": _set_array("velocity", _one(math.nan)),
    "velocity_inf": _set_array("velocity", _one(math.inf)),
    "velocity_1e308": _set_array("velocity", _one(1e308)),
    "velocity_minus_1e308": _set_array("velocity", _one(-1e308)),
    "velocity_empty": _set_array("velocity", lambda _n, _r: []),
    "velocity_3": _set_array("velocity", _length(3)),
    "velocity_100": _set_array("velocity", _length(100)),
    "position_nan": _set_array("position", _one(math.nan)),
    "position_1e308": _set_array("position", _one(1e308)),
    "names_empty": _attr("name", []),
    "names_unknown": _attr("name", ["a", "b", "c", "d"]),
    "names_duplicate": _attr("name", ["wheel_rl", "wheel_rl", "wheel_rr", "wheel_rr"]),
    "names_long": _attr("name", ["n" * 100_000]),
}

_IMU: dict[str, Mutation] = {
    "gyro_nan": _attr("angular_velocity.z", math.nan),
    "gyro_inf": _attr("angular_velocity.x", math.inf),
    "gyro_1e308": _attr("angular_velocity.z", 1e308),
    "accel_nan": _attr("linear_acceleration.x", math.nan),
    "accel_1e308": _attr("linear_acceleration.y", -1e308),
    "orientation_nan": _attr("orientation.w", math.nan),
}

_FIX: dict[str, Mutation] = {
    "lat_nan": _attr("latitude", math.nan),
    "lat_91": _attr("latitude", 91.0),
    "lon_200": _attr("longitude", 200.0),
    "alt_nan": _attr("altitude", math.nan),
    "alt_1e308": _attr("altitude", 1e308),
    "cov_nan": _cov(0, math.nan)(None, "position_covariance"),
    "cov_negative": _cov(4, -4.0)(None, "position_covariance"),
    "cov_inf": _cov(0, math.inf)(None, "position_covariance"),
    "cov_1e308": _cov(0, 1e308)(None, "position_covariance"),
    "status_no_fix": _attr("status.status", -1),
    "cov_type_99": _attr("position_covariance_type", 99),
}

_TWIST: dict[str, Mutation] = {
    "vel_nan": _attr("twist.twist.linear.x", math.nan),
    "vel_1e308": _attr("twist.twist.linear.y", 1e308),
    "vel_cov_nan": _cov(0, math.nan)(None, "twist.covariance"),
    "vel_cov_negative": _cov(7, -1.0)(None, "twist.covariance"),
    "frame_wrong": _attr("header.frame_id", "somewhere"),
}

_FORCES: dict[str, Mutation] = {
    "fy_nan": _set_array("fy_n", _one(math.nan)),
    "fz_1e308": _set_array("fz_n", _one(1e308)),
    "forces_3": _set_array("fx_n", _length(3)),
    "valid_empty": _attr("valid", []),
    "wheel_names_duplicate": _attr("wheel_names", ["wheel_fl"] * 4),
}

_RADII: dict[str, Mutation] = {
    "radius_nan": _set_array("radius_error_m", _one(math.nan)),
    "radius_1e308": _set_array("radius_error_m", _one(1e308)),
    "radius_std_negative": _set_array("radius_error_std_m", _one(-1.0)),
    "radius_3": _set_array("radius_error_m", _length(3)),
    "radius_names_unknown": _attr("wheel_names", ["x", "y"]),
    "radius_names_empty": _attr("wheel_names", []),
}

_ODOM: dict[str, Mutation] = {
    "speed_nan": _attr("twist.twist.linear.x", math.nan),
    "speed_1e308": _attr("twist.twist.linear.x", 1e308),
    "speed_negative_1e308": _attr("twist.twist.linear.x", -1e308),
}

#: bad messages per input topic: name -> mutation of a copy of a good message
MUTATIONS: dict[str, dict[str, Mutation]] = {
    tp.WHEEL_SPEEDS: {**_COMMON, **_JOINT},
    tp.STEERING: {**_COMMON, **_JOINT},
    tp.IMU_DATA: {**_COMMON, **_IMU},
    tp.GNSS_FIX: {**_COMMON, **_FIX},
    tp.GNSS_VELOCITY: {**_COMMON, **_TWIST},
    tp.TIRE_FORCES_TOPIC: {**_COMMON, **_FORCES},
    tp.OUT_TIRE_RADII: {**_COMMON, **_RADII},
    tp.OUT_ODOMETRY: {**_COMMON, **_ODOM},
}


# --------------------------------------------------------------------------- clock faults
#: one input message: topic, rclpy message, drive time (s since the bag's first message, log
#: time: unchanged by clock faults)
Message = tuple[str, Any, float]
ClockFault = Callable[[list[Message], int], list[Message]]


def _restamped(entry: Message, shift_ns: int) -> Message:
    topic, msg, drive_s = entry
    bad = _copy(msg)
    _stamp(bad, _t_ns(msg) + shift_ns)
    return topic, bad, drive_s


def _outlier(shift_ns: int) -> ClockFault:
    def fault(msgs: list[Message], at: int) -> list[Message]:
        return [*msgs[:at], _restamped(msgs[at], shift_ns), *msgs[at:]]

    return fault


def _shift_from(shift_ns: int, topic: str | None = None) -> ClockFault:
    def fault(msgs: list[Message], at: int) -> list[Message]:
        tail = [
            _restamped(e, shift_ns) if topic is None or e[0] == topic else e for e in msgs[at:]
        ]
        return [*msgs[:at], *tail]

    return fault


#: clock faults, applied one a minute in this order (shifts add up)
CLOCK_FAULTS: dict[str, ClockFault] = {
    "future_outlier": _outlier(2 * HOUR_NS),
    "step_back_1h": _shift_from(-HOUR_NS),
    "past_outlier": _outlier(-2 * HOUR_NS),
    "step_ahead_1h": _shift_from(HOUR_NS),
    "gnss_clock_2h_ahead": _shift_from(2 * HOUR_NS, tp.GNSS_FIX),
}


# --------------------------------------------------------------------------- running
def _copy(msg: Any) -> Any:
    from rclpy.serialization import deserialize_message, serialize_message

    return deserialize_message(serialize_message(msg), type(msg))


def load_messages(bag: Path, seconds: float | None = None) -> list[Message]:
    """The estimator's input messages of ``bag`` (rclpy types) in log order, the first
    ``seconds`` of it."""
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader

    from tire_estimation.nodes.bag_player import message_class

    out: list[Message] = []
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic in tp.INPUT_TOPICS]
        classes = {c.topic: message_class(c.msgtype) for c in conns}
        t0: int | None = None
        for conn, t_ns, raw in reader.messages(connections=conns):
            t0 = t_ns if t0 is None else t0
            drive_s = (t_ns - t0) * 1e-9
            if seconds is not None and drive_s > seconds:
                break
            msg = deserialize_message(bytes(raw), classes[conn.topic])
            out.append((conn.topic, msg, drive_s))
    return out


def non_finite(msg: Any) -> bool:
    """Whether any float in the message (recursively) is NaN or infinite."""
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if isinstance(value, float):
            if not math.isfinite(value):
                return True
        elif hasattr(value, "get_fields_and_field_types"):
            if non_finite(value):
                return True
        elif isinstance(value, (list, tuple, np.ndarray)) and len(value):
            first = value[0]
            if hasattr(first, "get_fields_and_field_types"):
                if any(non_finite(v) for v in value):
                    return True
            elif isinstance(first, (float, np.floating)) and not np.all(
                np.isfinite(np.asarray(value, dtype=float))
            ):
                return True
    return False


@dataclass
class RunResult:
    """What one run gave."""

    #: radius errors of the estimator after each whole second of drive time
    radii_m: dict[int, np.ndarray] = field(default_factory=dict)
    crashes: Counter[str] = field(default_factory=Counter)
    non_finite: Counter[str] = field(default_factory=Counter)
    published: Counter[str] = field(default_factory=Counter)
    bad_sent: Counter[str] = field(default_factory=Counter)
    #: bad messages after which no drop counter grew and nothing was held
    accepted: Counter[str] = field(default_factory=Counter)
    dropped: Counter[str] = field(default_factory=Counter)


def _held_or_dropped(est: Any, det: Any) -> int:
    """Every drop counter of both nodes and their estimators, plus held suspects."""
    total = sum(est.dropped.values()) + sum(det.dropped.values())
    total += sum(det.detector.dropped.values()) + det._stamps.held()
    pipeline = est.pipeline
    total += sum(pipeline.clock.dropped.values()) + pipeline.clock.held()
    for part in (pipeline.radius, pipeline.stiffness, pipeline.tyre_force):
        total += sum(getattr(part, "stats", {}).values()) if part is not None else 0
    return int(total)


def _capture(node: Any, result: RunResult, forward: Callable[[str, Any], None] | None) -> None:
    """Count what the node publishes and check it; hand it on to ``forward``."""
    for name in dir(node):
        if not name.startswith("pub_"):
            continue
        pub = getattr(node, name)

        def publish(msg: Any, topic: str = pub.topic_name) -> None:
            result.published[topic] += 1
            if non_finite(msg):
                result.non_finite[topic] += 1
            if forward is not None:
                forward(topic, msg)

        pub.publish = publish


def run(
    messages: list[Message],
    vehicle_file: Path,
    bad_plan: dict[int, list[tuple[str, str]]],
    rng: np.random.Generator,
    stiffness: bool = True,
) -> RunResult:
    """Feed ``messages`` (with the bad messages of ``bad_plan``: index -> (topic, mutation)
    pairs sent before that message) to an estimator node, and what it publishes to a
    detector node."""
    import rclpy
    from rclpy.parameter import Parameter

    from tire_estimation.nodes.detector_node import DetectorNode
    from tire_estimation.nodes.estimator_node import EstimatorNode

    result = RunResult()
    context = rclpy.Context()
    rclpy.init(context=context)
    good: dict[str, Any] = {}
    try:
        with tempfile.TemporaryDirectory() as tmp:
            vehicle = Parameter("vehicle_file", value=str(vehicle_file))
            est = EstimatorNode(
                context=context,
                parameter_overrides=[
                    vehicle,
                    Parameter("persistence_file", value=str(Path(tmp) / "radii.json")),
                    Parameter("stiffness_enabled", value=stiffness),
                ],
            )
            det = DetectorNode(
                context=context,
                parameter_overrides=[
                    vehicle,
                    Parameter("persistence_file", value=str(Path(tmp) / "detector.json")),
                ],
            )
            det_callbacks = {
                tp.OUT_TIRE_RADII: det.on_tire_radii,
                tp.OUT_ODOMETRY: det.on_odometry,
            }

            def call(callback: Callable[[Any], None], topic: str, msg: Any) -> None:
                try:
                    callback(msg)
                except Exception as exc:  # what escapes a callback is a crash
                    result.crashes[f"{topic}:{type(exc).__name__}"] += 1

            def to_detector(topic: str, msg: Any) -> None:
                if topic in det_callbacks:
                    good[topic] = msg
                    call(det_callbacks[topic], topic, msg)

            _capture(est, result, to_detector)
            _capture(det, result, None)
            callbacks = {sub.topic_name: sub.callback for sub in est.subscriptions}
            for k, (topic, msg, drive_s) in enumerate(messages):
                for bad_topic, mutation in bad_plan.get(k, ()):
                    template = good.get(bad_topic)
                    if template is None:
                        continue
                    bad = _copy(template)
                    MUTATIONS[bad_topic][mutation](bad, rng)
                    result.bad_sent[f"{bad_topic}:{mutation}"] += 1
                    target = det_callbacks.get(bad_topic) or callbacks.get(bad_topic)
                    if target is not None:
                        before = _held_or_dropped(est, det)
                        call(target, bad_topic, bad)
                        if _held_or_dropped(est, det) == before:
                            result.accepted[f"{bad_topic}:{mutation}"] += 1
                if topic in callbacks:
                    good[topic] = msg
                    call(callbacks[topic], topic, msg)
                second = int(drive_s)
                if second not in result.radii_m and est.estimator is not None:
                    result.radii_m[second] = np.asarray(
                        est.estimator.estimate().radius_error_m, dtype=float
                    )
            result.dropped.update(est.dropped)
            result.dropped.update({f"detector.{k}": v for k, v in det.dropped.items()})
            est.destroy_node()
            det.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    return result


def bad_plan(
    messages: list[Message], n_bad: int, rng: np.random.Generator
) -> dict[int, list[tuple[str, str]]]:
    """``n_bad`` bad messages at seeded places, kinds drawn evenly over the topics present
    (the detector's inputs included)."""
    present = sorted({t for t, _, _ in messages} | {tp.OUT_TIRE_RADII, tp.OUT_ODOMETRY})
    kinds = [(t, m) for t in present if t in MUTATIONS for m in MUTATIONS[t]]
    plan: dict[int, list[tuple[str, str]]] = {}
    for k, pick in zip(
        # after the first 2 % of the drive, when every stream has sent a good message to copy
        rng.integers(max(1, len(messages) // 50), len(messages), n_bad).tolist(),
        rng.integers(0, len(kinds), n_bad).tolist(),
        strict=True,
    ):
        plan.setdefault(k, []).append(kinds[pick])
    return plan


def with_clock_faults(
    messages: list[Message], every_s: float = 60.0
) -> tuple[list[Message], list[tuple[str, float]]]:
    """The messages with :data:`CLOCK_FAULTS` applied one every ``every_s`` of drive time
    (as many as fit); the faults with their drive times."""
    out = list(messages)
    faults: list[tuple[str, float]] = []
    for n, (name, fault) in enumerate(CLOCK_FAULTS.items(), start=1):
        at_s = n * every_s
        at = next((k for k, e in enumerate(out) if e[2] >= at_s), None)
        if at is None:
            break
        out = fault(out, at)
        faults.append((name, at_s))
    return out, faults


@dataclass
class FuzzReport:
    """The figures of one fuzz run."""

    messages: int
    bad_sent: int
    bad_kinds: int
    crashes: Counter[str]
    non_finite: Counter[str]
    #: per clock fault: |radius error - clean| (max over wheels) RECOVERY_S after it, m
    recovery_m: dict[str, float]
    final_diff_m: float
    dropped: Counter[str]
    #: bad messages neither dropped nor held, by topic:kind
    accepted: Counter[str]
    #: per output topic: messages published by the faulted run over the clean run's
    published_share: dict[str, float]

    @property
    def ok(self) -> bool:
        return (
            not self.crashes
            and not self.non_finite
            and all(v <= RECOVERY_TOLERANCE_M for v in self.recovery_m.values())
            and all(v >= MIN_PUBLISHED_SHARE for v in self.published_share.values())
        )

    def lines(self) -> list[str]:
        out = [
            f"input messages: {self.messages}",
            f"bad messages sent: {self.bad_sent} of {self.bad_kinds} kinds",
            f"crashes: {sum(self.crashes.values())} {dict(self.crashes) or ''}".rstrip(),
            f"non-finite outputs: {sum(self.non_finite.values())} "
            f"{dict(self.non_finite) or ''}".rstrip(),
        ]
        for name, diff in self.recovery_m.items():
            out.append(
                f"clock fault {name}: |radius - clean| {1e3 * diff:.3f} mm "
                f"{RECOVERY_S:.0f} s after it"
            )
        out.append(f"final |radius - clean|: {1e3 * self.final_diff_m:.3f} mm")
        shares = ", ".join(f"{t} {v:.3f}" for t, v in sorted(self.published_share.items()))
        out.append(f"published, faulted over clean: {shares}")
        out.append(f"dropped and counted by the estimator node: {sum(self.dropped.values())}")
        out.append(
            f"bad messages neither dropped nor held: {sum(self.accepted.values())} "
            f"{dict(sorted(self.accepted.items())) or ''}".rstrip()
        )
        out.append("verdict: " + ("pass" if self.ok else "FAIL"))
        return out


def fuzz(
    bag: Path,
    n_bad: int,
    seed: int = 0,
    seconds: float | None = None,
    stiffness: bool = True,
    clock_every_s: float = 60.0,
) -> FuzzReport:
    """A clean run and a run with ``n_bad`` bad messages and the clock faults, compared."""
    messages = load_messages(bag, seconds)
    vehicle_file = bag / "vehicle.yaml"
    clean = run(messages, vehicle_file, {}, np.random.default_rng(seed), stiffness)
    faulted, faults = with_clock_faults(messages, clock_every_s)
    rng = np.random.default_rng(seed)
    plan = bad_plan(faulted, n_bad, rng)
    bad = run(faulted, vehicle_file, plan, rng, stiffness)
    recovery: dict[str, float] = {}
    for name, at_s in faults:
        second = int(at_s + RECOVERY_S)
        if second in bad.radii_m and second in clean.radii_m:
            recovery[name] = float(np.max(np.abs(bad.radii_m[second] - clean.radii_m[second])))
    last = max(set(clean.radii_m) & set(bad.radii_m))
    return FuzzReport(
        messages=len(messages),
        bad_sent=sum(bad.bad_sent.values()),
        bad_kinds=len(bad.bad_sent),
        crashes=bad.crashes + clean.crashes,
        non_finite=bad.non_finite + clean.non_finite,
        recovery_m=recovery,
        final_diff_m=float(np.max(np.abs(bad.radii_m[last] - clean.radii_m[last]))),
        dropped=bad.dropped,
        accepted=bad.accepted,
        published_share={
            topic: bad.published[topic] / n for topic, n in clean.published.items() if n > 0
        },
    )


def main(argv: list[str] | None = None) -> int:
    """``python -m tire_estimation.evaluation.node_fuzz BAG [--bad N] ...``"""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", type=Path)
    parser.add_argument("--bad", type=int, default=10_000, help="bad messages (default 10000)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=None, help="first seconds of the bag")
    parser.add_argument("--no-stiffness", action="store_true", help="stiffness MPF off")
    parser.add_argument(
        "--clock-every-s", type=float, default=60.0, help="drive time between clock faults"
    )
    args = parser.parse_args(argv)
    report = fuzz(
        args.bag, args.bad, args.seed, args.seconds, not args.no_stiffness, args.clock_every_s
    )
    for line in report.lines():
        print(line)
    return 0 if report.ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
