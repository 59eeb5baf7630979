"""Shared test helpers."""

from __future__ import annotations

import importlib
import os
from types import ModuleType

import pytest


def import_ros(*modules: str) -> list[ModuleType]:
    """Import ROS modules for a test; skip when absent, unless the suite demands ROS.

    ``make test`` sets ``TIRE_ESTIMATION_REQUIRE_ROS=1``: there a missing rclpy or an unbuilt
    message package fails the test instead of skipping it.
    """
    try:
        return [importlib.import_module(m) for m in modules]
    except ImportError as exc:
        if os.environ.get("TIRE_ESTIMATION_REQUIRE_ROS") == "1":
            raise
        pytest.skip(f"ROS not available ({exc}); source env.sh after scripts/setup.sh")


def _worker_domain_id() -> None:
    """Give each pytest-xdist worker its own DDS domain, so parallel tests never see each other.

    ``scripts/run_tests.sh`` sets a base ``ROS_DOMAIN_ID`` (1-100); worker ``gwK`` uses the base
    plus K, wrapped into 1-101 (the range without port clashes on Linux).
    """
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if not worker.startswith("gw"):
        return
    base = int(os.environ.get("ROS_DOMAIN_ID", "1"))
    os.environ["ROS_DOMAIN_ID"] = str((base - 1 + int(worker[2:])) % 101 + 1)


_worker_domain_id()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Spread the ``slow`` tests over the pytest-xdist workers' first chunks.

    xdist's ``load`` scheduler first sends each of its ``n`` workers a block of ``c``
    consecutive tests (``c`` a quarter of the tests per worker) and then hands out the rest as
    workers free up. The k-th slow test is put at ``(k mod n) c + k div n``: every worker starts
    on its share of the long tests and the short ones fill the gaps, instead of one worker
    getting all of them, or one long test starting last and running alone. Every worker
    collects the same order (``PYTEST_XDIST_WORKER_COUNT``); without xdist nothing moves."""
    n = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "0"))
    slow = [item for item in items if item.get_closest_marker("slow") is not None]
    chunk = max((len(items) // n) // 4, 2) if n else 0
    if n < 2 or not slow or len(slow) > n * chunk:
        return  # (more slow tests than the first chunks hold: left in collection order)
    rest = [item for item in items if item.get_closest_marker("slow") is None]
    order: list[pytest.Item | None] = [None] * len(items)
    for k, item in enumerate(slow):
        order[(k % n) * chunk + k // n] = item
    fill = iter(rest)
    items[:] = [item if item is not None else next(fill) for item in order]
