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
    cfg = RadiusEstimatorConfig(n_particles=50, locked_axle_gyro_heading=True)
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
    assert abs(rear.slope) < 0.05
    assert "common radius" in rear.reason
    assert p.axles.status("front").split_observable is True


def test_no_verdict_without_turns_or_gyro() -> None:
    check = AxleCheck(VehicleParams())
    w = 20.0 / VehicleParams().nominal_tire_radius_m
    for _ in range(2000):
        check.on_wheel_speeds(np.full(4, w))
    assert check.status("rear").split_observable is None  # no gyro
    check.on_imu(np.zeros(3))
    for _ in range(2000):
        check.on_wheel_speeds(np.full(4, w))
    st = check.status("rear")
    assert st.split_observable is None and st.turning_samples == 0  # straight: no turns


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
