"""The shared validators of core/validation.py."""

from __future__ import annotations

import pytest

from tire_estimation.core.validation import require_choice
from tire_estimation.errors import ConfigError, VehicleConfigError


def test_require_choice_names_the_field_the_value_and_the_choices() -> None:
    require_choice("mode", "b", ("a", "b"))
    with pytest.raises(ConfigError, match=r"mode.*'c'.*must be one of \('a', 'b'\)"):
        require_choice("mode", "c", ("a", "b"))
    # a mapping lists its keys; an unhashable value is rejected, not a TypeError
    with pytest.raises(ConfigError, match=r"must be one of \('x', 'y'\)"):
        require_choice("mode", ["x"], {"x": 1, "y": 2})
    with pytest.raises(VehicleConfigError):
        require_choice("vehicle.drive", "none", ("front", "rear"), VehicleConfigError)
