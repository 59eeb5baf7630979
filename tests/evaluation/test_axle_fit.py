"""Axle cornering-stiffness fit against a vY reference (``evaluation/axle_fit.py``, issue 5).

The simulator's drives have a known axle stiffness and a single-track yaw balance up to its
four-wheel details; its truth is given at ``base_link`` (the rear-axle centre), so the tests move
vY and ay to the centre of gravity first. Measured (docs/stiffness_limits.md, "Revs: what sets
the stiffness scale"): asphalt_sine 100.3k / 120.3k for 100k / 120k, snow_sine 50.6k / 60.7k for
50k / 60k, yaw-moment R2 0.92 and 0.96.
"""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.axle_fit import (
    axle_curve,
    fit_axle_stiffness,
    fit_axles,
    kinematic_accel_ratio,
)
from tire_estimation.sim.simulator import simulate


def _cg_signals(scenario: str) -> tuple[VehicleParams, dict[str, np.ndarray], np.ndarray]:
    sim = simulate(scenario, seed=0)
    tr = sim.truth
    t = tr.t_ns * 1e-9
    lr = sim.vehicle.cg_to_rear_axle_m
    r = tr.yaw_rate_rad_s
    rdot = np.gradient(r, t)
    sig = {
        "vx_m_s": tr.velocity_m_s[:, 0],
        # base_link (rear axle) -> centre of gravity, lr ahead of it
        "vy_m_s": tr.velocity_m_s[:, 1] + lr * r,
        "yaw_rate_rad_s": r,
        "accel_y_m_s2": tr.acceleration_m_s2[:, 1] + lr * rdot,
        "yaw_accel_rad_s2": rdot,
        "delta_rad": np.interp(tr.t_ns, sim.steering.t_ns, sim.steering.angle_rad),
    }
    return sim.vehicle, sig, tr.stiffness


@pytest.mark.parametrize(("scenario", "mu"), [("asphalt_sine", 1.0), ("snow_sine", 0.3)])
def test_fit_recovers_simulated_axle_stiffness(scenario: str, mu: float) -> None:
    vehicle, sig, truth = _cg_signals(scenario)
    fit = fit_axles(vehicle, **sig, friction_coefficient=mu)
    rel_f = fit.cornering_stiffness_front_n_rad / truth[:, 1].mean() - 1.0
    rel_r = fit.cornering_stiffness_rear_n_rad / truth[:, 2].mean() - 1.0
    assert abs(rel_f) < 0.03 and abs(rel_r) < 0.03, (rel_f, rel_r)
    assert fit.yaw_moment_r2 > 0.85
    assert fit.n_samples == sig["vx_m_s"].size


def test_yaw_moment_r2_falls_when_the_yaw_balance_is_wrong() -> None:
    vehicle, sig, _ = _cg_signals("asphalt_sine")
    good = fit_axles(vehicle, **sig, friction_coefficient=1.0)
    rng = np.random.default_rng(0)
    noisy = dict(sig)
    # a yaw acceleration with three times its own spread added as noise
    spread = float(np.std(sig["yaw_accel_rad_s2"]))
    noise = rng.normal(0.0, 3 * spread, sig["vx_m_s"].size)
    noisy["yaw_accel_rad_s2"] = sig["yaw_accel_rad_s2"] + noise
    bad = fit_axles(vehicle, **noisy, friction_coefficient=1.0)
    assert good.yaw_moment_r2 > 0.85
    assert bad.yaw_moment_r2 < 0.3


def test_single_axle_fits_recover_the_curve() -> None:
    rng = np.random.default_rng(1)
    alpha = rng.uniform(-0.1, 0.1, 4000)
    linear = 80_000.0 * alpha + rng.normal(0.0, 100.0, alpha.size)
    assert fit_axle_stiffness(alpha, linear, 0.0) == pytest.approx(80_000.0, rel=0.005)
    # friction-limited tanh tyre, peak 4000 N: well into saturation at 0.1 rad
    sat = axle_curve(alpha, 80_000.0, 4000.0) + rng.normal(0.0, 100.0, alpha.size)
    assert fit_axle_stiffness(alpha, sat, 4000.0) == pytest.approx(80_000.0, rel=0.01)
    # the linear fit of the saturated curve is far below: the shape matters
    assert fit_axle_stiffness(alpha, sat, 0.0) < 0.7 * 80_000.0


def test_kinematic_accel_ratio_finds_a_roll_gain() -> None:
    _, sig, _ = _cg_signals("lane_change")
    args = (sig["vx_m_s"], sig["vy_m_s"], sig["yaw_rate_rad_s"], 0.02, 11)
    ay = sig["accel_y_m_s2"]
    assert kinematic_accel_ratio(ay, *args) == pytest.approx(1.0, abs=0.005)
    # an accelerometer tilted by a roll of 0.003 rad per m/s^2: ay (1 + 0.003 g)
    assert kinematic_accel_ratio(ay * (1 + 0.003 * 9.81), *args) == pytest.approx(
        1 + 0.003 * 9.81, abs=0.005
    )


def test_bad_input_is_named() -> None:
    vehicle = VehicleParams()
    ok = np.linspace(0.0, 1.0, 50)
    sig = dict.fromkeys(
        ("vx_m_s", "vy_m_s", "yaw_rate_rad_s", "accel_y_m_s2", "yaw_accel_rad_s2", "delta_rad"),
        ok,
    )
    with pytest.raises(ValueError, match="smooth_samples=4"):
        fit_axles(vehicle, **sig, smooth_samples=4)
    with pytest.raises(ValueError, match="friction_coefficient=-1"):
        fit_axles(vehicle, **sig, friction_coefficient=-1.0)
    with pytest.raises(ValueError, match=r"\(M,\)"):
        fit_axles(vehicle, **{**sig, "vy_m_s": ok[:10]})
    with pytest.raises(ValueError, match="all zero"):
        fit_axle_stiffness(np.zeros(5), np.ones(5), 0.0)
    with pytest.raises(ValueError, match="dt_s=0"):
        kinematic_accel_ratio(ok, ok, ok, ok, 0.0)
