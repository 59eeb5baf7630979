"""Front and rear wheel names exchanged, told from the turns (core/radius/axle_order.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.axle_check import AxleCheck
from tire_estimation.core.radius.axle_order import MIN_BINS, AxleOrder
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.sim_runs import simulated_radius_run

WHEELBASE_M = 2.7
RADIUS_M = 0.31
RATE_HZ = 100


def _drive(
    speed_m_s: float, curvature_1_m: float, seconds: float = 300.0, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stamps (ns), wheel speeds (N, 4; fl, fr, rl, rr, rad/s, named right), yaw rate (rad/s)
    and a_x (m/s^2) of a drive weaving at up to ``curvature_1_m`` with the speed varying by
    30 % around ``speed_m_s``; the front radii 0.5 % larger than the rear, their rolling speed
    with a noise of 0.1 % per sample (0.01 % over a second: slip, road, quantization)."""
    rng = np.random.default_rng(seed)
    t_s = np.arange(0.0, seconds, 1.0 / RATE_HZ)
    v_r = speed_m_s * (1.0 + 0.3 * np.sin(2.0 * math.pi * t_s / 47.0))
    a_x = np.gradient(v_r, t_s)
    kappa = curvature_1_m * np.sin(2.0 * math.pi * t_s / 13.0)
    yaw = v_r * kappa
    # the front axle's centre on the wider circle: v_f = v_r sqrt(1 + (L kappa)^2)
    v_f = v_r * np.sqrt(1.0 + (WHEELBASE_M * kappa) ** 2)
    front = v_f / (RADIUS_M * 1.005) * (1.0 + rng.normal(0.0, 1e-3, t_s.size))
    rear = v_r / RADIUS_M
    ws = np.column_stack([front, front, rear, rear]) + rng.normal(0.0, 2e-3, (t_s.size, 4))
    return np.round(t_s * 1e9).astype(np.int64), ws, yaw, a_x


def _feed(order: AxleOrder, ws: np.ndarray, t_ns: np.ndarray, yaw: np.ndarray, a_x: np.ndarray):
    """Feed every sample; the indices at which ``add`` returned True."""
    return [
        k
        for k in range(t_ns.size)
        if order.add(int(t_ns[k]), ws[k].tolist(), float(yaw[k]), float(a_x[k]))
    ]


@pytest.mark.parametrize("exchange", [False, True])
def test_town_turns_tell_the_axles_apart(exchange: bool) -> None:
    """Turns of 12.5 m at 4-9 m/s: the slope is about +1 named right, about -1 with the names
    exchanged; the exchange is reported once and the fit stops either way."""
    t_ns, ws, yaw, a_x = _drive(6.5, 0.08)
    if exchange:
        ws = ws[:, [2, 3, 0, 1]]
    order = AxleOrder(WHEELBASE_M, RADIUS_M)
    hits = _feed(order, ws, t_ns, yaw, a_x)
    assert order.decided and order.slope is not None
    assert order.exchanged is exchange
    assert len(hits) == int(exchange)
    assert order.slope == pytest.approx(-1.0 if exchange else 1.0, abs=0.1)
    # decided after the fewest bins, long before the end of the drive
    if exchange:
        assert MIN_BINS * RATE_HZ <= hits[0] < 200 * RATE_HZ


def test_highway_curves_chained_wheels_and_missing_fronts_decide_nothing() -> None:
    """Curves of 500 m at 25 m/s carry too little of the effect; two chained wheels per side
    (one speed written for both) fit exactly; no front wheels, no fit."""
    t_ns, ws, yaw, a_x = _drive(25.0, 0.002)
    for wired in (ws, ws[:, [2, 3, 0, 1]]):
        order = AxleOrder(WHEELBASE_M, RADIUS_M)
        assert _feed(order, wired, t_ns, yaw, a_x) == [] and not order.decided
    t_ns, ws, yaw, a_x = _drive(8.0, 0.08)
    chained = ws.copy()
    chained[:, :2] = chained[:, 2:]
    order = AxleOrder(WHEELBASE_M, RADIUS_M)
    assert _feed(order, chained, t_ns, yaw, a_x) == [] and not order.decided
    no_front = ws.copy()
    no_front[:, :2] = np.nan
    order = AxleOrder(WHEELBASE_M, RADIUS_M)
    assert _feed(order, no_front, t_ns, yaw, a_x) == [] and not order.decided


def test_slow_driving_does_not_count() -> None:
    """Below 2 m/s (a robot, a car park) the bins are left out."""
    t_ns, ws, yaw, a_x = _drive(1.2, 0.3)
    order = AxleOrder(WHEELBASE_M, RADIUS_M)
    assert _feed(order, ws[:, [2, 3, 0, 1]], t_ns, yaw, a_x) == [] and not order.decided


def test_the_axle_check_exchanges_the_axles_back() -> None:
    """Fed through the axle check (gyro and specific force from ``on_imu``): the exchange is
    reported by ``on_wheel_speeds`` once, then ``rewire_wheels`` puts the axles back and an
    exchanged side follows its axle."""
    vehicle = VehicleParams(wheelbase_m=WHEELBASE_M, nominal_tire_radius_m=RADIUS_M)
    check = AxleCheck(vehicle)
    t_ns, ws, yaw, a_x = _drive(6.5, 0.08)
    check.swapped["rear"] = True  # as if the (named) rear sides had been found exchanged
    wired = ws[:, [2, 3, 0, 1]]
    hits = []
    for k in range(t_ns.size):
        check.on_imu((0.0, 0.0, float(yaw[k])), (float(a_x[k]), 0.0, 9.81))
        if check.on_wheel_speeds(int(t_ns[k]), wired[k].tolist()):
            hits.append(k)
    assert len(hits) == 1 and check.order.exchanged and check.rewires_wheels
    assert check.swapped == {"front": True, "rear": False}
    sample = np.array([1.0, 2.0, 3.0, 4.0])
    # axles back (3, 4 | 1, 2 -> front 3, 4 ...), then the front sides swapped back
    np.testing.assert_array_equal(check.rewire_wheels(sample), [4.0, 3.0, 1.0, 2.0])


def test_a_town_drive_with_the_axles_named_the_other_way_round_is_learned_right() -> None:
    """A simulated `city` drive whose front and rear wheels arrive under each other's names:
    the estimator exchanges them back and learns the rear radii again (with the check off
    this drive's 8-min version ended +1.49 / -0.66 mm off)."""
    from tire_estimation.evaluation.axle_study import rewired

    sim, pipeline, _ = simulated_radius_run(
        "city", 0, 4.0, {"n_particles": 100}, {}, rewrite=lambda s: rewired(s, "front_rear")
    )
    assert pipeline.axles is not None and pipeline.axles.order.exchanged
    est = pipeline.radius.estimate()
    true = sim.truth.wheel_radius_m[-1, 2:] - sim.vehicle.nominal_tire_radius_m
    error = np.asarray(est.radius_error_m) - true
    assert np.all(np.abs(error) < 0.4e-3), error
    assert np.all(np.abs(error) < 3.0 * np.asarray(est.radius_error_std_m))
