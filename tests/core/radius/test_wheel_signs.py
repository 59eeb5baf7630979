"""Wheels whose speed arrives with its sign reversed (``core/radius/wheel_signs.py``)."""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.wheel_signs import DECIDE_S, WheelSigns
from tire_estimation.sim import SimResult, simulate
from tire_estimation.sources import sim_samples

R0 = 0.31
STEP_NS = 10_000_000  # 100 Hz


def _feed(
    signs: WheelSigns, t0_ns: int, seconds: float, wheels: list[float], speed_m_s: float
) -> int:
    """``seconds`` of wheel speeds ``wheels`` at 100 Hz with a Doppler speed ``speed_m_s``
    (east) at 10 Hz; returns the next stamp."""
    t = t0_ns
    for k in range(round(seconds * 100)):
        if k % 10 == 0:
            signs.on_velocity(t, speed_m_s, 0.0)
        signs.add(t, wheels)
        t += STEP_NS
    return t


def test_a_mirrored_right_side_is_found_after_the_decision_time() -> None:
    w = 10.0 / R0
    signs = WheelSigns(R0)
    t = _feed(signs, 1, DECIDE_S - 1.0, [w, -w, w, -w], 10.0)
    assert signs.reversed == [False] * 4 and not signs.any_reversed  # not yet decided
    _feed(signs, t, 2.0, [w, -w, w, -w], 10.0)
    assert signs.reversed == [False, True, False, True] and signs.settled
    assert signs.reversed_wheels == ["wheel_fr", "wheel_rr"]
    out = signs.correct(np.array([1.0, -2.0, 3.0, -4.0]))
    np.testing.assert_array_equal(out, [1.0, 2.0, 3.0, 4.0])


def test_every_wheel_negative_while_moving_is_reversed() -> None:
    w = 5.0 / R0
    signs = WheelSigns(R0)
    _feed(signs, 1, DECIDE_S + 1.0, [-w, -w, -w, -w], 5.0)
    assert signs.reversed == [True] * 4


def test_turning_on_the_spot_and_backing_up_for_a_while_are_not_reversed_wiring() -> None:
    w = 5.0 / R0
    signs = WheelSigns(R0)
    # a skid-steer robot turning on the spot: the receiver does not move
    t = _feed(signs, 1, 60.0, [w, -w, w, -w], 0.0)
    assert not signs.any_reversed and not signs.settled
    # backing up for 5 s, then forward: a fifth of the counted time backward
    t = _feed(signs, t, 5.0, [-w, -w, -w, -w], 5.0)
    _feed(signs, t, DECIDE_S, [w, w, w, w], 5.0)
    assert signs.settled and not signs.any_reversed


def test_positions_alone_give_the_speed_from_fixes_five_seconds_apart() -> None:
    w = 10.0 / R0
    signs = WheelSigns(R0)
    t = 1
    for k in range(int((DECIDE_S + 8.0) * 100)):
        if k % 10 == 0:
            signs.on_fix(t, 10.0 * k / 100, 0.0, 1.0)
        signs.add(t, [w, -w, w, -w])
        t += STEP_NS
    assert signs.reversed == [False, True, False, True]
    # a receiver standing still (fixes scattering by their std) gives no speed
    still = WheelSigns(R0)
    rng = np.random.default_rng(0)
    t = 1
    for k in range(int((DECIDE_S + 8.0) * 100)):
        if k % 10 == 0:
            still.on_fix(t, *rng.normal(0.0, 1.0, 2), 1.0)
        still.add(t, [w, -w, w, -w])
        t += STEP_NS
    assert not still.any_reversed


@cache
def _drive() -> SimResult:
    return simulate("robustness", seed=1, minutes=1.5)


def _run(sim: SimResult) -> EstimationPipeline:
    p = EstimationPipeline(
        PipelineConfig(radius=RadiusEstimatorConfig(n_particles=100)), sim.vehicle
    )
    p.push_all(sim_samples(sim, tire_forces=False))
    return p


@pytest.mark.parametrize("negated", [[1, 3], [0, 1, 2, 3]])
def test_the_estimator_negates_the_reversed_wheels_and_learns(negated: list[int]) -> None:
    """The right wheels (a mirrored side) or every wheel negated: without the check the pose
    never follows the fixes; with it the radii end within 0.3 mm of the drive wired right."""
    sim = _drive()
    ws = sim.wheel_speeds.wheel_speed_rad_s.copy()
    ws[:, negated] *= -1.0
    wired = dataclasses.replace(
        sim, wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws)
    )
    right, mirrored = _run(sim), _run(wired)
    assert mirrored.axles is not None and right.axles is not None
    assert [k for k in range(4) if mirrored.axles.signs.reversed[k]] == negated
    assert not right.axles.signs.any_reversed
    assert mirrored.radius is not None and right.radius is not None
    a = mirrored.radius.estimate().radius_error_m
    b = right.radius.estimate().radius_error_m
    assert np.all(np.abs(a - b) < 3e-4), (a, b)
