"""The shared input checks: covariances, repeated names, drop counter keys."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.input_checks import (
    checked_covariance,
    drop_key,
    finite_vector,
    merged_counts,
    stamp_after,
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


@pytest.mark.parametrize(
    ("value", "n", "expected"),
    [
        (np.array([1.0, -2.0, 3.0]), 3, [1.0, -2.0, 3.0]),
        ([1, 2, 3], 3, [1.0, 2.0, 3.0]),
        (np.array([[1.0], [2.0]]), 2, [1.0, 2.0]),
        (np.array([1e308, 1e308]), 2, [1e308, 1e308]),  # finite, their sum is not
        (0.25, 1, [0.25]),
        (np.float32(0.5), 1, [0.5]),
    ],
)
def test_finite_vectors_pass_as_float_vectors(value: object, n: int, expected: list) -> None:
    v = finite_vector(value, n, "x")
    assert v.dtype == np.float64 and v.shape == (n,)
    assert v.tolist() == expected


@pytest.mark.parametrize(
    ("value", "n", "kind"),
    [
        (np.array([1.0, NAN, 3.0]), 3, "nan"),
        (np.array([INF, 1.0, 1.0]), 3, "nan"),
        (np.array([INF, -INF]), 2, "nan"),
        ([1.0, NAN], 2, "nan"),
        (NAN, 1, "nan"),
        (INF, 1, "nan"),
        (np.array([1.0, 2.0]), 3, "wrong_length"),
        (1.0, 2, "wrong_length"),
    ],
)
def test_a_vector_not_finite_or_of_another_length_is_refused(
    value: object, n: int, kind: str
) -> None:
    with pytest.raises(InputError) as err:
        finite_vector(value, n, "x")
    assert err.value.kind == kind


def test_a_stamp_must_be_an_integer_after_the_last() -> None:
    assert stamp_after("imu", 5, None) == 5
    assert stamp_after("imu", 6, 5) == 6
    stamp = stamp_after("imu", np.int64(7), 6)
    assert stamp == 7 and type(stamp) is int
    for t_ns, last, kind in [
        (5, 5, "duplicate"),
        (4, 5, "out_of_order"),
        (True, None, "bad_stamp"),
        (5.0, None, "bad_stamp"),
    ]:
        with pytest.raises(InputError) as err:
            stamp_after("imu", t_ns, last)
        assert err.value.kind == kind
