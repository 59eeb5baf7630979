"""The estimator and detector nodes, driven in-process with a bag's messages, publish exactly what
the replay of the same bag computes: radii, odometry, stiffness, lateral state and alarms."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import import_ros
from tire_estimation.cli import main
from tire_estimation.core.pipeline import (
    DeflationOutput,
    EstimationPipeline,
    LateralOutput,
    OdometryOutput,
    Output,
    RadiiOutput,
    StiffnessOutput,
)
from tire_estimation.core.samples import Sample
from tire_estimation.replay import run_replay

pytestmark = pytest.mark.ros

N_PARTICLES = 100
DETECTOR = {"calibration_time_s": 60.0, "calibration_average_s": 20.0}


class _Outputs:
    """Records the pipeline's outputs as the node's messages carry them."""

    def __init__(self) -> None:
        self.rows: list[tuple[Any, ...]] = []

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Samples are not recorded."""

    def on_output(self, pipeline: EstimationPipeline, out: Output) -> None:
        """One row per output, in the node's message fields."""
        if type(out) is RadiiOutput:
            e = out.estimate
            self.rows.append(("radii", out.t_ns, *e.radius_error_m, *e.radius_error_std_m))
        elif type(out) is OdometryOutput:
            e = out.estimate
            self.rows.append(("odom", out.t_ns, *e.pose[:2], e.speed_m_s, e.yaw_rate_rad_s))
        elif type(out) is StiffnessOutput:
            self.rows.append(("stiffness", out.t_ns, *out.estimate.stiffness))
        elif type(out) is LateralOutput:
            e = out.estimate
            self.rows.append(("lateral", out.t_ns, e.source, e.vy_m_s, e.yaw_rate_rad_s))
        elif type(out) is DeflationOutput:
            s = out.step.status
            alarms = tuple(sorted((w.wheel_name, w.alarm_t_ns) for w in s.wheels if w.alarm))
            self.rows.append(("deflation", out.t_ns, int(s.calibration_state), alarms))


def _stamp(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _node_rows(ros: tuple[Any, Any], bag: Path, params: dict[str, Any]) -> list[tuple[Any, ...]]:
    """Every message of the bag's input topics, in log order, into the estimator node's
    callbacks; its radii and odometry into the detector node's; the published messages."""
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message
    from rosbags.rosbag2 import Reader

    from tire_estimation.nodes.bag_player import message_class
    from tire_estimation.nodes.detector_node import DetectorNode
    from tire_estimation.nodes.estimator_node import EstimatorNode

    _rclpy, context = ros
    est_node = EstimatorNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]
    )
    det_params = {"persistence_file": "", "vehicle_file": params["vehicle_file"]}
    det_params.update({f"detector.{k}": v for k, v in DETECTOR.items()})
    det_node = DetectorNode(
        context=context,
        parameter_overrides=[Parameter(k, value=v) for k, v in det_params.items()],
    )
    rows: list[tuple[Any, ...]] = []

    def radii(msg: Any) -> None:
        rows.append(("radii", _stamp(msg.header), *msg.radius_error_m, *msg.radius_error_std_m))
        det_node.on_tire_radii(msg)

    def odom(msg: Any) -> None:
        p = msg.pose.pose.position
        t = msg.twist.twist
        rows.append(("odom", _stamp(msg.header), p.x, p.y, t.linear.x, t.angular.z))
        det_node.on_odometry(msg)

    def stiffness(msg: Any) -> None:
        rows.append(("stiffness", _stamp(msg.header), *msg.stiffness))

    def lateral(msg: Any) -> None:
        rows.append(
            ("lateral", _stamp(msg.header), msg.source, msg.lateral_velocity_m_s,
             msg.yaw_rate_rad_s)
        )  # fmt: skip

    def deflation(msg: Any) -> None:
        alarms = tuple(
            sorted((w.wheel_name, round(w.alarm_time_s * 1e9)) for w in msg.wheels if w.alarm)
        )
        rows.append(("deflation", _stamp(msg.header), int(msg.calibration_state), alarms))

    est_node.pub_radii.publish = radii
    est_node.pub_odom.publish = odom
    est_node.pub_stiffness.publish = stiffness
    est_node.pub_lateral.publish = lateral
    det_node.pub_status.publish = deflation
    callbacks = {sub.topic_name: sub.callback for sub in est_node.subscriptions}
    reader = Reader(bag)
    reader.open()
    try:
        conns = [c for c in reader.connections if c.topic in callbacks]
        types = {c.topic: message_class(c.msgtype) for c in conns}
        for conn, _t, raw in reader.messages(connections=conns):
            callbacks[conn.topic](deserialize_message(bytes(raw), types[conn.topic]))
    finally:
        reader.close()
    # the end of the recording: what the node still holds for ordering
    est_node._publish(est_node.pipeline.flush())
    assert not est_node.dropped and not det_node.dropped
    est_node.destroy_node()
    det_node.destroy_node()
    return rows


@pytest.fixture
def ros() -> Any:
    (rclpy,) = import_ros("rclpy")
    context = rclpy.Context()
    rclpy.init(context=context)
    yield rclpy, context
    rclpy.shutdown(context=context)


#: the detector node's message carries the alarm time as float64 seconds since the epoch, whose
#: resolution there is 2.4e-7 s: alarm times agree to 1 us, everything else bit for bit
ALARM_TIME_TOLERANCE_NS = 1000


def _compare(node_rows: list[tuple[Any, ...]], replay_rows: list[tuple[Any, ...]]) -> None:
    def without_alarm_times(rows: list[tuple[Any, ...]]) -> list[tuple[Any, ...]]:
        return [(*r[:3], tuple(w for w, _t in r[3])) if r[0] == "deflation" else r for r in rows]

    def alarm_times(rows: list[tuple[Any, ...]]) -> list[int]:
        return [t for r in rows if r[0] == "deflation" for _w, t in r[3]]

    for kind in ("radii", "odom", "stiffness", "lateral", "deflation"):
        a = [r for r in without_alarm_times(node_rows) if r[0] == kind]
        b = [r for r in without_alarm_times(replay_rows) if r[0] == kind]
        assert len(a) == len(b), kind
        assert a == b, kind  # bit-identical floats
    node_t, replay_t = alarm_times(node_rows), alarm_times(replay_rows)
    assert len(node_t) == len(replay_t)
    tol = ALARM_TIME_TOLERANCE_NS
    assert all(abs(x - y) <= tol for x, y in zip(node_t, replay_t, strict=True))


def test_node_and_replay_agree_on_a_lateral_drive(ros: Any, tmp_path: Path) -> None:
    """Radius MPF, stiffness MPF and tyre-force KF on a drive with tyre forces."""
    bag = tmp_path / "lc"
    assert (
        main(["simulate", "lane_change", "--minutes", "0.3", "--seed", "2", "--out", str(bag)])
        == 0
    )
    config = {
        "radius": {"n_particles": N_PARTICLES, "seed": 5},
        "stiffness": {"n_particles": N_PARTICLES},
        "detector": DETECTOR,
    }
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(config))
    rec = _Outputs()
    run_replay(
        bag, tmp_path / "out", config_path=tmp_path / "cfg.yaml", plots=False, progress=False,
        observers=[rec],
    )  # fmt: skip
    params = {
        "vehicle_file": str(bag / "vehicle.yaml"),
        "persistence_file": "",
        "radius.n_particles": N_PARTICLES,
        "radius.seed": 5,
        "stiffness.n_particles": N_PARTICLES,
    }
    node_rows = _node_rows(ros, bag, params)
    kinds = {r[0] for r in rec.rows}
    assert {"radii", "odom", "stiffness", "lateral"} <= kinds
    assert {r[2] for r in rec.rows if r[0] == "lateral"} == {"tyre_force_kf", "stiffness_mpf"}
    _compare(node_rows, rec.rows)


def test_node_and_replay_raise_the_same_alarm(ros: Any, tmp_path: Path) -> None:
    """The bundled 6-min bag (pressure step on wheel_rl at 226.8 s) with a 60 s calibration:
    the same statuses and the same alarm from the detector node and from the replay."""
    bag = Path(__file__).resolve().parents[1] / "bags" / "ece_r64_6min"
    config = {
        "stiffness_enabled": False,
        "radius": {"n_particles": N_PARTICLES, "seed": 1},
        "detector": DETECTOR,
    }
    (tmp_path / "cfg.yaml").write_text(yaml.safe_dump(config))
    rec = _Outputs()
    report = run_replay(
        bag, tmp_path / "out", config_path=tmp_path / "cfg.yaml", plots=False, progress=False,
        observers=[rec],
    )  # fmt: skip
    alarms = report.metrics["detection"]["alarms"]
    assert [a["wheel"] for a in alarms] == ["wheel_rl"]
    assert 226.8 < alarms[0]["t_s"] < 226.8 + 600.0
    params = {
        "vehicle_file": str(bag / "vehicle.yaml"),
        "persistence_file": "",
        "radius.n_particles": N_PARTICLES,
        "radius.seed": 1,
        "stiffness_enabled": False,
    }
    node_rows = _node_rows(ros, bag, params)
    deflation = [r for r in node_rows if r[0] == "deflation"]
    assert deflation and deflation[-1][3][0][0] == "wheel_rl"
    _compare(node_rows, rec.rows)
