"""Vehicle description shared by the simulator, the estimators and the bag tools.

The description is read from ``vehicle.yaml`` next to a bag (or the bag's metadata custom data)
under the top-level key ``vehicle``. Frames follow REP-103: ``base_link`` is x forward, y left,
z up, with its origin at the centre of the rear axle on the ground.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import yaml

from tire_estimation.core import yamlio
from tire_estimation.core.validation import (
    Checked,
    in_range,
    require_choice,
    require_known_keys,
    require_vector3,
    unknown_key_reason,
)
from tire_estimation.errors import VehicleConfigError

DRIVES = ("front", "rear", "all")


@dataclass(frozen=True)
class VehicleParams(Checked):
    """Geometry and inertia of the vehicle (SI units; ranges checked at construction).

    Attributes:
        name: free-text identity of the vehicle (used to match persisted estimates).
        nominal_tire_radius_m: nominal effective rolling radius of every tyre, m.
        track_width_m: lateral distance between the left and right wheel centres, m.
        wheelbase_m: distance between front and rear axle, m; must equal lf + lr.
        cg_to_front_axle_m: lf, longitudinal distance of the centre of gravity to the front axle.
        cg_to_rear_axle_m: lr, longitudinal distance of the centre of gravity to the rear axle.
        cg_height_m: height of the centre of gravity above the ground, m.
        mass_kg: vehicle mass, kg.
        yaw_inertia_kg_m2: yaw moment of inertia about the centre of gravity, kg m^2.
        drive: driven axle, ``front``, ``rear`` or ``all``; with ``rear`` or ``all`` the radius
            estimator takes the traction slip out of the rear wheel speeds
            (``core/radius/drive_slip.py``).
        gnss_antenna_position_m: GNSS antenna position in ``base_link`` (x, y, z), m.
        imu_position_m: IMU position in ``base_link`` (x, y, z), m.
        steering_ratio: steering-wheel angle over road-wheel angle, 1 (for CAN conversion).
        cornering_stiffness_front_n_rad: nominal front-axle cornering stiffness, N/rad.
        cornering_stiffness_rear_n_rad: nominal rear-axle cornering stiffness, N/rad.
        longitudinal_stiffness_front_n: nominal front-axle longitudinal stiffness, N per unit
            slip.
        longitudinal_stiffness_rear_n: nominal rear-axle longitudinal stiffness, N per unit
            slip (with ``mass_kg``, the prior of a driven rear axle's slip).
    """

    name: str = "vehicle"
    nominal_tire_radius_m: Annotated[float, in_range(0.1, 1.5)] = 0.31
    track_width_m: Annotated[float, in_range(0.3, 3.5)] = 1.55
    wheelbase_m: Annotated[float, in_range(0.3, 8.0)] = 2.7
    cg_to_front_axle_m: Annotated[float, in_range(0.0, 8.0)] = 1.1
    cg_to_rear_axle_m: Annotated[float, in_range(0.0, 8.0)] = 1.6
    cg_height_m: Annotated[float, in_range(0.0, 3.0)] = 0.55
    mass_kg: Annotated[float, in_range(10.0, 60_000.0)] = 1500.0
    yaw_inertia_kg_m2: Annotated[float, in_range(0.1, 1e6)] = 2500.0
    drive: str = "front"
    gnss_antenna_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    imu_position_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    steering_ratio: Annotated[float, in_range(1.0, 50.0)] = 15.0
    cornering_stiffness_front_n_rad: Annotated[float, in_range(1.0, 1e7)] = 100_000.0
    cornering_stiffness_rear_n_rad: Annotated[float, in_range(1.0, 1e7)] = 120_000.0
    longitudinal_stiffness_front_n: Annotated[float, in_range(1.0, 1e7)] = 150_000.0
    longitudinal_stiffness_rear_n: Annotated[float, in_range(1.0, 1e7)] = 150_000.0

    ERROR = VehicleConfigError
    PREFIX = "vehicle."

    def check(self) -> None:
        err = VehicleConfigError
        if not isinstance(self.name, str) or not self.name:
            raise err("vehicle.name", self.name, "must be a non-empty string")
        lf_lr = self.cg_to_front_axle_m + self.cg_to_rear_axle_m
        if abs(lf_lr - self.wheelbase_m) > 0.02:
            raise err(
                "vehicle.wheelbase_m",
                self.wheelbase_m,
                f"must equal cg_to_front_axle_m + cg_to_rear_axle_m = {lf_lr:.3f} (within 2 cm)",
            )
        require_choice("vehicle.drive", self.drive, DRIVES, err)
        for field in ("gnss_antenna_position_m", "imu_position_m"):
            # within 20 m of base_link
            require_vector3(f"vehicle.{field}", getattr(self, field), 20.0, err, " m")

    @property
    def lf_m(self) -> float:
        """Distance from the centre of gravity to the front axle, m."""
        return self.cg_to_front_axle_m

    @property
    def lr_m(self) -> float:
        """Distance from the centre of gravity to the rear axle, m."""
        return self.cg_to_rear_axle_m

    def wheel_positions_m(self) -> tuple[tuple[float, float], ...]:
        """(x, y) of each wheel centre in ``base_link``, in the order of ``core.wheels.WHEELS``."""
        half = 0.5 * self.track_width_m
        lb = self.wheelbase_m
        return ((lb, half), (lb, -half), (0.0, half), (0.0, -half))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> VehicleParams:
        """Build from a mapping (the ``vehicle`` section of vehicle.yaml); unknown keys fail."""
        data = require_known_keys(cls, data, "vehicle", VehicleConfigError, prefix="vehicle.")
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key in ("gnss_antenna_position_m", "imu_position_m"):
                if not isinstance(value, (list, tuple)):
                    raise VehicleConfigError(f"vehicle.{key}", value, "must be a list [x, y, z]")
                value = tuple(
                    _float(f"vehicle.{key}[{i}]", v) if _is_number(v) else v
                    for i, v in enumerate(value)
                )
            elif key not in ("name", "drive") and _is_int(value):
                value = _float(f"vehicle.{key}", value)
            kwargs[key] = value
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """The ``vehicle`` section of vehicle.yaml (plain YAML-serializable types)."""
        out = dataclasses.asdict(self)
        for key in ("gnss_antenna_position_m", "imu_position_m"):
            out[key] = [float(v) for v in out[key]]
        return out


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _float(field: str, value: float) -> float:
    try:
        return float(value)
    except OverflowError as exc:  # an integer beyond the float range
        raise VehicleConfigError(field, value, "must be a finite number") from exc


def vehicle_from_document(data: object, source: str) -> VehicleParams:
    """The vehicle of a vehicle.yaml document (a mapping with the one key ``vehicle``);
    ``source`` (a path) names the document in errors."""
    if not isinstance(data, Mapping):
        raise VehicleConfigError("vehicle", None, f"{source} has no top-level 'vehicle' mapping")
    for key, value in data.items():
        if key != "vehicle":
            reason = unknown_key_reason(key, ("vehicle",), what="top-level key")
            raise VehicleConfigError(f"{source}: {key}", value, reason)
    if "vehicle" not in data:
        raise VehicleConfigError("vehicle", None, f"{source} has no top-level 'vehicle' mapping")
    return VehicleParams.from_dict(data["vehicle"])


def load_vehicle_yaml(path: str | Path) -> VehicleParams:
    """Read ``vehicle.yaml``; raise :class:`VehicleConfigError` naming what is wrong."""
    data = yamlio.load_file(path, "vehicle.yaml", VehicleConfigError)
    return vehicle_from_document(data, str(path))


def dump_vehicle_yaml(vehicle: VehicleParams, path: str | Path, comment: str = "") -> None:
    """Write ``vehicle.yaml`` with an optional leading comment (sources of the numbers)."""
    header = "".join(f"# {line}\n" for line in comment.splitlines()) if comment else ""
    text = yaml.safe_dump({"vehicle": vehicle.to_dict()}, sort_keys=False)
    Path(path).write_text(header + text)
