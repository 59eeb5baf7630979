"""A gross error of the radii, seen in the receiver's speed, and the radii moved to it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tire_estimation.core.radius.speed_scale import (
    GROSS_RATIO,
    MAX_RUN_M,
    MIN_RUN_M,
    RUN_WINDOW,
    WINDOW,
    SpeedScaleCheck,
    StraightRuns,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.sim_runs import simulated_radius_run


def test_two_windows_beyond_two_percent_ask_for_a_rescale_once() -> None:
    check = SpeedScaleCheck(RADIUS_M)
    rng = np.random.default_rng(0)
    factors = [
        check.add(k, 20.0 * 1.05 + 0.05 * rng.standard_normal(), 20.0, 0.0, RADIUS_M)
        for k in range(2 * WINDOW)
    ]
    assert factors[:-1] == [1.0] * (2 * WINDOW - 1)
    assert factors[-1] == pytest.approx(1.05, abs=0.002)
    # the windows start again: nothing more until two are full
    assert all(check.add(k, 21.0, 20.0, 0.0, RADIUS_M) == 1.0 for k in range(2 * WINDOW - 1))
    assert check.summary()["rescales"] == [factors[-1]]
    assert check.summary()["rescale_t_ns"] == [2 * WINDOW - 1]


def test_one_window_off_or_two_on_opposite_sides_rescale_nothing() -> None:
    check = SpeedScaleCheck(RADIUS_M)
    for ratio in (1.05, 1.0, 1.05, 0.95):
        assert all(check.add(0, 20.0 * ratio, 20.0, 0.0, RADIUS_M) == 1.0 for _ in range(WINDOW))
    assert check.rescales == []


def test_a_noisy_window_needs_more_than_two_percent() -> None:
    """3 m/s with 0.1 m/s of velocity noise (3.3 % per velocity): the median's standard error
    is 0.6 %, so 3 % is within six of them and nothing is rescaled."""
    check = SpeedScaleCheck(RADIUS_M)
    rng = np.random.default_rng(1)
    for _ in range(4 * WINDOW):
        assert check.add(0, 3.0 * 1.03 + 0.1 * rng.standard_normal(), 3.0, 0.0, RADIUS_M) == 1.0
    assert check.rescales == [] and abs(check.median_ratio["velocity"] - 1.03) < 0.01


def test_within_two_percent_turns_and_low_speed_nothing_is_rescaled() -> None:
    check = SpeedScaleCheck(RADIUS_M)
    for _ in range(3 * WINDOW):
        assert check.add(0, 20.0 * (1.0 + 0.9 * GROSS_RATIO), 20.0, 0.0, RADIUS_M) == 1.0
        assert check.add(0, 25.0, 20.0, 0.2, RADIUS_M) == 1.0  # turning: the lever arm's speed
        assert check.add(0, 2.5, 2.0, 0.0, RADIUS_M) == 1.0  # below 3 m/s
    assert check.rescales == [] and check.median_ratio["velocity"] == pytest.approx(1.018)
    check.enabled = False  # a study's switch: nothing is acted on
    assert all(check.add(0, 22.0, 20.0, 0.0, RADIUS_M) == 1.0 for _ in range(2 * WINDOW))


@pytest.mark.parametrize("stated_radius_m", [0.29, 0.33])
def test_a_wrong_nominal_radius_is_found_in_seconds(stated_radius_m: float) -> None:
    """vehicle.yaml states 290 or 330 mm for tyres of 310 mm (6.5 %): without the check the
    estimate crept at 1.5 mm/min and was still 8.3 mm off after 5 min (std 0.16 mm)."""
    vehicle = VehicleParams()
    stated = dataclasses.replace(vehicle, nominal_tire_radius_m=stated_radius_m)
    sim, pipeline, _ = simulated_radius_run(
        "robustness", 3, 2.0, {"n_particles": 100}, {}, vehicle=vehicle, stated_vehicle=stated
    )
    est = pipeline.radius.estimate()
    assert len(est.radius_rescales) == 1
    assert est.model_change_t_ns is not None
    assert est.model_change_t_ns >= pipeline.radius.speed_scale.rescale_t_ns[0]
    # the factor takes the radii from where the first seconds of learning left them (about
    # 3.5 mm of the 20 mm) to the truth
    factor = est.radius_rescales[0]
    assert (factor - 1.0) * (0.31 - stated_radius_m) > 0.0 and abs(factor - 1.0) > 0.04
    true = sim.truth.wheel_radius_m[-1, 2:]
    error = stated_radius_m + np.asarray(est.radius_error_m) - true
    assert np.all(np.abs(error) < 4.0 * np.asarray(est.radius_error_std_m))
    assert np.all(np.abs(error) < 0.6e-3)


def test_the_rescale_restarts_both_filters_from_the_scaled_common_radius() -> None:
    """What was learned under a gross scale error, the split included, is not kept: both
    filters start again from the prior, centred on the common radius times the factor."""
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.estimator import RadiusEstimator

    vehicle = VehicleParams()
    r_n = vehicle.nominal_tire_radius_m
    est = RadiusEstimator(
        RadiusEstimatorConfig(run_aug_kf=True), vehicle, np.random.default_rng(0)
    )
    assert est.kf is not None
    est.mpf.stats.mean[:] = [-0.004, -0.006]  # a learned split of 2 mm, common -5 mm
    est.kf.x[3:5] = [-0.004, -0.006]
    est._scale_radii(1.02)
    after = est.estimate()
    common = (r_n - 0.005) * 1.02 - r_n
    np.testing.assert_allclose(after.radius_error_m, [common, common], atol=1e-9)
    assert after.baseline is not None
    np.testing.assert_allclose(after.baseline.radius_error_m, [common, common], atol=1e-12)
    # the prior's uncertainty again (3 mm)
    np.testing.assert_allclose(after.radius_error_std_m, 0.003, rtol=0.05)
    np.testing.assert_allclose(after.baseline.radius_error_std_m, 0.003, rtol=1e-9)


RADIUS_M = 0.31


def drive_runs(
    runs: StraightRuns,
    seconds: float,
    scale: float = 1.0,
    yaw_rate_rad_s: float = 0.0,
    accel_m_s2: float = 0.0,
    std_m: float = 0.02,
    rng: np.random.Generator | None = None,
) -> list[float]:
    """Wheel samples at 100 Hz and fixes at 10 Hz of a drive at 10 m/s (plus ``accel_m_s2``
    times the time) on a path of constant yaw rate; the fixes' distance is ``scale`` times the
    wheels'. Returns the radii of the runs that ended over the wheels' (``RADIUS_M``)."""
    x = y = heading = 0.0
    speed = 10.0
    ratios = []
    for k in range(round(seconds * 100)):
        dt = 0.01
        runs.roll(dt, speed / RADIUS_M, yaw_rate_rad_s, speed)
        heading += yaw_rate_rad_s * dt
        x += scale * speed * np.cos(heading) * dt
        y += scale * speed * np.sin(heading) * dt
        speed += accel_m_s2 * dt
        if k % 10 == 9:
            noise = (0.0, 0.0) if rng is None else std_m * rng.standard_normal(2)
            radius_m = runs.fix(x + noise[0], y + noise[1], std_m, RADIUS_M)
            if radius_m is not None:
                ratios.append(radius_m / RADIUS_M)
    return ratios


def test_a_straight_run_gives_the_fixes_distance_over_the_wheels() -> None:
    """RTK-grade fixes (2 cm): runs of MIN_RUN_M (30 m, 3 s at 10 m/s), each within 0.2 %."""
    runs = StraightRuns()
    ratios = drive_runs(runs, 31.0, scale=1.03, rng=np.random.default_rng(0))
    assert len(ratios) == 10
    np.testing.assert_allclose(ratios, 1.03, atol=2e-3)
    # consumer fixes (1.5 m): runs of MAX_RUN_M (100 m), each within about 1.5 %
    runs = StraightRuns()
    ratios = drive_runs(runs, 160.0, scale=0.97, std_m=1.5, rng=np.random.default_rng(1))
    assert len(ratios) == 15
    assert abs(np.median(ratios) - 0.97) < 0.005 and np.std(ratios) < 0.02


def test_bends_speed_changes_slow_driving_and_gaps_give_no_run() -> None:
    runs = StraightRuns()
    # 0.04 rad/s (under the straight-driving bound): 0.12 rad over a 30-m run, taken; the arc
    # shortens the fitted slope by 0.12^2 / 40 = 0.04 %
    ratios = drive_runs(runs, 31.0, yaw_rate_rad_s=0.04)
    assert len(ratios) == 10 and np.all(np.abs(np.array(ratios) - 1.0) < 1e-3)
    # a turn: nothing
    assert drive_runs(StraightRuns(), 60.0, yaw_rate_rad_s=0.2) == []
    # accelerating at 4 m/s^2: the speed spans more than 30 % of its mean within a run (10 to
    # 18 m/s over the first 30 m)
    runs = StraightRuns()
    assert drive_runs(runs, 2.5, accel_m_s2=4.0) == [] and runs.rejected == 1
    # below MIN_RUN_SPEED_M_S: nothing
    runs = StraightRuns()
    for _ in range(3000):
        runs.roll(0.01, 0.5 / RADIUS_M, 0.0, 0.5)
        assert runs.fix(0.0, 0.0, 0.02, RADIUS_M) is None
    # a gap ends a run: what it spanned before (under MIN_RUN_M) is not a run
    runs = StraightRuns()
    assert drive_runs(runs, 2.0) == []
    runs.gap()
    assert drive_runs(runs, 2.0) == []


def test_runs_that_disagree_with_the_wheels_rescale_the_radii() -> None:
    """Two windows of RUN_WINDOW straight runs 5 % longer than the wheels' distance."""
    check = SpeedScaleCheck(RADIUS_M)
    rng = np.random.default_rng(2)
    factors = []
    x, t_ns = 0.0, 0
    for _ in range(2 * RUN_WINDOW * 30 + 10):
        for _ in range(10):
            check.runs.roll(0.01, 10.0 / RADIUS_M, 0.0, 10.0)
        x += 1.05 * 10.0 * 0.1
        t_ns += 100_000_000
        factors.append(check.add_fix(t_ns, x + 0.02 * rng.standard_normal(), 0.0, 0.02, RADIUS_M))
    rescaled = [f for f in factors if f != 1.0]
    assert len(rescaled) == 1 and rescaled[0] == pytest.approx(1.05, abs=2e-3)
    assert check.rescale_sources == ["fixes"]
    assert check.summary()["median_ratio"]["fixes"] == pytest.approx(1.05, abs=2e-3)
    assert (MIN_RUN_M, MAX_RUN_M) == (30.0, 100.0)


def test_a_wrong_nominal_radius_is_found_from_positions_alone() -> None:
    """No Doppler velocity (``gnss_velocity_enabled`` false in the simulator), vehicle.yaml 290
    mm for tyres of 310 mm: without the runs still 5 mm off after 5 min (std 0.14 mm)."""
    vehicle = VehicleParams()
    stated = dataclasses.replace(vehicle, nominal_tire_radius_m=0.29)
    sim, pipeline, _ = simulated_radius_run(
        "robustness", 2, 5.0, {}, {"gnss_velocity_enabled": False},
        vehicle=vehicle, stated_vehicle=stated,
    )  # fmt: skip
    est = pipeline.radius.estimate()
    assert len(est.radius_rescales) == 1
    assert est.model_change_t_ns is not None
    assert est.model_change_t_ns >= pipeline.radius.speed_scale.rescale_t_ns[0]
    assert pipeline.radius.speed_scale.rescale_sources == ["fixes"]
    true = sim.truth.wheel_radius_m[-1, 2:]
    error = 0.29 + np.asarray(est.radius_error_m) - true
    assert np.all(np.abs(error) < 4.0 * np.asarray(est.radius_error_std_m))
    assert np.all(np.abs(error) < 1.0e-3)


def test_a_scale_beyond_a_plausible_radius_error_is_refused_and_said() -> None:
    """Wheel speeds in m/s (the GNSS distance 3.2 times the wheels') or a radius given as a
    diameter: no rescale to a "radius" of 1 m; the factor is kept as refused."""
    check = SpeedScaleCheck(RADIUS_M)
    factors = [check.add(k, 20.0, 20.0 * RADIUS_M, 0.0, RADIUS_M) for k in range(2 * WINDOW)]
    assert factors == [1.0] * (2 * WINDOW) and check.rescales == []
    assert check.refused == [pytest.approx(1.0 / RADIUS_M)]
    assert check.summary()["refused"] == check.refused
    # 20 % is a tyre size, not a unit: rescaled
    factors = [check.add(k, 24.0, 20.0, 0.0, RADIUS_M) for k in range(2 * WINDOW)]
    assert factors[-1] == pytest.approx(1.2) and check.rescales == [pytest.approx(1.2)]


def test_the_wheel_heading_integrates_every_step_in_or_out_of_a_run() -> None:
    """The heading the wheel speeds turn through counts every step: turning (no run), slow
    (no run) and straight alike."""
    runs = StraightRuns()
    for _ in range(100):
        runs.roll(0.01, 60.0, 0.5, 20.0)  # 0.5 rad/s: too much turning for a run
    for _ in range(100):
        runs.roll(0.01, 1.0, -0.2, 0.3)  # too slow for a run
    assert runs.wheel_yaw_rad == pytest.approx(0.5 - 0.2)
