"""``tire-estimation export``: the learned radii as parameters a robot or vehicle description
includes.

The source is a node's persistence file (read with
:func:`~tire_estimation.persistence.load_state`, which checks the vehicle and tire set, and
restored into a radius estimator, whose ``load_state_dict`` checks every value) or a replay's
``metrics.json`` (its final radius errors). The effective radii, multipliers and speed scale
factor are :func:`~tire_estimation.core.radius.wheel_odometry.effective_radii`, what the node
publishes on ``/tire_estimation/wheel_radii`` and ``/tire_estimation/speed_scale_factor``.

Formats:

* ``diff_drive``: ros2_control ``diff_drive_controller`` parameters under the controller's
  name: ``wheel_radius`` (the nominal radius), ``left_wheel_radius_multiplier`` (wheel_rl) and
  ``right_wheel_radius_multiplier`` (wheel_rr);
* ``vehicle``: an ``effective_tire_radii`` mapping: per wheel the effective radius, its
  standard deviation and multiplier, and the speed scale factor (mean rear effective radius
  over nominal, Autoware's ``speed_scale_factor``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.radius.wheel_odometry import (
    EffectiveRadii,
    effective_radii,
    estimate_radii,
)
from tire_estimation.core.vehicle import VehicleParams, load_vehicle_yaml
from tire_estimation.core.wheels import WHEEL_RL, WHEEL_RR
from tire_estimation.errors import ConfigError, InputError, StateFileError
from tire_estimation.persistence import Identity, LearnedState, load_state, read_json

FORMATS = ("diff_drive", "vehicle")
#: largest metrics.json read, bytes
METRICS_MAX_BYTES = 256 << 20
#: particles of the estimator a persisted state is restored into (the mean comes back exactly;
#: the standard deviation as a restarted node reports it)
RESTORE_PARTICLES = 1000
#: the command-line name of the source in errors
SOURCE = "SOURCE"


@dataclass(frozen=True)
class LearnedRadii:
    """Radii read from a source.

    Attributes:
        source: ``persistence file`` or ``replay report``.
        path: the file read.
        vehicle: the vehicle they belong to.
        radii: effective radii, multipliers and speed scale factor.
    """

    source: str
    path: Path
    vehicle: VehicleParams
    radii: EffectiveRadii


def read_learned_radii(
    path: Path, vehicle: VehicleParams | None, tire_set_id: str = "default"
) -> LearnedRadii:
    """The radii in a persistence file or a replay's ``metrics.json``.

    ``vehicle`` is required for a persistence file (its name must be the file's); for a
    ``metrics.json`` it defaults to the ``vehicle.yaml`` in the replayed bag's directory.

    Raises:
        ConfigError: naming ``SOURCE`` or ``--vehicle`` and what is wrong.
    """
    path = Path(path)
    try:
        data = read_json(path, METRICS_MAX_BYTES)
    except StateFileError as exc:
        raise ConfigError(SOURCE, str(path), f"not readable: {exc}") from exc
    except OSError as exc:
        raise ConfigError(SOURCE, str(path), exc.strerror or type(exc).__name__) from exc
    if isinstance(data, dict) and "format_version" in data:
        if vehicle is None:
            raise ConfigError("--vehicle", None, "required for a persistence file")
        return LearnedRadii(
            "persistence file", path, vehicle, _from_persistence(path, vehicle, tire_set_id)
        )
    if isinstance(data, dict) and isinstance(data.get("radii"), dict):
        if vehicle is None:
            vehicle = _bag_vehicle(data.get("bag"))
        return LearnedRadii("replay report", path, vehicle, _from_metrics(path, data, vehicle))
    raise ConfigError(SOURCE, str(path), "neither a node's persistence file nor a metrics.json")


def _from_persistence(path: Path, vehicle: VehicleParams, tire_set_id: str) -> EffectiveRadii:
    state, reason = load_state(path, Identity(vehicle.name, tire_set_id))
    if state is None:
        raise ConfigError(SOURCE, str(path), reason)
    radius_state = state.get("radius", state)  # a file of before the parts: top-level ``rear``
    wheels = "all" if isinstance(radius_state, dict) and "front" in radius_state else "rear"
    config = RadiusEstimatorConfig(n_particles=RESTORE_PARTICLES, wheels=wheels, run_aug_kf=False)
    estimator = RadiusEstimator(config, vehicle, np.random.default_rng(0))
    learned = LearnedState({"radius": estimator})
    learned.load_state_dict(state)
    note = learned.notes.get("radius", "not in the file")
    if note != "restored":
        raise ConfigError(SOURCE, str(path), f"radius state {note}")
    return estimate_radii(estimator.estimate(), vehicle)


def _bag_vehicle(bag: object) -> VehicleParams:
    candidate = Path(bag) / "vehicle.yaml" if isinstance(bag, str) and bag else None
    if candidate is None or not candidate.is_file():
        raise ConfigError("--vehicle", None, f"required: no vehicle.yaml in the bag {bag!r}")
    return load_vehicle_yaml(candidate)


def _from_metrics(path: Path, data: dict[str, Any], vehicle: VehicleParams) -> EffectiveRadii:
    radii = data["radii"]
    final, stds = radii.get("final_radius_error_m"), radii.get("final_radius_error_std_m")
    if not isinstance(final, dict) or not isinstance(stds, dict) or not final:
        raise ConfigError(SOURCE, str(path), "radii.final_radius_error_m missing")
    missing = [w for w, v in final.items() if v is None or stds.get(w) is None]
    if missing:
        raise ConfigError(SOURCE, str(path), f"no final radius of {', '.join(missing)}")
    wheels = list(final)
    try:
        return effective_radii(
            wheels,
            [float(final[w]) for w in wheels],
            [float(stds[w]) for w in wheels],
            vehicle.nominal_tire_radius_m,
        )
    except (InputError, TypeError, ValueError) as exc:
        raise ConfigError(SOURCE, str(path), f"radii: {exc}") from exc


def diff_drive_parameters(radii: EffectiveRadii, controller: str) -> dict[str, Any]:
    """ros2_control ``diff_drive_controller`` parameters: the rear wheels are its left and
    right wheels, ``wheel_radius`` the nominal radius the multipliers refer to."""
    return {
        controller: {
            "ros__parameters": {
                "wheel_radius": _round(radii.nominal_radius_m),
                "left_wheel_radius_multiplier": _round(radii.of(WHEEL_RL)[1]),
                "right_wheel_radius_multiplier": _round(radii.of(WHEEL_RR)[1]),
            }
        }
    }


def vehicle_parameters(learned: LearnedRadii) -> dict[str, Any]:
    """The ``effective_tire_radii`` mapping of a vehicle description."""
    r = learned.radii
    return {
        "effective_tire_radii": {
            "vehicle": learned.vehicle.name,
            "nominal_radius_m": _round(r.nominal_radius_m),
            "speed_scale_factor": _round(r.speed_scale_factor),
            "wheels": {
                w: {
                    "radius_m": _round(float(r.radius_m[i])),
                    "radius_std_m": _round(float(r.radius_std_m[i])),
                    "multiplier": _round(float(r.multiplier[i])),
                }
                for i, w in enumerate(r.wheels)
            },
        }
    }


def render(learned: LearnedRadii, fmt: str, controller: str = "diff_drive_controller") -> str:
    """The YAML text of ``learned`` in format ``fmt`` (one of :data:`FORMATS`), with a
    comment naming the source."""
    if fmt == "diff_drive":
        doc = diff_drive_parameters(learned.radii, controller)
    elif fmt == "vehicle":
        doc = vehicle_parameters(learned)
    else:
        raise ConfigError("--format", fmt, f"must be one of {', '.join(FORMATS)}")
    header = (
        f"# learned effective tyre radii of vehicle {learned.vehicle.name!r}, exported by "
        f"tire-estimation from the {learned.source} {learned.path}\n"
    )
    return header + yaml.safe_dump(doc, sort_keys=False)


def _round(value: float) -> float:
    """Ten significant digits: a micrometre of radius is 3e-6 of it."""
    return float(f"{value:.10g}")
