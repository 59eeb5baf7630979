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
