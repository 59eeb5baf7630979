"""Wheel names and their order, shared by every module (contract v1), and a robot's own joint
and frame names for them."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

from tire_estimation.core.validation import unknown_key_reason
from tire_estimation.errors import ConfigError

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

#: frame of the pose (ENU, REP-105) and of the vehicle body (REP-103), contract names
MAP_FRAME: Final = "map"
BASE_FRAME: Final = "base_link"


@dataclass(frozen=True)
class Names:
    """The joint and frame names of one robot or vehicle, for the contract's names.

    Attributes:
        wheels: joint names of the front-left, front-right, rear-left and rear-right wheel
            (the order of :data:`WHEELS`).
        steering: joint name of the front road-wheel angle.
        base_frame: frame of the vehicle body (contract ``base_link``).
        map_frame: frame of the pose (contract ``map``, ENU).
    """

    wheels: tuple[str, str, str, str] = WHEELS
    steering: str = STEERING_JOINT
    base_frame: str = BASE_FRAME
    map_frame: str = MAP_FRAME

    @property
    def wheel_index(self) -> dict[str, int]:
        """Joint name -> index in :data:`WHEELS` order."""
        return {name: i for i, name in enumerate(self.wheels)}

    @classmethod
    def from_remaps(cls, remaps: Sequence[str], field: str = "name_remaps") -> Names:
        """Names from ``contract=own`` entries (``wheel_fl=front_left_wheel_joint``,
        ``base_link=base_footprint``); names not listed keep the contract's. Raises
        :class:`~tire_estimation.errors.ConfigError` naming ``field`` for an entry without ``=``,
        an unknown contract name (with the nearest one), a name given twice or two joints
        mapped to one name."""
        contract = [*WHEELS, STEERING_JOINT, BASE_FRAME, MAP_FRAME]
        own = dict(zip(contract, contract, strict=True))
        seen: set[str] = set()
        for entry in remaps:
            key, sep, value = str(entry).partition("=")
            key, value = key.strip(), value.strip()
            if not sep or not key or not value:
                raise ConfigError(field, entry, "entries are contract_name=own_name")
            if key not in own:
                raise ConfigError(field, entry, unknown_key_reason(key, contract, what="name"))
            if key in seen:
                raise ConfigError(field, entry, f"{key} is mapped twice")
            seen.add(key)
            own[key] = value
        joints = [own[n] for n in (*WHEELS, STEERING_JOINT)]
        if len(set(joints)) != len(joints):
            raise ConfigError(field, list(remaps), "two joints are mapped to one name")
        wheels = (own[WHEEL_FL], own[WHEEL_FR], own[WHEEL_RL], own[WHEEL_RR])
        return cls(wheels, own[STEERING_JOINT], own[BASE_FRAME], own[MAP_FRAME])


#: the contract's names
CONTRACT_NAMES: Final = Names()
