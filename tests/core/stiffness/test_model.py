"""Single-track model of Berntorp & Di Cairano 2018 (eq. 3, 4, 1, 12) vs the simulator."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.filter import BaselineConfig
from tire_estimation.core.stiffness.frontend import single_track_params
from tire_estimation.core.stiffness.model import (
    GRAVITY_M_S2,
    SingleTrackParams,
    kinematic_speed_row,
    lateral_slip_function,
    linearize,
    saturation_slip_at,
    slip_angles,
    wheel_slip,
    wheel_speed_gain,
)
from tire_estimation.core.stiffness.mpf import StiffnessMpf
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.sim import simulate
from tire_estimation.sim.tires import magic_formula


def test_wheel_slip_eq3() -> None:
    # driving: R w > vx -> (R w - vx) / (R w); braking: (R w - vx) / vx
    assert np.isclose(wheel_slip(np.array(20.0), 20.2), 0.2 / 20.2)
    assert np.isclose(wheel_slip(np.array(20.0), 19.8), -0.2 / 20.0)
    assert wheel_slip(np.array(0.0), 0.0) == 0.0


def test_slip_angles_eq4() -> None:
    p = SingleTrackParams.from_vehicle(VehicleParams())
    x = np.array([[20.0, 0.1, 0.05]])
    af, ar = slip_angles(x, 0.02, p)
    assert np.isclose(af[0], 0.02 - (0.1 + 1.1 * 0.05) / 20.0)
    assert np.isclose(ar[0], (1.6 * 0.05 - 0.1) / 20.0)


def test_rear_drive_uses_rear_slip() -> None:
    p = SingleTrackParams.from_vehicle(VehicleParams(), drive="rear")
    x = np.array([[20.0, 0.0, 0.0]])
    lin = linearize(x, 0.0, (20.0, 20.2), p)
    assert np.isclose(lin.a[0, 0, 0], (0.2 / 20.2) / 1500.0)
    pf = SingleTrackParams.from_vehicle(VehicleParams(), drive="front")
    assert linearize(x, 0.0, (20.0, 20.2), pf).a[0, 0, 0] == 0.0


def test_measurement_model_matches_simulator_truth() -> None:
    sim = simulate("stiffness_step", seed=3, minutes=0.1)
    v = sim.vehicle
    p = SingleTrackParams.from_vehicle(v, rolling_resistance_n=177.0, drag_n_s2_m2=0.42)
    tr, imu = sim.truth, sim.imu
    k = np.arange(100, imu.t_ns.size, 7)
    j = np.searchsorted(tr.t_ns, imu.t_ns[k]).clip(0, tr.t_ns.size - 1)
    js = np.searchsorted(sim.steering.t_ns, imu.t_ns[k]).clip(0, sim.steering.t_ns.size - 1)
    jw = np.searchsorted(sim.wheel_speeds.t_ns, imu.t_ns[k]).clip(
        0, sim.wheel_speeds.t_ns.size - 1
    )
    err = []
    for kk, jj, ss, ww in zip(k, j, js, jw, strict=True):
        r = tr.yaw_rate_rad_s[jj]
        # base_link is at the rear axle: vy_cg = vy_base + lr r
        x = np.array([[tr.velocity_m_s[jj, 0], tr.velocity_m_s[jj, 1] + v.lr_m * r, r]])
        ws = sim.wheel_speeds.wheel_speed_rad_s[ww] * v.nominal_tire_radius_m
        lin = linearize(x, float(sim.steering.angle_rad[ss]), (ws[:2].mean(), ws[2:].mean()), p)
        y = lin.h[0] + lin.d[0] @ (tr.stiffness[jj] - np.asarray(p.nominal))
        meas = np.array(
            [
                imu.linear_acceleration_m_s2[kk, 0],
                imu.linear_acceleration_m_s2[kk, 1],
                imu.angular_velocity_rad_s[kk, 2],
            ]
        )
        err.append(y - meas)
    e = np.asarray(err)
    # lateral acceleration and yaw rate: within noise + bias + two-track effects
    assert np.sqrt(np.mean(e[:, 1] ** 2)) < 0.2
    assert np.sqrt(np.mean(e[:, 2] ** 2)) < 0.02
    # longitudinal: within 0.5 m/s^2 (accelerometer bias, slip/radius offsets)
    assert np.sqrt(np.mean(e[:, 0] ** 2)) < 0.5


def test_wheel_speed_gain_matches_finite_difference() -> None:
    # d y / d(R w) of the driven axle(s), y = h + d w with w = [cx - Cx_n, 0, 0] (eq. 2-3, 12)
    x = np.array([[20.0, 0.3, 0.1], [15.0, -0.2, -0.05]])
    cx = np.array([120_000.0, 90_000.0])
    cases = (("front", (20.3, 20.0)), ("front", (19.7, 20.0)), ("rear", (20.0, 20.25)))
    for drive, ws in (*cases, ("all", (20.2, 19.9))):
        p = SingleTrackParams.from_vehicle(VehicleParams(), drive=drive)
        g = wheel_speed_gain(x, 0.05, ws, p, cx)

        def y(front: float, rear: float, p: SingleTrackParams = p) -> np.ndarray:
            lin = linearize(x, 0.05, (front, rear), p)
            w = np.zeros((2, 3))
            w[:, 0] = cx - p.nominal[0]
            return lin.h + np.einsum("nij,nj->ni", lin.d, w)

        h = 1e-5
        d_front = (y(ws[0] + h, ws[1]) - y(ws[0] - h, ws[1])) / (2 * h)
        d_rear = (y(ws[0], ws[1] + h) - y(ws[0], ws[1] - h)) / (2 * h)
        expected = {"front": [d_front], "rear": [d_rear], "all": [d_front, d_rear]}[drive]
        assert g.shape == (2, len(expected), 3)
        for j, e in enumerate(expected):
            np.testing.assert_allclose(g[:, j], e, rtol=1e-6, atol=1e-9)
        # order of magnitude: Cx / (m v) ~ 4 m/s^2 per m/s on the ax row
        assert 3.0 < np.abs(g[:, 0, 0]).max() < 5.0


def test_measurement_noise_covers_wheel_speed_noise_in_simulator() -> None:
    # Straight constant-speed drive, truth states: the spread of the ax residual is the IMU
    # noise plus the ABS wheel-speed noise carried through the slip (eq. 2-3); the filter's
    # measurement covariance must account for both (R alone is ~17 times too small).
    sim = simulate("asphalt_sine", seed=0, minutes=0.3)
    v = sim.vehicle
    cfg = StiffnessEstimatorConfig(n_particles=1, rolling_resistance_n=176.58, drag_n_s2_m2=0.42)
    p = SingleTrackParams.from_vehicle(v, rolling_resistance_n=176.58, drag_n_s2_m2=0.42)
    mpf = StiffnessMpf(cfg, p, np.random.default_rng(0))
    tr, imu, ws = sim.truth, sim.imu, sim.wheel_speeds
    k = np.flatnonzero(np.isin(imu.t_ns, tr.t_ns) & np.isin(imu.t_ns, ws.t_ns))[50:]
    j = np.searchsorted(tr.t_ns, imu.t_ns[k])
    jw = np.searchsorted(ws.t_ns, imu.t_ns[k])
    js = np.searchsorted(sim.steering.t_ns, imu.t_ns[k]).clip(0, sim.steering.t_ns.size - 1)
    resid, var = [], []
    for kk, jj, ww, ss in zip(k, j, jw, js, strict=True):
        r = tr.yaw_rate_rad_s[jj]
        mpf.x = np.array([[tr.velocity_m_s[jj, 0], tr.velocity_m_s[jj, 1] + v.lr_m * r, r]])
        w_axle = ws.wheel_speed_rad_s[ww] * v.nominal_tire_radius_m
        u = (float(w_axle[:2].mean()), float(w_axle[2:].mean()))
        delta = float(sim.steering.angle_rad[ss])
        lin = linearize(mpf.x, delta, u, p)
        resid.append(imu.linear_acceleration_m_s2[kk, 0] - lin.h[0, 0])
        var.append(mpf.measurement_cov(delta, u)[0, 0, 0])
    e = np.asarray(resid)
    ratio = np.var(e) / np.mean(var)
    assert 0.6 < ratio < 1.6


def test_lateral_slip_function_linear_and_tanh() -> None:
    a = np.linspace(-0.3, 0.3, 61)
    # alpha_s = 0: the linear tyre of eq. (2)
    assert np.array_equal(lateral_slip_function(a, 0.0), a)
    s = 0.05
    phi = lateral_slip_function(a, s)
    # slope 1 at small slip (C is the cornering stiffness), 76 % of the peak at alpha_s,
    # monotonic and bounded by alpha_s (the peak force C alpha_s)
    assert np.isclose(lateral_slip_function(np.array(1e-6), s), 1e-6, rtol=1e-6)
    assert np.isclose(lateral_slip_function(np.array(s), s), s * np.tanh(1.0))
    assert np.all(np.abs(phi) < s) and np.all(np.diff(phi) > 0)
    assert np.isclose(phi[-1], s * np.tanh(6.0))


def test_lateral_slip_function_magic_formula_is_the_pacejka_curve() -> None:
    a = np.linspace(-0.4, 0.4, 81)
    s, c, e = 0.05, 1.3, -0.5
    phi = lateral_slip_function(a, s, "magic_formula", c, e)
    # C_y phi is Pacejka's curve with stiffness B C D = C_y and peak D = C_y alpha_s (the
    # simulator's tyre function, written independently)
    cy = 40e3
    want = [magic_formula(float(x), cy, c, cy * s, e) for x in a]
    assert np.allclose(cy * phi, want, rtol=1e-12, atol=1e-9)
    # slope 1 at small slip, peak alpha_s (reached, not only approached), falls off beyond
    assert np.isclose(lateral_slip_function(np.array(1e-6), s, "magic_formula", c, e), 1e-6)
    assert np.isclose(phi.max(), s, rtol=2e-3) and phi.max() <= s
    assert phi[-1] < 0.95 * s and np.isclose(phi[-1], -phi[0])
    # E shapes the curve between: a more negative E rises more sharply to the peak
    mid = np.array(0.04)
    assert lateral_slip_function(mid, s, "magic_formula", c, -2.0) > lateral_slip_function(
        mid, s, "magic_formula", c, 0.0
    )
    # alpha_s = 0 stays linear whatever the shape; per particle as well
    assert np.array_equal(lateral_slip_function(a, 0.0, "magic_formula", c, e), a)
    both = lateral_slip_function(np.array([0.1, 0.1]), np.array([0.0, s]), "magic_formula", c, e)
    assert both[0] == 0.1 and np.isclose(cy * both[1], magic_formula(0.1, cy, c, cy * s, e))


def test_tyre_shape_reaches_the_regressor_of_the_filter_and_the_baselines() -> None:
    v = VehicleParams()
    kw = {"friction_coefficient": 0.3, "magic_formula_shape_c": 1.3}
    tanh_cfg = StiffnessEstimatorConfig(n_particles=4, **kw)
    mf_cfg = StiffnessEstimatorConfig(
        n_particles=4, tyre_shape="magic_formula", magic_formula_curvature_e=-0.5, **kw
    )
    rng = np.random.default_rng(0)
    tanh_p = StiffnessEstimator(tanh_cfg, v, rng).params
    mf_p = StiffnessEstimator(mf_cfg, v, rng).params
    assert (mf_p.tyre_shape, mf_p.magic_formula_shape_c, mf_p.magic_formula_curvature_e) == (
        "magic_formula",
        1.3,
        -0.5,
    )
    # the baselines take the same shape from the estimator's config
    assert single_track_params(BaselineConfig.sharing(mf_cfg), v) == mf_p
    x = np.array([[20.0, 0.0, 0.0]])
    a_s = mf_p.saturation_slip_front_rad
    for delta, same in ((1e-4, True), (2.0 * a_s, False)):
        a_tanh = linearize(x, delta, (20.0, 20.0), tanh_p).a[0, 1, 1]
        a_mf = linearize(x, delta, (20.0, 20.0), mf_p).a[0, 1, 1]
        # equal at small slip (same stiffness); at 2 alpha_s tanh(2) = 0.96 of the peak,
        # the Magic Formula (C 1.3, E -0.5) is near its peak
        assert np.isclose(a_tanh, a_mf, rtol=1e-6) == same
        want = magic_formula(delta, 1.0, 1.3, a_s, -0.5) * np.cos(delta) / v.mass_kg
        assert np.isclose(a_mf, want)


def test_tyre_shape_config_errors_name_the_field() -> None:
    for field, value in (
        ("tyre_shape", "brush"),
        ("magic_formula_shape_c", 2.5),
        ("magic_formula_curvature_e", 1.0),
    ):
        with pytest.raises(ConfigError, match=field):
            StiffnessEstimatorConfig(**{field: value})
        with pytest.raises(ConfigError, match=field):
            BaselineConfig(**{field: value})


def test_friction_coefficient_saturates_the_axle_forces() -> None:
    v = VehicleParams()
    mu, cf = 1.1, 70e3
    p = SingleTrackParams.from_vehicle(
        v, friction_coefficient=mu, cornering_stiffness_front_n_rad=cf
    )
    lin_p = SingleTrackParams.from_vehicle(v, cornering_stiffness_front_n_rad=cf)
    wheelbase = v.lf_m + v.lr_m
    fz_f = v.mass_kg * GRAVITY_M_S2 * v.lr_m / wheelbase
    fz_r = v.mass_kg * GRAVITY_M_S2 * v.lf_m / wheelbase
    # nominal override and alpha_s = mu Fz / C_n (peak mu Fz at the nominal stiffness)
    assert p.nominal[1] == cf and p.nominal[2] == v.cornering_stiffness_rear_n_rad
    assert np.isclose(p.saturation_slip_front_rad * cf, mu * fz_f)
    assert np.isclose(p.saturation_slip_rear_rad * p.nominal[2], mu * fz_r)
    assert lin_p.saturation_slip_front_rad == 0.0 and lin_p.saturation_slip_rear_rad == 0.0
    # straight ahead with 0.2 rad steer: the front slip angle is 0.2 rad, the rear 0
    x = np.array([[20.0, 0.0, 0.0]])
    delta = 0.2
    sat = linearize(x, delta, (20.0, 20.0), p)
    lin = linearize(x, delta, (20.0, 20.0), lin_p)
    # linear tyre: ay = Cf alpha cos(d) / m; saturating: Cf alpha_s tanh(alpha / alpha_s) ...
    assert np.isclose(lin.a[0, 1, 1], delta * np.cos(delta) / v.mass_kg)
    a_s = p.saturation_slip_front_rad
    assert np.isclose(sat.a[0, 1, 1], a_s * np.tanh(delta / a_s) * np.cos(delta) / v.mass_kg)
    # ... so the modelled front force stays below mu Fz_f at the nominal stiffness
    front_force = cf * sat.a[0, 1, 1] * v.mass_kg / np.cos(delta)
    assert 0.85 * mu * fz_f < front_force < mu * fz_f
    assert cf * lin.a[0, 1, 1] * v.mass_kg / np.cos(delta) > 1.4 * mu * fz_f


def test_friction_limited_saturation_keeps_the_peak_at_mu_fz() -> None:
    v = VehicleParams()
    mu = 0.3
    p = SingleTrackParams.from_vehicle(v, friction_coefficient=mu)
    wheelbase = v.lf_m + v.lr_m
    fz_f = v.mass_kg * GRAVITY_M_S2 * v.lr_m / wheelbase
    fz_r = v.mass_kg * GRAVITY_M_S2 * v.lf_m / wheelbase
    # snow-like stiffness: half the nominal, per particle (and one at the nominal)
    cyf = np.array([0.5, 1.0]) * p.nominal[1]
    cyr = np.array([0.5, 1.0]) * p.nominal[2]
    sat_f, sat_r = saturation_slip_at(p, cyf, cyr)
    # alpha_s = mu Fz / C: the peak C alpha_s is mu Fz at any stiffness
    assert np.allclose(cyf * sat_f, mu * fz_f) and np.allclose(cyr * sat_r, mu * fz_r)
    # at the nominal stiffness it is the nominal-based alpha_s of from_vehicle
    assert np.isclose(sat_f[1], p.saturation_slip_front_rad)
    assert np.isclose(sat_r[1], p.saturation_slip_rear_rad)
    # the per-particle slips enter the regressor: a large front slip angle (0.3 rad) gives a
    # front force of about mu Fz_f (tanh(>= 2) > 0.96) for both stiffnesses
    x = np.array([[20.0, 0.0, 0.0], [20.0, 0.0, 0.0]])
    delta = 0.3
    lin = linearize(x, delta, (20.0, 20.0), p, (sat_f, sat_r))
    force = cyf * lin.a[:, 1, 1] * v.mass_kg / np.cos(delta)
    assert np.all(force < mu * fz_f) and np.all(force > 0.96 * mu * fz_f)
    # the nominal-based alpha_s (``scaled``) halves the peak with the stiffness instead
    scaled = linearize(x, delta, (20.0, 20.0), p)
    force_scaled = cyf * scaled.a[:, 1, 1] * v.mass_kg / np.cos(delta)
    assert force_scaled[0] < 0.51 * mu * fz_f
    # per-particle alpha_s = 0 keeps the linear tyre there
    phi = lateral_slip_function(np.array([0.1, 0.1]), np.array([0.0, 0.05]))
    assert phi[0] == 0.1 and np.isclose(phi[1], 0.05 * np.tanh(2.0))


def test_mpf_friction_peak_uses_each_particles_stiffness_mean() -> None:
    v = VehicleParams()
    cfg = StiffnessEstimatorConfig(n_particles=4, friction_coefficient=0.3)
    p = SingleTrackParams.from_vehicle(v, friction_coefficient=0.3)
    mpf = StiffnessMpf(cfg, p, np.random.default_rng(0))
    mpf.stats.mean[:, 1] = np.array([-0.5, 0.0, 0.5, 1.0]) * p.nominal[1]
    mpf.stats.mean[:, 2] = np.array([-0.5, 0.0, 0.5, 1.0]) * p.nominal[2]
    sat = mpf._saturation_slips()
    assert sat is not None
    c = p.nominal[1] + mpf.stats.mean[:, 1]
    assert np.allclose(sat[0], p.saturation_slip_front_rad * p.nominal[1] / c)
    # the linear tyre has no saturation slips
    lin_p = SingleTrackParams.from_vehicle(v)
    assert StiffnessMpf(cfg, lin_p, np.random.default_rng(0))._saturation_slips() is None


def test_kinematic_speed_row_uses_measured_ax_and_vy_r() -> None:
    v = VehicleParams()
    p = SingleTrackParams.from_vehicle(v)
    x = np.array([[20.0, 0.5, 0.2], [21.0, -0.5, 0.2]])
    # wheel speed = each particle's vX: zero slip, no longitudinal tyre force at all
    lin = linearize(x, 0.01, (x[:, 0], x[:, 0]), p)
    assert np.all(lin.a[:, :, 0] == 0.0)
    kin = kinematic_speed_row(lin, x, 1.5, p)
    # dvX/dt = ax_cg + vY r with ax_cg = ax_imu + p_y dr + p_x r^2
    ax_cg = 1.5 + p.imu_x_m * 0.04 + p.imu_y_m * lin.rate[:, 2]
    assert np.allclose(kin.rate[:, 0], ax_cg + x[:, 1] * x[:, 2])
    assert np.allclose(kin.a[:, 0, :], p.imu_y_m * lin.a[:, 2, :])
    # row 0 of the measurement is the speed: y_0 = vX + e, independent of w
    assert np.array_equal(kin.h[:, 0], x[:, 0])
    assert np.all(kin.d[:, 0, :] == 0.0)
    assert np.array_equal(kin.rate[:, 1:], lin.rate[:, 1:])
    assert np.array_equal(kin.h[:, 1:], lin.h[:, 1:])
    assert np.array_equal(kin.d[:, 1:], lin.d[:, 1:])
