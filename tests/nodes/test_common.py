"""Node start-up: a parameter the node does not declare stops it with one line and exit 2."""

from __future__ import annotations

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

    def spin(_node: Any) -> None:
        raise AssertionError(f"{node} started with {ros_args}")

    monkeypatch.setattr(common.rclpy, "spin", spin)
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
