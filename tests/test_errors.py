"""The package's errors: short values in messages, and errors that survive pickling (a worker
process raises them to the campaign's or the fleet replay's parent)."""

from __future__ import annotations

import pickle

import pytest

from tire_estimation.errors import (
    BagError,
    ConfigError,
    InputError,
    ScenarioError,
    StateFileError,
    VehicleConfigError,
    short_repr,
)


@pytest.mark.parametrize(
    "error",
    [
        ConfigError("radius.n_particles", 0, "must be >= 1"),
        VehicleConfigError("vehicle.track_width_m", -1.0, "must be within [0.3, 3.5]"),
        InputError("nan", "no finite wheel speed"),
        BagError("no /vehicle/wheel_speeds in BAG"),
        ScenarioError("unknown scenario 'x'"),
        StateFileError("not UTF-8 JSON"),
    ],
)
def test_an_error_pickles_to_the_same_type_message_and_fields(error: Exception) -> None:
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error)
    assert str(back) == str(error)
    assert vars(back) == vars(error)


def test_a_config_error_names_the_field_and_a_short_value() -> None:
    err = ConfigError("sensors.wheel_speed_teeth", list(range(10_000)), "must be an integer")
    assert str(err).startswith("sensors.wheel_speed_teeth=[0, 1, 2, 3, 4, 5, ...]: ")
    assert err.field == "sensors.wheel_speed_teeth"
    assert len(short_repr("x" * 10_000)) <= 80
