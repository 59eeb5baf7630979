"""The half-period lag of the wheel speeds and its compensation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tire_estimation.core.radius.wheel_timing import (
    PERIOD_MIN_INTERVALS,
    WheelSpeedTiming,
    hold_pitch,
    speeds_at,
)

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


PITCH_RAD = 2.0 * math.pi / 48


def _edge_timed(t_s: np.ndarray, theta_rad: np.ndarray, pitch_rad: float, period_s: float):
    """An edge-timed ABS unit on a ring of ``pitch_rad`` teeth sampled every ``period_s``: the
    edges in the last period give ``(count - 1) pitch / span``; with fewer than two the speed of
    the last tooth interval, held."""
    edges = np.interp(np.arange(pitch_rad, theta_rad[-1], pitch_rad), theta_rad, t_s)
    out = []
    for t in np.arange(period_s, t_s[-1], period_s):
        hi = np.searchsorted(edges, t, side="right")
        lo = np.searchsorted(edges, t - period_s, side="right")
        if hi - lo >= 2:
            out.append((t, (hi - lo - 1) * pitch_rad / (edges[hi - 1] - edges[lo])))
        elif hi >= 2:
            out.append((t, pitch_rad / (edges[hi - 1] - edges[hi - 2])))
    return out


def _run(samples, timing: WheelSpeedTiming, true_rad_s, speeding_up) -> tuple[float, float]:
    """Mean error of the raw and the compensated speed against the truth while accelerating
    on the second ramp (the pitch is found on the first), rad/s."""
    raw, comp = [], []
    for t, w in samples:
        out = timing.compensate(round(t * 1e9), np.full(4, w), 0.5)
        if t > 24.0 and speeding_up(t):
            raw.append(w - true_rad_s(t))
            comp.append(out[0] - true_rad_s(t))
    return float(np.mean(raw)), float(np.mean(comp))


def test_the_tooth_pitch_is_read_off_the_held_values_and_its_lag_brought_back() -> None:
    # a wheel accelerating at 2 rad/s^2 from 2 to 26 rad/s, back down and up again: held
    # values below pitch / T = 13 rad/s (fewer than one edge per 10-ms period)
    t_s = np.linspace(0.0, 48.0, 480_001)
    alpha = np.where((t_s % 24.0) < 12.0, 2.0, -2.0)
    omega = 2.0 + np.concatenate([[0.0], np.cumsum(alpha[:-1]) * (t_s[1] - t_s[0])])
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) * np.diff(t_s))])
    samples = _edge_timed(t_s, theta, PITCH_RAD, 0.01)
    timing = WheelSpeedTiming()
    raw, comp = _run(
        samples, timing, lambda t: np.interp(t, t_s, omega), lambda t: 1.0 <= (t % 24.0) < 12.0
    )
    assert timing.tooth_pitch_rad == pytest.approx(PITCH_RAD, rel=0.03)
    # the lag of a tooth period read as a speed error (about 10 ms on average over this ramp,
    # 0.02 rad/s; the half period alone would leave 0.011 rad/s): a fiftieth is left
    assert raw < -0.015
    assert abs(comp) < 0.02 * abs(raw)


def test_the_half_period_stays_where_no_value_is_held() -> None:
    # a drive controller's encoder differenced every period, and a wheel speed quantized in
    # value (repeats whatever the speed): no pitch, the lag is T / 2
    t_s = np.arange(0.0, 60.0, 0.01)
    w = 3.0 + 2.0 * np.sin(0.2 * t_s)
    rng = np.random.default_rng(0)
    for values in (w + 0.01 * rng.standard_normal(t_s.size), np.round(w, 1)):
        timing = WheelSpeedTiming()
        for t, v in zip(t_s, values, strict=True):
            timing.compensate(round(t * 1e9), np.full(4, v), 0.5)
        assert timing.tooth_pitch_rad == 0.0
        assert timing.lag_s == pytest.approx(0.005)


def test_two_hold_bins_must_agree_on_the_pitch_and_speed_end_the_hold() -> None:
    # bins of 0.01, 0.02, 0.04, 0.08 and 0.16 rad per sample at a pitch of 0.13 rad: a change
    # in every 13th, 6.5th, ... sample, in every one past the pitch
    n = [1300] * 5
    angles = [13.0, 26.0, 52.0, 104.0, 208.0]
    assert hold_pitch(n, angles, [100, 200, 400, 800, 1300]) == pytest.approx(0.13)
    # changes at a rate that does not follow the angle (value quantization)
    assert hold_pitch(n, angles, [200, 200, 200, 200, 1300]) == 0.0
    # too few changes in the first two bins
    assert hold_pitch(n, angles, [99, 99, 400, 800, 1300]) == 0.0
    # no bin past the pitch with a new value in nearly every sample
    assert hold_pitch(n, angles, [100, 200, 400, 800, 1100]) == 0.0
    assert hold_pitch(n[:4], angles[:4], [100, 200, 400, 800]) == 0.0


def test_the_speeds_at_an_instant_come_off_a_line_with_its_variance() -> None:
    rel = np.arange(-0.5, 0.0001, 0.01)  # 100 Hz, the newest sample at 0
    line = np.column_stack([20.0 + 3.0 * rel, 21.0 - 2.0 * rel])
    value, var = speeds_at(-0.05, rel, line)
    np.testing.assert_allclose(value, [20.0 - 0.15, 21.0 + 0.1], atol=1e-9)
    assert var < 1e-20
    # white noise of 0.1 rad/s on each wheel: the sum's error at the window's end has the
    # variance stated (about 2 x 4 sigma^2 / n for the 21 samples of the window)
    rng = np.random.default_rng(3)
    errors, stated = [], []
    for _ in range(2000):
        noisy = line + 0.1 * rng.standard_normal(line.shape)
        value, var = speeds_at(-0.05, rel, noisy)
        errors.append(value.sum() - line[45].sum())
        stated.append(var)
    assert np.mean(stated) == pytest.approx(2 * 0.01 * (1 / 21 + 0.1**2 / 0.077), rel=0.1)
    assert np.var(errors) == pytest.approx(np.mean(stated), rel=0.1)
    # at 10 Hz the window holds two samples: interpolated, nothing stated
    slow = rel[::10]
    value, var = speeds_at(-0.05, slow, line[::10])
    np.testing.assert_allclose(value, [20.0 - 0.15, 21.0 + 0.1], atol=1e-9)
    assert var == 0.0
