"""Installed package files: the launch file, the diagnostic_aggregator analyzers, ``--version``."""

from __future__ import annotations

import ast
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from tests.conftest import import_ros

PACKAGE_DIR = Path(__file__).parents[1] / "src" / "tire_estimation"


def _console_scripts() -> set[str]:
    text = (PACKAGE_DIR / "setup.py").read_text()
    return set(re.findall(r'"([\w-]+) = tire_estimation', text))


def test_launch_file_starts_installed_executables_with_installed_parameter_files() -> None:
    """The launch file needs `launch_ros` (not in the PyPI wheels): checked as source."""
    tree = ast.parse((PACKAGE_DIR / "launch" / "tire_estimation.launch.py").read_text())
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant)}
    executables = {"estimator_node", "detector_node"}
    assert executables <= strings and executables <= _console_scripts()
    for name in ("estimator.yaml", "detector.yaml"):
        assert name in strings and (PACKAGE_DIR / "config" / name).is_file()
    assert "launch/*.launch.py" in (PACKAGE_DIR / "setup.py").read_text()


def _prefixes(analyzers: dict[str, Any]) -> list[str]:
    out: list[str] = []
    for spec in analyzers.values():
        if isinstance(spec, dict):
            out.extend(spec.get("startswith", []))
            out.extend(_prefixes(spec.get("analyzers", {})))
    return out


@pytest.mark.ros
def test_every_status_the_nodes_publish_has_an_analyzer(tmp_path: Path) -> None:
    rclpy, rclpy_parameter, est_mod, det_mod = import_ros(
        "rclpy",
        "rclpy.parameter",
        "tire_estimation.nodes.estimator_node",
        "tire_estimation.nodes.detector_node",
    )
    config = yaml.safe_load((PACKAGE_DIR / "config" / "diagnostic_aggregator.yaml").read_text())
    prefixes = _prefixes(config["analyzers"]["ros__parameters"])
    param = rclpy_parameter.Parameter
    context = rclpy.Context()
    rclpy.init(context=context)
    try:
        est = est_mod.EstimatorNode(
            context=context,
            parameter_overrides=[
                param("persistence_file", value=str(tmp_path / "radii.json")),
                param("radius.wheels", value="all"),
            ],
        )
        det = det_mod.DetectorNode(
            context=context,
            parameter_overrides=[param("persistence_file", value=str(tmp_path / "det.json"))],
        )
        names = [s.name for s in est.diagnostic_statuses() + det.diagnostic_statuses()]
        est.destroy_node()
        det.destroy_node()
    finally:
        rclpy.shutdown(context=context)
    assert len(names) >= 6
    for name in names:
        matches = [p for p in prefixes if name.startswith(p)]
        assert len(matches) == 1, f"{name!r} matched by {matches}"


def test_version_is_printed(capsys: pytest.CaptureFixture[str]) -> None:
    from tire_estimation import __version__
    from tire_estimation.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"tire-estimation {__version__}"
