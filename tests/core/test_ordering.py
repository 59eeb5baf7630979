"""StampOrderedDispatcher: live arrival order -> replay merge order."""

from __future__ import annotations

from tire_estimation.core.ordering import StampOrderedDispatcher


def _feed(arrivals: list[tuple[int, str]], **kw: int) -> list[tuple[int, str]]:
    d = StampOrderedDispatcher("wheel", **kw)
    out: list[tuple[int, str]] = []
    for t, kind in arrivals:
        out.extend((s[0], s[1]) for s in d.push(t, kind, None))
    out.extend((s[0], s[1]) for s in d.flush())
    return out


def test_samples_ahead_of_the_clock_wait_for_it() -> None:
    arrivals = [(10, "wheel"), (25, "gnss"), (15, "imu"), (20, "wheel"), (30, "wheel")]
    assert _feed(arrivals) == [
        (10, "wheel"),
        (15, "imu"),
        (20, "wheel"),
        (25, "gnss"),
        (30, "wheel"),
    ]


def test_equal_stamps_put_the_clock_first_like_the_replay() -> None:
    assert _feed([(10, "wheel"), (20, "gnss"), (20, "wheel")]) == [
        (10, "wheel"), (20, "wheel"), (20, "gnss"),
    ]  # fmt: skip


def test_late_samples_are_released_at_once() -> None:
    d = StampOrderedDispatcher("wheel")
    d.push(100, "wheel", None)
    assert d.push(90, "gnss", "late") == [(90, "gnss", "late")]
    assert len(d) == 0


def test_held_samples_are_released_when_the_clock_stops() -> None:
    d = StampOrderedDispatcher("wheel", max_hold_ns=50)
    d.push(10, "wheel", None)
    assert d.push(20, "gnss", "a") == []
    assert d.push(60, "gnss", "b") == []
    released = d.push(75, "gnss", "c")
    assert [s[2] for s in released] == ["a"]
    assert len(d) == 2
