"""Sensor models: each statistic is checked against its configuration or the truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.sim import SensorConfig, SimResult, simulate

from .conftest import NO_RANDOM_BIAS, rear_rolling_speed, rel_s


def _rear_speed_errors(res: SimResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Relative error of omega * r_true against the truth rolling speed of the rear wheels,
    evaluated at the centre of each measurement window. Returns (error, t_s, speed)."""
    cfg = SensorConfig()
    period = 1.0 / cfg.wheel_speed_rate_hz
    ws = res.wheel_speeds
    t = rel_s(ws.t_ns) - period / 2.0
    tt = rel_s(res.truth.t_ns)
    roll = rear_rolling_speed(res.truth, res.vehicle.track_width_m)
    errs, speeds = [], []
    for j, wheel in enumerate((2, 3)):
        v_true = np.interp(t, tt, roll[:, j])
        r_true = np.interp(t, tt, res.truth.wheel_radius_m[:, wheel])
        errs.append((ws.wheel_speed_rad_s[:, wheel] * r_true - v_true) / v_true)
        speeds.append(v_true)
    return np.column_stack(errs), t, np.column_stack(speeds)


def test_rear_wheel_speed_matches_rolling_speed_within_quantization() -> None:
    """Perfect tone ring: only the timer quantization and the window alignment remain.

    With edges at exact pitches, the ECU value (c-1) pitch / (tq_last - tq_first) is the mean
    angular speed over [t_first, t_last] except for the floor quantization of the two captures:
    |d(span)| < res, so |rel error| < res / span with span >= T - 2 pitch / omega. The centre of
    [t_first, t_last] is within pitch / omega of the window centre where the truth is taken,
    adding |a| pitch / (omega v) (= |a| * pitch * r / v^2).
    """
    res = simulate(
        "asphalt_sine",
        seed=2,
        minutes=0.5,
        sensors=SensorConfig(wheel_speed_tooth_pitch_error_std_rad=0.0),
    )
    cfg = SensorConfig()
    err, _, v = _rear_speed_errors(res)
    pitch = 2 * math.pi / cfg.wheel_speed_teeth
    period = 1.0 / cfg.wheel_speed_rate_hz
    r_nom = res.vehicle.nominal_tire_radius_m
    omega = v / r_nom
    span = period - 2 * pitch / omega
    a_max = np.max(np.abs(np.gradient(res.truth.velocity_m_s[:, 0], 0.02))) + 0.05
    bound = cfg.wheel_speed_timer_resolution_s / span + a_max * pitch / (omega * v) + 2e-6
    assert np.all(np.abs(err) <= bound), float(np.max(np.abs(err) / bound))
    # the quantization is real: errors are not all zero
    assert np.std(err) > 1e-7


@pytest.mark.parametrize("scenario", ["asphalt_sine", "stiffness_step"])
def test_rear_wheel_speed_mean_error_below_1e4_with_pitch_errors(scenario: str) -> None:
    res = simulate(scenario, seed=7, minutes=1.0)
    err, t, _ = _rear_speed_errors(res)
    keep = t > 2.0  # skip the initial transient of the stiffness_step start state
    assert np.all(np.abs(np.mean(err[keep], axis=0)) < 1e-4)
    # tooth pitch errors make per-sample noise of the order pitch_std / window angle
    assert 3e-4 < float(np.std(err[keep])) < 1e-2


def test_wheel_speed_zero_at_standstill(city_short: SimResult) -> None:
    ws = city_short.wheel_speeds
    t = rel_s(ws.t_ns)
    assert np.all(ws.wheel_speed_rad_s[t < 1.5] == 0.0)
    assert np.all(ws.wheel_speed_rad_s >= 0.0)
    assert np.max(ws.wheel_speed_rad_s) > 10.0


def test_wheel_speed_time_offset_shifts_the_stamps() -> None:
    base = simulate("asphalt_sine", seed=4, minutes=0.2)
    late = simulate(
        "asphalt_sine", seed=4, minutes=0.2, sensors=SensorConfig(wheel_speed_time_offset_s=0.05)
    )
    a = base.wheel_speeds
    b = late.wheel_speeds
    # a sample stamped t in `late` measures the window ending at t - 0.05 s = 5 periods earlier
    common = np.intersect1d(a.t_ns, b.t_ns - 50_000_000)
    ia = np.searchsorted(a.t_ns, common)
    ib = np.searchsorted(b.t_ns, common + 50_000_000)
    assert common.size > 1000
    np.testing.assert_array_equal(a.wheel_speed_rad_s[ia], b.wheel_speed_rad_s[ib])


def _gnss_errors(res: SimResult, ltp: LocalTangentPlane) -> np.ndarray:
    e, n, u = ltp.to_enu(res.gnss.lat_deg, res.gnss.lon_deg, res.gnss.alt_m)
    truth_idx = np.searchsorted(res.truth.t_ns, res.gnss.t_ns)
    assert np.array_equal(res.truth.t_ns[truth_idx], res.gnss.t_ns)
    p = res.truth.position_enu_m[truth_idx]
    return np.column_stack([e, n, u]) - p  # antenna at base_link by default


def test_gnss_error_statistics_match_configuration() -> None:
    cfg = SensorConfig(gnss_gm_tau_s=1.0)
    res = simulate("asphalt_sine", seed=11, minutes=5.0, sensors=cfg)
    ltp = LocalTangentPlane(*res.origin_lla)
    err = _gnss_errors(res, ltp)
    phi = math.exp(-1.0 / (cfg.gnss_rate_hz * cfg.gnss_gm_tau_s))
    # white part from first differences: var(d) = 2 sw^2 + 2 sgm^2 (1 - phi)
    d = np.diff(err[:, :2], axis=0)
    white_var = np.var(d) / 2.0 - cfg.gnss_gm_std_m**2 * (1.0 - phi)
    assert math.sqrt(white_var) == pytest.approx(cfg.gnss_white_std_m, rel=0.06)
    total = float(np.std(err[:, :2]))
    assert total == pytest.approx(cfg.gnss_total_std_m, rel=0.12)
    assert float(np.std(err[:, 2])) == pytest.approx(cfg.gnss_total_vertical_std_m, rel=0.15)
    assert abs(float(np.mean(err[:, :2]))) < 0.15
    # reported covariance = total variance
    cov = res.gnss.position_covariance_m2
    assert cov.shape == (err.shape[0], 3, 3)
    assert cov[0, 0, 0] == pytest.approx(cfg.gnss_total_std_m**2)
    assert cov[0, 2, 2] == pytest.approx(cfg.gnss_total_vertical_std_m**2)
    assert cov[0, 0, 1] == 0.0
    # 10 Hz
    assert np.all(np.diff(res.gnss.t_ns) == 100_000_000)


def test_default_gnss_total_error_is_about_1p5_m() -> None:
    assert 1.3 < SensorConfig().gnss_total_std_m < 1.6


NOISELESS_GNSS = {
    "gnss_white_std_m": 0.0,
    "gnss_white_vertical_std_m": 0.0,
    "gnss_gm_std_m": 0.0,
    "gnss_gm_vertical_std_m": 0.0,
}


def test_gnss_lever_arm_and_latency() -> None:
    vehicle = VehicleParams(gnss_antenna_position_m=(1.5, 0.3, 1.2))
    latency = 0.2
    res = simulate(
        "lane_change",
        seed=1,
        minutes=0.3,
        vehicle=vehicle,
        sensors=SensorConfig(**NOISELESS_GNSS, gnss_latency_s=latency),
    )
    ltp = LocalTangentPlane(*res.origin_lla)
    e, n, u = ltp.to_enu(res.gnss.lat_deg, res.gnss.lon_deg, res.gnss.alt_m)
    idx = np.searchsorted(res.truth.t_ns, res.gnss.t_ns - int(latency * 1e9))
    assert np.array_equal(res.truth.t_ns[idx], res.gnss.t_ns - int(latency * 1e9))
    p = res.truth.position_enu_m[idx]
    yaw = res.truth.yaw_rad[idx]
    exp_e = p[:, 0] + np.cos(yaw) * 1.5 - np.sin(yaw) * 0.3
    exp_n = p[:, 1] + np.sin(yaw) * 1.5 + np.cos(yaw) * 0.3
    assert np.max(np.abs(e - exp_e)) < 1e-6
    assert np.max(np.abs(n - exp_n)) < 1e-6
    assert np.max(np.abs(u - (p[:, 2] + 1.2))) < 1e-6
    # the first fix is stamped no earlier than the latency
    assert rel_s(res.gnss.t_ns[0]) >= latency - 1e-9


def test_gnss_doppler_velocity_optional() -> None:
    """The Doppler velocity is simulated by default (receivers report it) and can be left out."""
    plain = simulate(
        "asphalt_sine", seed=1, minutes=0.2, sensors=SensorConfig(gnss_velocity_enabled=False)
    )
    assert plain.gnss.velocity_enu_m_s is None
    res = simulate("asphalt_sine", seed=1, minutes=0.2)
    v = res.gnss.velocity_enu_m_s
    assert v is not None
    idx = np.searchsorted(res.truth.t_ns, res.gnss.t_ns)
    yaw = res.truth.yaw_rad[idx]
    vx, vy = res.truth.velocity_m_s[idx, 0], res.truth.velocity_m_s[idx, 1]
    ve = np.cos(yaw) * vx - np.sin(yaw) * vy
    err = v[:, 0] - ve
    assert float(np.std(err)) == pytest.approx(0.05, rel=0.2)
    # enabling Doppler leaves the position noise unchanged (independent generators)
    np.testing.assert_array_equal(plain.gnss.lat_deg, res.gnss.lat_deg)


def test_stated_accuracies_are_scaled_apart_from_the_errors() -> None:
    """``gnss_covariance_scale`` and ``gnss_velocity_covariance_scale`` change what the
    receiver states (the std times the factor), not its errors."""
    res = simulate("asphalt_sine", seed=1, minutes=0.2)
    scaled = simulate(
        "asphalt_sine",
        seed=1,
        minutes=0.2,
        sensors=SensorConfig(gnss_covariance_scale=3.0, gnss_velocity_covariance_scale=0.1),
    )
    np.testing.assert_array_equal(scaled.gnss.lat_deg, res.gnss.lat_deg)
    np.testing.assert_array_equal(scaled.gnss.velocity_enu_m_s, res.gnss.velocity_enu_m_s)
    np.testing.assert_allclose(
        scaled.gnss.position_covariance_m2, 9.0 * res.gnss.position_covariance_m2
    )
    cov, scaled_cov = res.gnss.velocity_covariance_m2_s2, scaled.gnss.velocity_covariance_m2_s2
    assert cov is not None and scaled_cov is not None
    np.testing.assert_allclose(scaled_cov, 0.01 * cov)
    assert cov[0, 0, 0] == pytest.approx(0.05**2)


def test_gnss_velocity_latency_is_injected_apart_from_the_position_latency() -> None:
    """A velocity stamped t describes the antenna at t - gnss_velocity_latency_s, whatever the
    fix's latency; its noise draws are unchanged by the latency."""
    sensors = {"gnss_velocity_enabled": True, "gnss_velocity_noise_std_m_s": 0.0}
    res = simulate(
        "ece_r64",
        seed=2,
        minutes=1.0,
        sensors=SensorConfig(**sensors, gnss_latency_s=0.1, gnss_velocity_latency_s=0.3),
    )
    v = res.gnss.velocity_enu_m_s
    assert v is not None
    speed = np.hypot(v[:, 0], v[:, 1])
    t_truth = res.truth.t_ns
    truth_speed = np.hypot(res.truth.velocity_m_s[:, 0], res.truth.velocity_m_s[:, 1])
    # the antenna is at base_link here: the measured speed is the truth 0.3 s before the stamp
    for lag_s, close in ((0.3, True), (0.1, False), (0.0, False)):
        ref = np.interp(res.gnss.t_ns - int(lag_s * 1e9), t_truth, truth_speed)
        assert bool(np.max(np.abs(speed - ref)) < 1e-6) is close, lag_s


def test_imu_at_rest_shows_gravity_and_configured_bias(city_short: SimResult) -> None:
    imu = city_short.imu
    t = rel_s(imu.t_ns)
    rest = t < 1.0  # the city drive starts standing still (speed reference 0 for 2 s)
    assert rest.sum() >= 100
    f = imu.linear_acceleration_m_s2[rest]
    w = imu.angular_velocity_rad_s[rest]
    k = math.sqrt(rest.sum())
    cfg = SensorConfig()
    assert np.mean(f[:, 2]) == pytest.approx(9.81, abs=4 * cfg.accel_noise_std_m_s2 / k)
    assert np.all(np.abs(np.mean(f[:, :2], axis=0)) < 4 * cfg.accel_noise_std_m_s2 / k)
    assert np.mean(w[:, 2]) == pytest.approx(0.01, abs=4 * cfg.gyro_noise_std_rad_s / k)
    assert np.std(w[:, 2]) == pytest.approx(cfg.gyro_noise_std_rad_s, rel=0.25)
    assert np.all(np.diff(imu.t_ns) == 10_000_000)


def test_an_imu_pitched_nose_up_reads_part_of_gravity_along_x() -> None:
    """``imu_mounting_pitch_deg``: the vectors turned about y; at rest f_x = g sin(pitch),
    f_z = g cos(pitch), the same draws as unpitched."""
    plain = simulate("city", seed=1, minutes=0.05)
    pitched = simulate(
        "city", seed=1, minutes=0.05, sensors=SensorConfig(imu_mounting_pitch_deg=3.0)
    )
    th = math.radians(3.0)
    f, f0 = pitched.imu.linear_acceleration_m_s2, plain.imu.linear_acceleration_m_s2
    np.testing.assert_allclose(f[:, 0], math.cos(th) * f0[:, 0] + math.sin(th) * f0[:, 2])
    np.testing.assert_allclose(f[:, 2], -math.sin(th) * f0[:, 0] + math.cos(th) * f0[:, 2])
    rest = rel_s(pitched.imu.t_ns) < 1.0
    assert np.mean(f[rest, 0]) == pytest.approx(9.81 * math.sin(th), abs=0.35)


def test_imu_straight_constant_speed() -> None:
    res = simulate(
        "asphalt_sine",
        seed=3,
        minutes=0.3,
        sensors=SensorConfig(**NO_RANDOM_BIAS, gyro_bias_rad_s=(0.0, 0.0, -0.02)),
    )
    t = rel_s(res.imu.t_ns)
    straight = (t > 2.0) & (t < 20.0)
    f = res.imu.linear_acceleration_m_s2[straight]
    assert np.mean(f[:, 2]) == pytest.approx(9.81, abs=0.01)
    assert abs(np.mean(f[:, 0])) < 0.01 and abs(np.mean(f[:, 1])) < 0.01
    assert np.mean(res.imu.angular_velocity_rad_s[straight, 2]) == pytest.approx(-0.02, abs=3e-4)


def test_imu_random_bias_has_configured_spread() -> None:
    cfg = SensorConfig()
    biases = []
    for seed in range(12):
        res = simulate("asphalt_sine", seed=seed, minutes=0.1)
        biases.append(np.mean(res.imu.angular_velocity_rad_s[:, 0]))  # no roll rate in truth
    assert np.std(biases) == pytest.approx(cfg.gyro_bias_initial_std_rad_s, rel=0.5)


def test_lateral_acceleration_equals_vx_times_r_in_steady_cornering() -> None:
    # quasi-steady cornering: a 50 s half sine of the steering (peak at ~27 s)
    res = simulate(
        "asphalt_sine",
        seed=1,
        minutes=0.8,
        sensors=SensorConfig(**NO_RANDOM_BIAS),
        straight_s=2.0,
        sine_frequency_hz=0.01,
        sine_periods=0.5,
        steer_amplitude_rad=0.02,
    )
    t_imu = rel_s(res.imu.t_ns)
    t_tr = rel_s(res.truth.t_ns)
    win_imu = (t_imu > 22.0) & (t_imu < 32.0)
    win_tr = (t_tr > 22.0) & (t_tr < 32.0)
    vx_r = res.truth.velocity_m_s[win_tr, 0] * res.truth.yaw_rate_rad_s[win_tr]
    ay_imu = np.mean(res.imu.linear_acceleration_m_s2[win_imu, 1])
    assert float(np.mean(vx_r)) > 1.5  # really cornering
    assert ay_imu == pytest.approx(float(np.mean(vx_r)), abs=0.02)
    np.testing.assert_allclose(res.truth.acceleration_m_s2[win_tr, 1], vx_r, atol=0.03)


def test_steering_sensor_noise_and_resolution() -> None:
    res = simulate("asphalt_sine", seed=2, minutes=0.2)
    cfg = SensorConfig()
    q = res.steering.angle_rad / cfg.steering_resolution_rad
    np.testing.assert_allclose(q, np.round(q), atol=1e-6)
    straight = rel_s(res.steering.t_ns) < 20.0
    assert float(np.std(res.steering.angle_rad[straight])) == pytest.approx(
        cfg.steering_noise_std_rad, rel=0.2
    )


def test_tire_forces_on_fl_and_rr_only() -> None:
    res = simulate("lane_change", seed=1, minutes=0.5)
    tf = res.tire_forces
    assert tf is not None
    assert tf.valid[0].tolist() == [True, False, False, True]
    assert np.all(tf.fy_n[:, 1] == 0.0) and np.all(tf.fz_n[:, 2] == 0.0)
    # load transfer in aggressive lane changes: Fz of the front-left wheel swings widely
    assert tf.fz_n[:, 0].min() < 3000.0 and tf.fz_n[:, 0].max() > 6000.0
    # nonlinear range: peak |Fy| / Fz near the friction limit (mu = 1)
    assert np.max(np.abs(tf.fy_n[:, 0]) / tf.fz_n[:, 0]) > 0.7
    off = simulate(
        "lane_change", seed=1, minutes=0.1, sensors=SensorConfig(tire_force_enabled=False)
    )
    assert off.tire_forces is None


def test_a_lost_wheel_signal_and_a_gnss_outage_are_injected_in_their_windows() -> None:
    """``wheel_speed_lost_*`` zeroes one wheel's readings in its window only;
    ``gnss_outage_*`` removes the fixes (and velocities) in its window only."""
    plain = simulate("asphalt_sine", seed=1, minutes=0.2)
    faults = SensorConfig(
        wheel_speed_lost_wheel="wheel_rr",
        wheel_speed_lost_from_s=3.0,
        wheel_speed_lost_duration_s=2.0,
        gnss_outage_from_s=4.0,
        gnss_outage_duration_s=3.0,
    )
    res = simulate("asphalt_sine", seed=1, minutes=0.2, sensors=faults)
    t = rel_s(res.wheel_speeds.t_ns)
    window = (t >= 3.0) & (t < 5.0)
    ws, ws0 = res.wheel_speeds.wheel_speed_rad_s, plain.wheel_speeds.wheel_speed_rad_s
    assert np.all(ws[window, 3] == 0.0) and np.all(ws0[window, 3] > 10.0)
    np.testing.assert_array_equal(ws[~window], ws0[~window])
    np.testing.assert_array_equal(ws[:, :3], ws0[:, :3])
    tg, tg0 = rel_s(res.gnss.t_ns), rel_s(plain.gnss.t_ns)
    assert not np.any((tg >= 4.0) & (tg < 7.0))
    assert tg.size == tg0.size - int(np.sum((tg0 >= 4.0) & (tg0 < 7.0)))
    assert res.gnss.velocity_enu_m_s is not None and res.gnss.velocity_enu_m_s.shape[0] == tg.size
    with pytest.raises(ConfigError, match="wheel_speed_lost_wheel"):
        SensorConfig(wheel_speed_lost_wheel="wheel_xx")
