"""Baselines of the stiffness estimator (AUGPF, EKF, KF + RLS): config, model, learning."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from scipy import stats

from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.filter import (
    BaselineConfig,
    Measurement,
    friction_saturation,
    model,
)
from tire_estimation.core.stiffness.frontend import StiffnessEstimate
from tire_estimation.core.stiffness.model import SingleTrackParams, slip_angles
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.evaluation.stiffness import NO_BIAS, truth_over_nominal
from tire_estimation.evaluation.stiffness_baselines import (
    AugPf,
    AugPfConfig,
    BaselineEstimator,
    EkfConfig,
    RlsConfig,
    gaussian_logpdf,
    model_jacobian,
)
from tire_estimation.evaluation.stiffness_compare import replay
from tire_estimation.sim import SimResult, simulate

#: 30 s stiffness_step drive with the 50 % drop at 15 s (bias-free IMU).
STEP_S = 15.0
SHARED: dict[str, Any] = {"initial_stiffness_factor": 0.7}


@pytest.fixture(scope="module")
def sim() -> SimResult:
    return simulate("stiffness_step", seed=0, minutes=0.5, sensors=NO_BIAS, step_time_s=STEP_S)


def _scores(sim: SimResult, est: Any) -> tuple[float, float, float]:
    """(vY RMSE after 2 s, |rel. error| of Cy_f over 10-15 s and over the last 3 s)."""
    res = replay(sim, est, lambda: est.initialized)
    t, ok = res["t_s"], res["ready"]
    rel = res["c"][:, 1] / res["truth_c"][:, 1] - 1.0
    m = ok & (t > 2.0)
    vy_rmse = float(np.sqrt(np.mean((res["vy"][m] - res["truth_vy"][m]) ** 2)))
    before = float(abs(np.mean(rel[ok & (t > 10.0) & (t < STEP_S - 0.5)])))
    after = float(abs(np.mean(rel[ok & (t > t[-1] - 3.0)])))
    return vy_rmse, before, after


# ------------------------------------------------------------------ configuration
@pytest.mark.parametrize(
    ("cls", "kw", "field"),
    [
        (AugPfConfig, {"n_particles": 0}, "n_particles"),
        (AugPfConfig, {"n_particles": 2.5}, "n_particles"),
        (AugPfConfig, {"stiffness_walk_std_fraction_sqrt_s": -0.1}, "stiffness_walk"),
        (AugPfConfig, {"resample_threshold": 1.5}, "resample_threshold"),
        (EkfConfig, {"process_vy_m_s_sqrt_s": 0.0}, "process_vy_m_s_sqrt_s"),
        (RlsConfig, {"forgetting": 1.5}, "forgetting"),
        (RlsConfig, {"kf_stiffness": "true"}, "kf_stiffness"),
        (RlsConfig, {"kf_measures_accel": 1}, "kf_measures_accel"),
        (BaselineConfig, {"tyre_shape": "pacejka"}, "tyre_shape"),
        (BaselineConfig, {"accel_noise_std_m_s2": float("nan")}, "accel_noise_std_m_s2"),
        (EkfConfig, {"initial_vy_std_m_s": -0.1}, "initial_vy_std_m_s"),
        (AugPfConfig, {"friction_coefficient": 0.05}, "friction_coefficient"),
    ],
)
def test_config_errors_name_field_and_value(cls: type, kw: dict[str, Any], field: str) -> None:
    value = next(iter(kw.values()))
    with pytest.raises(ConfigError, match=field) as info:
        cls(**kw)
    assert repr(value) in str(info.value) or str(value) in str(info.value)


def test_sharing_copies_common_fields() -> None:
    alg1 = StiffnessEstimatorConfig(n_particles=30, accel_noise_std_m_s2=0.07, drag_n_s2_m2=0.4)
    cfg = AugPfConfig.sharing(alg1, n_particles=12)
    assert cfg.n_particles == 12
    assert cfg.accel_noise_std_m_s2 == 0.07
    assert cfg.drag_n_s2_m2 == 0.4
    assert EkfConfig.sharing(alg1).gyro_noise_std_rad_s == alg1.gyro_noise_std_rad_s
    # the methods' own fields are not copied: n_particles, and RlsConfig.forgetting (the RLS
    # forgetting factor) is not Algorithm 1's NiW forgetting of the same name
    assert AugPfConfig.sharing(alg1).n_particles == AugPfConfig().n_particles
    other = StiffnessEstimatorConfig(forgetting=0.95)
    assert RlsConfig.sharing(other).forgetting == RlsConfig().forgetting


# ------------------------------------------------------------------ model helpers
def test_model_jacobian_matches_finite_differences_and_is_affine_in_w() -> None:
    p = SingleTrackParams.from_vehicle(VehicleParams())
    x = np.array([21.0, 0.3, 0.05])
    w = np.array([-2e4, -3e4, 1e4])
    ws = (21.3, 21.0)
    rate, y_hat, d_rate, d_meas, a, d = model_jacobian(x, w, 0.02, ws, p)
    r1, y1, _, _ = model(x[None, :], w[None, :], 0.02, ws, p)
    np.testing.assert_allclose(rate, r1[0])
    np.testing.assert_allclose(y_hat, y1[0])
    # d/dw exact (eq. 9 and 12 affine in w)
    dw = np.array([0.0, 1e3, 0.0])
    r2, y2, _, _ = model(x[None, :], (w + dw)[None, :], 0.02, ws, p)
    np.testing.assert_allclose(r2[0] - rate, a @ dw, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(y2[0] - y_hat, d @ dw, rtol=1e-9, atol=1e-12)
    # d/dx against a one-sided difference with a different step
    for j, h in enumerate((1e-4, 1e-5, 1e-6)):
        xp = x.copy()
        xp[j] += h
        rp, yp, _, _ = model(xp[None, :], w[None, :], 0.02, ws, p)
        np.testing.assert_allclose((rp[0] - rate) / h, d_rate[:, j], rtol=2e-3, atol=1e-3)
        np.testing.assert_allclose((yp[0] - y_hat) / h, d_meas[:, j], rtol=2e-3, atol=1e-3)


def test_friction_tyre_is_the_friction_limited_force_and_saturates_at_mu_g() -> None:
    mu = 0.3
    car = VehicleParams()
    p = SingleTrackParams.from_vehicle(car, friction_coefficient=mu)
    lin = SingleTrackParams.from_vehicle(car)
    c_n = np.asarray(p.nominal, dtype=float)
    # half and 1.5 x nominal cornering stiffness, same state
    w = np.array([[0.0, -0.5 * c_n[1], -0.5 * c_n[2]], [0.0, 0.5 * c_n[1], 0.5 * c_n[2]]])
    sat_f, sat_r = friction_saturation(p, w)
    assert friction_saturation(lin, w) is None
    # alpha_s = mu Fz / C: the peak C alpha_s is mu Fz whatever C is
    np.testing.assert_allclose((c_n[1] + w[:, 1]) * sat_f, p.saturation_slip_front_rad * c_n[1])
    np.testing.assert_allclose((c_n[2] + w[:, 2]) * sat_r, p.saturation_slip_rear_rad * c_n[2])
    # deep in saturation (|alpha| ~ 0.3 rad) the lateral specific force is mu g for both rows
    x = np.array([[20.0, -6.0, 0.0], [20.0, -6.0, 0.0]])
    _, y_hat, _, _ = model(x, w, 0.0, (20.0, 20.0), p)
    alpha_f, alpha_r = slip_angles(x, 0.0, p)
    assert np.all(alpha_f > 0.25) and np.all(alpha_r > 0.25)
    np.testing.assert_allclose(y_hat[:, 1], mu * 9.81, rtol=0.02)
    # the linear tyre scales with C instead
    _, y_lin, _, _ = model(x, w, 0.0, (20.0, 20.0), lin)
    assert y_lin[1, 1] / y_lin[0, 1] == pytest.approx(3.0, rel=0.01)


def test_model_jacobian_in_w_with_the_friction_tyre() -> None:
    p = SingleTrackParams.from_vehicle(VehicleParams(), friction_coefficient=0.3)
    x = np.array([15.0, -0.4, 0.12])
    w = np.array([0.0, -4e4, -5e4])
    ws = (15.1, 15.0)
    rate, y_hat, _, _, a_w, d_w = model_jacobian(x, w, 0.03, ws, p)
    _, _, a_sec, d_sec = model(x[None, :], w[None, :], 0.03, ws, p)
    for j, h in ((1, 50.0), (2, 50.0)):
        wp = w.copy()
        wp[j] += h
        rp, yp, _, _ = model(x[None, :], wp[None, :], 0.03, ws, p)
        np.testing.assert_allclose((rp[0] - rate) / h, a_w[:, j], rtol=1e-3, atol=1e-9)
        np.testing.assert_allclose((yp[0] - y_hat) / h, d_w[:, j], rtol=1e-3, atol=1e-9)
    # not affine any more: the derivative is below the secant a = phi(alpha) in saturation
    assert abs(d_w[1, 1]) < 0.9 * abs(d_sec[0, 1, 1])
    assert abs(a_w[1, 2]) < 0.9 * abs(a_sec[0, 1, 2])


def test_gaussian_logpdf_matches_scipy() -> None:
    rng = np.random.default_rng(3)
    b = rng.standard_normal((4, 3, 3))
    cov = b @ np.swapaxes(b, 1, 2) + 0.5 * np.eye(3)
    e = rng.standard_normal((4, 3))
    ref = [stats.multivariate_normal(np.zeros(3), cov[i]).logpdf(e[i]) for i in range(4)]
    np.testing.assert_allclose(gaussian_logpdf(e, cov), ref, rtol=1e-10)


def test_augpf_shapes_weights_and_frozen_stiffness() -> None:
    cfg = AugPfConfig(n_particles=64, initial_stiffness_factor=0.7)
    p = SingleTrackParams.from_vehicle(VehicleParams())
    pf = AugPf(cfg, p, np.random.default_rng(1))
    pf.initialize(np.array([20.0, 0.0, 0.0]), np.array([0.3, 0.3, 0.01]))
    meas = Measurement(
        y=np.array([0.0, 0.0, 0.0]),
        delta_rad=0.0,
        wheel_speed_m_s=(20.0, 20.0),
        speed_m_s=20.0,
        vx_measured=False,
    )
    w0 = pf.w.copy()
    for _ in range(20):
        pf.predict(0.01, learn=False, learn_cx=False)
        pf.update(meas, learn=False, learn_cx=False)
    assert pf.x.shape == (64, 3)
    assert pf.w.shape == (64, 3)
    assert pf.weights.shape == (64,)
    assert abs(pf.weights.sum() - 1.0) < 1e-12
    # no random walk while not learning: every stiffness is one of the initial particles
    assert np.all(np.isin(pf.w[:, 1], w0[:, 1]))
    e = pf.estimate()
    assert e.stiffness.shape == (3,)
    assert e.stiffness_std.shape == (3,)
    assert e.state_cov.shape == (3, 3)
    assert 1.0 <= e.n_eff <= 64.0


# ------------------------------------------------------------------ learning on the simulator
def test_augpf_learns_cy_front_and_tracks_vy(sim: SimResult) -> None:
    cfg = AugPfConfig(n_particles=100, **SHARED)
    est = BaselineEstimator(cfg, sim.vehicle, np.random.default_rng(100))
    vy_rmse, before, after = _scores(sim, est)
    assert isinstance(est.estimate(), StiffnessEstimate)
    # from 70 % of nominal: within 10 % before and 15 % after the 50 % step
    assert before < 0.10
    assert after < 0.15
    assert vy_rmse < 0.15


def test_ekf_learns_cy_front_and_tracks_vy(sim: SimResult) -> None:
    est = BaselineEstimator(EkfConfig(**SHARED), sim.vehicle)
    vy_rmse, before, after = _scores(sim, est)
    assert before < 0.05
    assert after < 0.05
    assert vy_rmse < 0.05
    assert np.isnan(est.estimate().n_eff)


def test_rls_learns_cy_front_and_tracks_vy() -> None:
    # the KF + RLS needs the full minute (step at 30 s): on the 30 s drive its closed loop
    # first locks onto ~20 % of the true stiffness (slip angles of a KF with that stiffness
    # explain the measured forces) and escapes only slowly (forgetting 0.998)
    full = simulate("stiffness_step", seed=0, minutes=1.0, sensors=NO_BIAS)
    est = BaselineEstimator(RlsConfig(**SHARED), full.vehicle)
    res = replay(full, est, lambda: est.initialized)
    t = res["t_s"]
    rel = res["c"][:, 1] / res["truth_c"][:, 1] - 1.0
    steady = ((t > 15.0) & (t < 29.5)) | (t > 45.0)
    final = t > 55.0
    vy_err = (res["vy"] - res["truth_vy"])[t > 2.0]
    # measured (seed 0): steady mean -4.5 %, last 5 s about -1 %, vY RMSE about 0.25 m/s
    assert abs(np.mean(rel[steady])) < 0.08
    assert abs(np.mean(rel[final])) < 0.05
    assert np.sqrt(np.mean(vy_err**2)) < 0.35
    # Cx is not estimated: it stays at the initial guess
    e = est.estimate()
    assert e.stiffness[0] == pytest.approx(0.7 * e.nominal[0])


def test_rls_with_the_friction_tyre_on_snow() -> None:
    # snow_sine seed 0 from 150 % of the truth (truth = half the nominal, mu 0.3): measured
    # steady mean error -3.9 / -4.2 % with the friction tyre, -8.2 / -9.3 % with the linear one
    snow = simulate("snow_sine", seed=0, sensors=NO_BIAS)
    start = 1.5 * truth_over_nominal(snow)
    err = {}
    for mu in (0.0, 0.3):
        cfg = RlsConfig(initial_stiffness_factor=start, friction_coefficient=mu)
        est = BaselineEstimator(cfg, snow.vehicle)
        res = replay(snow, est, lambda e=est: e.initialized)
        rel = res["c"] / res["truth_c"] - 1.0
        err[mu] = rel[res["t_s"] > res["t_s"][-1] - 5.0, 1:].mean(axis=0)
    assert np.all(np.abs(err[0.3]) < 0.06)
    assert np.all(err[0.0] < -0.07)


def test_augpf_reproducible_with_the_same_seed() -> None:
    short = simulate("stiffness_step", seed=1, minutes=0.1, sensors=NO_BIAS)
    cfg = AugPfConfig(n_particles=32, **SHARED)
    runs = [
        replay(
            short,
            BaselineEstimator(cfg, short.vehicle, np.random.default_rng(s)),
            lambda: True,
        )
        for s in (5, 5, 6)
    ]
    np.testing.assert_array_equal(runs[0]["c"], runs[1]["c"])
    np.testing.assert_array_equal(runs[0]["vy"], runs[1]["vy"])
    assert not np.array_equal(runs[0]["c"], runs[2]["c"])


def test_bad_input_is_counted_and_reset_forgets() -> None:
    est = BaselineEstimator(EkfConfig(), VehicleParams())
    est.on_wheel_speeds(10, [1.0, 2.0, 3.0])
    est.on_steering(20, float("nan"))
    est.on_imu(30, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    assert est.stats == {"wheel_speeds:wrong_length": 1, "steering:nan": 1, "imu:no_speed": 1}
    w = 20.0 / 0.31
    for k in range(50):
        t = 1_000_000_000 + k * 10_000_000
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_imu(t + 1, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    e = est.estimate()
    assert est.initialized
    assert not e.active
    assert e.reason == "no lateral excitation"
    assert abs(e.vx_m_s - 20.0) < 0.5
    est.reset()
    assert not est.initialized
    assert est.estimate().reason == "not initialized"


def test_a_measured_speed_freezes_cx_as_in_algorithm_1() -> None:
    # the front-end is Algorithm 1's: without wheel speeds the slip (eq. 3) is unknown, so
    # the EKF's Cx stays at the initial guess however much ax varies
    est = BaselineEstimator(EkfConfig(**SHARED), VehicleParams())
    for k in range(600):
        t = 1_000_000_000 + k * 10_000_000
        est.on_velocity(t, 20.0)
        est.on_steering(t + 1, 0.02)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.5 * np.sin(0.05 * k), 0.0, 9.81])
    e = est.estimate()
    assert e.active and not e.cx_active
    assert e.reason == "excited (Cx frozen: no wheel speeds)"
    assert e.stiffness[0] == pytest.approx(0.7 * e.nominal[0], rel=1e-12)
    with pytest.raises(TypeError, match="BaselineConfig"):
        BaselineEstimator(BaselineConfig(), VehicleParams())
