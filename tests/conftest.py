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
