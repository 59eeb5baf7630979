"""The online road grade: the GNSS altitude's grade checked against the IMU's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.road_grade import (
    G_M_S2,
    IMU_GRADE_STD_RAD,
    RoadGradeFit,
    SlidingLine,
)

DT_S = 0.01  # wheel speeds and IMU at 100 Hz, fixes at 10 Hz


def _drive(
    fit: RoadGradeFit,
    seconds: float,
    grade_rad: float,
    altitude_slope: float,
    imu: bool = True,
    accel_m_s2: float = 0.0,
    imu_bias_m_s2: float = 0.0,
    rng: np.random.Generator | None = None,
) -> None:
    """Drive ``seconds`` at 15 m/s plus ``accel_m_s2`` t on a road of grade ``grade_rad``;
    the fixes' altitude rises by ``altitude_slope`` per metre travelled (not the road's: a
    wandering receiver), the IMU's specific force is ``dv/dt + g sin(theta)`` plus a bias."""
    v = 15.0
    for k in range(int(seconds / DT_S)):
        v_next = v + accel_m_s2 * DT_S
        fx = accel_m_s2 + G_M_S2 * math.sin(grade_rad) + imu_bias_m_s2
        if rng is not None:
            fx += rng.normal(0.0, 0.5)  # vibration
        fit.roll(DT_S, v_next, fx if imu else None)
        v = v_next
        if k % 10 == 9:
            fit.fix(200.0 + altitude_slope * fit.distance_m)


def test_imu_grade_from_the_specific_force_while_accelerating() -> None:
    """f_x = dv/dt + g sin(theta): at 1.5 m/s^2 on a 5 % grade the IMU grade is the road's,
    not the acceleration's, and confirms the altitude grade."""
    fit = RoadGradeFit()
    _drive(fit, 12.0, 0.05, math.sin(0.05), accel_m_s2=1.5)
    assert fit.imu_grade_rad == pytest.approx(0.05, abs=2e-3)
    assert fit.altitude_grade_rad == pytest.approx(0.05, abs=1e-9)
    assert fit.source == "altitude"
    assert fit.grade_rad == fit.altitude_grade_rad
    assert fit.counts["imu"] == 0 and fit.counts["altitude"] > 50


def test_a_wandering_altitude_is_replaced_by_the_imu_grade() -> None:
    """On a flat road whose fixes climb by 20 % (an altitude drift) the IMU's grade, offset
    by a 0.1 m/s^2 bias (0.01 rad), is used."""
    fit = RoadGradeFit()
    _drive(fit, 30.0, 0.0, 0.2, imu_bias_m_s2=0.1, rng=np.random.default_rng(3))
    assert fit.altitude_grade_rad == pytest.approx(math.asin(0.2), abs=1e-9)
    assert fit.source == "imu"
    assert fit.grade_rad == fit.imu_grade_rad == pytest.approx(0.1 / G_M_S2, abs=3e-3)
    assert fit.check_nis > 100.0
    assert fit.counts["altitude"] == 0 and fit.counts["imu"] > 200


def test_the_check_is_a_chi_square_test_on_the_imu_offset() -> None:
    """An altitude grade 2 IMU stds (of the offset) from the IMU's passes the 99 % test, one
    of 3 stds does not."""
    for sigmas, source in ((2.0, "altitude"), (3.0, "imu")):
        fit = RoadGradeFit()
        _drive(fit, 20.0, 0.0, math.sin(sigmas * IMU_GRADE_STD_RAD))
        assert fit.source == source, sigmas


def test_without_an_imu_the_checked_grade_is_none_and_the_altitude_mode_keeps_it() -> None:
    checked, altitude = RoadGradeFit("checked"), RoadGradeFit("altitude")
    for fit in (checked, altitude):
        _drive(fit, 20.0, 0.03, math.sin(0.03), imu=False)
    assert checked.source == "none" and checked.grade_rad == 0.0
    assert altitude.source == "altitude"
    assert altitude.grade_rad == pytest.approx(0.03, abs=1e-9)


def test_an_imu_gap_restarts_the_imu_grade() -> None:
    """A stale IMU breaks the integral of f_x v: the IMU grade waits for a new quarter
    window (IMU_GRADE_MIN_SPAN_M)."""
    fit = RoadGradeFit()
    _drive(fit, 20.0, 0.04, math.sin(0.04))
    assert fit.source == "altitude"
    _drive(fit, 1.0, 0.04, math.sin(0.04), imu=False)
    _drive(fit, 1.5, 0.04, math.sin(0.04))  # 22 m of IMU: less than a quarter window
    assert fit.source == "none" and math.isnan(fit.imu_grade_rad)
    _drive(fit, 1.0, 0.04, math.sin(0.04))
    assert fit.source == "altitude"
    assert fit.imu_grade_rad == pytest.approx(0.04, abs=1e-3)


def test_a_restart_clears_the_imu_grade() -> None:
    """A wheel-speed gap restarts the IMU altitude (the integral of f_x v misses the gap)."""
    fit = RoadGradeFit()
    _drive(fit, 10.0, 0.02, math.sin(0.02))
    assert math.isfinite(fit.imu_grade_rad)
    fit.restart_imu()
    _drive(fit, 1.0, 0.02, math.sin(0.02))
    assert fit.source == "none" and math.isnan(fit.imu_grade_rad)


def test_sliding_line_slope_variance_matches_least_squares() -> None:
    rng = np.random.default_rng(5)
    fit = SlidingLine(max_points=200)
    s = 1.0e4
    for _ in range(700):
        s += rng.uniform(0.5, 2.5)
        fit.append(s, 3.0 + 0.02 * s + rng.normal(0.0, 1.5))
        while fit.pts[0][0] < s - 100.0:
            fit.popleft()
    a = np.asarray(fit.pts)
    _, cov = np.polyfit(a[:, 0] - a[0, 0], a[:, 1], 1, cov="unscaled")
    resid = a[:, 1] - np.polyval(np.polyfit(a[:, 0], a[:, 1], 1), a[:, 0])
    ref = float(resid @ resid) / (len(a) - 2) * cov[0, 0]
    assert fit.slope_var() == pytest.approx(ref, rel=1e-6)
    assert fit.span() == pytest.approx(a[-1, 0] - a[0, 0])
    fit.clear()
    assert not fit.pts and math.isnan(fit.slope_var())


def test_the_imu_grade_holds_in_reverse() -> None:
    """Reversing at 3 m/s with the nose 5 % up: the road falls along the travel (the fixes'
    altitude drops by sin(0.05) per metre), f_x = dv/dt + g sin(theta_nose). With the signed
    speed in ``f_x v`` the IMU grade is the travel's, -0.05, and confirms the altitude."""
    fit = RoadGradeFit()
    speed = -3.0
    for k in range(int(60.0 / DT_S)):
        fit.roll(DT_S, abs(speed), G_M_S2 * math.sin(0.05), speed)
        if k % 10 == 9:
            fit.fix(200.0 - math.sin(0.05) * fit.distance_m)
    assert fit.imu_grade_rad == pytest.approx(-0.05, abs=2e-3)
    assert fit.source == "altitude"
    assert fit.counts["imu"] == 0


def _flat_drive(fit: RoadGradeFit, seconds: float, bias_m_s2: float, altitude, seed: int = 0):
    """``seconds`` at 15 m/s on a flat road, the IMU's specific force offset by ``bias_m_s2``
    (an accelerometer bias, or g sin of a mounting pitch), the fixes' altitude ``altitude(s)``
    plus 1 m of white noise."""
    rng = np.random.default_rng(seed)
    for k in range(int(seconds / DT_S)):
        fit.roll(DT_S, 15.0, bias_m_s2 + rng.normal(0.0, 0.3))
        if k % 10 == 9:
            fit.fix(200.0 + altitude(fit.distance_m) + rng.normal(0.0, 1.0))


def test_an_imu_pitched_on_its_mount_is_found_against_the_altitude() -> None:
    """An IMU pitched 3 degrees nose-down (f_x offset by -g sin 3 deg) reads a -5.2 % grade on a
    flat road and overrules the altitude; over kilometres the offset is found and taken out,
    and the altitude is used again (a 5-min replay pitched 2 degrees nose-up: rear radii
    +0.34 mm off without it)."""
    from tire_estimation.core.radius.road_grade import OFFSET_MAX_SE

    fit = RoadGradeFit()
    bias = -G_M_S2 * math.sin(math.radians(3.0))
    _flat_drive(fit, 60.0, bias, lambda s: 0.0)
    assert fit.imu_offset == 0.0 and fit.source == "imu"  # 900 m: not yet
    _flat_drive(fit, 240.0, bias, lambda s: 0.0, seed=1)
    assert fit.imu_offset == pytest.approx(bias / G_M_S2, abs=OFFSET_MAX_SE)
    assert fit.imu_grade_rad == pytest.approx(0.0, abs=3e-3)
    assert fit.source == "altitude" and fit.grade_rad == fit.altitude_grade_rad


def test_the_estimate_reports_the_imu_offset_taken_out() -> None:
    """``RadiusEstimate.road_grade_imu_offset_rad`` is the road grade's offset, in rad."""
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.estimator import RadiusEstimator
    from tire_estimation.core.vehicle import VehicleParams

    est = RadiusEstimator(RadiusEstimatorConfig(), VehicleParams(), np.random.default_rng(0))
    assert est.estimate().road_grade_imu_offset_rad == 0.0
    est.grade.imu_offset = 0.05
    assert est.estimate().road_grade_imu_offset_rad == pytest.approx(math.asin(0.05))


def test_a_wandering_altitude_is_not_taken_for_an_imu_offset() -> None:
    """An altitude wandering by 20 m (the Husky's receiver: tens of metres) over a 4.5-km drive
    keeps the offset at 0, and so does one within what the check allows for; an IMU gap
    restarts its fit."""
    fit = RoadGradeFit()
    _flat_drive(fit, 300.0, 0.4, lambda s: 20.0 * math.sin(s / 300.0))
    assert fit.imu_offset == 0.0
    fit = RoadGradeFit()
    _flat_drive(fit, 300.0, 0.1, lambda s: 0.0)
    assert fit.imu_offset == 0.0  # 1 % of grade: within what the check allows for
    fit = RoadGradeFit()
    _flat_drive(fit, 300.0, 0.4, lambda s: 0.0)
    assert fit.imu_offset == pytest.approx(0.4 / G_M_S2, abs=3e-3)
    offset = fit.imu_offset
    fit.restart_imu()
    assert fit.imu_offset == offset and len(fit._offset_fit.pts) == 0
