"""AxleCheck: an axle whose two wheels report the same speed through the turns has an
unobservable left-right split; a normal axle has an observable one."""

from __future__ import annotations

import dataclasses
import json
from functools import cache
from pathlib import Path

import numpy as np
import pytest

from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
from tire_estimation.core.radius.axle_check import AxleCheck, AxleCheckConfig
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError
from tire_estimation.sim import SimResult, simulate
from tire_estimation.sources import sim_samples


@cache
def _drive() -> SimResult:
    return simulate("lane_change", seed=0, minutes=0.5)


def _locked(sim: SimResult) -> SimResult:
    """Both rear wheels report the left one's speed (a spool, or one signal copied)."""
    ws = sim.wheel_speeds.wheel_speed_rad_s.copy()
    ws[:, 3] = ws[:, 2]
    return dataclasses.replace(
        sim, wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws)
    )


def _pipeline(sim: SimResult) -> EstimationPipeline:
    cfg = RadiusEstimatorConfig(n_particles=50)
    p = EstimationPipeline(PipelineConfig(radius=cfg), sim.vehicle)
    p.push_all(sim_samples(sim, tire_forces=False))
    return p


def test_a_normal_drive_has_observable_splits() -> None:
    p = _pipeline(_drive())
    assert p.axles is not None
    for axle in ("front", "rear"):
        st = p.axles.status(axle)
        assert st.split_observable is True, st
        assert st.turning_samples >= 300
        assert 0.8 < st.slope < 1.2


def test_a_locked_rear_axle_is_found_and_the_front_is_not_blamed() -> None:
    p = _pipeline(_locked(_drive()))
    assert p.axles is not None
    rear = p.axles.status("rear")
    assert rear.split_observable is False
    assert abs(rear.slope) < 0.1
    assert "common radius" in rear.reason
    assert p.axles.status("front").split_observable is True


def test_no_verdict_without_turns_or_gyro() -> None:
    check = AxleCheck(VehicleParams())
    w = 20.0 / VehicleParams().nominal_tire_radius_m
    for k in range(2000):
        check.on_wheel_speeds(k * 10_000_000, np.full(4, w))
    assert check.status("rear").split_observable is None  # no gyro
    check.on_imu(np.zeros(3))
    for k in range(2000, 4000):
        check.on_wheel_speeds(k * 10_000_000, np.full(4, w))
    st = check.status("rear")
    assert st.split_observable is None and st.turning_samples == 0  # straight: no turns


def _free_axle_with_a_split_step(check: AxleCheck, minutes: float = 4.0) -> list[float]:
    """100 Hz samples of a free axle at 20 m/s: left turns while the radii are equal, right
    turns after the right rear tyre has lost 1 % of its radius (a deflation: the split term
    changes by 0.01 w, about 0.7 rad/s, while a turn's difference is 0.25 rad/s). The slope
    every 10 s."""
    vehicle = VehicleParams()
    r0, track = vehicle.nominal_tire_radius_m, vehicle.track_width_m
    n = int(minutes * 6000)
    slopes = []
    for k in range(n):
        t_s = k * 0.01
        after = k >= n // 2
        # turns of 4 s every 10 s, left before the step, right after it
        yaw_rate = (0.05 if (t_s % 10.0) < 4.0 else 0.0) * (-1.0 if after else 1.0)
        right_radius = r0 * (0.99 if after else 1.0)
        wl = (20.0 - 0.5 * yaw_rate * track) / r0
        wr = (20.0 + 0.5 * yaw_rate * track) / right_radius
        check.on_imu(np.array([0.0, 0.0, yaw_rate]))
        check.on_wheel_speeds(k * 10_000_000, np.array([wl, wr, wl, wr]))
        if k % 1000 == 999:
            slopes.append(check.slope("rear"))
    return slopes


def test_a_split_that_changes_does_not_lock_a_free_axle() -> None:
    slopes = _free_axle_with_a_split_step(AxleCheck(VehicleParams()))
    assert not np.isnan(slopes[-1])
    # the block that holds the step misfits alone: the slope stays near 1
    assert np.nanmin(slopes) > 0.8
    # one split term over the whole memory (blocks as long as the memory) misreads the step
    one_block = AxleCheck(VehicleParams(), AxleCheckConfig(block_s=1e6, memory_s=60.0))
    assert np.nanmin(_free_axle_with_a_split_step(one_block)) < 0.5


def test_config_is_validated() -> None:
    with pytest.raises(ConfigError, match="locked_slope"):
        AxleCheckConfig(locked_slope=1.5)


def test_the_replay_reports_the_unobservable_split(tmp_path: Path) -> None:
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.replay import run_replay

    bag = tmp_path / "locked"
    write_sim_bag(_locked(_drive()), bag)
    report = run_replay(bag, tmp_path / "out", stiffness=False, plots=False, progress=False)
    rear = report.metrics["radii"]["axles"]["rear"]
    assert rear["split_observable"] is False
    assert report.metrics["radii"]["axles"]["front"]["split_observable"] is True
    assert "REAR AXLE: the left-right split is unobservable" in report.summary()
    written = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert written["radii"]["axles"]["rear"]["split_observable"] is False


def test_a_spool_turns_the_heading_over_to_the_gyro_and_a_free_axle_does_not() -> None:
    """The simulator's locked rear axle (both wheels at the mean of their free-rolling speeds):
    the check finds it and the radius MPF takes the heading change from the gyro; on the same
    drive with a free axle nothing changes (no gyro heading)."""
    from tire_estimation.sim import SensorConfig

    for locked in (False, True):
        sim = simulate(
            "robustness", seed=3, minutes=3, sensors=SensorConfig(wheel_speed_rear_locked=locked)
        )
        p = _pipeline(sim)
        assert p.radius is not None and p.axles is not None
        rear = p.axles.status("rear")
        assert rear.split_observable is (not locked), rear
        assert (p.radius.gyro_heading_samples > 1000) is locked
        assert p.axles.status("front").split_observable is True


def _dead_rear_left(sim: SimResult, start_s: float, end_s: float) -> SimResult:
    """The rear-left wheel reads 0 from ``start_s`` to ``end_s`` (a dead sensor)."""
    ws = sim.wheel_speeds.wheel_speed_rad_s.copy()
    t = (sim.wheel_speeds.t_ns - sim.wheel_speeds.t_ns[0]) * 1e-9
    ws[(t >= start_s) & (t < end_s), 2] = 0.0
    return dataclasses.replace(
        sim, wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws)
    )


def test_signal_lost_at_once_and_back_after_half_a_second() -> None:
    """A wheel reading below 20 % of the others loses its signal at the first such sample; it
    is back after 0.5 s of readings like theirs; a tight turn (inner wheel 73 % of the others)
    is not a loss; below the check's speed nothing is judged."""
    check = AxleCheck(VehicleParams())
    w = 20.0 / VehicleParams().nominal_tire_radius_m
    t = 0
    for _ in range(10):
        t += 10_000_000
        check.on_wheel_speeds(t, [w, w, 0.73 * w, w])
    assert not check.signal_lost(2)
    check.on_wheel_speeds(t + 10_000_000, [w, w, 0.0, w])
    assert check.signal_lost(2) and not check.signal_lost(3)
    t += 10_000_000
    for k in range(1, 50):  # 0.49 s back
        check.on_wheel_speeds(t + k * 10_000_000, [w, w, w, w])
    assert check.signal_lost(2)
    check.on_wheel_speeds(t + 51 * 10_000_000, [w, w, w, w])
    assert not check.signal_lost(2)
    assert check.lost_signals() == {"wheel_rl": pytest.approx(0.5, abs=0.02)}
    slow = AxleCheck(VehicleParams())
    for k in range(1, 10):
        slow.on_wheel_speeds(k * 10_000_000, [1.0, 1.0, 0.0, 1.0])  # 0.31 m/s
    assert not slow.signal_lost(2)


def test_wheels_never_reported_are_not_reported_as_lost() -> None:
    """A vehicle that publishes only its rear wheels (NaN for the front ones): the front
    wheels are named as not reported, not as lost signals; a front wheel that reported and
    then read zero is a lost signal."""
    nan = float("nan")
    w = 20.0 / VehicleParams().nominal_tire_radius_m
    rear_only = AxleCheck(VehicleParams())
    for k in range(1, 200):
        rear_only.on_wheel_speeds(k * 10_000_000, [nan, nan, w, w])
    assert rear_only.unreported_wheels() == ("wheel_fl", "wheel_fr")
    assert rear_only.lost_signals() == {}
    assert rear_only.signal_lost(0) and not rear_only.signal_lost(2)
    lost_front = AxleCheck(VehicleParams())
    for k in range(1, 200):
        lost_front.on_wheel_speeds(k * 10_000_000, [w if k < 100 else 0.0, w, w, w])
    assert lost_front.unreported_wheels() == ()
    assert lost_front.lost_signals() == {"wheel_fl": pytest.approx(1.0, abs=0.02)}


def test_a_dead_rear_wheel_pauses_learning_and_keeps_the_pose() -> None:
    """A rear wheel that reads 0 for 10 s: the estimator says so, learns nothing meanwhile,
    keeps its pose (the live wheel and the gyro), and the axle verdict is not spoiled."""
    sim = _dead_rear_left(_drive(), 10.0, 20.0)
    cfg = RadiusEstimatorConfig(n_particles=50)
    p = EstimationPipeline(PipelineConfig(radius=cfg), sim.vehicle)
    samples = list(sim_samples(sim, tire_forces=False))
    t0 = samples[0].t_ns
    reasons = set()
    for s in samples:
        p.push(s)
        if p.radius is not None and 12e9 < s.t_ns - t0 < 19e9:
            reasons.add(p.radius.estimate().state_reason)
    assert p.radius is not None and p.axles is not None
    # the other gates (a lane change's lateral acceleration) come first; never learning
    assert "wheel_rl signal lost" in reasons and "estimating" not in reasons, reasons
    # 10 s dead and the 0.5 s it takes to come back
    assert p.axles.lost_signals()["wheel_rl"] == pytest.approx(10.5, abs=0.1)
    assert p.radius.estimate().state == "running"
    assert p.radius.stats["wheel_speeds:signal_lost_rl"] > 900
    assert p.radius.stats.get("gnss_fix:outlier", 0) == 0
    assert 0.8 < p.axles.status("rear").slope < 1.2


def test_both_axles_at_the_same_fraction_is_a_scale_error_not_a_lock() -> None:
    """Wheel speeds in m/s instead of rad/s (x r0 = 0.31) scale both axles' differences alike:
    the verdict names the unit or the radius, and the rear is not taken as locked."""
    sim = _drive()
    ws = sim.wheel_speeds.wheel_speed_rad_s * sim.vehicle.nominal_tire_radius_m
    scaled = dataclasses.replace(
        sim, wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws)
    )
    p = _pipeline(scaled)
    assert p.axles is not None and not p.axles.locked("rear")
    for axle in ("front", "rear"):
        st = p.axles.status(axle)
        assert st.split_observable is None and "unit" in st.reason, st
        assert st.slope == pytest.approx(sim.vehicle.nominal_tire_radius_m, rel=0.15)
    # one axle alone that low is still a lock
    assert _pipeline(_locked(_drive())).axles.locked("rear")  # type: ignore[union-attr]


def _rewired(sim: SimResult, swap_rear: bool = False, flip_gyro: bool = False) -> SimResult:
    """The rear wheels' sides exchanged in the input and/or the gyro's yaw rate negated (an IMU
    frame with z down)."""
    ws = sim.wheel_speeds.wheel_speed_rad_s.copy()
    if swap_rear:
        ws[:, [2, 3]] = ws[:, [3, 2]]
    gyro = sim.imu.angular_velocity_rad_s.copy()
    if flip_gyro:
        gyro[:, 2] = -gyro[:, 2]
    return dataclasses.replace(
        sim,
        wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws),
        imu=dataclasses.replace(sim.imu, angular_velocity_rad_s=gyro),
    )


def _no_velocity(sim: SimResult) -> SimResult:
    gnss = dataclasses.replace(sim.gnss, velocity_enu_m_s=None, velocity_covariance_m2_s2=None)
    return dataclasses.replace(sim, gnss=gnss)


def test_a_reversed_gyro_is_found_from_the_gnss_course_and_negated() -> None:
    """Both axles' differences turn against a gyro with z down; the receiver's course sides
    with the wheels: the gyro is negated and both splits are observable again."""
    p = _pipeline(_rewired(_drive(), flip_gyro=True))
    axles = p.axles
    assert axles is not None and axles.gyro_reversed
    assert axles.swapped == {"front": False, "rear": False}
    assert axles.gyro_course_slope is not None and axles.gyro_course_slope < -0.8
    for axle in ("front", "rear"):
        st = axles.status(axle)
        assert st.split_observable is True and 0.8 < st.slope < 1.2, st
        assert "negated" in st.reason
    # without the receiver's velocity nothing says which is right: the two axles outvote the
    # gyro (neither is taken as locked) and the verdict says so
    p = _pipeline(_no_velocity(_rewired(_drive(), flip_gyro=True)))
    assert p.axles is not None and not p.axles.gyro_reversed
    for axle in ("front", "rear"):
        st = p.axles.status(axle)
        assert st.split_observable is None and "reversed" in st.reason, st
        assert st.slope < -0.8 and not p.axles.locked(axle)


def test_exchanged_rear_wheels_are_swapped_back() -> None:
    """The rear speeds arrive as (rr, rl): the gyro agrees with the course, so the rear axle's
    sides are exchanged back; the front is left alone."""
    p = _pipeline(_rewired(_drive(), swap_rear=True))
    axles = p.axles
    assert axles is not None and not axles.gyro_reversed
    assert axles.gyro_course_slope is not None and axles.gyro_course_slope > 0.8
    assert axles.swapped == {"front": False, "rear": True}
    rear = axles.status("rear")
    assert rear.split_observable is True and rear.swapped and 0.8 < rear.slope < 1.2, rear
    assert "exchanged" in rear.reason
    # positions only: the rear is not trusted (common radius only) and the verdict names both
    # possible causes
    p = _pipeline(_no_velocity(_rewired(_drive(), swap_rear=True)))
    assert p.axles is not None and not p.axles.swapped["rear"]
    rear = p.axles.status("rear")
    assert rear.split_observable is False and "exchanged" in rear.reason, rear
    assert "reversed" in rear.reason


def test_a_course_against_the_gyro_and_both_axles_changes_nothing() -> None:
    """A receiver velocity in (north, east) instead of (east, north) mirrors the course: the
    gyro and both axles agree with each other, so nothing is rewired and the verdict says so."""
    sim = _drive()
    vel = sim.gnss.velocity_enu_m_s.copy()
    vel[:, [0, 1]] = vel[:, [1, 0]]
    p = _pipeline(
        dataclasses.replace(sim, gnss=dataclasses.replace(sim.gnss, velocity_enu_m_s=vel))
    )
    axles = p.axles
    assert axles is not None and not axles.rewired and axles.course_suspect
    assert axles.gyro_course_slope is not None and axles.gyro_course_slope < -0.8
    for axle in ("front", "rear"):
        st = axles.status(axle)
        assert st.split_observable is True and "not in ENU" in st.reason, st
