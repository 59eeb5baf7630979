"""Rewind and replay at the onset of learning (``core/activation_replay``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tire_estimation.core.stiffness.activation_replay import (
    SNAPSHOTS_PER_HORIZON,
    ActivationReplay,
)
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.filter import BaselineConfig, Measurement, StiffnessFilter
from tire_estimation.core.stiffness.frontend import StiffnessFrontEnd
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.evaluation.stiffness import sine_study

MS = 1_000_000


class _Counter:
    """A 'filter' whose state is the list of stamps it ran, and a shared object."""

    def __init__(self, shared: object) -> None:
        self.ran: list[int] = []
        self.shared = shared


def _recorded(
    horizon_s: float, n: int, shared: object = None
) -> tuple[ActivationReplay[_Counter, int], _Counter, list[int]]:
    """``n`` steps at 100 Hz recorded; each step's record is its stamp."""
    replay: ActivationReplay[_Counter, int] = ActivationReplay(horizon_s, shared=(shared,))
    filt = _Counter(shared)
    stamps = [k * 10 * MS for k in range(1, n + 1)]
    for t in stamps:
        filt.ran.append(t)
        replay.record(t, t, filt)
    return replay, filt, stamps


def test_rewind_goes_back_one_horizon_and_returns_every_step_after_the_copy() -> None:
    shared = object()
    replay, filt, stamps = _recorded(1.0, 300, shared)  # 3 s
    # copies every 0.1 s; kept: the newest at or before t - 1 s and all after it
    assert replay.snapshot_count == SNAPSHOTS_PER_HORIZON + 1
    got = replay.rewind()
    assert got is not None
    copy, steps = got
    t_copy = copy.ran[-1]
    assert stamps[-1] - 1100 * MS <= t_copy <= stamps[-1] - 1000 * MS
    # the copy ran exactly the steps up to its stamp, the steps are the rest, in order
    assert copy.ran == [t for t in stamps if t <= t_copy]
    assert steps == [t for t in stamps if t > t_copy]
    assert copy.ran + steps == stamps
    # a deep copy, except the shared object
    assert copy is not filt and copy.ran is not filt.ran
    assert copy.shared is shared
    # forgotten after the rewind
    assert replay.snapshot_count == replay.step_count == 0
    assert replay.rewind() is None


def test_rewind_starts_at_the_copy_before_the_first_excited_step() -> None:
    replay, _, stamps = _recorded(1.0, 300)
    onset = 2555 * MS  # the steps from 2.555 s on are excited
    got = replay.rewind(excited=lambda t: t >= onset)
    assert got is not None
    copy, steps = got
    t_copy = copy.ran[-1]
    # the newest copy before the onset: at most one interval (0.1 s) before it
    assert onset - 100 * MS <= t_copy < onset
    assert steps == [t for t in stamps if t > t_copy]
    # an onset older than every copy: the oldest copy; no excited step: no replay
    replay, _, stamps = _recorded(1.0, 300)
    got = replay.rewind(excited=lambda t: True)
    assert got is not None and got[0].ran[-1] <= stamps[-1] - 1000 * MS
    replay, _, _ = _recorded(1.0, 300)
    assert replay.rewind(excited=lambda t: False) is None
    assert replay.snapshot_count == replay.step_count == 0


def test_short_history_rewinds_to_the_first_copy() -> None:
    replay, _, _ = _recorded(1.0, 3)
    got = replay.rewind()
    assert got is not None
    assert got[0].ran == [10 * MS]
    assert got[1] == [20 * MS, 30 * MS]


def test_zero_horizon_keeps_nothing_and_negative_is_rejected() -> None:
    replay: ActivationReplay[_Counter, int] = ActivationReplay(0.0)
    replay.record(10, 10, _Counter(None))
    assert not replay.enabled
    assert replay.snapshot_count == replay.step_count == 0
    assert replay.rewind() is None
    with pytest.raises(ValueError, match="horizon_s"):
        ActivationReplay(-0.1)
    with pytest.raises(ConfigError, match="activation_replay_s"):
        StiffnessEstimatorConfig(activation_replay_s=11.0)
    with pytest.raises(ConfigError, match="activation_replay_s"):
        StiffnessEstimatorConfig(activation_replay_s=float("nan"))


class _RecordingMpf:
    """Stands in for ``StiffnessMpf``: logs the learning flag of every predict / update."""

    def __init__(self) -> None:
        self.initialized = False
        self.log: list[tuple[str, bool, float]] = []

    def initialize(self, x0: Any, x0_std: Any, bias0: Any = None) -> None:
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        self.log.append(("predict", learn, dt_s))

    def update(
        self,
        y: Any,
        delta_rad: float,
        wheel_speed_m_s: Any,
        learn: bool,
        vx_m_s: float | None = None,
        learn_cx: bool | None = None,
    ) -> None:
        self.log.append(("update", learn, float(y[1])))


def _drive(replay_s: float) -> tuple[StiffnessEstimator, list[bool], int]:
    """1.5 s straight, then a steering step of 0.004 rad (just above ``activation_steer_rad``
    0.003: the RMS over the 1 s window passes it about 0.57 s later); ay carries the sample
    index."""
    cfg = StiffnessEstimatorConfig(n_particles=10, activation_replay_s=replay_s)
    est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(0))
    est.mpf = _RecordingMpf()  # type: ignore[assignment]
    w = 20.0 / 0.31
    active = []
    n = 300
    for k in range(n):
        t = 1_000_000_000 + k * 10 * MS
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, 0.004 if k >= 150 else 0.0)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.0, float(k), 9.81])
        active.append(est._active)  # the stub has no estimate()
    return est, active, n


def test_estimator_replays_the_window_with_learning_on_and_loses_no_step() -> None:
    est, active, n = _drive(1.0)
    on = active.index(True)
    assert 200 <= on < 215
    log = est.mpf.log  # type: ignore[attr-defined]
    updates = [(learn, k) for kind, learn, k in log if kind == "update"]
    # every IMU sample updated exactly once, in order: the copy's past plus the replay
    assert [k for _, k in updates] == [float(k) for k in range(n)]
    learned = [k for learn, k in updates if learn]
    # learning from the copy before the steering onset (sample 150; copies every 0.1 s), not
    # from the straight second before the activation, and from then on
    first = int(learned[0])
    assert 140 < first <= 150
    assert learned == [float(k) for k in range(first, n)]
    assert est.replay_count == 1
    # predictions: one per step after the first, learning as the updates
    predicts = [learn for kind, learn, _ in log if kind == "predict"]
    assert len(predicts) == n - 1
    assert predicts.count(True) == len(learned)


def test_estimator_without_replay_learns_from_the_activation_on() -> None:
    est, active, n = _drive(0.0)
    on = active.index(True)
    log = est.mpf.log  # type: ignore[attr-defined]
    updates = [(learn, k) for kind, learn, k in log if kind == "update"]
    assert [k for learn, k in updates if learn] == [float(k) for k in range(on, n)]
    assert est.replay_count == 0


def test_replay_settles_the_rear_of_a_slow_snow_drive() -> None:
    # snow drive 0 from 150 %, the simulator's tyre curve: without the replay the rear Cy
    # leaves the 5 % band for good 3.95 s after activation, with it 0.32 s after
    # (docs/results.md section 6, the table of options)
    overrides = {
        "niw_update": "rao_blackwellized",
        "friction_coefficient": 0.3,
        "tyre_shape": "magic_formula",
        "magic_formula_curvature_e": -0.5,
    }
    settle = {}
    for replay_s in (0.0, 1.0):
        res = sine_study(
            "snow_sine", 1.5, 1, n=200, first_seed=0,
            overrides={**overrides, "activation_replay_s": replay_s},
        )  # fmt: skip
        settle[replay_s] = res["per_run"][0]["settling_s"][2]
    assert settle[0.0] > 2.0
    assert settle[1.0] < 1.0


class _RecordingFilter(StiffnessFilter):
    """Stands in for a filter behind the front-end: logs the learning flag of every update."""

    def __init__(self) -> None:
        self.log: list[tuple[bool, float]] = []

    def initialize(self, x0: Any, x0_std: Any) -> None:
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        pass

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        self.log.append((learn, float(meas.y[1])))


class _RecordingFrontEnd(StiffnessFrontEnd[_RecordingFilter]):
    def make_filter(self) -> _RecordingFilter:
        return _RecordingFilter()


def test_any_filter_behind_the_front_end_replays_the_onset_as_algorithm_1() -> None:
    est = _RecordingFrontEnd(
        BaselineConfig(activation_replay_s=1.0), VehicleParams(), np.random.default_rng(0)
    )
    w = 20.0 / 0.31
    for k in range(300):
        t = 1_000_000_000 + k * 10 * MS
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, 0.004 if k >= 150 else 0.0)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.0, float(k), 9.81])
    log = est.filter.log  # type: ignore[attr-defined]
    assert [k for _, k in log] == [float(k) for k in range(300)]
    learned = [int(k) for learn, k in log if learn]
    assert 140 < learned[0] <= 150
    assert learned == list(range(learned[0], 300))


def test_nothing_below_the_minimum_speed_is_replayed() -> None:
    # steering from the start, the car at 3 m/s (below min_speed_m_s 5) for 1.5 s, then 20 m/s:
    # learning starts at the speed step and replays none of the slow samples
    cfg = StiffnessEstimatorConfig(n_particles=10, activation_replay_s=1.0)
    est = StiffnessEstimator(cfg, VehicleParams(), np.random.default_rng(0))
    est.mpf = _RecordingMpf()  # type: ignore[assignment]
    for k in range(300):
        t = 1_000_000_000 + k * 10 * MS
        w = (3.0 if k < 150 else 20.0) / 0.31
        est.on_wheel_speeds(t, [w, w, w, w])
        est.on_steering(t + 1, 0.02)
        est.on_imu(t + 2, [0.0, 0.0, 0.0], [0.0, float(k), 9.81])
    log = est.mpf.log  # type: ignore[attr-defined]
    updates = [(learn, k) for kind, learn, k in log if kind == "update"]
    assert [k for _, k in updates] == [float(k) for k in range(300)]
    learned = [int(k) for learn, k in updates if learn]
    assert learned == list(range(150, 300))
