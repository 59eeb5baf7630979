"""Shared short simulations for the simulator tests (module-scoped to keep the suite fast)."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.sim import SensorConfig, SimResult, simulate
from tire_estimation.sim.streams import TruthStream

#: IMU without random bias: the configured deterministic bias is all there is.
NO_RANDOM_BIAS = {
    "gyro_bias_initial_std_rad_s": 0.0,
    "gyro_bias_random_walk_rad_s_sqrt_s": 0.0,
    "accel_bias_initial_std_m_s2": 0.0,
    "accel_bias_random_walk_m_s2_sqrt_s": 0.0,
}


def rel_s(t_ns: np.ndarray) -> np.ndarray:
    """Stamps in seconds from the start of the drive."""
    from tire_estimation.sim import START_TIME_NS

    return (t_ns - START_TIME_NS) * 1e-9


def rear_rolling_speed(truth: TruthStream, vehicle_track_m: float) -> np.ndarray:
    """(M, 2) rolling speed of wheel_rl, wheel_rr (rear wheels at x = 0 of base_link)."""
    vx = truth.velocity_m_s[:, 0]
    r = truth.yaw_rate_rad_s
    half = 0.5 * vehicle_track_m
    # wheel centre velocity along x: vx - r * y_wheel
    return np.column_stack([vx - r * half, vx + r * half])


@pytest.fixture(scope="session")
def ece_short() -> SimResult:
    """2 min of ece_r64: the pressure step happens at 0.63 * 120 s."""
    return simulate("ece_r64", seed=3, minutes=2.0)


@pytest.fixture(scope="session")
def city_short() -> SimResult:
    return simulate(
        "city",
        seed=0,
        minutes=1.5,
        sensors=SensorConfig(**NO_RANDOM_BIAS, gyro_bias_rad_s=(0.0, 0.0, 0.01)),
    )
