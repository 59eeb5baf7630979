"""Single-track model of Berntorp & Di Cairano 2018 (eq. 3, 4, 1, 12) vs the simulator."""

from __future__ import annotations

import numpy as np

from tire_estimation.core.stiffness_model import (
    SingleTrackParams,
    linearize,
    slip_angles,
    wheel_slip,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim import simulate


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
