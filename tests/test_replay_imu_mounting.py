"""A bag whose IMU is turned on its mount: found, taken out, reported (core/imu_mounting.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import main


def _replay(tmp_path: Path, name: str, sensors: list[str]) -> dict:
    bag, out = tmp_path / name, tmp_path / f"{name}_out"
    argv = ["simulate", "robustness", "--minutes", "3", "--seed", "1", "--out", str(bag)]
    assert main([*argv, *(a for kv in sensors for a in ("--sensor", kv))]) == 0
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(yaml.safe_dump({"radius": {"n_particles": 200}}))
    argv = ["replay", str(bag), "--out", str(out), "--config", str(cfg)]
    assert main([*argv, "--no-progress", "--no-plots"]) == 0
    return json.loads((out / "metrics.json").read_text())


def test_an_imu_turned_90_degrees_is_rotated_back_and_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    clean = _replay(tmp_path, "clean", [])
    capsys.readouterr()
    turned = _replay(tmp_path, "turned", ["imu_mounting_yaw_deg=90"])
    printed = capsys.readouterr().out
    mount = turned["imu_mounting"]
    assert mount["corrected"] and mount["yaw_deg"] == pytest.approx(90.0)
    assert mount["decided_s"] < 30.0
    assert "IMU AXES: the IMU's horizontal axes are turned +90.0 deg" in printed
    assert clean["imu_mounting"]["decided"] and not clean["imu_mounting"]["corrected"]
    # the radii as with the IMU mounted right
    for wheel, err in clean["radii"]["final_radius_error_m"].items():
        assert turned["radii"]["final_radius_error_m"][wheel] == pytest.approx(err, abs=1e-4)
    # the stiffness MPF restarted in base_link axes tracks the lateral state (with the IMU
    # left turned: yaw rate 57 deg/s, sideslip 33 deg off on a 5-min drive)
    lateral = turned["lateral_by_source"]["stiffness_mpf"]
    assert lateral["yaw_rate_rmse_deg_s"] < 0.5 and lateral["sideslip_rmse_deg"] < 1.0


def test_an_imu_upside_down_is_turned_back_and_said(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    flipped = _replay(tmp_path, "flipped", ["imu_upside_down=true"])
    printed = capsys.readouterr().out
    assert flipped["imu_mounting"]["upside_down"]
    assert not flipped["imu_mounting"]["corrected"]
    assert "IMU AXES: the IMU's z axis points down" in printed
    # the gyro was turned back with it: no reversed yaw rate left for the axle check
    assert flipped["radii"]["gyro_reversed"] is False
    lateral = flipped["lateral_by_source"]["stiffness_mpf"]
    assert lateral["yaw_rate_rmse_deg_s"] < 0.5 and lateral["sideslip_rmse_deg"] < 1.0
