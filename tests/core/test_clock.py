"""ClockGuard: outliers dropped, new clocks adopted, one continuous time, nothing else lost."""

from __future__ import annotations

import itertools

import pytest

from tire_estimation.core.clock import STEP_AFTER_PRESENT_NS, ClockGuard, ClockGuardConfig

MS = 1_000_000
HOUR = 3600 * 1_000_000_000


def _feed(guard: ClockGuard[int], events: list[tuple[str, int]]) -> list[tuple[int, int]]:
    """Admit ``(stream, stamp)`` events (item = index); return what was released."""
    out: list[tuple[int, int]] = []
    for k, (stream, t_ns) in enumerate(events):
        out.extend(guard.admit(stream, t_ns, k))
    return out


def _two_streams(t0_ns: int, n: int, step_ns: int = 10 * MS) -> list[tuple[str, int]]:
    events = []
    for k in range(n):
        events.append(("wheel", t0_ns + k * step_ns))
        if k % 5 == 0:
            events.append(("imu", t0_ns + k * step_ns + 1))
    return events


def test_steady_stamps_pass_unchanged() -> None:
    guard: ClockGuard[int] = ClockGuard()
    events = _two_streams(10**12, 200)
    out = _feed(guard, events)
    assert [u for u, _ in out] == [t for _, t in events]
    assert guard.offset_ns("wheel") == guard.offset_ns("imu") == 0
    assert not guard.dropped and not guard.jumps and guard.held() == 0


def test_one_sample_two_hours_ahead_is_dropped_and_counted() -> None:
    guard: ClockGuard[int] = ClockGuard()
    events = _two_streams(10**12, 100)
    events.insert(50, ("wheel", events[49][1] + 2 * HOUR))
    out = _feed(guard, events)
    released = [k for _, k in out]
    assert 50 not in released
    assert len(released) == len(events) - 1
    assert guard.dropped == {"wheel": 1}
    assert guard.drop_counts() == {"wheel:clock_jump": 1}
    assert guard.offset_ns("wheel") == 0 and not guard.jumps


def test_a_clock_stepped_back_an_hour_is_adopted_and_time_stays_continuous() -> None:
    guard: ClockGuard[int] = ClockGuard()
    before = _two_streams(10**13, 100)
    after = _two_streams(10**13 + 100 * 10 * MS - HOUR, 100)
    out = _feed(guard, before + after)
    # nothing lost: the suspects were released once the new clock was confirmed
    assert sorted(k for _, k in out) == list(range(len(before) + len(after)))
    internal = [u for u, _ in sorted(out, key=lambda e: e[1])]
    wheel = [u for (u, k) in sorted(out, key=lambda e: e[1]) if (before + after)[k][0] == "wheel"]
    assert all(b > a for a, b in itertools.pairwise(wheel))
    last_before = max(internal[: len(before)])
    assert min(internal[len(before) :]) == last_before + STEP_AFTER_PRESENT_NS
    offset = guard.offset_ns("wheel")
    assert abs(offset - HOUR) < 20 * MS
    assert guard.offset_ns("imu") == offset  # the second stream takes the first one's clock
    assert guard.jumps["wheel"] == 1 and not guard.dropped


def test_a_pause_of_every_stream_keeps_its_stamps() -> None:
    """A recording paused for a minute: the estimators see the gap, stamps are unchanged."""
    guard: ClockGuard[int] = ClockGuard()
    events = _two_streams(10**12, 100) + _two_streams(10**12 + 61 * 10**9, 100)
    out = _feed(guard, events)
    assert sorted(u for u, _ in out) == sorted(t for _, t in events)
    assert guard.offset_ns("wheel") == guard.offset_ns("imu") == 0
    assert guard.jumps["wheel"] == 1


def test_one_stream_jumping_alone_is_mapped_onto_the_others() -> None:
    guard: ClockGuard[int] = ClockGuard()
    events = []
    for k in range(300):
        t = 10**12 + k * 10 * MS
        events.append(("wheel", t))
        if k % 10 == 0:
            # the GNSS receiver's clock runs two hours ahead from the 10th fix on
            events.append(("gnss", t + (2 * HOUR if k >= 100 else 0)))
    out = _feed(guard, events)
    assert guard.offset_ns("wheel") == 0
    # the newest suspect arrived right after the wheel sample of its true stamp
    assert guard.offset_ns("gnss") == -2 * HOUR
    gnss_internal = [u for u, k in out if events[k][0] == "gnss"]
    assert len(gnss_internal) == 30
    assert all(b > a for a, b in itertools.pairwise(gnss_internal))


def test_admit_now_takes_what_admit_would_release_at_once_and_leaves_the_rest() -> None:
    """admit_now, with admit for the samples it leaves, releases what admit alone releases and
    leaves the guard in the same state (outliers, a jump of one stream, a step back)."""
    events = []
    for k in range(300):
        t = 10**12 + k * 10 * MS
        events.append(("wheel", t - (HOUR if k >= 200 else 0)))
        if k % 10 == 0:
            events.append(("gnss", t + (2 * HOUR if k >= 100 else 0)))
    events.insert(50, ("wheel", events[49][1] + 2 * HOUR))
    plain: ClockGuard[int] = ClockGuard()
    fast: ClockGuard[int] = ClockGuard()
    at_once = 0
    for k, (stream, t_ns) in enumerate(events):
        expected = plain.admit(stream, t_ns, k)
        u_ns = fast.admit_now(stream, t_ns)
        if u_ns is None:
            assert fast.admit(stream, t_ns, k) == expected
        else:
            at_once += 1
            assert [(u_ns, k)] == expected
        assert fast.present_ns == plain.present_ns
        assert fast.held() == plain.held()
    assert 0 < at_once < len(events)
    assert fast.dropped == plain.dropped and fast.jumps == plain.jumps
    assert fast.offset_ns("wheel") == plain.offset_ns("wheel") != 0
    assert fast.offset_ns("gnss") == plain.offset_ns("gnss") != 0


def test_suspects_never_confirmed_are_dropped_at_the_end() -> None:
    guard: ClockGuard[int] = ClockGuard(ClockGuardConfig(confirm_samples=5))
    out = _feed(guard, [("wheel", 10**12), ("wheel", 10**12 + HOUR), ("wheel", 10**12 + HOUR)])
    assert len(out) == 1 and guard.held() == 2
    guard.discard_held()
    assert guard.held() == 0 and guard.dropped == {"wheel": 2}


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [({"max_jump_s": 0.0}, "max_clock_jump_s"), ({"confirm_samples": 0}, "confirm_samples")],
)
def test_config_names_the_bad_field(kwargs: dict[str, float], name: str) -> None:
    with pytest.raises((ValueError, TypeError), match=name):
        ClockGuardConfig(**kwargs)  # type: ignore[arg-type]
