"""One end-to-end check with the real simulator (skipped when it cannot be imported)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tire_estimation.bag import topics as tp
from tire_estimation.bag.reader import read_bag
from tire_estimation.bag.writer import write_sim_bag

sim = pytest.importorskip("tire_estimation.sim")
if not hasattr(sim, "simulate"):
    pytest.skip("tire_estimation.sim.simulate not available", allow_module_level=True)


def test_simulated_bag_round_trip(tmp_path: Path) -> None:
    result = sim.simulate("ece_r64", seed=3, minutes=0.5)
    data = read_bag(
        write_sim_bag(result, tmp_path / "sim"), require=[tp.WHEEL_SPEEDS, tp.IMU_DATA]
    )
    assert data.vehicle == result.vehicle
    assert data.scenario == "ece_r64" and data.seed == 3
    assert data.wheel_speeds is not None and data.imu is not None and data.gnss is not None
    np.testing.assert_array_equal(data.wheel_speeds.t_ns, result.wheel_speeds.t_ns)
    np.testing.assert_array_equal(
        data.wheel_speeds.wheel_speed_rad_s, result.wheel_speeds.wheel_speed_rad_s
    )
    np.testing.assert_array_equal(
        data.imu.linear_acceleration_m_s2, result.imu.linear_acceleration_m_s2
    )
    np.testing.assert_array_equal(data.gnss.lat_deg, result.gnss.lat_deg)
    odo = data.truth_odometry
    assert odo is not None
    np.testing.assert_array_equal(odo.position_m, result.truth.position_enu_m)
    radii = data.truth_wheel_radii
    assert radii is not None
    rows = np.searchsorted(result.truth.t_ns, radii.t_ns)
    np.testing.assert_array_equal(radii.values, result.truth.wheel_radius_m[rows])
    # zero-order hold of the reduced-rate truth stays within the writer's tolerance
    held = radii.values[np.searchsorted(radii.t_ns, result.truth.t_ns, side="right") - 1]
    assert np.max(np.abs(held - result.truth.wheel_radius_m)) <= 1e-5
    assert data.duration_s == pytest.approx(30.0, abs=0.1)
    # both axles' Cx (the rear one is what a rear-driven vehicle's estimate is scored against)
    stiff = data.truth_stiffness
    assert stiff is not None and stiff.names == tp.TRUTH_STIFFNESS_NAMES
    veh = result.vehicle
    np.testing.assert_allclose(
        stiff.values[0, [0, 3]],
        [veh.longitudinal_stiffness_front_n, veh.longitudinal_stiffness_rear_n],
        rtol=1e-9,
    )
