"""Vehicle physics and scenario effects, checked on the truth stream."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.sim import SensorConfig, SimResult, simulate
from tire_estimation.sim.tires import inverse_magic_formula_e0, magic_formula

from .conftest import rear_rolling_speed, rel_s


@pytest.mark.parametrize("fixture", ["ece_short", "city_short"])
def test_yaw_rate_is_derivative_of_heading(fixture: str, request: pytest.FixtureRequest) -> None:
    res: SimResult = request.getfixturevalue(fixture)
    tr = res.truth
    dt = 0.02
    yaw = np.unwrap(tr.yaw_rad)
    d_yaw = (yaw[2:] - yaw[:-2]) / (2 * dt)
    err = d_yaw - tr.yaw_rate_rad_s[1:-1]
    assert np.max(np.abs(err)) < 2e-3
    assert float(np.sqrt(np.mean(err**2))) < 3e-4
    assert np.max(np.abs(tr.yaw_rate_rad_s)) > 0.05  # there is turning
    assert np.all(np.abs(tr.yaw_rad) <= math.pi)


@pytest.mark.parametrize("fixture", ["ece_short", "city_short"])
def test_enu_velocity_matches_body_velocity_rotated_by_yaw(
    fixture: str, request: pytest.FixtureRequest
) -> None:
    res: SimResult = request.getfixturevalue(fixture)
    tr = res.truth
    dt = 0.02
    v_enu = (tr.position_enu_m[2:, :2] - tr.position_enu_m[:-2, :2]) / (2 * dt)
    yaw = tr.yaw_rad[1:-1]
    vx, vy = tr.velocity_m_s[1:-1, 0], tr.velocity_m_s[1:-1, 1]
    exp = np.column_stack(
        [np.cos(yaw) * vx - np.sin(yaw) * vy, np.sin(yaw) * vx + np.cos(yaw) * vy]
    )
    assert np.max(np.abs(v_enu - exp)) < 0.03
    # ENU origin at the first truth sample, and lat/lon consistent with it
    assert np.all(tr.position_enu_m[0] == 0.0)
    assert tr.lat_deg[0] == pytest.approx(res.origin_lla[0], abs=1e-12)


def test_pressure_step_changes_radius_by_sensitivity(ece_short: SimResult) -> None:
    (event,) = [e for e in ece_short.events if e.kind == "pressure_step"]
    assert event.detail["wheel"] == "wheel_rl"
    assert event.t_s == pytest.approx(0.63 * 120.0, abs=0.01)
    tr = ece_short.truth
    t = rel_s(tr.t_ns)
    before, after = t < event.t_s - 0.1, t > event.t_s + 0.1
    dp_kpa = (tr.tire_pressure_pa[after][0] - tr.tire_pressure_pa[before][-1]) / 1e3
    assert dp_kpa[2] == pytest.approx(-0.2 * 230.0)
    assert np.all(dp_kpa[[0, 1, 3]] == 0.0)
    dr = tr.wheel_radius_m[after][0] - tr.wheel_radius_m[before][-1]
    assert dr[2] == pytest.approx(0.03e-3 * dp_kpa[2], abs=1e-9)  # 0.03 mm/kPa * -46 kPa
    assert np.all(np.abs(dr[[0, 1, 3]]) < 1e-12)
    # radii: nominal plus a sub-millimetre manufacturing offset per tyre
    r0 = tr.wheel_radius_m[0]
    assert np.all(np.abs(r0 - ece_short.vehicle.nominal_tire_radius_m) < 1.5e-3)
    assert np.ptp(r0) > 0.0


def test_ece_r64_speeds_and_excitation(ece_short: SimResult) -> None:
    v_kmh = ece_short.truth.velocity_m_s[:, 0] * 3.6
    assert v_kmh.min() > 40.0 and v_kmh.max() < 120.0
    ay = ece_short.truth.acceleration_m_s2[:, 1]
    assert 0.5 < np.max(np.abs(ay)) < 4.0


def test_deflation_options() -> None:
    res = simulate(
        "ece_r64",
        seed=1,
        minutes=0.5,
        deflate_wheel="wheel_fr",
        deflation_fraction=0.1,
        deflation_time_min=0.25,
    )
    (event,) = res.events
    assert event.detail["wheel"] == "wheel_fr" and event.t_s == pytest.approx(15.0)
    assert res.truth.tire_pressure_pa[-1, 1] == pytest.approx(0.9 * 230e3)


def test_diffusion_loses_pressure_at_the_configured_rate() -> None:
    res = simulate(
        "diffusion",
        seed=1,
        minutes=1.0,
        wheels=["wheel_rl", "wheel_rr"],
        rate_kpa_per_min=3.0,
        start_min=0.0,
    )
    p = res.truth.tire_pressure_pa
    loss_kpa = (p[0] - p[-1]) / 1e3
    np.testing.assert_allclose(loss_kpa, [0.0, 0.0, 3.0, 3.0], atol=1e-6)
    dr = res.truth.wheel_radius_m[-1] - res.truth.wheel_radius_m[0]
    np.testing.assert_allclose(dr[2:], -3.0 * 0.03e-3, atol=1e-9)


def test_speed_dependent_radius_injection() -> None:
    c = 2e-6
    base = simulate("asphalt_sine", seed=1, minutes=0.2)
    grown = simulate(
        "asphalt_sine",
        seed=1,
        minutes=0.2,
        sensors=SensorConfig(radius_speed_coefficient_m_per_m2_s2=c),
    )
    roll = rear_rolling_speed(grown.truth, grown.vehicle.track_width_m)
    dr = grown.truth.wheel_radius_m[:, 2:] - base.truth.wheel_radius_m[:, 2:]
    np.testing.assert_allclose(dr, c * roll**2, rtol=1e-3)
    # the wheels then turn slower for the same road speed
    assert np.mean(grown.wheel_speeds.wheel_speed_rad_s[:, 2]) < np.mean(
        base.wheel_speeds.wheel_speed_rad_s[:, 2]
    )


def test_road_grade_adds_gravity_to_specific_force_and_altitude() -> None:
    res = simulate(
        "asphalt_sine",
        seed=1,
        minutes=0.4,
        sensors=SensorConfig(road_grade_amplitude_rad=0.04, road_grade_wavelength_m=400.0),
    )
    alt = res.truth.position_enu_m[:, 2]
    # peak-to-peak altitude of a sine grade: 2 A lambda / (2 pi) = 5.1 m
    assert np.ptp(alt) == pytest.approx(2 * 0.04 * 400 / (2 * math.pi), rel=0.1)
    assert np.max(res.imu.linear_acceleration_m_s2[:, 0]) > 0.3


def test_stiffness_drop_changes_lateral_response() -> None:
    drop = simulate("stiffness_step", seed=0)
    same = simulate("stiffness_step", seed=0, stiffness_drop_fraction=0.0)
    t = rel_s(drop.truth.t_ns)
    pre, post = t < 29.9, t > 31.0
    # identical until the surface change
    np.testing.assert_array_equal(drop.truth.velocity_m_s[pre], same.truth.velocity_m_s[pre])
    k = drop.truth.stiffness
    np.testing.assert_allclose(k[post][0], 0.5 * k[pre][-1])
    assert drop.events[0].kind == "stiffness_step" and drop.events[0].t_s == 30.0
    # softer tyres: larger lateral velocity (more sideslip), smaller yaw-rate gain
    vy_drop = np.sqrt(np.mean(drop.truth.velocity_m_s[post, 1] ** 2))
    vy_same = np.sqrt(np.mean(same.truth.velocity_m_s[post, 1] ** 2))
    assert vy_drop > 1.25 * vy_same
    r_drop = np.sqrt(np.mean(drop.truth.yaw_rate_rad_s[post] ** 2))
    r_same = np.sqrt(np.mean(same.truth.yaw_rate_rad_s[post] ** 2))
    assert r_drop < 0.95 * r_same
    # small slip as in the paper: longitudinal < 5 % (front Fx / (Cx/2) on the drop surface)
    assert np.max(np.abs(drop.truth.acceleration_m_s2[t > 2.0, 0])) < 2.5


def test_snow_is_softer_than_asphalt() -> None:
    snow = simulate("snow_sine", seed=0)
    asphalt = simulate("asphalt_sine", seed=0)
    assert snow.truth.stiffness[0, 1] == pytest.approx(0.5 * asphalt.truth.stiffness[0, 1])
    t = rel_s(snow.truth.t_ns)
    assert np.all(np.abs(snow.truth.yaw_rate_rad_s[t < 21.0]) < 0.01)  # straight first
    assert np.max(np.abs(snow.truth.yaw_rate_rad_s)) > 0.05  # then the sine


def test_magic_formula_slope_and_inverse() -> None:
    stiffness, c, d = 50_000.0, 1.65, 4000.0
    eps = 1e-6
    slope = magic_formula(eps, stiffness, c, d, 0.0) - magic_formula(-eps, stiffness, c, d, 0.0)
    assert slope / (2 * eps) == pytest.approx(stiffness, rel=1e-6)
    for f in (-3000.0, -100.0, 0.0, 500.0, 3500.0):
        x = inverse_magic_formula_e0(f, stiffness, c, d)
        assert magic_formula(x, stiffness, c, d, 0.0) == pytest.approx(f, abs=1e-6)
    # saturation: never above D
    assert abs(magic_formula(0.5, stiffness, 1.3, d, -0.5)) <= d


def test_load_dependent_radius_injection() -> None:
    c = -1.5e-6  # m per N: a loaded tyre rolls on a smaller radius
    quiet = {
        "tire_force_noise_fx_n": 0.0,
        "tire_force_noise_fy_n": 0.0,
        "tire_force_noise_fz_n": 0.0,
    }
    base = simulate("lane_change", seed=2, minutes=0.3, sensors=SensorConfig(**quiet))
    loaded = simulate(
        "lane_change",
        seed=2,
        minutes=0.3,
        sensors=SensorConfig(**quiet, radius_load_coefficient_m_per_n=c),
    )
    v = loaded.vehicle
    fz_static_front = v.mass_kg * 9.81 * v.cg_to_rear_axle_m / v.wheelbase_m / 2.0
    tf = loaded.tire_forces
    assert tf is not None
    idx = np.searchsorted(tf.t_ns, loaded.truth.t_ns)
    dr = loaded.truth.wheel_radius_m[:, 0] - base.truth.wheel_radius_m[:, 0]
    np.testing.assert_allclose(dr, c * (tf.fz_n[idx, 0] - fz_static_front), atol=1e-9)
    assert np.ptp(dr) > 4e-3  # load swings of several kN in the lane changes


def test_slow_scenario_stays_slow_and_turns_tightly() -> None:
    """``slow``: 1-8 m/s manoeuvring with turns of 5-12 m radius (path curvature = yaw rate /
    speed), stops included."""
    res = simulate("slow", seed=2, minutes=3.0)
    tr = res.truth
    v = tr.velocity_m_s[:, 0]
    assert v.max() < 8.5
    moving = v > 1.5
    curvature = np.abs(tr.yaw_rate_rad_s[moving] / v[moving])
    assert 1.0 / 12.5 < np.percentile(curvature, 99) < 1.0 / 4.5
    assert np.mean(v < 0.1) > 0.005  # it stops
    assert np.mean((v > 1.0) & (v < 4.0)) > 0.3  # most of it below 4 m/s
