"""Restart from the start of learning with a recentred prior (``activation_restart_s``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.core.stiffness.test_activation_replay import _RecordingMpf
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError

MS = 1_000_000
N = 4


class _Stats:
    def __init__(self) -> None:
        self.mean = np.zeros((N, 3))


class _LearningMpf(_RecordingMpf):
    """``_RecordingMpf`` (logs every predict / update) whose learning updates add 1 to the mean
    of particle 0 and 3 to that of particle 1 (weights 0.5 / 0.5 / 0 / 0), so the weighted
    estimate after ``m`` learning updates is ``2 m`` (the prior mean is 0)."""

    def __init__(self) -> None:
        super().__init__()
        self.stats = _Stats()
        self.weights = np.array([0.5, 0.5, 0.0, 0.0])

    def update(self, y: Any, delta_rad: float, wheel_speed_m_s: Any, learn: bool, *a: Any) -> None:
        super().update(y, delta_rad, wheel_speed_m_s, learn, *a)
        if learn:
            self.stats.mean[0] += 1.0
            self.stats.mean[1] += 3.0

    @property
    def updates(self) -> list[tuple[bool, float]]:
        """(learning, ay) of every update, in order."""
        return [(learn, k) for kind, learn, k in self.log if kind == "update"]

    @property
    def predicts(self) -> int:
        return sum(1 for kind, _, _ in self.log if kind == "predict")


def _drive(
    restart_s: float, steer: Any, n: int = 400, est: StiffnessEstimator | None = None
) -> tuple[StiffnessEstimator, list[bool]]:
    """``n`` IMU samples at 100 Hz, 20 m/s, steering ``steer(k)``; ay carries the index."""
    if est is None:
        cfg = StiffnessEstimatorConfig(n_particles=N, activation_restart_s=restart_s)
        est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(0))
        est.mpf = _LearningMpf()  # type: ignore[assignment]
    w = 20.0 / 0.31
    active = []
    t0 = est._t_ns + 10 * MS if est._t_ns else 1_000_000_000
    for k in range(n):
        t = t0 + k * 10 * MS
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, steer(k))
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.0, float(k), 9.81])
        active.append(est._active)
    return est, active


def _step_at_100(k: int) -> float:
    return 0.004 if k >= 100 else 0.0


def test_restart_moves_the_prior_mean_to_the_estimate_and_relearns_every_step_once() -> None:
    est, active = _drive(1.0, _step_at_100)
    on = active.index(True)
    assert 150 <= on < 170
    mpf = est.mpf
    assert isinstance(mpf, _LearningMpf)
    assert est.restart_count == 1
    # the restarted filter is the copy taken when learning started: it ran every sample
    # exactly once, in order, learning from the activation on
    assert [k for _, k in mpf.updates] == [float(k) for k in range(400)]
    assert [k for learn, k in mpf.updates if learn] == [float(k) for k in range(on, 400)]
    assert mpf.predicts == 399
    # 1 s at 100 Hz after the activation: the samples on .. on + 100 were learned before the
    # restart, so the estimate then was 2 x 101; the copy's prior mean (0) was moved there for
    # every particle, and the copy then learned the 400 - on samples since the activation
    m = 101
    learned = 400 - on
    np.testing.assert_allclose(mpf.stats.mean[0], 2 * m + learned)
    np.testing.assert_allclose(mpf.stats.mean[1], 2 * m + 3 * learned)
    np.testing.assert_allclose(mpf.stats.mean[2:], 2 * m)


def test_without_restart_the_prior_mean_stays_the_initial_guess() -> None:
    est, active = _drive(0.0, _step_at_100)
    on = active.index(True)
    mpf = est.mpf
    assert isinstance(mpf, _LearningMpf)
    assert est.restart_count == 0
    np.testing.assert_allclose(mpf.stats.mean[0], 400 - on)
    np.testing.assert_allclose(mpf.stats.mean[2:], 0.0)


def test_only_the_first_learning_phase_restarts_and_reset_rearms() -> None:
    # steering from 1 s to 3.5 s and again from 5.5 s: learning twice, one restart
    def twice(k: int) -> float:
        return 0.004 if 100 <= k < 350 or k >= 550 else 0.0

    est, active = _drive(1.0, twice, n=800)
    assert active[700] and not active[500]
    assert est.restart_count == 1
    est.reset()
    est.mpf = _LearningMpf()  # type: ignore[assignment]
    _drive(1.0, _step_at_100, est=est)
    assert est.restart_count == 2


def test_a_phase_shorter_than_the_restart_time_disarms_it() -> None:
    # 0.008 rad for 0.3 s only: learning for about 1.1 s (window 1 s), restart time 2 s: no
    # restart, and the learned statistics are not recentred at a later activation either
    def short_then_long(k: int) -> float:
        return 0.008 if 100 <= k < 130 else (0.004 if k >= 500 else 0.0)

    est, active = _drive(2.0, short_then_long, n=900)
    assert any(active[100:300]) and not active[450] and active[850]
    assert est.restart_count == 0


def test_restored_statistics_are_not_recentred() -> None:
    cfg = StiffnessEstimatorConfig(n_particles=20, activation_restart_s=1.0)
    est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(0))
    state = est.state_dict()
    est.load_state_dict(state)
    est.mpf = _LearningMpf()  # type: ignore[assignment]
    _drive(1.0, _step_at_100, est=est)
    assert est.restart_count == 0


def test_restart_time_is_validated() -> None:
    with pytest.raises(ConfigError, match="activation_restart_s"):
        StiffnessEstimatorConfig(activation_restart_s=11.0)
    with pytest.raises(ConfigError, match="activation_restart_s"):
        StiffnessEstimatorConfig(activation_restart_s=-1.0)
    with pytest.raises(ConfigError, match="activation_restart_s"):
        StiffnessEstimatorConfig(activation_restart_s=float("nan"))
