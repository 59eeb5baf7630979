"""Front-end of the stiffness estimator: bad input, activation, config errors, state."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.stiffness_config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness_estimator import StiffnessEstimator
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, InputError


def _est(n: int = 50) -> StiffnessEstimator:
    return StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=n), VehicleParams(), np.random.default_rng(0)
    )


def _straight(est: StiffnessEstimator, seconds: float, steer: float = 0.0) -> None:
    w = 20.0 / 0.31
    for k in range(int(seconds * 100)):
        t = 1_000_000_000 + k * 10_000_000
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, steer)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])


def test_config_errors_name_field() -> None:
    with pytest.raises(ConfigError, match="forgetting"):
        StiffnessEstimatorConfig(forgetting=1.5)
    with pytest.raises(ConfigError, match="n_particles"):
        StiffnessEstimatorConfig(n_particles=0)
    with pytest.raises(ConfigError, match="drive"):
        StiffnessEstimatorConfig(drive="left")
    with pytest.raises(ConfigError, match="prior_dof"):
        StiffnessEstimatorConfig(prior_dof=3.0)


def test_bad_input_is_counted_not_raised() -> None:
    est = _est()
    est.on_wheel_speeds(10, [1.0, 2.0, 3.0])
    est.on_wheel_speeds(11, [np.nan, 1.0, 1.0, 1.0])
    est.on_imu(20, [0.0, 0.0], [0.0, 0.0, 9.81])
    est.on_steering(30, 0.1)
    est.on_steering(29, 0.1)
    est.on_velocity(5, float("inf"))
    assert est.stats["wrong_length"] == 2
    assert est.stats["nan"] == 2
    assert est.stats["out_of_order"] == 1


def test_activation_false_on_straight_true_with_steering() -> None:
    est = _est()
    _straight(est, 3.0)
    e = est.estimate()
    assert not e.active
    assert e.reason == "no lateral excitation"
    np.testing.assert_allclose(e.stiffness, e.nominal, rtol=1e-9)
    assert abs(e.vx_m_s - 20.0) < 0.5
    est2 = _est()
    _straight(est2, 2.0, steer=0.02)
    assert est2.estimate().active


def test_state_dict_roundtrip_and_reset() -> None:
    est = _est()
    _straight(est, 1.0, steer=0.02)
    d = est.state_dict()
    other = _est()
    other.load_state_dict(d)
    np.testing.assert_allclose(other.state_dict()["mean"], d["mean"], rtol=1e-9, atol=1e-6)
    with pytest.raises(InputError):
        other.load_state_dict({**d, "vehicle": "other"})
    est.reset()
    assert est.estimate().reason == "not initialized"


def test_rear_drive_variant_by_config() -> None:
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=10, drive="rear"),
        VehicleParams(),
        np.random.default_rng(0),
    )
    assert est.params.drive == "rear"
    assert est.params.nominal[0] == VehicleParams().longitudinal_stiffness_rear_n
