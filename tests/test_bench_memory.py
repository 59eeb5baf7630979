"""The replay's peak-memory benchmark measures a replay of its own process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tire_estimation.bench_memory import replay_peak_rss

ROOT = Path(__file__).resolve().parents[1]


def test_the_peak_memory_is_that_of_one_replay_process() -> None:
    """The child's own peak, not that of the (large) process it was forked from."""
    ballast = np.ones(80_000_000)  # 640 MB held by this process while the child runs
    out = replay_peak_rss(ROOT / "bags" / "comma2k19_rav4_seg40", stiffness=False, plots=False)
    assert ballast[-1] == 1.0
    assert out["duration_s"] == pytest.approx(60.0, abs=1.0)
    # an interpreter with NumPy and the estimators holds tens of MB; one minute of a drive
    # stays far below the 400-MB budget of a long one
    assert 40.0 < out["peak_rss_mb"] < 400.0
    assert out["wall_s"] > 0.0 and out["stiffness"] is False


def test_a_replay_that_fails_names_the_bag(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="not_a_bag"):
        replay_peak_rss(tmp_path / "not_a_bag")
