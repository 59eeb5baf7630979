"""Node start-up and stop: a parameter the node does not declare, or a value its configure
rejects, stops it with one line and exit 2; Ctrl-C and SIGTERM stop the console scripts with
exit 0, no traceback, and the learned state saved."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import import_ros

pytestmark = pytest.mark.ros


def _start(
    node: str, ros_args: list[str], monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> tuple[int | str | None, list[str]]:
    """Run the node's console entry point with ``--ros-args ...``; spinning fails the test."""
    (module,) = import_ros(f"tire_estimation.nodes.{node}")
    from tire_estimation.nodes import common

    def spin(_node: Any, _stop: Any) -> None:
        raise AssertionError(f"{node} started with {ros_args}")

    monkeypatch.setattr(common, "spin_until_stopped", spin)
    with pytest.raises(SystemExit) as exc:
        module.main(["--ros-args", "-p", "persistence_file:=''", *ros_args])
    captured = capsys.readouterr()
    return exc.value.code, captured.err.strip().splitlines()


@pytest.mark.parametrize(
    ("node", "given", "nearest"),
    [
        ("estimator_node", "radius.n_particle:=100", "radius.n_particles"),
        ("estimator_node", "stiffness_enable:=false", "stiffness_enabled"),
        ("estimator_node", "radiuss.n_particles:=100", "radius.n_particles"),
        ("detector_node", "detector.thresold_m:=0.01", "detector.threshold_m"),
        ("detector_node", "vehicle.nam:=car", "vehicle.name"),
    ],
)
def test_an_unknown_parameter_stops_the_node_naming_the_nearest(
    node: str, given: str, nearest: str, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    code, lines = _start(node, ["-p", given], monkeypatch, capsys)
    assert code == 2
    assert len(lines) == 1 and len(lines[0]) <= 300, lines
    assert given.split(":=")[0] in lines[0] and f"did you mean {nearest}?" in lines[0]


def test_an_unknown_key_of_a_params_file_stops_the_node(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    params = tmp_path / "params.yaml"
    params.write_text("estimator_node:\n  ros__parameters:\n    radius:\n      n_particle: 100\n")
    code, lines = _start("estimator_node", ["--params-file", str(params)], monkeypatch, capsys)
    assert code == 2 and len(lines) == 1
    assert "did you mean radius.n_particles?" in lines[0]


def test_an_unreadable_params_file_is_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    missing = tmp_path / "missing.yaml"
    code, lines = _start("estimator_node", ["--params-file", str(missing)], monkeypatch, capsys)
    assert code == 2 and len(lines) == 1 and "Traceback" not in lines[0]
    assert lines[0].startswith("estimator_node: configuration error:") and "params" in lines[0]


def test_a_bad_value_found_at_configure_stops_the_node(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: Any
) -> None:
    missing = tmp_path / "missing_vehicle.yaml"
    code, lines = _start("estimator_node", ["-p", f"vehicle_file:={missing}"], monkeypatch, capsys)
    assert code == 2 and len(lines) == 1 and "Traceback" not in lines[0]
    assert lines[0].startswith("estimator_node: configuration error:")
    assert "missing_vehicle.yaml" in lines[0] and "file not found" in lines[0]


# --- the console scripts stopped by Ctrl-C or SIGTERM ---------------------------------------
STATE_FILE = "state.json"


def _launch(node: str, tmp_path: Path, *params: str) -> tuple[subprocess.Popen[bytes], Path]:
    """Start the console script with a vehicle identity and a persistence file; wait until it
    is up. Its log (stdout and stderr) goes to a file."""
    exe = shutil.which(node)
    assert exe is not None, f"{node} console script not on PATH (source env.sh)"
    log = tmp_path / f"{node}.log"
    with log.open("w") as out:
        proc = subprocess.Popen(
            [exe, "--ros-args", "-p", "vehicle.name:=test_car",
             "-p", f"persistence_file:={tmp_path / STATE_FILE}", *params],
            stdout=out, stderr=subprocess.STDOUT, env=os.environ.copy(),
        )  # fmt: skip
    deadline = time.monotonic() + 30.0
    try:
        while f"{node} up:" not in log.read_text():
            assert proc.poll() is None, log.read_text()
            assert time.monotonic() < deadline, f"{node} not up within 30 s"
            time.sleep(0.05)
    except AssertionError:
        proc.kill()
        proc.wait()
        raise
    return proc, log


def _stop(proc: subprocess.Popen[bytes], sig: signal.Signals, log: Path) -> tuple[int, str]:
    proc.send_signal(sig)
    try:
        code = proc.wait(timeout=15)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        raise AssertionError(f"no exit within 15 s of {sig.name}: {log.read_text()}") from None
    return code, log.read_text()


@pytest.mark.parametrize(
    ("node", "sig"),
    [("estimator_node", signal.SIGTERM), ("detector_node", signal.SIGINT)],
    ids=["estimator_node-SIGTERM", "detector_node-SIGINT"],
)
def test_a_signal_stops_an_idle_node_cleanly(
    node: str, sig: signal.Signals, tmp_path: Path
) -> None:
    """Nothing learned: exit 0, no traceback, and the log says why nothing was written."""
    import_ros("rclpy")
    proc, log = _launch(node, tmp_path)
    code, text = _stop(proc, sig, log)
    assert code == 0, text
    assert "Traceback" not in text and "context is invalid" not in text, text
    assert "unchanged since restored" in text
    assert f"{tmp_path / STATE_FILE} not written" in text
    assert not (tmp_path / STATE_FILE).exists()


def _spin_until(executor: Any, cond: Callable[[], bool], proc: Any, timeout_s: float) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert proc.poll() is None, "the node died"
        assert time.monotonic() < deadline, "timed out"
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.serial  # fed over DDS in real time
@pytest.mark.parametrize(
    ("node", "sig"),
    [("estimator_node", signal.SIGINT), ("detector_node", signal.SIGTERM)],
    ids=["estimator_node-SIGINT", "detector_node-SIGTERM"],
)
def test_a_signal_saves_what_the_node_learned(
    node: str, sig: signal.Signals, tmp_path: Path
) -> None:
    """Fed over DDS, then stopped: exit 0, no traceback, the learned state on disk under the
    vehicle's identity."""
    rclpy, executors, qos_mod = import_ros("rclpy", "rclpy.executors", "rclpy.qos")
    params = ["-p", "sensor_qos:=reliable", "-p", "stiffness_enabled:=false"]
    proc, log = _launch(node, tmp_path, *(params if node == "estimator_node" else []))
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = executors.SingleThreadedExecutor(context=context)
    try:
        feeder = rclpy.create_node("shutdown_test_feeder", context=context)
        executor.add_node(feeder)
        feed = _estimator_feed if node == "estimator_node" else _detector_feed
        feed(feeder, executor, qos_mod, proc)
        code, text = _stop(proc, sig, log)
    finally:
        if proc.poll() is None:
            proc.kill()
        executor.shutdown()
        rclpy.shutdown(context=context)
    assert code == 0, text
    assert "Traceback" not in text and "context is invalid" not in text, text
    saved = json.loads((tmp_path / STATE_FILE).read_text())
    assert saved["vehicle_name"] == "test_car" and saved["state"]


def _subscribed(*publishers: Any, subscription: Any = None) -> bool:
    """The node subscribes to every feeder publisher and, when given, publishes what the
    feeder's ``subscription`` listens to (an output published before the two matched is lost,
    which a loaded machine makes likely)."""
    matched = all(p.get_subscription_count() > 0 for p in publishers)
    return matched and (subscription is None or subscription.get_publisher_count() > 0)


def _estimator_feed(feeder: Any, executor: Any, qos_mod: Any, proc: Any) -> None:
    """2.5 s of straight driving (wheel speeds 100 Hz, GNSS 10 Hz), paced by the radii the node
    publishes (its queue holds 100 samples: a node slowed by a loaded machine would lose the
    overflow, fixes among them, without a word); waits for the odometry the node publishes up
    to the last stamp."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState, NavSatFix

    from tests.nodes.test_estimator_node import _fix, _wheels
    from tire_estimation_msgs.msg import TireRadii

    qos = qos_mod.QoSProfile(depth=1000, reliability=qos_mod.ReliabilityPolicy.RELIABLE)
    wheels = feeder.create_publisher(JointState, "/vehicle/wheel_speeds", qos)
    fixes = feeder.create_publisher(NavSatFix, "/gnss/fix", qos)
    odometry_ns: list[int] = []
    radii_ns: list[int] = []

    def stamp_into(stamps: list[int]) -> Callable[[Any], None]:
        return lambda m: stamps.append(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec)

    odometry = feeder.create_subscription(
        Odometry, "/tire_estimation/odometry", stamp_into(odometry_ns), 100
    )
    radii = feeder.create_subscription(
        TireRadii, "/tire_estimation/tire_radii", stamp_into(radii_ns), 100
    )
    _spin_until(executor, lambda: _subscribed(wheels, fixes, subscription=odometry), proc, 15.0)
    _spin_until(executor, lambda: radii.get_publisher_count() > 0, proc, 15.0)
    t0_ns, t_ns = 1_000_000_000_000, 1_000_000_000_000
    for k in range(250):
        t_ns = t0_ns + k * 10_000_000
        wheels.publish(_wheels(t_ns, [20.0 / 0.31] * 4))
        if k % 10 == 0:
            fixes.publish(_fix(t_ns, 20.0 * (t_ns - t0_ns) * 1e-9, 0.0))
            executor.spin_once(timeout_sec=0.005)
        if k % 50 == 49:
            # radii every 0.1 s, up to the 50 ms the node holds for ordering
            behind_ns = t_ns - 160_000_000
            _spin_until(executor, lambda b=behind_ns: _newest(radii_ns) >= b, proc, 15.0)
    last_odometry_ns = t_ns - 60_000_000
    _spin_until(executor, lambda: _newest(odometry_ns) >= last_odometry_ns, proc, 15.0)


def _newest(stamps_ns: list[int]) -> int:
    return stamps_ns[-1] if stamps_ns else -1


def _detector_feed(feeder: Any, executor: Any, qos_mod: Any, proc: Any) -> None:
    """2 s of odometry and tire radii at 10 Hz; waits for the deflation status of each."""
    from nav_msgs.msg import Odometry

    from tests.nodes.test_detector_node import MU_CAL, Feeder
    from tire_estimation_msgs import msg as msg_mod

    qos = qos_mod.QoSProfile(depth=100, reliability=qos_mod.ReliabilityPolicy.RELIABLE)
    odometry = feeder.create_publisher(Odometry, "/tire_estimation/odometry", qos)
    radii = feeder.create_publisher(msg_mod.TireRadii, "/tire_estimation/tire_radii", qos)
    statuses: list[Any] = []
    status = feeder.create_subscription(
        msg_mod.DeflationStatus, "/tire_estimation/deflation", statuses.append, 100
    )
    _spin_until(executor, lambda: _subscribed(odometry, radii, subscription=status), proc, 15.0)
    feed = Feeder(msg_mod, Odometry)
    for _ in range(20):
        feed.t_ns += 100_000_000
        odometry.publish(feed.odometry())
        radii.publish(feed.radii(MU_CAL))
        executor.spin_once(timeout_sec=0.005)
    _spin_until(executor, lambda: len(statuses) >= 20, proc, 15.0)


# --- the executor -----------------------------------------------------------------------------
def test_nodes_spin_in_the_events_executor_or_the_single_threaded_one_without_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import sys

    rclpy, executors = import_ros("rclpy", "rclpy.executors")
    from tire_estimation.nodes.common import make_executor

    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        events = make_executor(context)
        # the C++ executor is no rclpy.executors.Executor (it only looks like one)
        assert type(events).__name__ == "EventsExecutor"
        assert not isinstance(events, executors.SingleThreadedExecutor)
        events.shutdown()
        monkeypatch.setitem(sys.modules, "rclpy.experimental", None)  # import fails
        fallback = make_executor(context)
        assert type(fallback) is executors.SingleThreadedExecutor
        fallback.shutdown()
    finally:
        rclpy.shutdown(context=context)


def test_the_spinning_console_script_answers_its_lifecycle_services(tmp_path: Path) -> None:
    """Without autostart, a lifecycle manager's configure and activate reach the node through
    the executor it spins in; a signal then stops it with exit 0."""
    rclpy, executors = import_ros("rclpy", "rclpy.executors")
    from lifecycle_msgs.msg import State, Transition
    from lifecycle_msgs.srv import ChangeState, GetState

    exe = shutil.which("estimator_node")
    assert exe is not None, "estimator_node console script not on PATH (source env.sh)"
    log = tmp_path / "estimator_node.log"
    with log.open("w") as out:
        proc = subprocess.Popen(
            [exe, "--ros-args", "-p", "autostart:=false", "-p", "persistence_file:=''"],
            stdout=out, stderr=subprocess.STDOUT, env=os.environ.copy(),
        )  # fmt: skip
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = executors.SingleThreadedExecutor(context=context)
    try:
        manager = rclpy.create_node("lifecycle_test_manager", context=context)
        executor.add_node(manager)
        change = manager.create_client(ChangeState, "/estimator_node/change_state")
        get = manager.create_client(GetState, "/estimator_node/get_state")
        assert change.wait_for_service(timeout_sec=30.0), log.read_text()
        assert get.wait_for_service(timeout_sec=10.0), log.read_text()

        def call(client: Any, request: Any, what: str, resend_s: float = 30.0) -> Any:
            """The answer to ``request``, sent again every ``resend_s`` (a request sent while
            discovery is still matching the service's endpoints can be lost)."""
            deadline = time.monotonic() + 30.0
            while True:
                future = client.call_async(request)
                resend = time.monotonic() + resend_s
                while not future.done() and time.monotonic() < resend:
                    assert proc.poll() is None, log.read_text()
                    assert time.monotonic() < deadline, f"no answer to {what}: {log.read_text()}"
                    executor.spin_once(timeout_sec=0.05)
                if future.done():
                    return future.result()
                client.remove_pending_request(future)

        # get_state changes nothing: asked until it is answered, the services are reachable
        state = call(get, GetState.Request(), "get_state", resend_s=2.0).current_state
        assert state.id == State.PRIMARY_STATE_UNCONFIGURED
        for transition in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
            request = ChangeState.Request(transition=Transition(id=transition))
            assert call(change, request, f"transition {transition}").success, log.read_text()
        state = call(get, GetState.Request(), "get_state").current_state
        assert state.id == State.PRIMARY_STATE_ACTIVE
        assert "estimator_node up:" in log.read_text()
        code, text = _stop(proc, signal.SIGINT, log)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        executor.shutdown()
        rclpy.shutdown(context=context)
    assert code == 0, text
    assert "Traceback" not in text, text
