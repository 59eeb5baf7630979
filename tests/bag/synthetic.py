"""A synthetic SimResult built directly with NumPy (independent of the simulator)."""

from __future__ import annotations

import numpy as np

from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim.streams import (
    GnssStream,
    ImuStream,
    SimEvent,
    SimResult,
    SteeringStream,
    TireForceStream,
    TruthStream,
    WheelSpeedStream,
)

START_NS = 1_700_000_000_123_456_789


def _times(
    rng: np.random.Generator, duration_s: float, rate_hz: float, jitter: bool
) -> np.ndarray:
    period = round(1e9 / rate_hz)
    t = START_NS + np.arange(int(duration_s * rate_hz)) * period
    if jitter:  # keep strictly increasing
        t = t + rng.integers(0, period // 4, size=t.size)
    return t.astype(np.int64)


def make_result(
    duration_s: float = 20.0,
    *,
    seed: int = 1,
    truth_hz: float = 100.0,
    with_velocity: bool = True,
    with_forces: bool = True,
) -> SimResult:
    """Drive with random-valued streams, a pressure step at half time, and one event."""
    rng = np.random.default_rng(seed)
    t_w = _times(rng, duration_s, 100.0, True)
    t_s = _times(rng, duration_s, 100.0, True)
    t_i = _times(rng, duration_s, 100.0, True)
    t_g = _times(rng, duration_s, 10.0, False)
    t_t = _times(rng, duration_s, truth_hz, False)
    m_g = t_g.size
    cov = np.einsum("nij,nkj->nik", a := rng.normal(size=(m_g, 3, 3)), a)
    gnss = GnssStream(
        t_ns=t_g,
        lat_deg=48.1 + rng.normal(0, 1e-3, m_g),
        lon_deg=11.5 + rng.normal(0, 1e-3, m_g),
        alt_m=500 + rng.normal(0, 1, m_g),
        position_covariance_m2=cov,
        velocity_enu_m_s=rng.normal(0, 10, (m_g, 3)) if with_velocity else None,
        velocity_covariance_m2_s2=(
            np.einsum("nij,nkj->nik", b := rng.normal(size=(m_g, 3, 3)), b)
            if with_velocity
            else None
        ),
    )
    m_t = t_t.size
    half = m_t // 2
    radius = np.full((m_t, 4), 0.31) + rng.normal(0, 1e-7, (m_t, 4))  # below the tolerance
    radius[half:, 2] -= 0.003  # deflation of wheel_rl
    pressure = np.full((m_t, 4), 230_000.0)
    pressure[half:, 2] = 150_000.0
    stiffness = np.tile([150_000.0, 100_000.0, 120_000.0], (m_t, 1))
    truth = TruthStream(
        t_ns=t_t,
        lat_deg=48.1 + rng.normal(0, 1e-3, m_t),
        lon_deg=11.5 + rng.normal(0, 1e-3, m_t),
        alt_m=500 + rng.normal(0, 1, m_t),
        position_enu_m=rng.normal(0, 100, (m_t, 3)),
        yaw_rad=rng.uniform(-np.pi, np.pi, m_t),
        velocity_m_s=rng.normal(0, 10, (m_t, 2)),
        yaw_rate_rad_s=rng.normal(0, 0.3, m_t),
        acceleration_m_s2=rng.normal(0, 1, (m_t, 2)),
        wheel_radius_m=radius,
        tire_pressure_pa=pressure,
        stiffness=stiffness,
    )
    forces = None
    if with_forces:
        forces = TireForceStream(
            t_ns=t_w,
            fx_n=rng.normal(0, 1000, (t_w.size, 4)),
            fy_n=rng.normal(0, 1000, (t_w.size, 4)),
            fz_n=rng.normal(4000, 100, (t_w.size, 4)),
            valid=rng.random((t_w.size, 4)) > 0.2,
        )
    return SimResult(
        scenario="synthetic",
        seed=seed,
        vehicle=VehicleParams(name="test_car", nominal_tire_radius_m=0.31),
        origin_lla=(48.1, 11.5, 500.0),
        wheel_speeds=WheelSpeedStream(t_w, rng.normal(30, 5, (t_w.size, 4))),
        steering=SteeringStream(t_s, rng.normal(0, 0.05, t_s.size)),
        imu=ImuStream(
            t_i,
            rng.normal(0, 0.1, (t_i.size, 3)),
            rng.normal([0, 0, 9.81], 0.5, (t_i.size, 3)),
            gyro_noise_std_rad_s=0.002,
            accel_noise_std_m_s2=0.05,
        ),
        gnss=gnss,
        truth=truth,
        tire_forces=forces,
        events=(
            SimEvent(duration_s / 2, "pressure_step", {"wheel": "wheel_rl", "to_pa": 150000.0}),
        ),
        config={"gnss": {"rate_hz": 10.0}, "noise": np.float64(0.5), "wheels": ("a", "b")},
    )
