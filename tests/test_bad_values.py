"""Bad input values are dropped and counted under the same ``<stream>:<kind>`` names by the
estimator node (``/diagnostics``: ``dropped.<stream>:<kind>``) and by the replay of the same
bag (``metrics.json``: ``dropped_samples``): GNSS covariances that are NaN, infinite, negative
or not positive semi-definite, a fix without altitude (used, counted ``no_altitude``), a wheel
or joint named twice. A fix whose covariance type is unknown is used with the default."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import Reader, StoragePlugin, Writer

from tests.conftest import import_ros
from tire_estimation.bag import messages as mb
from tire_estimation.bag import topics as tp
from tire_estimation.bag.typestore import get_typestore
from tire_estimation.cli import main
from tire_estimation.core.pipeline import EstimationPipeline, Output
from tire_estimation.core.samples import GnssFix, Sample
from tire_estimation.replay import run_replay

pytestmark = pytest.mark.ros

N_PARTICLES = 100
NAN = float("nan")
#: fix index -> (altitude, covariance (3, 3), covariance type) replacing the fix's own
BAD_FIXES: dict[int, tuple[float | None, list[float], int]] = {
    40: (None, [NAN, 0, 0, 0, 2.25, 0, 0, 0, 4.0], mb.COVARIANCE_TYPE_KNOWN),
    50: (None, [np.inf, 0, 0, 0, 2.25, 0, 0, 0, 4.0], mb.COVARIANCE_TYPE_KNOWN),
    60: (None, [2.25, 0, 0, 0, 2.25, 0, 0, 0, -4.0], mb.COVARIANCE_TYPE_KNOWN),
    # horizontal block fine, vertical correlation impossible (not positive semi-definite)
    70: (None, [2.25, 0, 3.0, 0, 2.25, 0, 3.0, 0, 1.0], mb.COVARIANCE_TYPE_KNOWN),
    # no altitude: used horizontally, counted
    80: (NAN, [2.25, 0, 0, 0, 2.25, 0, 0, 0, 4.0], mb.COVARIANCE_TYPE_KNOWN),
    # covariance type unknown (0): its values are not read, the default is used
    90: (None, [NAN] * 9, 0),
}
#: the counts both paths must report for the messages above
EXPECTED = {
    "gnss_fix:bad_covariance": 4,
    "gnss_fix:no_altitude": 1,
    "wheel_speeds:duplicate_wheel": 1,
    "steering:duplicate_joint": 1,
    "tire_forces:duplicate_wheel": 1,
}


class _Fixes:
    """The radius estimator's update of every GNSS fix it was handed, by stamp."""

    def __init__(self) -> None:
        self.updates: dict[int, Any] = {}

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Keep the update of a fix."""
        if type(sample) is GnssFix:
            self.updates[sample.t_ns] = result

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """Outputs are not recorded."""


def _stamp(msg: Any) -> int:
    return mb.stamp_to_ns(msg.header.stamp)


def _bad_bag(source: Path, out: Path) -> dict[int, int]:
    """``source`` written to ``out`` with the fixes of :data:`BAD_FIXES` and one wheel-speed,
    steering and tyre-force message that names a wheel (joint) twice; the stamps of the fixes
    of :data:`BAD_FIXES` by index."""
    store = get_typestore()
    writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conns: dict[str, Any] = {}
    seen: dict[str, int] = {}
    stamps: dict[int, int] = {}
    with Reader(source) as reader:
        for conn, log_ns, raw in reader.messages():
            k = seen[conn.topic] = seen.get(conn.topic, -1) + 1
            if conn.topic not in conns:
                conns[conn.topic] = writer.add_connection(
                    conn.topic, conn.msgtype, typestore=store
                )
            msg = store.deserialize_cdr(raw, conn.msgtype)
            if conn.topic == tp.GNSS_FIX and k in BAD_FIXES:
                alt, cov, cov_type = BAD_FIXES[k]
                stamps[k] = _stamp(msg)
                msg = mb.nav_sat_fix(
                    _stamp(msg), msg.latitude, msg.longitude,
                    msg.altitude if alt is None else alt, cov, covariance_type=cov_type,
                )  # fmt: skip
            elif conn.topic in (tp.WHEEL_SPEEDS, tp.STEERING) and k == 1000:
                names = [*msg.name, msg.name[-1]]
                values = [*msg.velocity, 1.0] if conn.topic == tp.WHEEL_SPEEDS else None
                position = None if values is not None else [*msg.position, 0.5]
                msg = mb.joint_state(_stamp(msg), names, position=position, velocity=values)
            elif conn.topic == tp.TIRE_FORCES_TOPIC and k == 500:
                msg = mb.tire_forces(
                    _stamp(msg), [*msg.wheel_names, msg.wheel_names[0]],
                    [*msg.fx_n, 0.0], [*msg.fy_n, 0.0], [*msg.fz_n, 0.0], [*msg.valid, True],
                )  # fmt: skip
            writer.write(conns[conn.topic], log_ns, store.serialize_cdr(msg, conn.msgtype))
    writer.close()
    for extra in ("vehicle.yaml", "sim_config.yaml"):
        if (source / extra).exists():
            shutil.copy(source / extra, out / extra)
    return stamps


def _node_dropped(ros: tuple[Any, Any], bag: Path, params: dict[str, Any]) -> dict[str, int]:
    """Every input message of the bag, in log order, into the estimator node's callbacks: the
    ``dropped.*`` counters of its radius estimator's diagnostic status."""
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message

    from tire_estimation.nodes.bag_player import message_class
    from tire_estimation.nodes.estimator_node import EstimatorNode

    _rclpy, context = ros
    node = EstimatorNode(
        context=context, parameter_overrides=[Parameter(k, value=v) for k, v in params.items()]
    )
    try:
        callbacks = {sub.topic_name: sub.callback for sub in node.subscriptions}
        with Reader(bag) as reader:
            conns = [c for c in reader.connections if c.topic in callbacks]
            types = {c.topic: message_class(c.msgtype) for c in conns}
            for conn, _t, raw in reader.messages(connections=conns):
                callbacks[conn.topic](deserialize_message(bytes(raw), types[conn.topic]))
        node.pipeline.flush()
        main_status = node.diagnostic_statuses()[0]
        return {
            kv.key.removeprefix("dropped."): int(kv.value)
            for kv in main_status.values
            if kv.key.startswith("dropped.")
        }
    finally:
        node.destroy_node()


@pytest.fixture
def ros() -> Any:
    (rclpy,) = import_ros("rclpy")
    context = rclpy.Context()
    rclpy.init(context=context)
    yield rclpy, context
    rclpy.shutdown(context=context)


def test_node_and_replay_drop_and_count_bad_values_alike(ros: Any, tmp_path: Path) -> None:
    sim = tmp_path / "sim"
    assert (
        main(["simulate", "lane_change", "--minutes", "0.3", "--seed", "3", "--out", str(sim)])
        == 0
    )
    bag = tmp_path / "bad"
    stamps = _bad_bag(sim, bag)
    config = tmp_path / "cfg.yaml"
    config.write_text(f"stiffness_enabled: false\nradius: {{n_particles: {N_PARTICLES}}}\n")
    fixes = _Fixes()
    report = run_replay(
        bag, tmp_path / "out", config_path=config, plots=False, progress=False, observers=[fixes]
    )
    replay = report.metrics["dropped_samples"]
    node = _node_dropped(
        ros,
        bag,
        {
            "vehicle_file": str(bag / "vehicle.yaml"),
            "persistence_file": "",
            "radius.n_particles": N_PARTICLES,
            "stiffness_enabled": False,
        },
    )
    assert {k: replay.get(k) for k in EXPECTED} == EXPECTED, replay
    assert {k: node.get(k) for k in EXPECTED} == EXPECTED, node
    # the same samples reach the same pipeline: every counter agrees
    assert node == replay, (node, replay)
    # the fix without altitude and the fix of unknown covariance type were used; the others
    # never reached the estimator
    assert fixes.updates[stamps[80]].accepted and fixes.updates[stamps[90]].accepted
    assert not any(stamps[k] in fixes.updates for k in (40, 50, 60, 70))
