"""The campaign sub-command (evaluation.campaign.cli)."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import pytest

from tire_estimation.evaluation.campaign.cli import add_campaign_parser
from tire_estimation.evaluation.campaign.spec import (
    CampaignError,
    EceCampaignPlan,
    calibration_cases,
    ece_r64_cases,
)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tire-estimation")
    sub = parser.add_subparsers(dest="command", required=True)
    add_campaign_parser(sub)
    return parser


def test_calibration_sensor_overrides_reach_the_drives() -> None:
    """``--sensor KEY=VALUE`` overrides the simulator's SensorConfig over the GNSS level; an
    unknown field or a bad value is a CampaignError."""
    from tire_estimation.evaluation.campaign.cli import _sensor_options
    from tire_estimation.evaluation.campaign.spec import GNSS_LEVELS

    args = _parser().parse_args(
        ["campaign", "calibration", "--out", "x", "--sensor", "gnss_velocity_enabled=true"]
    )
    sensors = _sensor_options(args.sensor)
    assert sensors == {"gnss_velocity_enabled": True}
    cases = calibration_cases(seeds=2, sensors=sensors)
    assert all(c.sensors == {**GNSS_LEVELS["calibration"], **sensors} for c in cases)
    with pytest.raises(CampaignError, match="gnss_velocity_xyz"):
        _sensor_options([("gnss_velocity_xyz", True)])
    with pytest.raises(CampaignError, match="gnss_velocity_enabled"):
        _sensor_options([("gnss_velocity_enabled", "yes")])


def test_ece_sensor_overrides_reach_every_drive() -> None:
    """``campaign ece-r64 --sensor KEY=VALUE`` reaches the step, robustness and diffusion
    drives over their GNSS and road levels (the GNSS Doppler velocity re-validation)."""
    from tire_estimation.evaluation.campaign.cli import _cmd_ece_r64
    from tire_estimation.evaluation.campaign.spec import GNSS_LEVELS, ROAD_LEVELS

    args = _parser().parse_args(
        ["campaign", "ece-r64", "--out", "x", "--sensor", "gnss_velocity_enabled=true"]
    )
    assert args.func is _cmd_ece_r64 and args.sensor == [("gnss_velocity_enabled", True)]
    plan = EceCampaignPlan(
        step_cases=2, robustness_cases=2, diffusion_cases=2,
        sensors={"gnss_velocity_enabled": True},
    )  # fmt: skip
    cases = ece_r64_cases(plan)
    assert {c.kind for c in cases} == {"step", "robustness", "diffusion"}
    for c in cases:
        assert c.sensors["gnss_velocity_enabled"] is True
        level = GNSS_LEVELS[c.labels["gnss"]]
        road = ROAD_LEVELS[c.labels["road"]] if "road" in c.labels else {}
        assert c.sensors == {**level, **road, "gnss_velocity_enabled": True}
    # without overrides the drives are exactly their levels (the campaigns run so far)
    base = ece_r64_cases(dataclasses.replace(plan, sensors={}))
    assert all("gnss_velocity_enabled" not in c.sensors for c in base)


def test_cli_parser_and_user_errors(tmp_path: Path) -> None:
    parser = _parser()
    args = parser.parse_args(
        ["campaign", "ece-r64", "--out", str(tmp_path), "--minutes", "3", "--gnss", "good"]
    )
    assert args.func.__name__ == "_cmd_ece_r64"
    assert args.gnss == ("good",)
    assert args.scheduler is None and args.executor == "dask"
    args = parser.parse_args(["campaign", "calibration", "--out", str(tmp_path)])
    assert args.seeds == 20 and args.at_min == 10.0
    # a user error: deflation after the end of the drive
    bad = parser.parse_args(
        ["campaign", "ece-r64", "--out", str(tmp_path), "--minutes", "3", "--deflation-min", "5"]
    )
    with pytest.raises(CampaignError):
        bad.func(bad)
    bad = parser.parse_args(
        ["campaign", "calibration", "--out", str(tmp_path), "--estimator", "n_particles=1"]
    )
    with pytest.raises(CampaignError):
        bad.func(bad)
