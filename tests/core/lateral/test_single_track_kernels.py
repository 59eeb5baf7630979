"""The compiled single-track discretization and linear-KF step against their NumPy reference
(``reference_single_track``): equal to about 1e-12 on random inputs and over a filtered drive."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from tests.core.lateral.reference_single_track import (
    ReferenceLinearKF,
    first_order_hold,
    kf_predict,
    kf_update,
    zero_order_hold,
)
from tire_estimation.core.lateral import single_track_kernels as kernels
from tire_estimation.core.lateral.linear_kf import LinearLateralKF, LinearLateralKFConfig
from tire_estimation.core.lateral.single_track import (
    SingleTrackModel,
    SingleTrackParams,
    axle_forces,
    continuous_matrices,
)
from tire_estimation.core.vehicle import VehicleParams

RTOL = 1e-12


def _random_params(rng: np.random.Generator) -> SingleTrackParams:
    return SingleTrackParams(
        mass_kg=float(rng.uniform(800.0, 3000.0)),
        yaw_inertia_kg_m2=float(rng.uniform(800.0, 5000.0)),
        lf_m=float(rng.uniform(0.8, 1.8)),
        lr_m=float(rng.uniform(0.8, 1.8)),
        cf_n_rad=float(rng.uniform(3e4, 2.5e5)),
        cr_n_rad=float(rng.uniform(3e4, 2.5e5)),
    )


def _model(p: SingleTrackParams) -> np.ndarray:
    return kernels.model_constants(
        p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m, p.lr_m, p.cf_n_rad, p.cr_n_rad
    )


def _close(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = float(np.max(np.abs(expected)))
    np.testing.assert_allclose(actual, expected, rtol=RTOL, atol=RTOL * scale)


def test_discretizations_equal_the_numpy_matrix_exponential() -> None:
    # speeds from 1 to 70 m/s and steps from 1 to 200 ms: 0 to 6 squarings
    rng = np.random.default_rng(0)
    squared = set()
    for _ in range(300):
        p = _random_params(rng)
        vx, dt = float(rng.uniform(1.0, 70.0)), float(rng.uniform(0.001, 0.2))
        a, b = continuous_matrices(p, vx)
        squared.add(math.ceil(math.log2(max(np.abs(a * dt).sum(axis=1).max(), 0.25) / 0.25)))
        ad, b0, b1 = first_order_hold(a, b, dt)
        foh = np.empty((2, 4))
        kernels.first_order_hold(_model(p), vx, dt, foh)
        _close(foh, np.column_stack([ad, b0, b1]))
        ad, bd = zero_order_hold(a, b, dt)
        zoh = np.empty((2, 3))
        kernels.zero_order_hold(_model(p), vx, dt, zoh)
        _close(zoh, np.column_stack([ad, bd]))
    assert len(squared) >= 4


def test_kf_step_equals_the_numpy_predict_and_update() -> None:
    rng = np.random.default_rng(1)
    for _ in range(300):
        p = _random_params(rng)
        q = np.diag(rng.uniform(0.001, 1.0, 2))
        r = np.diag(rng.uniform(1e-5, 1.0, 2))
        x = rng.normal(0.0, [1.0, 0.3])
        half = rng.normal(size=(2, 2))
        cov = half @ half.T + 1e-3 * np.eye(2)
        vx, dt = float(rng.uniform(3.0, 70.0)), float(rng.uniform(0.002, 0.1))
        d0, d1 = (float(v) for v in rng.normal(0.0, 0.05, 2))
        ay, yaw = float(rng.normal(0.0, 3.0)), float(rng.normal(0.0, 0.3))
        x_ref, p_ref = kf_predict(x, cov, p, q, dt, vx, d0, d1)
        x_ref, p_ref = kf_update(x_ref, p_ref, p, r, vx, d1, ay, yaw)
        consts = kernels.kf_constants(_model(p), q[0, 0], q[1, 1], r[0, 0], r[1, 1])
        x_c, p_c = x.copy(), cov.copy()
        kernels.kf_step(x_c, p_c, consts, dt, vx, d0, d1, ay, yaw)
        _close(x_c, x_ref)
        _close(p_c, p_ref)


def _sine_drive(kf: LinearLateralKF, model: SingleTrackModel, seed: int) -> np.ndarray:
    """A 30-s sine-steer drive of the model with noisy sensors, a speed change, a low-speed
    stretch and a gap; the filter's [vy, r, P] after every IMU sample."""
    rng = np.random.default_rng(seed)
    p = model.params
    out = []
    delta_prev = 0.0
    for k in range(3000):
        t_ns = 1_000_000_000 + k * 10_000_000 + (600_000_000 if k >= 2000 else 0)
        vx = 2.0 if 1200 <= k < 1300 else 15.0 + 10.0 * math.sin(0.2 * k * 0.01)
        delta = 0.05 * math.sin(2 * math.pi * 0.7 * k * 0.01)
        x = model.step(0.01, max(vx, 3.0), delta, delta_prev)
        delta_prev = delta
        ff, fr = axle_forces(p, float(x[0]), float(x[1]), max(vx, 3.0), delta)
        kf.on_velocity(t_ns, vx)
        kf.on_steering(t_ns, delta)
        kf.on_imu(
            t_ns,
            [0.0, 0.0, float(x[1]) + 0.002 * rng.standard_normal()],
            [0.0, (ff + fr) / p.mass_kg + 0.05 * rng.standard_normal(), 9.81],
        )
        out.append([*kf.x, *kf.p.ravel()])
    return np.asarray(out)


@pytest.mark.parametrize("seed", [0, 1])
def test_linear_kf_follows_its_numpy_reference_over_a_drive(seed: int) -> None:
    veh = VehicleParams()
    cfg = LinearLateralKFConfig(accel_y_std_m_s2=0.05)
    p = SingleTrackParams.from_vehicle(veh)
    compiled = _sine_drive(LinearLateralKF(cfg, veh), SingleTrackModel(p), seed)
    reference = _sine_drive(ReferenceLinearKF(cfg, veh), SingleTrackModel(p), seed)
    assert np.ptp(compiled[:, 0]) > 0.1  # the drive excites vy
    for col in range(compiled.shape[1]):
        _close(compiled[:, col], reference[:, col])


def test_single_track_model_steps_equal_the_numpy_discretization() -> None:
    p = dataclasses.replace(SingleTrackParams.from_vehicle(VehicleParams()), cf_n_rad=9e4)
    model, vx, dt = SingleTrackModel(p), 20.0, 0.01
    model.reset(vx, 0.0)
    x_ref = model.x.copy()
    a, b = continuous_matrices(p, vx)
    ad, b0, b1 = first_order_hold(a, b, dt)
    az, bz = zero_order_hold(a, b, dt)
    delta_prev = 0.0
    for k in range(1, 200):
        delta = 0.04 * math.sin(0.05 * k)
        if k % 2:
            x = model.step(dt, vx, delta, delta_prev)
            x_ref = ad @ x_ref + b0 * delta_prev + b1 * (delta - delta_prev) / dt
        else:
            x = model.step(dt, vx, delta)
            x_ref = az @ x_ref + bz * delta
        delta_prev = delta
        _close(x, x_ref)
