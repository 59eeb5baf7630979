"""The fixes' stated covariance checked against their innovations, and scaled when it is off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.fix_scale import (
    LIMIT,
    MAX_SCALE,
    MIN_SHARE,
    WINDOW_MIN_FIXES,
    WINDOW_S,
    FixCovarianceCheck,
    across_track,
)
from tire_estimation.evaluation.residuals import analyze_trace
from tire_estimation.evaluation.sim_runs import simulated_radius_run

#: fixes at 10 Hz
PERIOD_NS = 100_000_000


def _feed(check: FixCovarianceCheck, nis: np.ndarray, t0_ns: int = 0) -> list[bool]:
    return [check.add(t0_ns + k * PERIOD_NS, float(v)) for k, v in enumerate(nis)]


def _chi2_1(rng: np.random.Generator, n: int, factor: float) -> np.ndarray:
    """Squared innovations across the track over their stated variance, the fixes' variance
    ``factor`` times the stated one (1 dof)."""
    return factor * rng.chisquare(1.0, n)


def test_the_innovation_across_the_track() -> None:
    """Heading north-east: across is north-west; a variance that is not positive gives NaN."""
    yaw = math.pi / 4.0
    across = np.array([-1.0, 1.0]) / math.sqrt(2.0)
    innovation = 2.0 * across + np.array([5.0, 5.0])  # 2 m across, the rest along
    s_m2, r_m2 = np.diag([4.0, 4.0]), np.diag([1.0, 3.0])
    nis, share = across_track(yaw, innovation, s_m2, r_m2)
    assert nis == pytest.approx(1.0) and share == pytest.approx(0.5)
    assert all(math.isnan(v) for v in across_track(yaw, innovation, np.zeros((2, 2)), r_m2))


def test_stated_covariance_that_fits_is_left_alone() -> None:
    check = FixCovarianceCheck()
    changed = _feed(check, _chi2_1(np.random.default_rng(0), 6000, 1.0))
    assert not any(changed) and check.scale == 1.0 and check.changes == []
    assert check.last_ratio is not None and abs(check.last_ratio - 1.0) < 0.3


@pytest.mark.parametrize("factor", [10.0, 0.1])
def test_two_windows_beyond_the_band_scale_the_covariance(factor: float) -> None:
    check = FixCovarianceCheck()
    n_window = int(WINDOW_S * 1e9 / PERIOD_NS) + 1
    changed = _feed(check, _chi2_1(np.random.default_rng(1), 2 * n_window, factor))
    # the first window only notes the ratio; the second, on the same side, scales
    assert changed.index(True) == 2 * n_window - 1 and changed.count(True) == 1
    assert check.scale == pytest.approx(factor, rel=0.25)
    assert check.changes == [check.scale] and check.change_t_ns == [(2 * n_window - 1) * PERIOD_NS]
    # with the scale applied the innovations fit: nothing more changes
    more = _feed(check, _chi2_1(np.random.default_rng(2), 3 * n_window, 1.0), 10**12)
    assert not any(more) and len(check.changes) == 1
    assert np.allclose(check.apply(np.eye(2)), check.scale * np.eye(2))


def test_one_window_off_opposite_sides_or_inside_the_band_change_nothing() -> None:
    check = FixCovarianceCheck()
    rng = np.random.default_rng(3)
    n_window = int(WINDOW_S * 1e9 / PERIOD_NS) + 1
    t0 = 0
    for factor in (10.0, 1.0, 10.0, 0.1, 0.9 * LIMIT, 0.9 * LIMIT, 1.1 / LIMIT, 1.1 / LIMIT):
        assert not any(_feed(check, _chi2_1(rng, n_window, factor), t0))
        t0 += 10**12
    assert check.scale == 1.0


def test_a_window_needs_its_time_and_its_fixes_outliers_and_nan_do_not_move_it() -> None:
    check = FixCovarianceCheck()
    # a slow receiver: 1 fix a second, WINDOW_MIN_FIXES - 1 of them in far more than WINDOW_S
    slow = [check.add(k * 10**9, 20.0) for k in range(WINDOW_MIN_FIXES - 1)]
    assert not any(slow) and check.last_ratio is None
    # NaN is not counted; the median ignores a tenth of gross outliers
    check = FixCovarianceCheck()
    rng = np.random.default_rng(4)
    nis = _chi2_1(rng, 6000, 1.0)
    nis[::10] = 1e4
    nis[5::10] = math.nan
    assert not any(_feed(check, nis)) and check.scale == 1.0


def test_a_stated_covariance_that_is_a_small_part_of_the_innovations_is_not_scaled() -> None:
    """When the cloud's spread or a Gauss-Markov error of a fixed size makes up most of the
    innovation covariance, the NIS does not measure the stated covariance: scaling it would run
    to the bound (a robot configuration with a 2-m Gauss-Markov error did)."""
    check = FixCovarianceCheck()
    rng = np.random.default_rng(5)
    nis = _chi2_1(rng, 6000, 0.05)
    assert not any(check.add(k * PERIOD_NS, float(v), 0.9 * MIN_SHARE) for k, v in enumerate(nis))
    assert check.scale == 1.0 and check.last_ratio is not None and check.last_ratio < 0.1
    later = 10**12  # past the open window
    assert any(check.add(later + k * PERIOD_NS, float(v), MIN_SHARE) for k, v in enumerate(nis))


def test_the_scale_is_bounded_and_a_disabled_check_does_nothing() -> None:
    check = FixCovarianceCheck()
    n_window = int(WINDOW_S * 1e9 / PERIOD_NS) + 1
    _feed(check, np.full(4 * n_window, 1e6))
    assert check.scale == MAX_SCALE
    check = FixCovarianceCheck(enabled=False)
    assert not any(_feed(check, np.full(4 * n_window, 1e6))) and check.scale == 1.0


@pytest.mark.parametrize(("stated_scale", "low", "high"), [(0.3, 4.0, 40.0), (3.0, 0.05, 0.25)])
def test_a_receiver_that_misstates_its_accuracy_no_longer_misleads_the_radii(
    stated_scale: float, low: float, high: float
) -> None:
    """Positions only, the fixes' covariance stated 3.3 times too small (std) or 3 times too
    large: without the check the rear radii ended 1.65 mm off at a 0.05 mm std (too small),
    0.27 mm at a 0.44 mm std (too large) on the 10-min version of this drive."""
    sim, pipeline, trace = simulated_radius_run(
        "robustness", 3, 5.0, {"n_particles": 200},
        {"gnss_velocity_enabled": False, "gnss_covariance_scale": stated_scale},
    )  # fmt: skip
    est = pipeline.radius.estimate()
    # the variance is off by 1 / stated_scale^2: found, within a factor of two
    assert low < est.fix_covariance_scale < high and len(est.fix_covariance_changes) >= 1
    # the verdict judges the fixes from the latest change on
    assert est.model_change_t_ns == pipeline.radius.fix_scale.change_t_ns[-1]
    assert trace.model_change_t_ns == est.model_change_t_ns
    judged = analyze_trace(trace)["tests"]
    assert judged["fixes_before_model_change"] == np.count_nonzero(
        np.asarray(trace.innov_t_ns) < est.model_change_t_ns
    )
    assert judged["fixes_before_model_change"] > 0
    true = sim.truth.wheel_radius_m[-1, 2:]
    error = 0.31 + np.asarray(est.radius_error_m) - true
    assert np.all(np.abs(error) < 3.0 * np.asarray(est.radius_error_std_m))
    assert np.all(np.abs(error) < 0.5e-3)


def test_clean_drives_are_not_scaled() -> None:
    _, pipeline, _ = simulated_radius_run("robustness", 3, 5.0, {"n_particles": 200}, {})
    est = pipeline.radius.estimate()
    assert est.fix_covariance_scale == 1.0 and est.fix_covariance_changes == ()
    assert est.model_change_t_ns is None
    assert pipeline.radius.fix_scale.last_ratio is not None
    assert 1.0 / LIMIT < pipeline.radius.fix_scale.last_ratio < LIMIT
