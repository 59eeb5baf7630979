"""Map frozen configuration dataclasses onto ROS parameters and back (no rclpy import here).

A dataclass field becomes the parameter ``<prefix>.<field>``; its description, unit and range come
from the field's ``metadata`` (keys ``doc``, ``unit``, ``range``) and its default from the
dataclass. The node declares the parameters with descriptors built from :func:`parameter_specs`
and rebuilds the dataclass with :func:`build_config`, so validation lives in one place.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TypeVar

from tire_estimation.core.validation import Rule, field_rules
from tire_estimation.errors import ConfigError

T = TypeVar("T")


@dataclass(frozen=True)
class ParameterSpec:
    """One ROS parameter derived from a dataclass field."""

    name: str
    field: str
    default: Any
    kind: type
    doc: str
    unit: str
    range: tuple[float, float] | None
    choices: tuple[str, ...] | None = None
    rule: Rule | None = None

    def summary(self) -> str:
        """Unit and allowed values in one phrase: ``m; in [0, 0.05]``."""
        parts = [self.unit] if self.unit else []
        if self.rule is not None:
            parts.append(self.rule.text())
        elif self.choices:
            parts.append("one of (" + ", ".join(self.choices) + ")")
        return "; ".join(parts)


# unit of a field from the suffix of its name (the longest suffix that matches)
_UNIT_SUFFIXES: dict[str, str] = {
    "_m": "m",
    "_s": "s",
    "_rad": "rad",
    "_n": "N",
    "_kg": "kg",
    "_m_s": "m/s",
    "_m_s2": "m/s^2",
    "_rad_s": "rad/s",
    "_n_rad": "N/rad",
    "_n_s2_m2": "N s^2/m^2",
    "_kg_m2": "kg m^2",
    "_m_sqrt_s": "m/sqrt(s)",
    "_rad_sqrt_s": "rad/sqrt(s)",
    "_m_s_sqrt_s": "m/s/sqrt(s)",
    "_m_s2_sqrt_s": "m/s^2/sqrt(s)",
    "_rad_s_sqrt_s": "rad/s/sqrt(s)",
    "_m2_s2": "m^2/s^2",
    "_rad2_s2": "rad^2/s^2",
    "_n2": "N^2",
    "_s2_per_m": "s^2/m",
    "_m_per_n": "m/N",
    "_m_per_m2_s2": "m/(m/s)^2",
}


def unit_of(name: str) -> str:
    """The unit a field's name carries (``dt_s`` -> ``s``), or ``""``."""
    best = ""
    for suffix in _UNIT_SUFFIXES:
        if name.endswith(suffix) and len(suffix) > len(best):
            best = suffix
    return _UNIT_SUFFIXES.get(best, "")


def attribute_docs(cls: type) -> dict[str, str]:
    """Per-field text of a Google-style ``Attributes:`` section of ``cls``'s docstring."""
    docs: dict[str, str] = {}
    lines = (cls.__doc__ or "").splitlines()
    inside = False
    current: str | None = None
    indent = 0
    for line in lines:
        stripped = line.strip()
        if stripped == "Attributes:":
            inside, indent = True, len(line) - len(line.lstrip())
            continue
        if not inside:
            continue
        if stripped and len(line) - len(line.lstrip()) <= indent:
            break
        head, sep, rest = stripped.partition(": ")
        if sep and head.isidentifier() and len(line) - len(line.lstrip()) == indent + 4:
            current = head
            docs[current] = rest.strip()
        elif current is not None and stripped:
            docs[current] += " " + stripped
    return docs


def _field_kind(tp: Any, default: Any) -> type:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        tp = args[0] if args else str
    if tp in (bool, int, float, str):
        return tp
    if isinstance(tp, str):
        return {"bool": bool, "int": int, "float": float, "str": str}.get(
            tp.split("|")[0].strip(), type(default)
        )
    if typing.get_origin(tp) is typing.Literal:
        return str
    return type(default)


def parameter_specs(cls: type, prefix: str) -> list[ParameterSpec]:
    """Specs of every scalar field of dataclass ``cls`` (nested dataclasses are not expanded)."""
    hints = typing.get_type_hints(cls)
    docs = attribute_docs(cls)
    rules: Mapping[str, Rule] = field_rules(cls)
    specs = []
    for f in dataclasses.fields(cls):
        if f.default is dataclasses.MISSING:
            if f.default_factory is dataclasses.MISSING:  # type: ignore[misc]
                continue
            default = f.default_factory()  # type: ignore[misc]
        else:
            default = f.default
        kind = _field_kind(hints.get(f.name, type(default)), default)
        if kind is list:
            kind = tuple
        if kind not in (bool, int, float, str, tuple):
            continue
        if kind is tuple and str in typing.get_args(hints.get(f.name)):
            # a list of names (ROS string array)
            kind, default = list, [str(v) for v in default]
        elif kind is tuple:
            if not all(isinstance(v, (int, float)) for v in default):
                continue
            default = [float(v) for v in default]
        meta = f.metadata
        rule = rules.get(f.name)
        rng = meta.get("range")
        choices = meta.get("choices")
        if rule is not None and rng is None and rule.kind in ("range", "int_range"):
            rng = (rule.low, rule.high)
        if rule is not None and choices is None and rule.kind == "choice":
            choices = rule.choices
        specs.append(
            ParameterSpec(
                name=f"{prefix}.{f.name}" if prefix else f.name,
                field=f.name,
                default=default,
                kind=kind,
                doc=str(meta.get("doc", docs.get(f.name, ""))),
                unit=str(meta.get("unit", unit_of(f.name))),
                range=(float(rng[0]), float(rng[1])) if rng else None,
                choices=tuple(choices) if choices else None,
                rule=rule,
            )
        )
    return specs


def build_config(cls: type[T], prefix: str, values: Mapping[str, Any]) -> T:
    """Build ``cls`` from parameter values keyed by full parameter name (missing = default).

    Raises :class:`ConfigError` naming the parameter when a value has the wrong type; range and
    consistency checks are the dataclass's own (its annotations and ``check``).
    """
    kwargs: dict[str, Any] = {}
    for spec in parameter_specs(cls, prefix):
        if spec.name not in values:
            continue
        value = values[spec.name]
        if spec.kind is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if spec.kind is list:
            if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
                raise ConfigError(spec.name, value, "must be a list of strings")
            kwargs[spec.field] = tuple(value)
            continue
        if spec.kind is tuple:
            if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in value
            ):
                raise ConfigError(spec.name, value, "must be a list of numbers")
            kwargs[spec.field] = tuple(float(v) for v in value)
            continue
        if spec.default is None and value in ("", None):
            value = None
        elif not isinstance(value, spec.kind) or (spec.kind is int and isinstance(value, bool)):
            raise ConfigError(spec.name, value, f"must be of type {spec.kind.__name__}")
        kwargs[spec.field] = value
    try:
        return cls(**kwargs)
    except ConfigError as exc:
        if not prefix or exc.field.startswith(f"{prefix}."):
            raise
        # name the parameter as the user spells it (radius.n_particles, not n_particles)
        raise type(exc)(f"{prefix}.{exc.field}", exc.value, exc.reason) from exc


def first_sentence(doc: str) -> str:
    """The first sentence of a field's description: the one-line text of the parameter file."""
    text = " ".join(doc.split())
    depth = 0
    for i, ch in enumerate(text):
        depth += ch in "([{"
        depth -= ch in ")]}"
        if ch == "." and depth == 0 and (i + 1 == len(text) or text[i + 1] == " "):
            return text[: i + 1]
    return text


def _yaml_value(value: Any) -> str:
    import yaml

    return (
        yaml.safe_dump(value, default_flow_style=True, width=1000)
        .strip()
        .removesuffix("\n...")
        .removesuffix(" ...")
    )


def render_params_yaml(node_name: str, sections: list[tuple[str, type, str]]) -> str:
    """A ROS 2 parameters file documenting every parameter with unit and default.

    ``sections``: (prefix, dataclass, title). The result is loadable with ``--params-file`` and
    by ``tire-estimation replay --config``; every value is the dataclass default.
    """
    lines = [
        f"# Parameters of {node_name}: every parameter with its default.",
        "# Each parameter: [unit; allowed values] and what it sets; the full description is in",
        "# the configuration dataclass's docstring and in `ros2 param describe`.",
        "# Generated from the configuration dataclasses by",
        f"#   python -m tire_estimation.params {node_name} > "
        f"src/tire_estimation/config/{node_name.removesuffix('_node')}.yaml",
        "# (a test checks that this file matches the code).",
        f"{node_name}:",
        "  ros__parameters:",
    ]
    for prefix, cls, title in sections:
        lines.append(f"    # --- {title}")
        for spec in parameter_specs(cls, prefix):
            doc = first_sentence(spec.doc)
            summary = spec.summary()
            words = (f"[{summary}] {doc}" if summary else doc).split(" ")
            line = "    #"
            for word in words:
                if len(line) + 1 + len(word) > 99:
                    lines.append(line)
                    line = "    #"
                line += " " + word
            if line.strip() != "#":
                lines.append(line)
            if spec.default is None:
                lines.append(
                    f"    # {spec.name}: (optional, unset by default; {spec.kind.__name__})"
                )
            else:
                lines.append(f"    {spec.name}: {_yaml_value(spec.default)}")
    return "\n".join(lines) + "\n"


def estimator_sections() -> list[tuple[str, type, str]]:
    """The parameter sections of ``estimator_node`` (node options, vehicle, radius filter)."""
    from tire_estimation.core.lateral.tyre_force_kf import TyreForceKFConfig
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
    from tire_estimation.core.vehicle import VehicleParams
    from tire_estimation.node_config import EstimatorNodeOptions

    return [
        ("", EstimatorNodeOptions, "node"),
        ("vehicle", VehicleParams, "vehicle (ignored when vehicle_file is set)"),
        ("radius", RadiusEstimatorConfig, "tire-radius MPF (Lundquist et al. 2014)"),
        ("tyre_force", TyreForceKFConfig, "lateral state from tyre forces (Tuononen 2009)"),
        (
            "stiffness",
            StiffnessEstimatorConfig,
            "tyre stiffness and lateral state, noise-adaptive MPF (Berntorp & Di Cairano 2018)",
        ),
    ]


def detector_sections() -> list[tuple[str, type, str]]:
    """The parameter sections of ``detector_node`` (node options, vehicle identity, CUSUM)."""
    from tire_estimation.core.deflation.config import DeflationDetectorConfig
    from tire_estimation.node_config import DetectorNodeOptions, VehicleIdentity

    return [
        ("", DetectorNodeOptions, "node"),
        ("vehicle", VehicleIdentity, "vehicle identity (ignored when vehicle_file is set)"),
        ("detector", DeflationDetectorConfig, "CUSUM deflation detector (Lundquist et al. 2014)"),
    ]


NODES = {"estimator_node": estimator_sections, "detector_node": detector_sections}


if __name__ == "__main__":
    import sys

    node = sys.argv[1] if len(sys.argv) > 1 else "estimator_node"
    print(render_params_yaml(node, NODES[node]()), end="")
