"""The core must not import ROS, message packages or rosbags (DEVELOPERS.md rule 1)."""

from __future__ import annotations

import ast
from pathlib import Path

import tire_estimation.core as core_pkg

FORBIDDEN_PREFIXES = ("rclpy", "rosbags", "rosidl", "ament_index_python")
CORE_DIR = Path(core_pkg.__file__).parent


def _imported_modules(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    names: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.extend(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.append(node.module)
    return names


def _is_forbidden(module: str) -> bool:
    top = module.split(".")[0]
    return top.startswith(FORBIDDEN_PREFIXES) or top.endswith("_msgs")


def test_core_has_python_files() -> None:
    assert len(list(CORE_DIR.rglob("*.py"))) >= 3


def test_core_imports_no_ros_or_bag_library() -> None:
    offenders = {
        str(path.relative_to(CORE_DIR)): mod
        for path in CORE_DIR.rglob("*.py")
        for mod in _imported_modules(path)
        if _is_forbidden(mod)
    }
    assert offenders == {}


def test_detector_catches_a_forbidden_import(tmp_path: Path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("import rclpy\nfrom sensor_msgs.msg import Imu\nimport numpy\n")
    assert [m for m in _imported_modules(bad) if _is_forbidden(m)] == ["rclpy", "sensor_msgs.msg"]
