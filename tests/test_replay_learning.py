"""The report says per wheel how long the radius was learned and why not, and says plainly
when a wheel never learned (its estimate is then the prior)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import main


@pytest.fixture(scope="module")
def drive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("learn") / "lc"
    assert (
        main(["simulate", "lane_change", "--minutes", "0.5", "--seed", "4", "--out", str(out)])
        == 0
    )
    return out


def _replay(bag: Path, out: Path, radius: dict[str, object]) -> dict:
    cfg = out.parent / f"{out.name}.yaml"
    cfg.write_text(yaml.safe_dump({"radius": {"n_particles": 100, **radius}}))
    argv = ["replay", str(bag), "--out", str(out), "--config", str(cfg)]
    assert main([*argv, "--no-progress", "--no-plots", "--no-stiffness"]) == 0
    return json.loads((out / "metrics.json").read_text())["radii"]["learning"]


def test_a_drive_above_the_speed_gate_learns_most_of_the_time(drive: Path, tmp_path: Path) -> None:
    learning = _replay(drive, tmp_path / "a", {})
    assert set(learning) == {"wheel_rl", "wheel_rr"}
    for w in learning.values():
        assert w["learned_s"] > 10.0
        assert 0.3 < w["share"] <= 1.0
        # the time not learned is explained by reasons
        assert all(v >= 0.0 for v in w["paused_s"].values())


def test_a_wheel_that_never_learned_is_reported(
    drive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Every sample below the speed gate (60 km/h against a 100 m/s gate): no learning, the
    reason is the low speed, and the summary says the estimate is the prior."""
    capsys.readouterr()
    learning = _replay(drive, tmp_path / "b", {"min_speed_m_s": 100.0})
    for w in learning.values():
        assert w["learned_s"] == 0.0 and w["share"] == 0.0
        assert max(w["paused_s"], key=w["paused_s"].get) == "low speed"
    printed = capsys.readouterr().out
    assert printed.count("NEVER LEARNED: the estimate below is the prior (paused: low speed") == 2
    assert printed.count("radius.min_speed_m_s sets the speed floor") == 2
