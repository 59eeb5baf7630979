"""ClockCheck: the lag that aligns the receiver's speed with the wheels' names a clock offset
between the two streams, and stays at zero for one clock."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.clock_check import LEADING_S, ClockCheck, leading_check
from tire_estimation.core.samples import GnssVelocity, WheelSpeeds

RADIUS_M = 0.31


def _check(gnss_late_s: float | None, seconds: float = 300.0) -> dict:
    """A speed profile (a slow wave and random accelerations) driven for ``seconds``: wheel
    speeds at 100 Hz, the GNSS velocity at 10 Hz stamped ``gnss_late_s`` late (None: none)."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, seconds, 0.01)
    accel = np.repeat(rng.normal(0.0, 0.6, t.size // 500 + 1), 500)[: t.size]
    speed = 20.0 + 4.0 * np.sin(2 * np.pi * t / 90.0) + np.cumsum(accel) * 0.01
    check = ClockCheck(RADIUS_M)
    for k in range(t.size):
        t_ns = round(t[k] * 1e9)
        omega = speed[k] / RADIUS_M
        check.on_sample(None, WheelSpeeds(t_ns, np.array([omega] * 4)), None)
        if gnss_late_s is not None and k % 10 == 0:
            v = np.array([speed[k], 0.0, 0.0]) + rng.normal(0.0, 0.05, 3)
            check.on_sample(None, GnssVelocity(t_ns + round(gnss_late_s * 1e9), v, None), None)
    return check.result()


@pytest.mark.parametrize("late_s", [18.0, -5.0, 1.5, 7.33])
def test_a_clock_offset_is_found_and_sized(late_s: float) -> None:
    """Sized to a few hundredths of a second: the GNSS profile is read at the wheel
    profile's own stamps, so the bins' sampling (a wheel sample at a bin's start, the mean of
    the velocities over it) cancels."""
    res = _check(late_s)
    assert res["lag_s"] == pytest.approx(late_s, abs=0.03)
    assert res["offset"] is True and res["correlation"] > 0.99
    assert res["correlation_at_zero"] < res["correlation"]


def test_one_clock_is_no_offset_and_no_velocity_is_not_judged() -> None:
    res = _check(0.0)
    assert res["lag_s"] == 0.0 and res["offset"] is False
    late = _check(0.3)  # a latency the sensor agreement sizes, not a clock offset
    assert abs(late["lag_s"]) <= 0.5 and late["offset"] is False
    none = _check(None)
    assert none["lag_s"] is None and none["offset"] is False


def test_the_leading_check_reads_the_first_minutes_only() -> None:
    """Over the first LEADING_S of stamps: the samples after the first one beyond them are
    not read."""
    samples = []
    for t in np.arange(0.0, 2 * LEADING_S, 0.1):
        v = 20.0 + 4.0 * np.sin(2 * np.pi * t / 60.0)
        samples.append(WheelSpeeds(round(t * 1e9), np.full(4, v / RADIUS_M)))
        samples.append(GnssVelocity(round((t + 4.0) * 1e9), np.array([v, 0.0, 0.0]), None))
    samples.sort(key=lambda s: s.t_ns)
    it = iter(samples)
    res = leading_check(it, RADIUS_M)
    assert res["offset"] is True and res["lag_s"] == pytest.approx(4.0, abs=0.03)
    rest = list(it)
    assert len(rest) == sum(s.t_ns > LEADING_S * 1e9 for s in samples) - 1
