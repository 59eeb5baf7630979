"""The shared input checks: covariances, repeated names, drop counter keys."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.input_checks import (
    checked_covariance,
    drop_key,
    merged_counts,
    unique_names,
)
from tire_estimation.errors import InputError

NAN, INF = float("nan"), float("inf")
GOOD = [2.25, 0.5, 0.0, 0.5, 2.25, 0.0, 0.0, 0.0, 4.0]


@pytest.mark.parametrize(
    "values",
    [
        GOOD,
        [2.25, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 0.0],  # vertical not known: semi-definite
        [1.0, 0.3, 0.3, 1.0],  # 2x2
        np.diag([1e-6, 1e-6, 1e6]).ravel(),
    ],
)
def test_valid_covariances_pass_unchanged(values: list[float]) -> None:
    cov = checked_covariance(values, "cov")
    assert cov is not None
    np.testing.assert_array_equal(cov.ravel(), np.asarray(values, dtype=float))


@pytest.mark.parametrize("values", [None, [0.0] * 9, [0.0] * 4])
def test_absent_or_all_zero_is_not_reported(values: list[float] | None) -> None:
    assert checked_covariance(values, "cov") is None


@pytest.mark.parametrize(
    "values",
    [
        [NAN, *GOOD[1:]],
        [*GOOD[:8], INF],
        [*GOOD[:4], -INF, *GOOD[5:]],
        [-2.25, *GOOD[1:]],  # negative horizontal variance
        [*GOOD[:8], -4.0],  # negative vertical variance
        [2.25, 3.0, 0.0, 3.0, 2.25, 0.0, 0.0, 0.0, 4.0],  # horizontal correlation > 1
        [2.25, 0.0, 5.0, 0.0, 2.25, 0.0, 5.0, 0.0, 4.0],  # vertical correlation > 1
        [1.0, 0.9, 0.9, 0.9, 1.0, -0.9, 0.9, -0.9, 1.0],  # minors >= 0, determinant < 0
        [2.25, 0.5, 0.0, -0.5, 2.25, 0.0, 0.0, 0.0, 4.0],  # not symmetric
        [0.0, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 4.0],  # east variance 0
        ["a"] * 9,
    ],
)
def test_bad_covariances_are_refused(values: list[object]) -> None:
    with pytest.raises(InputError) as err:
        checked_covariance(values, "cov")
    assert err.value.kind == "bad_covariance"


def test_a_covariance_of_another_size_is_wrong_length() -> None:
    with pytest.raises(InputError) as err:
        checked_covariance([1.0] * 6, "cov")
    assert err.value.kind == "wrong_length"


def test_a_known_name_given_twice_is_refused() -> None:
    known = {"wheel_fl": 0, "wheel_rl": 2}
    unique_names(["wheel_fl", "engine", "engine", "wheel_rl"], known, "duplicate_wheel")
    with pytest.raises(InputError) as err:
        unique_names(["wheel_fl", "wheel_rl", "wheel_fl"], known, "duplicate_wheel")
    assert err.value.kind == "duplicate_wheel"


def test_drop_counters_are_keyed_by_stream_and_kind() -> None:
    assert drop_key("gnss_fix", "bad_covariance") == "gnss_fix:bad_covariance"
    assert merged_counts({"a:x": 1, "b:y": 2}, {"a:x": 3}) == {"a:x": 4, "b:y": 2}
