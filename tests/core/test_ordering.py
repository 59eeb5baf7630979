"""ReorderBuffer: live arrival order -> the pipeline's (stamp, priority) order."""

from __future__ import annotations

import numpy as np

from tire_estimation.core.ordering import ReorderBuffer
from tire_estimation.core.samples import (
    GnssFix,
    GnssVelocity,
    ImuSample,
    MeasuredVelocity,
    Sample,
    Steering,
    WheelSpeeds,
    merge,
    order_key,
)

_MAKE = {
    "wheel": lambda t: WheelSpeeds(t, np.zeros(4)),
    "steer": lambda t: Steering(t, 0.0),
    "imu": lambda t: ImuSample(t, np.zeros(3), np.zeros(3)),
    "gnss": lambda t: GnssFix(t, 58.0, 15.0, 0.0, None),
    "vel": lambda t: GnssVelocity(t, np.zeros(3), None),
    "speed": lambda t: MeasuredVelocity(t, 1.0),
}
_NAME = {type(f(1)): name for name, f in _MAKE.items()}


def _names(samples: list[Sample]) -> list[tuple[int, str]]:
    return [(s.t_ns, _NAME[type(s)]) for s in samples]


def _feed(arrivals: list[tuple[int, str]], **kw: int) -> list[tuple[int, str]]:
    buf = ReorderBuffer(**kw)
    out: list[Sample] = []
    for t, kind in arrivals:
        out.extend(buf.push(_MAKE[kind](t)))
    out.extend(buf.flush())
    return _names(out)


def test_samples_ahead_of_the_clock_wait_for_it() -> None:
    arrivals = [(10, "wheel"), (25, "gnss"), (15, "imu"), (20, "wheel"), (30, "wheel")]
    assert _feed(arrivals) == [
        (10, "wheel"),
        (15, "imu"),
        (20, "wheel"),
        (25, "gnss"),
        (30, "wheel"),
    ]


def test_equal_stamps_follow_the_priority_whatever_the_arrival() -> None:
    # a fix's velocity, the fix, the IMU and the steering of one instant arrive in any order
    arrivals = [(10, "wheel"), (20, "vel"), (20, "gnss"), (20, "imu"), (20, "steer")]
    arrivals += [(20, "wheel"), (30, "wheel")]
    assert _feed(arrivals) == [
        (10, "wheel"), (20, "wheel"), (20, "steer"), (20, "imu"), (20, "gnss"), (20, "vel"),
        (30, "wheel"),
    ]  # fmt: skip


def test_any_interleaving_of_ordered_streams_gives_the_merged_order() -> None:
    rng = np.random.default_rng(0)
    streams = {
        "wheel": np.arange(0, 1000, 10),
        "imu": np.arange(0, 1000, 10),
        "steer": np.arange(5, 1000, 20),
        "gnss": np.arange(0, 1000, 100),
        "vel": np.arange(0, 1000, 100),
    }
    expected = _names(list(merge([[_MAKE[k](int(t)) for t in ts] for k, ts in streams.items()])))
    assert expected == sorted(expected, key=lambda e: order_key(_MAKE[e[1]](e[0])))
    for _ in range(5):
        # each stream arrives in its own order with its own transport lag (below the delay);
        # the streams interleave accordingly, ties at random
        lag = {k: int(rng.integers(0, 50)) for k in streams}
        arrivals = [
            (int(t) + lag[k], rng.random(), int(t), k) for k, ts in streams.items() for t in ts
        ]
        arrivals.sort()
        assert _feed([(t, k) for _, _, t, k in arrivals], delay_ns=50) == expected
        # without the delay, a sample that lags the clock comes out of order
        if max(lag.values()) > lag["wheel"] + 10:
            assert _feed([(t, k) for _, _, t, k in arrivals]) != expected


def test_late_samples_are_released_at_once_and_counted() -> None:
    buf = ReorderBuffer()
    buf.push(_MAKE["wheel"](100))
    assert _names(buf.push(_MAKE["gnss"](90))) == [(90, "gnss")]
    assert _names(buf.push(_MAKE["wheel"](80))) == [(80, "wheel")]
    assert len(buf) == 0
    assert buf.late == {"gnss_fix": 1, "wheel_speeds": 1}
    assert buf.push(_MAKE["imu"](110)) == []  # ahead of the clock: held, not late
    assert buf.late["imu"] == 0


def test_held_samples_are_released_when_the_clock_stops() -> None:
    buf = ReorderBuffer(max_hold_ns=50)
    buf.push(_MAKE["wheel"](10))
    assert buf.push(_MAKE["gnss"](20)) == []
    assert buf.push(_MAKE["gnss"](60)) == []
    assert _names(buf.push(_MAKE["gnss"](75))) == [(20, "gnss")]
    assert len(buf) == 2


def test_a_measured_velocity_is_a_clock_too() -> None:
    # data without wheel speeds (the measured speed instead) are not held for the hold limit
    assert _feed([(10, "imu"), (10, "speed"), (20, "imu"), (20, "speed")], max_hold_ns=10**9) == [
        (10, "imu"), (10, "speed"), (20, "imu"), (20, "speed"),
    ]  # fmt: skip
