"""The checked constructors of the typed samples (shared by the node and the bag reader)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from tire_estimation.core.samples import (
    COVARIANCE_TYPE_UNKNOWN,
    STATUS_NO_FIX,
    GnssFix,
    GnssVelocity,
    ImuSample,
    MeasuredVelocity,
    Steering,
)
from tire_estimation.errors import InputError

COV = [2.25, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0, 4.0]
KNOWN = 3


def _fix(alt: float = 80.0, cov: list[float] = COV, cov_type: int = KNOWN, status: int = 0):
    return GnssFix.from_navsat(10, status, 58.4, 15.6, alt, cov, cov_type)


def test_a_navsat_fix_with_a_known_covariance_keeps_it() -> None:
    fix = _fix()
    assert fix.covariance_m2 is not None
    np.testing.assert_array_equal(fix.covariance_m2.ravel(), COV)
    assert (fix.t_ns, fix.lat_deg, fix.lon_deg, fix.alt_m) == (10, 58.4, 15.6, 80.0)


def test_covariance_type_unknown_is_not_read() -> None:
    assert _fix(cov=[float("nan")] * 9, cov_type=COVARIANCE_TYPE_UNKNOWN).covariance_m2 is None


@pytest.mark.parametrize(
    ("kwargs", "kind"),
    [
        ({"cov": [float("nan"), *COV[1:]]}, "bad_covariance"),
        ({"cov": [*COV[:8], -4.0]}, "bad_covariance"),
        ({"status": STATUS_NO_FIX}, "no_fix"),
        ({"alt": 2e5}, "out_of_range"),
    ],
)
def test_bad_fixes_are_refused_with_their_kind(kwargs: dict, kind: str) -> None:
    with pytest.raises(InputError) as err:
        _fix(**kwargs)
    assert err.value.kind == kind


@pytest.mark.parametrize("alt", [float("nan"), float("inf")])
def test_a_fix_without_altitude_is_kept_with_nan(alt: float) -> None:
    assert math.isnan(_fix(alt=alt).alt_m)


NAN = float("nan")
GOOD_IMU = ([0.0, 0.0, 0.1], [0.5, 0.0, 9.81])


@pytest.mark.parametrize(
    ("make", "kind"),
    [
        (lambda: Steering.checked(10, "left"), "bad_value"),
        (lambda: Steering.checked(10, NAN), "nan"),
        (lambda: Steering.checked(10, 1.3), "out_of_range"),
        (lambda: MeasuredVelocity.checked(10, "fast"), "bad_value"),
        (lambda: MeasuredVelocity.checked(10, float("inf")), "nan"),
        (lambda: ImuSample.checked(10, [0.0, 0.0], GOOD_IMU[1]), "wrong_shape"),
        (lambda: ImuSample.checked(10, [0.0, NAN, 0.0], GOOD_IMU[1]), "nan"),
        (lambda: ImuSample.checked(10, GOOD_IMU[0], [0.0, 0.0, NAN]), "nan"),
        (lambda: ImuSample.checked(10, [40.0, 0.0, 0.0], GOOD_IMU[1]), "out_of_range"),
        (lambda: ImuSample.checked(10, GOOD_IMU[0], [0.0, 0.0, 250.0]), "out_of_range"),
        (lambda: GnssVelocity.checked(10, [1.0, NAN, 0.0], None), "nan"),
        (lambda: GnssVelocity.checked(10, [0.0, 250.0, 0.0], None), "out_of_range"),
    ],
)
def test_bad_scalars_and_vectors_are_refused_with_their_kind(
    make: Callable[[], object], kind: str
) -> None:
    with pytest.raises(InputError) as err:
        make()
    assert err.value.kind == kind


def test_good_samples_keep_their_values() -> None:
    assert Steering.checked(10, "0.25").angle_rad == 0.25
    assert MeasuredVelocity.checked(10, -3).vx_m_s == -3.0
    imu = ImuSample.checked(10, *GOOD_IMU)
    np.testing.assert_array_equal(imu.angular_velocity_rad_s, GOOD_IMU[0])
    np.testing.assert_array_equal(imu.linear_acceleration_m_s2, GOOD_IMU[1])
    vel = GnssVelocity.checked(10, [1.0, -2.0, 0.1], None)
    np.testing.assert_array_equal(vel.velocity_enu_m_s, [1.0, -2.0, 0.1])
    assert vel.covariance_m2_s2 is None
