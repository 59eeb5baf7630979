"""Parameter mapping: dataclass fields <-> ROS parameters, and the documented YAML."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.params import (
    NODES,
    attribute_docs,
    build_config,
    estimator_sections,
    parameter_specs,
    render_params_yaml,
)

CONFIG_DIR = Path(__file__).parents[1] / "src/tire_estimation/config"
YAML_PATH = CONFIG_DIR / "estimator.yaml"


@pytest.mark.parametrize("node", sorted(NODES))
def test_committed_yaml_matches_the_code(node: str) -> None:
    path = CONFIG_DIR / f"{node.removesuffix('_node')}.yaml"
    assert path.read_text() == render_params_yaml(node, NODES[node]())


def test_every_parameter_is_documented_with_its_default() -> None:
    text = YAML_PATH.read_text()
    params = yaml.safe_load(text)["estimator_node"]["ros__parameters"]
    for prefix, cls, _ in estimator_sections():
        for spec in parameter_specs(cls, prefix):
            assert spec.doc, f"{spec.name} has no description"
            if spec.default is None:
                assert f"# {spec.name}: (optional" in text
            else:
                assert params[spec.name] == spec.default


def test_yaml_loads_back_into_the_dataclasses() -> None:
    params = yaml.safe_load(YAML_PATH.read_text())["estimator_node"]["ros__parameters"]
    assert build_config(RadiusEstimatorConfig, "radius", params) == RadiusEstimatorConfig()
    assert build_config(VehicleParams, "vehicle", params) == VehicleParams()


def test_wrong_type_and_out_of_range_name_the_parameter() -> None:
    with pytest.raises(ConfigError, match=r"radius\.n_particles"):
        build_config(RadiusEstimatorConfig, "radius", {"radius.n_particles": "many"})
    with pytest.raises(ConfigError, match="n_particles"):
        build_config(RadiusEstimatorConfig, "radius", {"radius.n_particles": 2})
    with pytest.raises(ConfigError, match=r"vehicle\.gnss_antenna_position_m"):
        build_config(VehicleParams, "vehicle", {"vehicle.gnss_antenna_position_m": ["a"]})


def test_attribute_docs_parses_google_style() -> None:
    class Example:
        """Doc.

        Attributes:
            speed_m_s: the speed, m/s. Default 3.
                Continued line.
            name: a name.
        """

    assert attribute_docs(Example) == {
        "speed_m_s": "the speed, m/s. Default 3. Continued line.",
        "name": "a name.",
    }
