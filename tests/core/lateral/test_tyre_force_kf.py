"""Tyre-force Kalman filter (Tuononen 2009): virtual sensors, relay, filter, robustness."""

from __future__ import annotations

import dataclasses
import itertools
import math
import re

import numpy as np
import pytest

from tests.core.lateral import reference_tyre_force as reference
from tests.core.lateral.reference_single_track import expm_small
from tire_estimation.core.lateral import tyre_force_kernels
from tire_estimation.core.lateral.estimate import LateralEstimate
from tire_estimation.core.lateral.single_track import (
    SingleTrackModel,
    SingleTrackParams,
    axle_forces,
    continuous_matrices,
    steady_state,
)
from tire_estimation.core.lateral.tyre_force_filter import (
    HysteresisRelay,
    axle_force_deviation,
)
from tire_estimation.core.lateral.tyre_force_kf import (
    TUONONEN_2009_VEHICLE,
    TyreForceEstimator,
    TyreForceKFConfig,
)
from tire_estimation.core.lateral.virtual_tyre import (
    MagicFormulaTyre,
    inverse_magic_formula,
    magic_formula,
    peak_slip_factor,
    virtual_load,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.evaluation import lateral_tyre
from tire_estimation.replay import section_config
from tire_estimation.sim import SensorConfig, simulate

ALL_WHEELS = ("wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr")


# --------------------------------------------------------------------------- virtual tyres
def test_inverse_magic_formula_round_trip() -> None:
    tyre = MagicFormulaTyre(cornering_stiffness_n_rad=50_000.0)
    for fz in (1500.0, 4000.0, 7000.0):
        b, _ = tyre.factors(fz)
        alpha_peak = tyre.x_peak / b
        for frac in (-0.8, -0.5, -0.1, 0.0, 0.02, 0.3, 0.7, 0.8):
            alpha = frac * alpha_peak
            fy = tyre.force(alpha, fz)
            assert tyre.slip_angle(fy, fz) == pytest.approx(alpha, abs=1e-8)


def test_inverse_magic_formula_saturates_at_the_peak() -> None:
    b, c, d, e = 10.0, 1.3, 4000.0, -0.5
    xp = peak_slip_factor(c, e)
    # the peak: C atan(phi(x*)) = pi / 2, so the force there is D
    assert magic_formula(xp / b, b, c, d, e) == pytest.approx(d, rel=1e-9)
    assert inverse_magic_formula(1.2 * d, b, c, d, e) == pytest.approx(xp / b)
    assert inverse_magic_formula(-1.2 * d, b, c, d, e) == pytest.approx(-xp / b)


def test_virtual_load_mirrors_the_measured_load_change() -> None:
    # eq. (12)-(13): +600 N on the sensor wheel -> -600 N on the virtual wheel
    assert virtual_load(4600.0, 4000.0, 4100.0) == pytest.approx(3500.0)


def test_virtual_sensor_reproduces_a_measured_wheel_in_the_linear_range() -> None:
    # every wheel measured without noise: predict wheel_fr from wheel_fl and rl from rr
    sensors = SensorConfig(
        tire_force_wheels=ALL_WHEELS,
        tire_force_noise_fx_n=0.0,
        tire_force_noise_fy_n=0.0,
        tire_force_noise_fz_n=0.0,
    )
    sim = simulate("lane_change", seed=3, minutes=0.15, sensors=sensors)
    tf = sim.tire_forces
    assert tf is not None
    est = TyreForceEstimator(TyreForceKFConfig(), sim.vehicle)
    for axle, (src, dst) in enumerate(((0, 1), (3, 2))):
        tyre = est.tyres[axle]
        static = est.nominal_static_load_n[axle]
        fy1, fz1, fy2 = tf.fy_n[:, src], tf.fz_n[:, src], tf.fy_n[:, dst]
        pred = np.array(
            [
                tyre.virtual_force(a, b, virtual_load(b, static, static))
                for a, b in zip(fy1, fz1, strict=True)
            ]
        )
        linear = np.abs(fy1) < 0.3 * fz1
        assert linear.sum() > 100 and np.abs(fy2[linear]).max() > 1000.0
        assert np.abs(pred - fy2)[linear].max() < 50.0
        assert np.abs(pred - fy2).max() < 150.0  # beyond the linear range as well


# --------------------------------------------------------------------------- equations
def test_transition_matrix_is_eq_21() -> None:
    a = reference.transition_matrix(0.01, 20.0, 1500.0, 2500.0, 1.1, 1.6)
    expected = np.array(
        [
            [1.0, -0.01 * 20.0, 0.01 / 1500.0, 0.01 / 1500.0],
            [0.0, 1.0, 1.1 / 2500.0 * 0.01, -1.6 / 2500.0 * 0.01],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    np.testing.assert_allclose(a, expected)


@pytest.mark.parametrize("rows", [[0, 1, 2, 3], [0, 1, 2], [0, 1, 3], [0, 1]])
def test_compiled_kf_step_equals_the_numpy_reference(rows: list[int]) -> None:
    rng = np.random.default_rng(len(rows) + rows[-1])
    consts = tyre_force_kernels.kf_constants(1500.0, 2500.0, 1.1, 1.6, [1e-4, 1e-5, 4e4, 4e4])
    for _ in range(20):
        x = rng.normal(size=4) * np.array([0.3, 0.1, 3000.0, 3000.0])
        g = rng.normal(size=(4, 4)) * np.array([0.1, 0.03, 300.0, 300.0])
        p = g @ g.T + np.eye(4) * 1e-3
        dt, vx, moment = 0.01, float(rng.uniform(5.0, 40.0)), float(rng.normal() * 500.0)
        z = x[rows] + rng.normal(size=len(rows)) * np.array([0.1, 0.01, 200.0, 200.0])[rows]
        r_diag = np.array([1e-3, 1e-4, 9e4, 9e4])[rows]
        x_ref, p_ref = reference.predict(x, p, consts, dt, vx, moment)
        x_ref, p_ref = reference.update(x_ref, p_ref, rows, z, r_diag)
        x_c, p_c = x.copy(), p.copy()
        tyre_force_kernels.predict(x_c, p_c, consts, dt, vx, moment)
        finite = tyre_force_kernels.update(x_c, p_c, np.array(rows, dtype=np.intp), z, r_diag)
        assert finite
        np.testing.assert_allclose(x_c, x_ref, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(p_c, p_ref, rtol=1e-9, atol=1e-12 * float(np.abs(p_ref).max()))


def test_compiled_kf_update_says_when_it_diverged() -> None:
    consts = tyre_force_kernels.kf_constants(1500.0, 2500.0, 1.1, 1.6, [1e-4, 1e-5, 4e4, 4e4])
    x, p = np.zeros(4), np.eye(4)
    tyre_force_kernels.predict(x, p, consts, 0.01, 20.0, 0.0)
    rows = np.arange(4, dtype=np.intp)
    z = np.array([0.0, 0.0, np.inf, 0.0])
    assert not tyre_force_kernels.update(x, p, rows, z, np.ones(4))
    # a singular innovation covariance does not raise: the state is not finite
    x, p = np.zeros(4), np.zeros((4, 4))
    assert not tyre_force_kernels.update(x, p, rows, np.ones(4), np.zeros(4))


def test_axle_force_deviation_is_eq_29() -> None:
    assert axle_force_deviation(np.array([1000.0, -500.0]), np.array([700.0, 200.0])) == 1000.0


def test_single_track_steady_state_has_the_understeer_gain() -> None:
    p = SingleTrackParams.from_vehicle(VehicleParams())
    v, delta = 20.0, 0.02
    wb = p.lf_m + p.lr_m
    k_us = p.mass_kg / wb * (p.lr_m / p.cf_n_rad - p.lf_m / p.cr_n_rad)
    _, r = steady_state(p, v, delta)
    assert r == pytest.approx(v * delta / (wb + k_us * v * v), rel=1e-9)


def _linear_single_track_truth(
    p: SingleTrackParams, vx: float, t_s: np.ndarray, delta_fn, substeps: int = 50
) -> np.ndarray:
    """[vy_cg, r] of eq. (23-28) at ``t_s`` for a continuous steer angle ``delta_fn(t)``,
    integrated with ``substeps`` midpoint-sampled zero-order-hold steps per interval."""
    a, b = continuous_matrices(p, vx)
    x = steady_state(p, vx, float(delta_fn(t_s[0])))
    out = [x]
    for t0, t1 in itertools.pairwise(t_s):
        h = (t1 - t0) / substeps
        aug = np.zeros((3, 3))
        aug[:2, :2] = a * h
        aug[:2, 2] = b * h
        e = expm_small(aug)
        for j in range(substeps):
            x = e[:2, :2] @ x + e[:2, 2] * float(delta_fn(t0 + (j + 0.5) * h))
        out.append(x)
    return np.array(out)


def test_single_track_first_order_hold_follows_a_steering_ramp() -> None:
    # a steering ramp from rest: the first-order hold is exact for it, the hold of the newest
    # sample over the step is not (it leads by half a step)
    p = SingleTrackParams.from_vehicle(VehicleParams())
    vx, rate, dt = 20.0, 0.05, 0.01
    t = np.arange(0.0, 0.5 + 1e-9, dt)
    truth = _linear_single_track_truth(p, vx, t, lambda s: rate * s)
    foh = SingleTrackModel(p)
    zoh = SingleTrackModel(p)
    foh.reset(vx, 0.0)
    zoh.reset(vx, 0.0)
    err_foh, err_zoh = [], []
    for k in range(1, t.size):
        x_foh = foh.step(dt, vx, rate * t[k], rate * t[k - 1])
        x_zoh = zoh.step(dt, vx, rate * t[k])
        err_foh.append(x_foh - truth[k])
        err_zoh.append(x_zoh - truth[k])
    assert truth[-1, 1] > 0.09  # ~5.8 deg/s reached
    assert np.abs(np.array(err_foh)).max() < 1e-6
    # the end-of-step hold runs ahead of the truth (~1.2e-3 rad/s at the end)
    assert np.array(err_zoh)[-1, 1] > 5e-4


def test_kf_yaw_rate_has_no_steering_lead_on_a_linear_vehicle() -> None:
    # Noise-free inputs from the linear single-track model itself (eq. 23-28, continuous
    # sinusoidal steering, all four wheels measured, static loads): the filter's model is then
    # exact, so its yaw rate must match the truth up to discretization. Holding the newest
    # steering sample over the single-track model's step led the truth by half a step (5 ms),
    # an error of ~0.065 deg/s RMSE here (with the first-order hold: ~3e-4 deg/s).
    vehicle = VehicleParams()
    p = SingleTrackParams.from_vehicle(vehicle)
    vx, amp, period, dt = 16.7, 0.03, 2.5, 0.01
    t = np.arange(0.0, 6.0 + 1e-9, dt)

    def delta_fn(s: float) -> float:
        return amp * math.sin(2.0 * math.pi * max(s - 1.0, 0.0) / period)

    truth = _linear_single_track_truth(p, vx, t, delta_fn)
    est = TyreForceEstimator(TyreForceKFConfig(), vehicle)
    fz = np.repeat(est.nominal_static_load_n, 2)
    omega = np.full(4, vx / vehicle.nominal_tire_radius_m)
    kf_r, st_r = [], []
    for k, tk in enumerate(t):
        t_ns = round(tk * 1e9) + 1_000_000_000
        delta = delta_fn(tk)
        est.on_wheel_speeds(t_ns, omega)
        est.on_steering(t_ns, delta)
        f_axle = axle_forces(p, truth[k, 0], truth[k, 1], vx, delta)
        # per wheel: half the axle force, in the wheel frame (front wheels steered by delta)
        fy = np.array([f_axle[0], f_axle[0], f_axle[1], f_axle[1]]) / 2.0
        fy[:2] /= math.cos(delta)
        e = est.on_tire_forces(t_ns, np.zeros(4), fy, fz, np.ones(4, dtype=bool))
        assert e is not None
        kf_r.append(e.yaw_rate_rad_s)
        st_r.append(est.single_track_estimate().yaw_rate_rad_s)
    scored = t > 1.0
    r_true = truth[scored, 1]
    assert np.degrees(np.abs(r_true).max()) > 5.0  # a real manoeuvre (~7.6 deg/s peak)
    st_rmse = np.degrees(np.sqrt(np.mean((np.array(st_r)[scored] - r_true) ** 2)))
    kf_rmse = np.degrees(np.sqrt(np.mean((np.array(kf_r)[scored] - r_true) ** 2)))
    assert st_rmse < 0.005
    assert kf_rmse < 0.005


# --------------------------------------------------------------------------- relay
def test_relay_hysteresis_switching() -> None:
    relay = HysteresisRelay(on_threshold=500.0, off_threshold=250.0)
    seq = [0, 300, 499, 501, 400, 260, 251, 249, 300, 499, 800, 100]
    states = [relay.update(x) for x in seq]
    assert states == [
        False,  # 0
        False,  # 300 (below on)
        False,  # 499
        True,  # 501 > on
        True,  # 400 (between: hold)
        True,  # 260
        True,  # 251
        False,  # 249 < off
        False,  # 300 (between: hold)
        False,  # 499
        True,  # 800
        False,  # 100
    ]


# --------------------------------------------------------------------------- config
def test_config_errors_name_the_field() -> None:
    with pytest.raises(ConfigError, match="force_variance_n2=-1"):
        TyreForceKFConfig(force_variance_n2=-1.0)
    with pytest.raises(ConfigError, match="max_gap_s"):
        TyreForceKFConfig(max_gap_s=2e12)
    with pytest.raises(ConfigError, match=r"min_speed_m_s=0\.1"):
        TyreForceKFConfig(min_speed_m_s=0.1)
    with pytest.raises(ConfigError, match="nope"):
        section_config(TyreForceKFConfig, "tyre_force", {"nope": 1})
    assert section_config(TyreForceKFConfig, "tyre_force", {"max_gap_s": 2}).max_gap_s == 2.0


def test_every_config_field_is_documented_with_a_default() -> None:
    doc = TyreForceKFConfig.__doc__ or ""
    attrs = doc.split("Attributes:")[1]
    for f in dataclasses.fields(TyreForceKFConfig):
        m = re.search(rf"^\s+{f.name}: (.*?)(?=^\s+\w+: |\Z)", attrs, re.M | re.S)
        assert m, f.name
        assert "Default" in m.group(1), f.name


def test_table_1_defaults() -> None:
    c = TyreForceKFConfig()
    assert (c.process_noise_vy_m2_s2, c.process_noise_yaw_rate_rad2_s2) == (0.01, 0.01)
    assert c.process_noise_force_n2 == 1e4
    v = TUONONEN_2009_VEHICLE
    assert (v.mass_kg, v.lf_m, v.lr_m, v.yaw_inertia_kg_m2) == (1603.0, 1.05, 1.525, 3156.0)


# --------------------------------------------------------------------------- filter on the sim
@pytest.fixture(scope="module")
def lane_change() -> tuple[lateral_tyre.LateralTrace, dict]:
    sim = simulate("lane_change", seed=2, minutes=0.5)
    trace = lateral_tyre.run(sim)
    return trace, lateral_tyre.scores(trace)


def test_kf_meets_the_issue_targets_on_lane_change(lane_change) -> None:
    trace, s = lane_change
    kf = s["overall"]["tyre_force_kf"]
    assert kf["vy_rmse_m_s"] <= 0.1
    assert kf["yaw_rate_rmse_deg_s"] <= 0.5
    assert np.all(np.isfinite(trace.kf_vy_m_s)) and np.all(np.isfinite(trace.kf_yaw_rate_rad_s))


def test_kf_beats_the_single_track_model_in_the_nonlinear_phases(lane_change) -> None:
    _, s = lane_change
    nl = s["nonlinear"]
    assert nl["samples"] > 200  # the relay did see nonlinear phases
    assert s["relay_switches"] > 0
    assert nl["tyre_force_kf"]["vy_rmse_m_s"] < 0.8 * nl["single_track"]["vy_rmse_m_s"]
    assert nl["tyre_force_kf"]["yaw_rate_rmse_deg_s"] < nl["single_track"]["yaw_rate_rmse_deg_s"]


def test_relay_is_linear_when_driving_straight(lane_change) -> None:
    trace, _ = lane_change
    # the first lane change starts at t = 3 s
    straight = (trace.t_s > 1.0) & (trace.t_s < 2.9)
    assert not trace.nonlinear[straight].any()


# --------------------------------------------------------------------------- robustness
def _feed_ok(est: TyreForceEstimator, t: int) -> LateralEstimate | None:
    est.on_steering(t, 0.01)
    est.on_wheel_speeds(t, np.full(4, 20.0 / 0.31))
    fy = np.array([800.0, 0.0, 0.0, 700.0])
    fz = np.array([4300.0, 0.0, 0.0, 3000.0])
    valid = np.array([True, False, False, True])
    return est.on_tire_forces(t, np.zeros(4), fy, fz, valid)


def test_bad_inputs_are_dropped_and_counted() -> None:
    est = TyreForceEstimator(TyreForceKFConfig(), VehicleParams())
    t = 1_000_000_000
    valid = np.array([True, False, False, True])
    good = np.array([500.0, 0.0, 0.0, 500.0]), np.array([4300.0, 0.0, 0.0, 3000.0])
    # no steering / speed yet
    assert est.on_tire_forces(t, np.zeros(4), good[0], good[1], valid) is None
    assert est.stats["tire_forces:no_steering"] == 1
    for k in range(1, 20):
        assert _feed_ok(est, t + k * 10_000_000) is not None
    t_last = t + 19 * 10_000_000
    est.on_tire_forces(t_last - 5, np.zeros(4), *good, valid)  # out of order
    est.on_tire_forces(t_last + 1, np.zeros(4), np.array([np.nan, 0, 0, 1.0]), good[1], valid)
    est.on_tire_forces(t_last + 2, np.zeros(3), *good, valid)  # wrong length
    est.on_tire_forces(t_last + 3, np.zeros(4), *good, np.zeros(4, dtype=bool))
    est.on_tire_forces(1.5, np.zeros(4), *good, valid)  # type: ignore[arg-type]
    est.on_steering(t_last + 4, float("inf"))
    est.on_wheel_speeds(t_last + 4, [1.0, 2.0])
    est.on_wheel_speeds(t_last + 5, [1.0, 2.0, 3.0])
    est.on_wheel_speeds(t_last + 6, "fast")
    assert est.stats == {
        "tire_forces:no_steering": 1,
        "tire_forces:out_of_order": 1,
        "tire_forces:nan": 1,
        "tire_forces:wrong_length": 1,
        "tire_forces:no_valid_sensor": 1,
        "tire_forces:bad_stamp": 1,
        "steering:nan": 1,
        "wheel_speeds:wrong_length": 2,
        "wheel_speeds:bad_value": 1,
    }
    e = est.estimate()
    values = [e.vx_m_s, e.vy_m_s, e.yaw_rate_rad_s, e.sideslip_rad]
    assert all(math.isfinite(v) for v in values)
    assert np.all(np.isfinite(e.covariance)) and e.covariance.shape == (3, 3)
    assert e.axle_lateral_force_n.shape == (2,) and e.source == "tyre_force_kf"
    assert e.linearity in ("linear", "nonlinear", "unknown")


def test_estimate_before_any_input_is_finite() -> None:
    e = TyreForceEstimator(TyreForceKFConfig(), VehicleParams()).estimate()
    assert e.t_ns == 0 and e.linearity == "unknown"
    assert np.all(np.isfinite(e.covariance))


def test_a_gap_reinitializes_and_low_speed_is_unknown() -> None:
    est = TyreForceEstimator(TyreForceKFConfig(), VehicleParams())
    t = 0
    for k in range(5):
        _feed_ok(est, t + k * 10_000_000)
    _feed_ok(est, t + 2_000_000_000)  # 2 s gap > max_gap_s
    assert est.stats["tire_forces:gap"] == 1
    est.on_steering(t + 2_010_000_000, 0.0)
    est.on_wheel_speeds(t + 2_010_000_000, np.full(4, 1.0))  # 0.31 m/s
    est.on_tire_forces(
        t + 2_010_000_000,
        np.zeros(4),
        np.zeros(4),
        np.array([4300.0, 0, 0, 3000.0]),
        np.array([True, False, False, True]),
    )
    assert est.estimate().linearity == "unknown"


def test_an_input_stamped_after_the_forces_is_not_fresh() -> None:
    """Steering and wheel speeds stamped 0.3 s after the forces are not used for them (a
    negative age is not fresh, however small)."""
    est = TyreForceEstimator(TyreForceKFConfig(), VehicleParams())
    t = 1_000_000_000
    future = t + 300_000_000
    est.on_steering(future, 0.01)
    est.on_wheel_speeds(future, np.full(4, 20.0 / 0.31))
    fy, fz = np.array([800.0, 0.0, 0.0, 700.0]), np.array([4300.0, 0.0, 0.0, 3000.0])
    valid = np.array([True, False, False, True])
    assert est.on_tire_forces(t + 1, np.zeros(4), fy, fz, valid) is None
    assert est.stats["tire_forces:no_steering"] == 1
