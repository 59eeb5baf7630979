"""The traction slip of driven rear wheels, learned against the free-rolling front axle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.drive_slip import (
    GRAVITY_M_S2,
    ROLLING_RESISTANCE_COEFFICIENT,
    DriveSlip,
)
from tire_estimation.core.vehicle import VehicleParams

RADIUS_M = 0.31
FRONT_RADIUS_M = 0.3105  # the axles' radii differ: the regression's intercept takes it
C1_TRUE = 0.01  # m / C_x: 1500 kg over 150 kN per axle
C2_TRUE = 2.8e-6  # rho C_d A / (2 C_x)


def _drive(
    slip: DriveSlip,
    seconds: float,
    rng: np.random.Generator,
    front_measured: bool = True,
    amplitude_m_s: float = 6.0,
    noise: float = 1e-3,
    driven: str = "rear",
) -> tuple[np.ndarray, np.ndarray]:
    """A straight drive at 20 +- ``amplitude_m_s`` m/s (a sine of 40 s) whose rear wheels slip by
    ``c1 (a + c_rr g) + c2 v^2`` while they drive, ``noise`` relative wheel-speed noise per
    sample at 100 Hz (``driven="front"``: the front wheels slip instead). Returns the corrected
    rear speeds times the rear radius and the true speeds, over the last 100 s."""
    out, truth = [], []
    n = int(seconds * 100)
    omega = 2 * math.pi / 40.0
    for k in range(n):
        t = k * 0.01
        v = 20.0 + amplitude_m_s * math.sin(omega * t)
        a = amplitude_m_s * omega * math.cos(omega * t)
        # the rear wheels slip while they drive; braking (a negative force) is not modelled
        kappa = C1_TRUE * (a + ROLLING_RESISTANCE_COEFFICIENT * GRAVITY_M_S2) + C2_TRUE * v * v
        kappa = max(kappa, 0.0)
        wf = v * (1.0 + (kappa if driven == "front" else 0.0)) / FRONT_RADIUS_M
        wr = v * (1.0 + (kappa if driven == "rear" else 0.0)) / RADIUS_M
        ws = np.array([wf, wf, wr, wr]) * (1.0 + noise * rng.standard_normal(4))
        corrected = slip.correct(round(t * 1e9), ws, 0.0, 0.5, front_measured)
        if k >= n - 10_000:
            out.append(0.5 * RADIUS_M * (corrected[2] + corrected[3]))
            truth.append(v)
    return np.array(out), np.array(truth)


def _vehicle(drive: str, stiffness_n: float = 150_000.0) -> VehicleParams:
    return VehicleParams(
        drive=drive,
        nominal_tire_radius_m=RADIUS_M,
        mass_kg=1500.0,
        longitudinal_stiffness_rear_n=stiffness_n,
        longitudinal_stiffness_front_n=stiffness_n,
    )


@pytest.mark.parametrize("stiffness_n", [75_000.0, 300_000.0])
def test_the_slip_is_learned_from_a_prior_twice_off_and_removed(stiffness_n: float) -> None:
    slip = DriveSlip(_vehicle("rear", stiffness_n))
    assert slip.prior[0] == pytest.approx(1500.0 / stiffness_n)
    rolled, truth = _drive(slip, 600.0, np.random.default_rng(0))
    assert slip.learned
    c1, c2 = slip.coefficients
    assert c1 == pytest.approx(C1_TRUE, rel=0.1)
    assert c2 == pytest.approx(C2_TRUE, rel=0.1)
    # the corrected rear wheels roll the true speed: the mean slip (0.3-0.5 %) is gone to 0.01 %
    assert abs(np.mean(rolled / truth - 1.0)) < 1e-4
    assert slip.summary()["source"] == "learned"
    assert 0.003 < slip.mean_slip < 0.006
    # what the slip model adds to the radii's std: mostly the assumed rolling resistance
    # (0.31 m x 0.01 x 9.81 m/s^2 x 0.003 = 0.09 mm)
    assert 0.08e-3 < np.sqrt(slip.radius_variance_m2()) < 0.15e-3


def test_a_front_driven_car_is_watched_and_left_alone() -> None:
    """Its front wheels slip (the slope comes out negative): nothing is corrected, and the rear
    wheel speeds, which roll freely, come through as they are."""
    slip = DriveSlip(_vehicle("front"))
    rolled, truth = _drive(slip, 600.0, np.random.default_rng(1), driven="front")
    assert slip.learnable and not slip.enabled and not slip.detected
    assert abs(np.mean(rolled / truth - 1.0)) < 1e-4
    assert slip.summary()["source"] == "off" and slip.radius_variance_m2() == 0.0


def test_rear_wheels_that_slip_under_a_front_drive_are_found_and_corrected() -> None:
    """vehicle.yaml says front, the rear wheels slip (the mean slip is 0.1-0.3 %): within a few
    minutes the slope says rear-driven, the correction comes on and the summary says so."""
    slip = DriveSlip(_vehicle("front"))
    rolled, truth = _drive(slip, 600.0, np.random.default_rng(1))
    assert slip.detected and slip.enabled and slip.learned
    assert slip.coefficients[0] == pytest.approx(C1_TRUE, rel=0.1)
    assert abs(np.mean(rolled / truth - 1.0)) < 1e-4
    assert slip.summary()["detected"] is True


def test_a_front_driven_car_passes_a_sample_through() -> None:
    slip = DriveSlip(_vehicle("front"))
    ws = np.array([60.0, 60.0, 61.0, 61.0])
    assert slip.correct(0, ws, 0.0, 0.5, True) is ws


def test_all_wheel_drive_uses_the_prior_and_says_so() -> None:
    slip = DriveSlip(_vehicle("all"))
    # equal slip on both axles: the force splits like the stiffnesses
    assert slip.prior[0] == pytest.approx(1500.0 / 300_000.0)
    _drive(slip, 120.0, np.random.default_rng(2))
    assert not slip.learned
    assert slip.coefficients == slip.prior
    assert slip.summary()["source"] == "prior"


def test_front_wheels_filled_in_from_the_rear_teach_nothing() -> None:
    slip = DriveSlip(_vehicle("rear", 75_000.0))
    _drive(slip, 300.0, np.random.default_rng(3), front_measured=False)
    assert not slip.learned
    assert slip.bins == 0.0
    # the prior is applied all the same, and its whole size is counted as uncertain
    assert slip.mean_slip > 0.0
    assert np.sqrt(slip.radius_variance_m2()) > RADIUS_M * slip.mean_slip


def test_a_rear_wheel_not_reported_passes_through() -> None:
    slip = DriveSlip(_vehicle("rear"))
    ws = np.array([60.0, 60.0, math.nan, 61.0])
    assert slip.correct(0, ws, 0.0, 0.5, True) is ws


def test_a_cruise_too_steady_to_tell_the_slope_keeps_the_prior() -> None:
    """Speed 20 +- 0.02 m/s: the acceleration's spread (0.002 m/s^2) is far below the noise the
    wheel speeds (0.3 % per sample) put into it (0.007 m/s^2); its slope would come out near
    zero (errors in variables), so the prior is kept and said to be."""
    slip = DriveSlip(_vehicle("rear", 75_000.0))
    _drive(slip, 600.0, np.random.default_rng(4), amplitude_m_s=0.02, noise=3e-3)
    assert slip.bins > 100.0
    assert slip.reliability < 0.5
    assert not slip.learned and slip.coefficients == slip.prior


def test_the_noise_in_the_acceleration_does_not_shrink_the_slope() -> None:
    """Speed 20 +- 0.15 m/s, 0.3 % wheel-speed noise: 14 % of the acceleration's spread is
    noise, which would shrink a plain least-squares slope by as much; the corrected least
    squares recovers it (seeds 6-11: 0.0097 mean, 0.0008 std each; plain least squares on
    the same drives 0.0083; on this one 0.0100 against 0.0086)."""
    slip = DriveSlip(_vehicle("rear"))
    _drive(slip, 1800.0, np.random.default_rng(7), amplitude_m_s=0.15, noise=3e-3)
    assert 0.8 < slip.reliability < 0.9
    assert slip.coefficients[0] == pytest.approx(C1_TRUE, abs=0.0005)
    assert slip.coefficient_std[0] == pytest.approx(0.0008, rel=0.1)
