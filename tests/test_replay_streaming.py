"""The replay in one pass, window by window: the report of the bundled bag is the report of
the whole bag decoded at once, number for number; with the report computed over many small
chunks (a long drive) the figures agree to rounding."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from tire_estimation import replay, spill
from tire_estimation.replay import run_replay

ROOT = Path(__file__).resolve().parents[1]
#: fewer particles than the defaults: the figures compared, not their accuracy
CONFIG = "radius:\n  n_particles: 100\nstiffness:\n  n_particles: 40\n"
TIMING = {"wall_s", "timing_s", "realtime_factor"}


def _figures(m: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in m.items() if k not in TIMING}


def _close(a: Any, b: Any, path: str = "") -> list[str]:
    """Where ``a`` and ``b`` differ beyond rounding (relative 1e-9)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return [f"{path}: keys {sorted(a)} != {sorted(b)}"]
        return [d for k in a for d in _close(a[k], b[k], f"{path}/{k}")]
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        return [d for i, (x, y) in enumerate(zip(a, b, strict=True)) for d in _close(x, y, path)]
    if isinstance(a, float) and isinstance(b, float):
        return [] if math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-15) else [f"{path}: {a} {b}"]
    return [] if a == b else [f"{path}: {a!r} != {b!r}"]


def _replay(bag: Path, out: Path, cfg: Path, **kw: Any) -> dict[str, Any]:
    report = run_replay(bag, out, config_path=cfg, plots=False, progress=False, **kw)
    return _figures(report.metrics)


def test_the_bundled_bag_gives_the_numbers_of_the_whole_bag(tmp_path: Path) -> None:
    """comma2k19 (radius MPF, stiffness MPF, linear KF against /reference/odometry): decoded
    at once, and in windows of 30 s and of 5 s."""
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    bag = ROOT / "bags" / "comma2k19_rav4_seg40"
    whole = _replay(bag, tmp_path / "whole", cfg, window_s=math.inf)
    assert whole["stiffness"]["final"] and whole["position"]["rmse_m"] is not None
    assert whole["lateral_by_source"]["stiffness_mpf"]["vy_rmse_m_s"] is not None
    for window_s in (30.0, 5.0):
        assert _replay(bag, tmp_path / f"w{window_s}", cfg, window_s=window_s) == whole


def test_a_report_over_small_chunks_agrees_to_rounding(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A simulated drive with tyre forces (all estimators and the truth streams): the metrics
    summed over chunks of 500 rows and interpolated window by window, as for a long drive."""
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.sim import SensorConfig, simulate

    sim = simulate("ece_r64", seed=3, minutes=0.5, sensors=SensorConfig(tire_force_enabled=True))
    bag = write_sim_bag(sim, tmp_path / "bag")
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(CONFIG)
    whole = _replay(bag, tmp_path / "whole", cfg, window_s=math.inf)
    assert whole["lateral_by_source"]["tyre_force_kf"]["vy_rmse_m_s"] is not None
    assert whole["stiffness"]["rel_rmse_vs_truth"]
    assert whole["radii"]["rmse_vs_truth_m"] and whole["position"]["against"] == "/truth/fix"
    monkeypatch.setattr(spill, "CHUNK_ROWS", 500)
    monkeypatch.setattr(replay, "CHUNK_ROWS", 500)
    chunked = _replay(bag, tmp_path / "chunked", cfg, window_s=4.0)
    assert not _close(chunked, whole)


def test_what_the_estimator_did_once_is_reported_once_however_many_windows(
    tmp_path: Path,
) -> None:
    """The radius trace's state lists (the fix covariance's changes, the radii's rescales) hold
    the latest state, not rows: a replay in windows of 5 s reports them as the whole bag does
    (they were once appended again for every window)."""
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.sim import SensorConfig, simulate

    sensors = SensorConfig(gnss_velocity_enabled=False, gnss_covariance_scale=0.3)
    bag = write_sim_bag(
        simulate("robustness", seed=3, minutes=3.0, sensors=sensors), tmp_path / "b"
    )
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("stiffness_enabled: false\nradius:\n  n_particles: 100\n")
    whole = _replay(bag, tmp_path / "whole", cfg, window_s=math.inf)
    changes = whole["radii"]["fix_covariance"]["changes"]
    assert len(changes) == 1 and changes[0] > 3.0
    windows = _replay(bag, tmp_path / "windows", cfg, window_s=5.0)
    assert windows["radii"]["fix_covariance"] == whole["radii"]["fix_covariance"]
    assert windows["radii"]["rescales"] == whole["radii"]["rescales"] == []
