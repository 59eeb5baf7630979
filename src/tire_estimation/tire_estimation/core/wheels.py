"""Wheel names and their order, shared by every module (contract v1)."""

from __future__ import annotations

from typing import Final

WHEEL_FL: Final = "wheel_fl"
WHEEL_FR: Final = "wheel_fr"
WHEEL_RL: Final = "wheel_rl"
WHEEL_RR: Final = "wheel_rr"

#: Canonical order of per-wheel arrays shaped ``(..., 4)`` throughout the package.
WHEELS: Final[tuple[str, str, str, str]] = (WHEEL_FL, WHEEL_FR, WHEEL_RL, WHEEL_RR)
WHEEL_INDEX: Final[dict[str, int]] = {name: i for i, name in enumerate(WHEELS)}
REAR_WHEELS: Final[tuple[str, str]] = (WHEEL_RL, WHEEL_RR)
FRONT_WHEELS: Final[tuple[str, str]] = (WHEEL_FL, WHEEL_FR)

#: Name of the steering joint on ``/vehicle/steering``.
STEERING_JOINT: Final = "front_wheel_angle"
