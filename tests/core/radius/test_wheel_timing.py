"""The half-period lag of the wheel speeds and its compensation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.wheel_timing import PERIOD_MIN_INTERVALS, WheelSpeedTiming

ALPHA = np.array([2.0, 2.0, -3.0, 1.5])  # rad/s^2


def _window_mean(t_s: float, period_s: float) -> np.ndarray:
    """What a sensor reports at ``t_s``: the mean speed over its last period, which for a
    constant acceleration is the speed half a period earlier."""
    return 20.0 + ALPHA * (t_s - 0.5 * period_s)


@pytest.mark.parametrize("period_s", [0.01, 0.02])
def test_a_window_mean_is_brought_to_its_stamp(period_s: float) -> None:
    timing = WheelSpeedTiming()
    out = np.zeros(4)
    for k in range(1, 200):
        t_s = k * period_s
        out = timing.compensate(round(t_s * 1e9), _window_mean(t_s, period_s), 0.5)
    assert timing.sample_period_s == pytest.approx(period_s)
    truth = 20.0 + ALPHA * 199 * period_s
    raw_error = np.abs(_window_mean(199 * period_s, period_s) - truth)
    np.testing.assert_allclose(raw_error, np.abs(ALPHA) * 0.5 * period_s)
    np.testing.assert_allclose(out, truth, atol=1e-9)


def test_nothing_is_compensated_before_the_period_is_known() -> None:
    timing = WheelSpeedTiming()
    ws = _window_mean(0.01, 0.01)
    for k in range(1, PERIOD_MIN_INTERVALS):
        ws = _window_mean(k * 0.01, 0.01)
        assert timing.compensate(k * 10_000_000, ws, 0.5) is ws
    assert timing.sample_period_s == 0.0


def test_the_period_is_the_median_interval_so_a_lost_sample_does_not_move_it() -> None:
    timing = WheelSpeedTiming()
    t_ns = 0
    for k in range(100):
        t_ns += 20_000_000 if k % 10 == 5 else 10_000_000  # one sample in ten lost
        timing.compensate(t_ns, np.full(4, 30.0), 0.5)
    assert timing.sample_period_s == pytest.approx(0.01)
    assert timing.lag_s == pytest.approx(0.005)


def test_a_gap_restarts_the_derivative_and_a_nan_wheel_spoils_only_itself() -> None:
    timing = WheelSpeedTiming()
    for k in range(1, 100):
        timing.compensate(k * 10_000_000, _window_mean(k * 0.01, 0.01), 0.5)
    # one rear wheel not reported for a sample: the others are still compensated
    ws = _window_mean(1.0, 0.01)
    ws[2] = math.nan
    out = timing.compensate(1_000_000_000, ws, 0.5)
    assert math.isnan(out[2])
    np.testing.assert_allclose(out[[0, 1, 3]], (20.0 + ALPHA * 1.0)[[0, 1, 3]], atol=1e-9)
    out = timing.compensate(1_010_000_000, _window_mean(1.01, 0.01), 0.5)
    assert np.all(np.isfinite(out))
    # after a gap longer than max_gap_s the speeds pass as they are (no derivative yet)
    ws = _window_mean(3.0, 0.01)
    np.testing.assert_array_equal(timing.compensate(3_000_000_000, ws, 0.5), ws)
