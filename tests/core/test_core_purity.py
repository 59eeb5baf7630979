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


MAX_CORE_MODULE_LINES = 600
PACKAGE_DIR = CORE_DIR.parent


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _top_level_imports(path: Path, modules: set[str]) -> set[str]:
    """Modules of ``modules`` that ``path`` imports at module level (not inside functions).

    ``from pkg import sub`` depends on ``pkg.sub`` when that is a module, else on ``pkg``.
    """
    tree = ast.parse(path.read_text(), filename=str(path))
    names: set[str] = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                names.add(sub if sub in modules else node.module)
    return names & modules


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_no_core_module_is_over_600_lines() -> None:
    sizes = {
        str(path.relative_to(CORE_DIR)): len(path.read_text().splitlines())
        for path in CORE_DIR.rglob("*.py")
    }
    assert {name: n for name, n in sizes.items() if n > MAX_CORE_MODULE_LINES} == {}


def test_the_package_has_no_import_cycle() -> None:
    modules = {_module_name(p): p for p in PACKAGE_DIR.rglob("*.py")}
    graph = {
        name: _top_level_imports(path, set(modules)) - {name} for name, path in modules.items()
    }
    assert _cycles(graph) == []


def test_the_cycle_finder_finds_a_cycle() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]
