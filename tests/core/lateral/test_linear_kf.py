"""Linear single-track Kalman filter (the lateral baseline)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.lateral.linear_kf import LinearLateralKF, LinearLateralKFConfig
from tire_estimation.core.lateral.single_track import (
    SingleTrackModel,
    SingleTrackParams,
    axle_forces,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError


def test_config_errors_name_the_field() -> None:
    with pytest.raises(ConfigError, match="accel_y_std_m_s2"):
        LinearLateralKFConfig(accel_y_std_m_s2=0.0)
    with pytest.raises(ConfigError, match="cornering_stiffness_front_n_rad"):
        LinearLateralKFConfig(cornering_stiffness_front_n_rad=-1.0)


def test_recovers_vy_from_data_of_its_own_model() -> None:
    # data from the exact linear single-track model (sine steering at 20 m/s) with sensor noise:
    # the filter must recover the unmeasured vy far below its own variation
    veh = VehicleParams()
    p = SingleTrackParams.from_vehicle(veh)
    model = SingleTrackModel(p)
    rng = np.random.default_rng(4)
    vx, dt = 20.0, 0.01
    kf = LinearLateralKF(LinearLateralKFConfig(accel_y_std_m_s2=0.05), veh)
    vy_true, vy_est = [], []
    delta_prev = 0.0
    model.reset(vx, 0.0)
    for k in range(3000):
        t_ns = 1_000_000_000 + k * 10_000_000
        delta = 0.05 * math.sin(2 * math.pi * 1.0 * k * dt)
        x = model.step(dt, vx, delta, delta_prev)
        delta_prev = delta
        ff, fr = axle_forces(p, float(x[0]), float(x[1]), vx, delta)
        ay = (ff + fr) / p.mass_kg + 0.05 * rng.standard_normal()
        r = float(x[1]) + 0.002 * rng.standard_normal()
        kf.on_velocity(t_ns, vx)
        kf.on_steering(t_ns, delta)
        kf.on_imu(t_ns, [0.0, 0.0, r], [0.0, ay, 9.81])
        if k > 100:
            vy_true.append(float(x[0]))
            vy_est.append(kf.estimate().vy_m_s)
    err = np.asarray(vy_est) - np.asarray(vy_true)
    rmse = float(np.sqrt(np.mean(err**2)))
    assert np.std(vy_true) > 0.1
    assert rmse < 0.1 * np.std(vy_true)


def test_bad_input_is_counted_and_the_state_stays_finite() -> None:
    kf = LinearLateralKF(LinearLateralKFConfig(), VehicleParams())
    t0 = 1_000_000_000
    for k in range(100):
        t = t0 + k * 10_000_000
        kf.on_velocity(t, 20.0)
        kf.on_steering(t, 0.02)
        kf.on_imu(t, [0.0, 0.0, 0.1], [0.0, 2.0, 9.81])
    kf.on_imu(t0, [0.0, 0.0, 0.1], [0.0, 2.0, 9.81])  # out of order
    kf.on_imu(t0 + 2_000_000_000, [math.nan, 0.0, 0.0], [0.0, 0.0, 9.81])
    kf.on_steering(t0 + 2_000_000_000, [0.1, 0.2])
    kf.on_velocity(t0 + 2_000_000_000, "fast")
    assert kf.stats == {
        "imu:out_of_order": 1,
        "imu:nan": 1,
        "steering:wrong_length": 1,
        "velocity:bad_value": 1,
    }
    e = kf.estimate()
    assert kf.initialized and all(math.isfinite(v) for v in (e.vy_m_s, e.yaw_rate_rad_s))
    assert e.yaw_rate_rad_s == pytest.approx(0.1, abs=0.01)
