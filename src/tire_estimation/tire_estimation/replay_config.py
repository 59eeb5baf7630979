"""The parameter file of ``tire-estimation replay --config``: read, checked key by key, split into
sections.

Three layouts are accepted: the node's ROS 2 parameters file (``estimator_node:
ros__parameters: radius.x: v``, also under ``/estimator_node`` or ``/**``), a mapping with one
sub-mapping per section (``radius: {x: v}``), and flat ``section.x`` keys; the layouts may be
mixed. Top-level scalar keys are the node options (``stiffness_enabled``). The sections are
:data:`SECTIONS`; ``vehicle`` is checked but not applied (the replay takes the bag's vehicle).

Every key must be known: an unknown section, parameter or node, a key given twice (nested and
flat) or a section that is not a mapping is a :class:`~tire_estimation.errors.ConfigError` naming
the key and the nearest valid one, so that no setting is silently ignored.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any, TypeVar

from tire_estimation.core import yamlio
from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.lateral.linear_kf import LinearLateralKFConfig
from tire_estimation.core.lateral.tyre_force_kf import TyreForceKFConfig
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.validation import reject_unknown_keys, unknown_key_reason
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.node_config import EstimatorNodeOptions
from tire_estimation.params import build_config, parameter_specs

NODE_NAME = "estimator_node"
#: top-level keys of a ROS 2 parameters file that address the estimator node
NODE_KEYS = (NODE_NAME, f"/{NODE_NAME}", "/**")
ROS_PARAMETERS = "ros__parameters"
#: the sections of the file (prefix -> configuration class); "" holds the node options
SECTIONS: dict[str, type] = {
    "": EstimatorNodeOptions,
    "radius": RadiusEstimatorConfig,
    "tyre_force": TyreForceKFConfig,
    "stiffness": StiffnessEstimatorConfig,
    "detector": DeflationDetectorConfig,
    "linear_kf": LinearLateralKFConfig,
    "vehicle": VehicleParams,
}
T = TypeVar("T")


def _fields(section: str) -> list[str]:
    return [spec.field for spec in parameter_specs(SECTIONS[section], section)]


def _all_keys() -> list[str]:
    """Every valid flat key: ``radius.n_particles``, ..., and the node options."""
    return [f"{s}.{f}" if s else f for s in SECTIONS for f in _fields(s)]


def _parameters(data: dict[Any, Any]) -> dict[Any, Any]:
    """The parameters of a ROS 2 parameters file (merged over its node keys), or ``data``
    itself when it is not one."""
    if not any(k in NODE_KEYS or (isinstance(v, dict) and ROS_PARAMETERS in v)
               for k, v in data.items()):  # fmt: skip
        return data
    params: dict[Any, Any] = {}
    for node, body in data.items():
        if node not in NODE_KEYS:
            near = isinstance(node, str) and difflib.get_close_matches(node, [NODE_NAME], 1, 0.85)
            reason = (
                f"unknown node; did you mean {NODE_NAME}?"
                if near
                else f"not {NODE_NAME}: --config reads the parameters of {NODE_NAME} "
                "(its detector section included)"
            )
            raise ConfigError(str(node), body, reason)
        if not isinstance(body, dict):
            raise ConfigError(str(node), body, f"must be a mapping with the key {ROS_PARAMETERS}")
        reject_unknown_keys(body, (ROS_PARAMETERS,), prefix=f"{node}.")
        section = body.get(ROS_PARAMETERS) or {}
        if not isinstance(section, dict):
            raise ConfigError(f"{node}.{ROS_PARAMETERS}", section, "must be a mapping")
        for key, value in section.items():
            if key in params:
                raise ConfigError(str(key), value, "given twice")
            params[key] = value
    return params


def _put(sections: dict[str, dict[str, Any]], section: str, name: Any, value: Any) -> None:
    full = f"{section}.{name}" if section else str(name)
    if not isinstance(name, str):
        raise ConfigError(full, value, f"keys must be text, not {type(name).__name__}")
    values = sections.setdefault(section, {})
    if name in values:
        raise ConfigError(full, value, "given twice (nested and flat)")
    values[name] = value


def parse_sections(data: object, source: str = "--config") -> dict[str, dict[str, Any]]:
    """Sections of a parsed parameter document: ``{"radius": {...}, "": {...}, ...}``, every
    key checked against the configuration classes."""
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(source, data, "must hold a mapping")
    sections: dict[str, dict[str, Any]] = {}
    top_level = [s for s in SECTIONS if s] + _fields("")
    for key, value in _parameters(data).items():
        if not isinstance(key, str):
            raise ConfigError(str(key), value, f"keys must be text, not {type(key).__name__}")
        if key in SECTIONS and key:
            if value is None:  # a section with every line commented out
                continue
            if not isinstance(value, dict):
                raise ConfigError(key, value, f"must be a mapping of {key}.* parameters")
            for name, v in value.items():
                _put(sections, key, name, v)
        elif "." in key:
            section, name = key.split(".", 1)
            if section not in SECTIONS or not section:
                raise ConfigError(key, value, unknown_key_reason(key, _all_keys()))
            _put(sections, section, name, value)
        elif isinstance(value, dict):
            raise ConfigError(key, value, unknown_key_reason(key, top_level, what="section"))
        elif key not in _fields(""):
            raise ConfigError(key, value, unknown_key_reason(key, top_level))
        else:
            _put(sections, "", key, value)
    for section, values in sections.items():
        reject_unknown_keys(values, _fields(section), prefix=f"{section}." if section else "")
    return sections


def load_config_sections(path: Path | None) -> dict[str, dict[str, Any]]:
    """Sections of the parameter file ``path`` (None: no file, every default); ConfigError
    naming ``--config`` or the key for anything that is not a known parameter."""
    if path is None:
        return {}
    return parse_sections(yamlio.load_file(path, "--config"))


def section_config(cls: type[T], prefix: str, values: dict[str, Any]) -> T:
    """``cls`` from one section's values; an unknown key or a value of the wrong type raises
    ConfigError naming ``prefix.key``."""
    dotted = f"{prefix}." if prefix else ""
    reject_unknown_keys(values, [s.field for s in parameter_specs(cls, prefix)], prefix=dotted)
    return build_config(cls, prefix, {f"{dotted}{k}": v for k, v in values.items()})


def load_radius_config(
    path: Path | None, overrides: dict[str, Any] | None = None
) -> RadiusEstimatorConfig:
    """The ``radius`` section as :class:`RadiusEstimatorConfig` (unknown keys raise)."""
    values = dict(load_config_sections(path).get("radius", {}))
    values.update(overrides or {})
    return section_config(RadiusEstimatorConfig, "radius", values)
