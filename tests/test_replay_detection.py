"""The replay runs the deflation detector: alarms, calibration, the plot, and what it prints."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tire_estimation.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_the_demo_warns_on_the_deflated_wheel(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The bundled bag with the demo configuration: armed after its 150 s calibration, one
    alarm on wheel_rl after the pressure step at 226.8 s, the CUSUM plot written."""
    out = tmp_path / "demo"
    bag = ROOT / "bags" / "ece_r64_6min"
    argv = [
        "replay",
        str(bag),
        "--out",
        str(out),
        "--config",
        str(ROOT / "scripts/demo_config.yaml"),
    ]
    assert main([*argv, "--no-progress"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    det = metrics["detection"]
    assert det["ran"] and det["armed"]

    assert [a["wheel"] for a in det["alarms"]] == ["wheel_rl"]
    assert 226.8 < det["alarms"][0]["t_s"] < 226.8 + 600.0
    assert det["calibration"]["required_s"] == 150.0
    assert 150.0 <= det["calibration"]["done_at_s"] < 226.8
    assert det["wheels"]["wheel_rl"]["max_cusum_over_threshold"] > 1.0
    assert det["wheels"]["wheel_rr"]["max_cusum_over_threshold"] < 1.0
    assert (out / "detection.png").stat().st_size > 10_000
    printed = capsys.readouterr().out
    assert "DEFLATION WARNING: wheel_rl at" in printed
    assert "after the pressure step on wheel_rl at 227 s" in printed


def test_a_short_bag_says_the_detector_was_not_armed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With the default 20-min calibration a 1-min bag cannot arm the detector: the report and
    stdout say so instead of an empty alarm list alone."""
    out = tmp_path / "comma"
    bag = ROOT / "bags" / "comma2k19_rav4_seg40"
    assert main(["replay", str(bag), "--out", str(out), "--no-progress", "--no-stiffness"]) == 0
    det = json.loads((out / "metrics.json").read_text())["detection"]
    assert det["ran"] and not det["armed"] and det["alarms"] == []
    assert det["calibration"]["required_s"] == 1200.0
    assert det["calibration"]["done_at_s"] is None
    assert 0.0 < det["calibration"]["driving_time_s"] < 1200.0
    assert not any(w["calibrated"] for w in det["wheels"].values())
    printed = capsys.readouterr().out
    assert "deflation detector: not armed: the calibration needs 1200 s" in printed
