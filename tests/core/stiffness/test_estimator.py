"""Front-end of the stiffness estimator: bad input, activation, config errors, state."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.frontend import SlidingWindow
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
    with pytest.raises(ConfigError, match="state_proposal"):
        StiffnessEstimatorConfig(state_proposal="optimal")
    with pytest.raises(ConfigError, match="friction_coefficient"):
        StiffnessEstimatorConfig(friction_coefficient=-1.0)
    with pytest.raises(ConfigError, match="first_learning"):
        StiffnessEstimatorConfig(first_learning="ekf")
    with pytest.raises(ConfigError, match="speed_noise_std_m_s"):
        StiffnessEstimatorConfig(speed_noise_std_m_s=0.0)
    with pytest.raises(ConfigError, match="cornering_stiffness_front_n_rad"):
        StiffnessEstimatorConfig(cornering_stiffness_front_n_rad=-5.0)


def test_bad_input_is_counted_not_raised() -> None:
    est = _est()
    est.on_wheel_speeds(10, [1.0, 2.0, 3.0])
    est.on_wheel_speeds(11, [np.nan, 1.0, 1.0, 1.0])
    est.on_imu(20, [0.0, 0.0], [0.0, 0.0, 9.81])
    est.on_steering(30, 0.1)
    est.on_steering(29, 0.1)
    est.on_velocity(5, float("inf"))
    assert est.stats == {
        "wheel_speeds:wrong_length": 1,
        "wheel_speeds:nan": 1,
        "imu:wrong_length": 1,
        "steering:out_of_order": 1,
        "velocity:nan": 1,
    }


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
    # learned relative to other nominal stiffnesses (eq. 7): not restored
    with pytest.raises(InputError, match="nominal"):
        other.load_state_dict({**d, "nominal": [2.0 * v for v in d["nominal"]]})
    est.reset()
    assert est.estimate().reason == "not initialized"


def test_a_rear_driven_vehicle_names_its_rear_axle_cx() -> None:
    rear = VehicleParams(name="rear", drive="rear", longitudinal_stiffness_rear_n=180_000.0)
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=50), rear, np.random.default_rng(0)
    )
    _straight(est, 1.0, steer=0.02)
    e = est.estimate()
    assert e.names == ("cx_rear", "cy_front", "cy_rear")
    assert e.nominal[0] == 180_000.0
    d = est.state_dict()
    assert d["names"] == ["cx_rear", "cy_front", "cy_rear"]
    # the state of a front-driven vehicle of the same name and nominal values is another Cx
    with pytest.raises(InputError, match="names"):
        est.load_state_dict({**d, "names": ["cx_front", "cy_front", "cy_rear"]})
    front = _est()
    _straight(front, 1.0, steer=0.02)
    assert front.estimate().names == ("cx_front", "cy_front", "cy_rear")


_ZERO3 = [[0.0] * 3 for _ in range(3)]


_BAD_STATES = [
    ("noise_cov", _ZERO3, "not positive definite"),
    ("mean_cov", [[-1.0 if i == j else 0.0 for j in range(3)] for i in range(3)],
     "not positive definite"),
    ("noise_cov", [[1e20 if i == j else 0.0 for j in range(3)] for i in range(3)],
     "standard deviations"),
    ("dof", 1e308, "dof"),
    ("dof", int("9" * 500), "too large"),
    ("dof", float("nan"), "not finite"),
    ("mean", [1.5e6, 0.0, 0.0], "stiffness bounds"),
    ("mean", [0.0, -1e5, 0.0], "stiffness bounds"),
    ("mean", [0.0, 0.0], "list of 3"),
    ("names", ["a", "b", "c"], "names"),
    ("version", 2, "version"),
    ("extra", 1, "unknown keys extra"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("key", "value", "reason"), _BAD_STATES, ids=[f"{k} {r}" for k, _, r in _BAD_STATES]
)
def test_an_implausible_state_is_rejected_and_changes_nothing(
    key: str, value: object, reason: str
) -> None:
    est = _est()
    _straight(est, 1.0, steer=0.02)
    before = est.state_dict()
    with pytest.raises(InputError, match=reason) as info:
        est.load_state_dict({**before, key: value})
    assert info.value.kind == "state"
    assert est.state_dict() == before
    st = est.mpf.stats
    assert all(np.all(np.isfinite(a)) for a in (st.mean, st.scale, st.gamma, st.dof))


def test_rear_drive_from_the_vehicle() -> None:
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=10),
        dataclasses.replace(VehicleParams(), drive="rear"),
        np.random.default_rng(0),
    )
    assert est.params.drive == "rear"
    assert est.params.nominal[0] == VehicleParams().longitudinal_stiffness_rear_n


def _drive(
    est: StiffnessEstimator,
    t0_s: float,
    seconds: float,
    steer: float = 0.0,
    accel_x: float | np.ndarray = 0.0,
) -> float:
    """Constant 20 m/s, steering ``steer``, ax ``accel_x`` (scalar or per 10 ms sample)."""
    w = 20.0 / 0.31
    n = round(seconds * 100)
    ax = np.broadcast_to(np.asarray(accel_x, dtype=float), (n,))
    for k in range(n):
        t = 1_000_000_000 + round((t0_s + 0.01 * k) * 1e9)
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, steer)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [float(ax[k]), 0.0, 9.81])
    return t0_s + 0.01 * n


def test_sliding_window_matches_numpy() -> None:
    rng = np.random.default_rng(7)
    win = SlidingWindow(0.5)
    t = np.cumsum(rng.integers(5_000_000, 15_000_000, 300))
    v = rng.standard_normal(300) * 0.3 + 0.1
    for i in range(300):
        win.add(int(t[i]), float(v[i]))
        inside = v[: i + 1][t[: i + 1] > t[i] - 500_000_000]
        assert np.isclose(win.rms, np.sqrt(np.mean(inside**2)), rtol=1e-9)
        assert np.isclose(win.std, np.std(inside), rtol=1e-6, atol=1e-12)


def test_learning_stops_one_window_after_the_steering_ends() -> None:
    # Sec. V: learning must pause on straight driving. The old exponential mean of delta^2
    # needed ln((0.05 / 0.003)^2) = 5.6 windows to fall below the threshold.
    est = _est()
    t = _drive(est, 0.0, 2.0, steer=0.05)
    assert est.estimate().active
    t = _drive(est, t, 1.05)
    e = est.estimate()
    assert not e.active and e.reason == "no lateral excitation"
    frozen = est.mpf.stats.mean.copy()
    _drive(est, t, 2.0)
    # no NiW update any more: every particle's mean is one of the frozen ones (resampling
    # only copies them)
    now = est.mpf.stats.mean
    assert (now[:, None, :] == frozen[None, :, :]).all(axis=-1).any(axis=-1).all()


def test_cx_frozen_without_longitudinal_excitation() -> None:
    # lateral excitation, constant (biased) ax: Cx is confounded with the accelerometer bias
    # and must keep its prior (Sec. II-B), while the cornering stiffnesses are learned
    est = _est()
    _drive(est, 0.0, 4.0, steer=0.02, accel_x=0.4)
    e = est.estimate()
    assert e.active and not e.cx_active
    assert e.stiffness[0] == e.nominal[0]
    assert np.all(est.mpf.stats.mean[:, 0] == 0.0)
    assert np.any(est.mpf.stats.mean[:, 1:] != 0.0)
    # square-wave ax of +-1 m/s^2 (drive force steps): Cx is learned
    est2 = _est()
    square = np.where((np.arange(400) // 50) % 2 == 0, 1.0, -1.0)
    _drive(est2, 0.0, 4.0, steer=0.02, accel_x=square)
    e2 = est2.estimate()
    assert e2.active and e2.cx_active
    assert e2.stiffness[0] != e2.nominal[0]


def _drive_measured_speed(
    est: StiffnessEstimator, seconds: float, steer: float, accel_x: np.ndarray
) -> None:
    """Measured speed 20 m/s (no wheel speeds), steering ``steer``, ax per 10 ms sample."""
    for k in range(round(seconds * 100)):
        t = 1_000_000_000 + k * 10_000_000
        est.on_velocity(t, 20.0)
        est.on_steering(t + 1, steer)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [float(accel_x[k]), 0.0, 9.81])


def test_cx_frozen_with_a_measured_speed() -> None:
    # square-wave ax (longitudinal excitation) but no wheel speeds: the slip (eq. 3) is
    # unknown, so Cx is not observable and keeps its prior
    square = np.where((np.arange(400) // 50) % 2 == 0, 1.0, -1.0)
    est = StiffnessEstimator(
        StiffnessEstimatorConfig(n_particles=50), VehicleParams(), np.random.default_rng(0)
    )
    _drive_measured_speed(est, 4.0, 0.02, square)
    e = est.estimate()
    assert e.active and not e.cx_active
    assert "no wheel speeds" in e.reason
    assert e.stiffness[0] == e.nominal[0]
    assert np.isfinite(e.vy_m_s)


def test_integer_config_values_and_nominal_override() -> None:
    # zeros from YAML / ROS parameters arrive as int: the bias covariances must stay float
    cfg = StiffnessEstimatorConfig(
        n_particles=20,
        imu_bias_states=False,
        accel_noise_std_m_s2=1,
        cornering_stiffness_front_n_rad=70_000,
        cornering_stiffness_rear_n_rad=90_000,
    )
    est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(0))
    _drive(est, 0.0, 1.0, steer=0.02)
    e = est.estimate()
    assert est.mpf.p_bias.dtype == np.float64
    assert e.nominal[1] == 70_000.0 and e.nominal[2] == 90_000.0
    assert np.all(np.isfinite(e.stiffness))


def test_a_speed_stamped_after_the_imu_sample_is_not_used() -> None:
    """A wheel speed two hours ahead of the IMU does not start the filter (its age would be
    negative); the same speed stamped before the IMU does."""
    future, now = _est(), _est()
    t = 1_000_000_000
    w = 20.0 / 0.31
    future.on_wheel_speeds(t + 7200 * 1_000_000_000, [w, w, w, w])
    now.on_wheel_speeds(t, [w, w, w, w])
    for est in (future, now):
        for k in range(1, 50):
            est.on_imu(t + k * 10_000_000, [0.0, 0.0, 0.0], [0.0, 0.0, 9.81])
    assert not future.initialized
    assert now.initialized


@pytest.mark.parametrize("first_learning", ["mpf", "grid"])
def test_the_trace_row_holds_the_values_of_the_estimate(first_learning: str) -> None:
    cfg = StiffnessEstimatorConfig(n_particles=50, first_learning=first_learning)
    est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(3))
    # steering with longitudinal excitation: Cx and the cornering stiffness learned (for less
    # than the grid's hand-over time, so that the grid's cornering stiffness is published)
    t = _drive(est, 0.0, 2.0)
    t = _drive(est, t, 1.5, steer=0.02, accel_x=np.sin(np.arange(150) * 0.05))
    if first_learning == "grid":
        assert est._published_grid() is not None  # the grid's cornering stiffness is published
    e, row = est.estimate(), est.trace_row()
    assert row.active == e.active is True
    assert (row.vx_m_s, row.vy_m_s, row.yaw_rate_rad_s) == (e.vx_m_s, e.vy_m_s, e.yaw_rate_rad_s)
    assert row.sideslip_rad == e.sideslip_rad
    np.testing.assert_array_equal(row.stiffness, e.stiffness)
    np.testing.assert_array_equal(row.stiffness_std, e.stiffness_std)
    assert row.gyro_bias_rad_s == e.gyro_bias_rad_s[2]
    assert row.mean_log_predictive == e.mean_log_predictive
