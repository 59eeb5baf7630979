"""The switchable model effects of the radius estimator: load-dependent radius, road grade and
rear brake slip (issue 7). Closed-loop injection tests are in
``tests/evaluation/test_residuals.py``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.effects import REAR_BRAKE_SLIP_ONSET_M_S2
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.sim.tires import TireModelConfig

VEH = VehicleParams()
OMEGA = 20.0 / VEH.nominal_tire_radius_m  # 20 m/s on every wheel
#: the simulator's braking: the rear axle takes (1 - front share) of the braking force
TIRES = TireModelConfig()
#: physical rear brake slip of the simulated vehicle, s^2/m: (1 - front share) m / C_x,rear
K_BRAKE = (1.0 - TIRES.brake_front_share) * VEH.mass_kg / VEH.longitudinal_stiffness_rear_n


def _estimator(**cfg: float) -> RadiusEstimator:
    return RadiusEstimator(
        RadiusEstimatorConfig(n_particles=50, **cfg), VEH, np.random.default_rng(0)
    )


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("radius_load_coefficient_m_per_n", 2e-4),
        ("road_grade_correction_gain", -0.1),
        ("rear_brake_slip_s2_per_m", -1e-3),
        ("rear_brake_slip_s2_per_m", 0.1),
        ("gnss_velocity_latency_s", 2.0),
    ],
)
def test_effect_switches_are_validated(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=field):
        RadiusEstimatorConfig(**{field: value})


@pytest.mark.parametrize("coef", [0.0, -2e-6])
def test_load_transfer_turns_equal_wheel_speeds_into_a_yaw_rate(coef: float) -> None:
    """Equal wheel speeds with 2 m/s^2 to the left: the loaded right rear tyre rolls on
    r + c dFz, the unloaded left one on r - c dFz, so the rear axle turns at
    omega 2 c dFz / l_T with dFz = m a_y h lf / (l_T L) (speed unchanged)."""
    est = _estimator(radius_load_coefficient_m_per_n=coef)
    est.on_imu(0, [0.0, 0.0, 0.0], [0.0, 2.0, 9.81])
    est.on_wheel_speeds(1_000_000, [OMEGA] * 4)
    out = est.estimate()
    lt, wb = VEH.track_width_m, VEH.wheelbase_m
    d_fz = VEH.mass_kg * 2.0 * VEH.cg_height_m / lt * VEH.cg_to_front_axle_m / wb
    assert d_fz == pytest.approx(433.7, abs=0.1)
    assert out.yaw_rate_rad_s == pytest.approx(OMEGA * 2.0 * coef * d_fz / lt, abs=1e-12)
    assert out.speed_m_s == pytest.approx(20.0, rel=1e-12)


def _climb(
    gain: float, grade_rad: float, imu: bool = True, source: str = "checked"
) -> RadiusEstimator:
    """60 s straight east at 20 m/s along the slope on a constant grade, exact GNSS fixes and
    (``imu``) the IMU's specific force ``f_x = g sin(theta)``."""
    est = _estimator(
        road_grade_correction_gain=gain, init_min_distance_m=20.0, road_grade_source=source
    )
    ltp = LocalTangentPlane(48.0, 11.0, 500.0)
    f_imu = np.array([9.80665 * math.sin(grade_rad), 0.0, 9.80665 * math.cos(grade_rad)])
    for k in range(6001):  # wheel speeds and IMU at 100 Hz, fixes at 10 Hz
        t_ns = k * 10_000_000
        if imu:
            est.on_imu(t_ns, np.zeros(3), f_imu)
        est.on_wheel_speeds(t_ns, [OMEGA] * 4)
        if k % 10 == 0:
            s = 20.0 * k * 0.01
            lat, lon, alt = ltp.to_lla(s * math.cos(grade_rad), 0.0, s * math.sin(grade_rad))
            est.on_gnss_fix(t_ns, float(lat), float(lon), float(alt), np.eye(3))
    return est


@pytest.mark.parametrize(("imu", "source"), [(True, "checked"), (False, "altitude")])
def test_grade_is_estimated_from_altitude_and_corrects_the_distance(
    imu: bool, source: str
) -> None:
    """The altitude grade, confirmed by the IMU's (or alone, ``road_grade_source:
    altitude``), corrects the distance."""
    grade = 0.08
    r = VEH.nominal_tire_radius_m
    for gain in (0.0, 1.0):
        out = _climb(gain, grade, imu, source).estimate()
        # sin(theta) = dz / ds over the last 100 m of wheel-travelled distance
        assert out.road_grade_rad == pytest.approx(grade, abs=1e-3)
        assert out.road_grade_source == "altitude"
        assert out.road_grade_counts["altitude"] > 500
        assert out.road_grade_counts["imu"] == out.road_grade_counts["none"] == 0
        # eq. (6a) on wheel speeds reduced by gain (1 - cos theta): the horizontal speed
        scale = 1.0 - gain * (1.0 - math.cos(grade))
        expected = OMEGA * scale * (r + float(np.mean(out.radius_error_m)))
        assert out.speed_m_s == pytest.approx(expected, rel=1e-9)


def test_checked_grade_without_an_imu_is_not_used() -> None:
    """Without an IMU to check it against, the checked grade does not trust the altitude: no
    correction, the speed is that of the wheel speeds."""
    out = _climb(1.0, 0.08, imu=False).estimate()
    assert out.road_grade_rad == 0.0
    assert out.road_grade_source == "none"
    assert out.road_grade_counts["none"] > 500
    assert out.road_grade_counts["altitude"] == 0
    r = VEH.nominal_tire_radius_m
    expected = OMEGA * (r + float(np.mean(out.radius_error_m)))
    assert out.speed_m_s == pytest.approx(expected, rel=1e-9)


def test_sliding_line_slope_matches_least_squares():
    """The O(1) grade fit equals a least-squares line over the points in the window, far from
    the origin and across rebuilds and the point cap."""
    from tire_estimation.core.radius.road_grade import SlidingLine

    rng = np.random.default_rng(8)
    fit = SlidingLine(max_points=300)
    s = 4.0e5  # 400 km into a drive
    for k in range(3000):
        s += rng.uniform(0.0, 3.0)
        fit.append(s, 250.0 + 0.03 * s + rng.normal(0.0, 0.5))
        while fit.pts and fit.pts[0][0] < s - 100.0 * (1.0 + (k // 700) % 3):
            fit.popleft()
        if k % 97 == 0 and len(fit.pts) >= 5:
            a = np.asarray(fit.pts)
            ref = np.polyfit(a[:, 0] - a[0, 0], a[:, 1], 1)[0]
            assert fit.slope() == pytest.approx(ref, rel=1e-9, abs=1e-12)
    assert len(fit.pts) <= 300


def test_physical_rear_brake_slip_of_the_simulated_vehicle() -> None:
    """35 % of the braking force on the rear axle, 1500 kg, 150 kN rear-axle stiffness."""
    k = (1.0 - 0.65) * 1500.0 / 150_000.0
    assert k == pytest.approx(3.5e-3, rel=1e-12)
    assert k == pytest.approx(K_BRAKE, rel=1e-12)


def _sim_rear_slip(fx: float, onset: float) -> float:
    """The simulator's rear-wheel slip for the specific force ``fx`` of a vehicle whose driving
    resistances are ``m onset``: the tyre forces sum to ``m fx + m onset``; when negative (the
    brakes), each rear wheel takes (1 - front share) / 2 of it and slips by ``F / C_x,wheel``
    (the small-slip slope of the simulator's Magic Formula, wheel stiffness C_x,rear / 2)."""
    f_tyres = VEH.mass_kg * (fx + onset)
    if f_tyres >= 0.0:
        return 0.0  # driving: the front axle takes it, the rear wheels roll freely
    f_wheel = 0.5 * (1.0 - TIRES.brake_front_share) * f_tyres
    return f_wheel / (0.5 * VEH.longitudinal_stiffness_rear_n)


def _braked(fx: float, **cfg: float) -> tuple[RadiusEstimator, float]:
    """20 m/s, IMU specific force ``fx``, rear wheels turning at v (1 + kappa) / r."""
    est = _estimator(**cfg)
    kappa = _sim_rear_slip(fx, REAR_BRAKE_SLIP_ONSET_M_S2)
    est.on_imu(0, [0.0, 0.0, 0.0], [fx, 0.0, 9.81])
    est.on_wheel_speeds(1_000_000, [OMEGA, OMEGA, OMEGA * (1 + kappa), OMEGA * (1 + kappa)])
    return est, kappa


def test_rear_brake_slip_correction_gives_back_the_ground_speed() -> None:
    """3 m/s^2 of deceleration, 2.75 of it braking: the rear wheels turn 0.96 % slower; with the
    physical k the corrected speed is the ground speed (eq. 6a with zero radius errors)."""
    est, kappa = _braked(-3.0, rear_brake_slip_s2_per_m=K_BRAKE)
    assert kappa == pytest.approx(-K_BRAKE * 2.75, rel=1e-12)
    assert kappa == pytest.approx(-9.625e-3, rel=1e-12)
    out = est.estimate()
    assert out.rear_brake_decel_m_s2 == pytest.approx(2.75, rel=1e-12)
    assert out.speed_m_s == pytest.approx(20.0, rel=1e-12)
    assert out.yaw_rate_rad_s == pytest.approx(0.0, abs=1e-12)


def test_rear_brake_slip_off_leaves_the_wheel_speeds() -> None:
    """Switched off (default), the braking slip shows as a speed error of v kappa; the braking
    deceleration is still reported."""
    assert RadiusEstimatorConfig().rear_brake_slip_s2_per_m == 0.0
    est, kappa = _braked(-3.0)
    out = est.estimate()
    assert out.rear_brake_decel_m_s2 == pytest.approx(2.75, rel=1e-12)
    assert out.speed_m_s == pytest.approx(20.0 * (1.0 + kappa), rel=1e-12)
    assert out.speed_m_s == pytest.approx(19.8075, rel=1e-9)


@pytest.mark.parametrize("fx", [-0.2, 0.0, 1.5])
def test_rear_brake_slip_is_zero_without_braking(fx: float) -> None:
    """A deceleration within the driving resistances (a_0 = 0.25 m/s^2) or an acceleration: no
    braking, no correction of equal wheel speeds."""
    est, kappa = _braked(fx, rear_brake_slip_s2_per_m=K_BRAKE)
    assert kappa == 0.0
    out = est.estimate()
    assert out.rear_brake_decel_m_s2 == 0.0
    assert out.speed_m_s == pytest.approx(20.0, rel=1e-12)


def test_rear_brake_slip_without_imu_uses_the_wheel_deceleration() -> None:
    """No (or a stale) IMU: the braking deceleration is the low-passed wheel-speed derivative of
    the gates (3 m/s^2 here), as for the load transfer."""
    est = _estimator(rear_brake_slip_s2_per_m=K_BRAKE)
    est.on_imu(0, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])  # stale after 0.5 s
    r = VEH.nominal_tire_radius_m
    for k in range(301):  # 3 s at 100 Hz, 24 -> 15 m/s
        v = 24.0 - 3.0 * 0.01 * k
        est.on_wheel_speeds(k * 10_000_000, [v / r] * 4)
    out = est.estimate()
    # the corrected speed falls 1 / (1 + kappa) faster than the wheels: b = 2.78 instead of 2.75
    assert out.rear_brake_decel_m_s2 == pytest.approx(2.78, abs=0.02)
    kappa = -K_BRAKE * out.rear_brake_decel_m_s2
    # the wheel speeds, means over their 10 ms, are first brought to their stamps: 15 m/s less
    # 3 m/s^2 x 5 ms (core/radius/wheel_timing.py)
    assert est.timing.lag_s == pytest.approx(0.005)
    assert out.speed_m_s == pytest.approx((15.0 - 3.0 * 0.005) / (1.0 + kappa), rel=1e-9)


def test_every_effect_is_a_config_switch_off_by_default_but_the_road_grade() -> None:
    """One object per effect: its field is a ``RadiusEstimatorConfig`` field, 0 by default
    (the road grade: 1, the geometric correction with the IMU-checked grade) and checked
    against the object's limits; names and fields are unique; the grid holds 0 and the
    default."""
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.effects import EFFECTS

    cfg = RadiusEstimatorConfig()
    assert len({e.name for e in EFFECTS}) == len({e.config_field for e in EFFECTS}) == 9
    on_by_default = {"road_grade": 1.0}
    assert cfg.road_grade_source == "checked"
    for e in EFFECTS:
        assert e.value(cfg) == on_by_default.get(e.name, 0.0)
        assert 0.0 in e.grid and e.value(cfg) in e.grid
        hi = e.limits[1]
        with pytest.raises(ConfigError, match=e.config_field):
            RadiusEstimatorConfig(**{e.config_field: hi + 1.0})
        assert e.overrides(0.1)[e.config_field] == 0.1
        # exactly one kind of correction
        kinds = (e.fix_delay_sign or e.velocity_delay_sign, e.antenna_axis is not None)
        assert sum(map(bool, (*kinds, e.wheel_speeds is not None))) == 1
