"""Checks of a saved estimator state: numbers, vectors, covariances, dof, stamps, keys."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core import state_checks as checks
from tire_estimation.errors import InputError


def test_the_radius_band_is_a_fraction_of_the_nominal_radius() -> None:
    # 25 %: a tyre of another size than vehicle.yaml states, not a unit or a diameter
    assert checks.radius_error_limit_m(0.31) == pytest.approx(0.0775)
    # unknown vehicle: the largest nominal radius a vehicle description allows (1.5 m)
    assert checks.radius_error_limit_m() == pytest.approx(0.375)


@pytest.mark.parametrize(
    ("value", "reason"),
    [
        (True, "not a number"),
        ("1.0", "not a number"),
        (None, "not a number"),
        ([1.0], "not a number"),
        (10**500, "too large"),
        (math.nan, "not finite"),
        (-math.inf, "not finite"),
    ],
)
def test_number_rejects_what_is_not_a_finite_number(value: object, reason: str) -> None:
    with pytest.raises(InputError, match=reason) as info:
        checks.number("state", "x", value)
    assert info.value.kind == "state"


def test_number_bounded_and_stamp() -> None:
    assert checks.number("k", "x", 3) == 3.0
    assert checks.bounded("k", "x", 0.5, 0.0, 1.0) == 0.5
    with pytest.raises(InputError, match=r"x=2 is outside \[0, 1\]"):
        checks.bounded("k", "x", 2, 0.0, 1.0)
    assert checks.stamp_ns("k", "t", None) is None
    assert checks.stamp_ns("k", "t", 1_700_000_000_000_000_000) == 1_700_000_000_000_000_000
    for bad in (1.5, True, -1, 1 << 63, "1"):
        with pytest.raises(InputError, match="t="):
            checks.stamp_ns("k", "t", bad)


def test_vector_length_and_band() -> None:
    np.testing.assert_array_equal(checks.vector("k", "m", [1e-3, -2e-3], 2, 0.01), [1e-3, -2e-3])
    for bad, reason in (([1.0], "list of 2"), ("ab", "list of 2"), ({"a": 1}, "list of 2"),
                        ([0.02, 0.0], "outside"), ([0.0, "x"], r"m\[1\]")):  # fmt: skip
        with pytest.raises(InputError, match=reason):
            checks.vector("k", "m", bad, 2, 0.01)


@pytest.mark.parametrize(
    ("matrix", "reason"),
    [
        ([[0.0, 0.0], [0.0, 0.0]], "not positive definite"),
        ([[-1e-6, 0.0], [0.0, -1e-6]], "not positive definite"),
        ([[1e-6, 2e-6], [2e-6, 1e-6]], "not positive definite"),
        ([[1e-6, 1e-7], [0.0, 1e-6]], "not symmetric"),
        ([[1.0, 0.0], [0.0, 1.0]], "standard deviations"),
        ([[1e-30, 0.0], [0.0, 1e-6]], "standard deviations"),
        ([[1e-6, 0.0]], "2 x 2"),
        ([[1e-6, 0.0], [0.0]], "list of 2"),
        ([[1e-6, math.nan], [math.nan, 1e-6]], "not finite"),
    ],
)
def test_covariance_rejects(matrix: list[list[float]], reason: str) -> None:
    with pytest.raises(InputError, match=reason):
        checks.covariance("k", "c", matrix, 2, 1e-9, 0.01)


def test_covariance_accepts_a_symmetric_positive_definite_matrix() -> None:
    c = checks.covariance("k", "c", [[1e-6, 5e-7], [5e-7 * (1 + 1e-12), 1e-6]], 2, 1e-9, 0.01)
    np.testing.assert_allclose(c, c.T, rtol=0, atol=0)


def test_dof_range_keys_choice_and_shown() -> None:
    assert checks.dof("k", "dof", 250.0, 2) == 250.0
    for bad in (3.0, 0.0, 1e10, 1e308):
        with pytest.raises(InputError, match="dof"):
            checks.dof("k", "dof", bad, 2)
    d = {"a": 1, "b": 2}
    assert checks.require_keys("k", "s", d, ("a",), ("b",)) is d
    with pytest.raises(InputError, match="lacks c"):
        checks.require_keys("k", "s", d, ("a", "c"), ("b",))
    with pytest.raises(InputError, match="unknown keys b"):
        checks.require_keys("k", "s", d, ("a",))
    with pytest.raises(InputError, match="not an object"):
        checks.require_keys("k", "s", [1], ())
    checks.choice("k", "version", 1, 1)
    with pytest.raises(InputError, match="expected 1"):
        checks.choice("k", "version", True, 1)
    assert checks.shown(10**5000) == "<huge int>"
    assert len(checks.shown(list(range(1000)))) == 60
