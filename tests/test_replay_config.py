"""The replay's parameter file: its layouts, and no key that is not applied."""

from __future__ import annotations

from pathlib import Path

import pytest

from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.errors import ConfigError
from tire_estimation.replay_config import (
    SECTIONS,
    load_config_sections,
    parse_sections,
    section_config,
)

PARAMS = Path(__file__).resolve().parents[1] / "src/tire_estimation/config/estimator.yaml"


def test_the_node_parameter_file_loads_and_builds_every_section() -> None:
    sections = load_config_sections(PARAMS)
    assert set(sections) == {"", "vehicle", "radius", "tyre_force", "stiffness"}
    for prefix, values in sections.items():
        section_config(SECTIONS[prefix], prefix, values)  # every default is valid


def test_the_layouts_mix_and_an_empty_section_is_allowed() -> None:
    data = {
        "/**": {"ros__parameters": {"radius.seed": 3, "stiffness_enabled": False}},
        "estimator_node": {"ros__parameters": {"radius": {"n_particles": 100}, "detector": None}},
    }
    assert parse_sections(data) == {
        "radius": {"seed": 3, "n_particles": 100},
        "": {"stiffness_enabled": False},
    }
    assert parse_sections({"radius.seed": 1, "linear_kf": {"max_gap_s": 1.0}}) == {
        "radius": {"seed": 1},
        "linear_kf": {"max_gap_s": 1.0},
    }
    assert parse_sections(None) == {}


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"radius": {"n_particle": 1}}, "radius.n_particle=1: unknown key; did you mean radius"),
        ({"radius.n_particle": 1}, "did you mean radius.n_particles?"),
        ({"radiu.n_particles": 1}, "did you mean radius.n_particles?"),
        ({"radiu": {"seed": 1}}, "unknown section; did you mean radius?"),
        ({"stiffness_enable": 1}, "did you mean stiffness_enabled?"),
        ({"radius": 5}, "radius=5: must be a mapping of radius.* parameters"),
        ({"radius": {"seed": 1}, "radius.seed": 2}, "radius.seed=2: given twice"),
        ({"estimator_node": {"ros__parameter": {}}}, "did you mean estimator_node.ros__param"),
        ({"estimator_nod": {"ros__parameters": {}}}, "unknown node; did you mean estimator_node"),
        ({"detector_node": {"ros__parameters": {}}}, "not estimator_node"),
        ({"vehicle": {"mas_kg": 1}}, "did you mean vehicle.mass_kg?"),
        ({3: 1}, "3=1: keys must be text"),
    ],
)
def test_a_key_that_would_not_apply_is_an_error(data: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace(".", r"\.").replace("*", r"\*")):
        parse_sections(data)


def test_section_values_name_the_key_and_the_type() -> None:
    with pytest.raises(ConfigError, match=r"radius\.n_particles='many': must be of type int"):
        section_config(RadiusEstimatorConfig, "radius", {"n_particles": "many"})
    with pytest.raises(ConfigError, match=r"radius\.forgetting_factor=7\.0: must be within"):
        section_config(RadiusEstimatorConfig, "radius", {"forgetting_factor": 7})
