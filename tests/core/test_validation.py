"""The shared validators of core/validation.py."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import pytest

from tire_estimation.core.validation import (
    Checked,
    NonNegative,
    Positive,
    field_rules,
    in_range,
    one_of,
    require_choice,
    require_vector3,
)
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


def test_an_unknown_key_names_the_nearest_valid_one() -> None:
    from tire_estimation.core.validation import known_names, reject_unknown_keys

    valid = ("n_particles", "seed", "forgetting_factor")
    reject_unknown_keys({"seed": 1}, valid)
    with pytest.raises(ConfigError, match=r"radius\.n_particle=3: unknown key; did you mean "
                       r"radius\.n_particles\?$"):  # fmt: skip
        reject_unknown_keys({"seed": 1, "n_particle": 3}, valid, prefix="radius.")
    # none near: the first valid keys; mixed key types are no TypeError (no sorting)
    with pytest.raises(ConfigError, match="unknown key; valid: forgetting_factor, n_particles"):
        reject_unknown_keys({"zzz": 1, 2: 3}, valid)
    with pytest.raises(VehicleConfigError, match="keys must be text, not int"):
        reject_unknown_keys({2: 3, "zzz": 1}, valid, VehicleConfigError)
    assert known_names("ece_r46", ["city", "ece_r64"]) == "did you mean ece_r64?"
    assert known_names("moon", "abcdefg") == "known: a, b, c, d, e, ..."


@pytest.mark.parametrize(
    ("value", "field", "reason"),
    [
        ((0.0, 1.0), "p", "3 numbers"),
        ([0.0, 1.0, 2.0], "p", "3 numbers"),
        ((0.0, "a", 2.0), "p[1]", "must be a number"),
        ((0.0, 1.0, float("inf")), "p[2]", "must be finite"),
        ((-2.5, 0.0, 0.0), "p[0]", r"within \+-2 m"),
    ],
)
def test_a_vector3_is_three_finite_numbers_within_the_limit(
    value: object, field: str, reason: str
) -> None:
    require_vector3("p", (1.0, -2.0, 0.5), 2.0, VehicleConfigError, " m")
    with pytest.raises(VehicleConfigError, match=reason) as info:
        require_vector3("p", value, 2.0, VehicleConfigError, " m")
    assert info.value.field == field


@dataclass(frozen=True)
class _Base(Checked):
    gain: Positive = 1.0
    share: Annotated[float, in_range(0.0, 1.0)] = 0.5
    label: str = "x"


@dataclass(frozen=True)
class _Child(_Base):
    ERROR = VehicleConfigError
    PREFIX = "child."

    mode: Annotated[str, one_of(("a", "b"))] = "a"
    low: NonNegative = 0.0
    high: NonNegative = 1.0

    def check(self) -> None:
        if self.high < self.low:
            raise ConfigError("child.high", self.high, f"must be >= low={self.low}")


def test_field_rules_read_the_annotations_in_field_order_with_the_bases() -> None:
    rules = field_rules(_Child)
    assert list(rules) == ["gain", "share", "mode", "low", "high"]  # label has no rule
    assert rules["share"].text() == "in [0, 1]"
    assert rules["mode"].text() == "one of (a, b)"
    assert rules["gain"].text() == "> 0"


@pytest.mark.parametrize(
    ("kwargs", "field", "value"),
    [
        ({"gain": 0.0}, "gain", 0.0),
        ({"share": 1.5}, "share", 1.5),
        ({"gain": float("nan")}, "gain", "nan"),
    ],
)
def test_construction_checks_each_annotated_rule(
    kwargs: dict[str, float], field: str, value: object
) -> None:
    with pytest.raises(ConfigError) as info:
        _Base(**kwargs)
    assert info.value.field == field
    assert str(info.value.value) == str(value)


def test_a_subclass_names_fields_with_its_prefix_raises_its_error_and_runs_check() -> None:
    with pytest.raises(VehicleConfigError) as info:
        _Child(mode="c")
    assert info.value.field == "child.mode"
    with pytest.raises(VehicleConfigError) as info:
        _Child(gain=-1.0)
    assert info.value.field == "child.gain"
    with pytest.raises(ConfigError, match=r"must be >= low=2\.0"):
        _Child(low=2.0, high=1.0)
    assert _Child(low=1.0, high=2.0).high == 2.0
