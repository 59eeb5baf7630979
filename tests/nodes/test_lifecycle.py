"""Both nodes as lifecycle nodes, driven through their transitions in-process: parameters in
every state, inputs processed and outputs published only while active, deactivate saves,
cleanup destroys what configure made, a failed configure leaves the node unconfigured."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros

T0_NS = 1_000_000_000_000
OWN_TOPICS = ("/tire_estimation/", "/diagnostics", "/vehicle/", "/imu/", "/gnss/")


@pytest.fixture
def ros() -> Any:
    (rclpy,) = import_ros("rclpy")
    context = rclpy.Context()
    rclpy.init(context=context)
    yield rclpy, context
    rclpy.shutdown(context=context)


@pytest.fixture
def published(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, Any]]:
    """What reaches rclpy's publish, as (topic, message): a lifecycle publisher passes a
    message on only while activated."""
    (publisher_mod,) = import_ros("rclpy.publisher")
    sent: list[tuple[str, Any]] = []

    def publish(self: Any, msg: Any) -> None:
        if self.topic_name.startswith(OWN_TOPICS):  # not /parameter_events
            sent.append((self.topic_name, msg))

    monkeypatch.setattr(publisher_mod.Publisher, "publish", publish)
    return sent


def _own(entities: list[Any]) -> list[str]:
    """The topics of the node's own publishers or subscriptions (not rclpy's built-ins)."""
    return [e.topic_name for e in entities if e.topic_name.startswith(OWN_TOPICS)]


def _estimator(ros: Any, tmp_path: Path, **params: Any) -> Any:
    _rclpy, context = ros
    from rclpy.parameter import Parameter

    from tire_estimation.nodes.estimator_node import EstimatorNode

    values = {
        "persistence_file": str(tmp_path / "radii.json"),
        "radius.n_particles": 200,
        "vehicle.name": "test_car",
        "autostart": False,
        **params,
    }
    overrides = [Parameter(k, value=v) for k, v in values.items()]
    return EstimatorNode(context=context, parameter_overrides=overrides)


def _drive(node: Any, t0_ns: int, seconds: float) -> int:
    """Wheel speeds at 100 Hz and GNSS at 10 Hz into the node's subscription callbacks."""
    from tests.nodes.test_estimator_node import _fix, _wheels

    callbacks = {sub.topic_name: sub.callback for sub in node.subscriptions}
    t_ns = t0_ns
    for k in range(round(seconds * 100)):
        t_ns = t0_ns + k * 10_000_000
        callbacks["/vehicle/wheel_speeds"](_wheels(t_ns, [20.0 / 0.31] * 4))
        if k % 10 == 0:
            callbacks["/gnss/fix"](_fix(t_ns, 20.0 * (t_ns - T0_NS) * 1e-9, 0.0))
    return t_ns + 10_000_000


def test_estimator_node_transitions(
    ros: Any, tmp_path: Path, published: list[tuple[str, Any]]
) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn as Return

    from tire_estimation.nodes.common import state_text

    path = tmp_path / "radii.json"
    node = _estimator(ros, tmp_path)
    # unconfigured: the parameters are there, nothing else
    assert node.state_label() == "unconfigured"
    assert node.get_parameter("radius.n_particles").value == 200
    assert node.describe_parameters(["autostart"])[0].read_only
    assert _own(node.subscriptions) == [] and _own(node.publishers) == []
    assert not hasattr(node, "pipeline")

    # inactive: subscribed and publishers made, but a message is counted and dropped
    assert node.trigger_configure() == Return.SUCCESS
    assert node.state_label() == "inactive"
    assert "/vehicle/wheel_speeds" in _own(node.subscriptions)
    assert "/tire_estimation/tire_radii" in _own(node.publishers)
    t_ns = _drive(node, T0_NS, 2.0)
    node._publish_diag()
    assert published == []
    assert node.dropped["wheel_speeds:inactive"] == 200
    assert node.dropped["gnss_fix:inactive"] == 20
    assert node.received["wheel_speeds"] == 200
    assert state_text(node._learned) == node.state_file.saved_text  # nothing learned

    # active: processed and published
    assert node.trigger_activate() == Return.SUCCESS
    assert node.state_label() == "active"
    t_ns = _drive(node, t_ns, 3.0)
    topics = {topic for topic, _msg in published}
    assert {"/tire_estimation/odometry", "/tire_estimation/tire_radii"} <= topics
    node._publish_diag()
    assert published[-1][0] == "/diagnostics"
    values = {kv.key: kv.value for kv in published[-1][1].status[0].values}
    assert values["dropped.wheel_speeds:inactive"] == "200"
    assert not path.exists()

    # deactivate: saves what was learned, then nothing goes out
    assert node.trigger_deactivate() == Return.SUCCESS
    assert node.state_label() == "inactive"
    assert path.is_file()
    saved = path.read_text()
    n_published = len(published)
    _drive(node, t_ns, 1.0)
    node._publish_diag()
    assert len(published) == n_published
    assert node.dropped["wheel_speeds:inactive"] == 300

    # cleanup: what configure made is gone; a new configure restores the saved state
    assert node.trigger_cleanup() == Return.SUCCESS
    assert node.state_label() == "unconfigured"
    assert _own(node.subscriptions) == [] and _own(node.publishers) == []
    assert node.services and all("reset" not in s.srv_name for s in node.services)
    assert path.read_text() == saved  # unchanged state: not written again
    assert node.trigger_configure() == Return.SUCCESS
    assert "radius restored" in node.state_file.note
    assert node.dropped == {}  # a fresh configuration

    assert node.trigger_shutdown() == Return.SUCCESS
    assert node.state_label() == "finalized"
    assert _own(node.subscriptions) == [] and _own(node.publishers) == []
    node.destroy_node()


def test_a_failed_configure_leaves_the_node_unconfigured(ros: Any, tmp_path: Path) -> None:
    from rclpy.lifecycle import TransitionCallbackReturn as Return

    from tire_estimation.errors import TireEstimationError

    missing = tmp_path / "missing_vehicle.yaml"
    node = _estimator(ros, tmp_path, vehicle_file=str(missing))
    assert node.trigger_configure() == Return.FAILURE
    assert node.state_label() == "unconfigured"
    assert isinstance(node.configure_error, TireEstimationError)
    assert "missing_vehicle.yaml" in str(node.configure_error)
    assert "file not found" in str(node.configure_error)
    assert _own(node.subscriptions) == [] and _own(node.publishers) == []
    node.destroy_node()
    # with autostart the constructor raises it (the console script: one line, exit 2)
    with pytest.raises(TireEstimationError, match="missing_vehicle"):
        _estimator(ros, tmp_path, vehicle_file=str(missing), autostart=True)


def test_detector_node_transitions(
    ros: Any, tmp_path: Path, published: list[tuple[str, Any]]
) -> None:
    from nav_msgs.msg import Odometry
    from rclpy.lifecycle import TransitionCallbackReturn as Return
    from rclpy.parameter import Parameter

    from tests.nodes.test_detector_node import MU_CAL, Feeder, _params
    from tire_estimation.nodes.detector_node import DetectorNode
    from tire_estimation_msgs import msg as msg_mod

    _rclpy, context = ros
    path = tmp_path / "deflation.json"
    params = _params(Parameter, tmp_path, autostart=False)
    node = DetectorNode(context=context, parameter_overrides=params)
    assert node.state_label() == "unconfigured"
    assert node.get_parameter("detector.calibration_time_s").value == 20.0
    assert not hasattr(node, "on_tire_radii")

    assert node.trigger_configure() == Return.SUCCESS
    feed = Feeder(msg_mod, Odometry)
    feed.drive(node, 1.0, MU_CAL)
    node.publish_diag()
    assert published == []
    assert node.dropped == {"odometry:inactive": 10, "tire_radii:inactive": 10}
    assert node.detector.status().calibrated_driving_time_s == 0.0

    assert node.trigger_activate() == Return.SUCCESS
    feed.drive(node, 2.0, MU_CAL)
    statuses = [m for topic, m in published if topic == "/tire_estimation/deflation"]
    assert len(statuses) == 20
    assert node.detector.status().calibrated_driving_time_s > 0.0
    path.unlink(missing_ok=True)  # a calibration event may have saved already
    feed.drive(node, 1.0, MU_CAL)

    n_published = len(published)
    assert node.trigger_deactivate() == Return.SUCCESS
    assert path.is_file()  # deactivate saved the calibration progress
    feed.drive(node, 1.0, MU_CAL)
    assert len(published) == n_published
    assert node.dropped["tire_radii:inactive"] == 20

    assert node.trigger_cleanup() == Return.SUCCESS
    assert _own(node.subscriptions) == [] and _own(node.publishers) == []
    assert node.trigger_shutdown() == Return.SUCCESS
    assert node.state_label() == "finalized"
    node.destroy_node()


def test_bad_input_is_dropped_and_counted_by_kind(
    ros: Any, tmp_path: Path, published: list[tuple[str, Any]]
) -> None:
    """Active: a message the conversion rejects is counted under the error's kind, any other bad
    input (here not a message at all) as ``invalid``; neither raises."""
    from tests.nodes.test_estimator_node import _wheels

    node = _estimator(ros, tmp_path, autostart=True)
    callback = {sub.topic_name: sub.callback for sub in node.subscriptions}[
        "/vehicle/wheel_speeds"
    ]
    callback(_wheels(T0_NS, [float("nan")] * 4))
    callback(object())
    callback(_wheels(T0_NS, [20.0 / 0.31] * 4))
    assert node.received["wheel_speeds"] == 3
    assert node.dropped == {"wheel_speeds:nan": 1, "wheel_speeds:invalid": 1}
    node.finish()
    node.destroy_node()
