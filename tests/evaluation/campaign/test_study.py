"""Result directories: campaign, merge, redetect (evaluation.campaign.study, output)."""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import Any

import pytest

from tire_estimation.evaluation.campaign.cli import add_campaign_parser
from tire_estimation.evaluation.campaign.execute import Execution
from tire_estimation.evaluation.campaign.spec import (
    CampaignError,
    EceCampaignPlan,
)
from tire_estimation.evaluation.campaign.study import run_ece_r64_campaign
from tire_estimation.evaluation.campaign.summary import summarize_detection


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tire-estimation")
    sub = parser.add_subparsers(dest="command", required=True)
    add_campaign_parser(sub)
    return parser


def test_small_ece_campaign_on_dask(tmp_path: Path) -> None:
    """A 3.5-min drive with the step at 1.25 min (1 min of CUSUM calibration) and a 2-min drive
    without deflation, on a threads-only Dask cluster with one worker."""
    plan = EceCampaignPlan(
        step_cases=1,
        robustness_cases=1,
        diffusion_cases=0,
        step_minutes=3.5,
        deflation_min=1.25,
        robustness_minutes=2.0,
        detector_calibration_s=60.0,
        tyre_sensitivities_mm_per_kpa=(0.05,),
        gnss_levels=("good",),
        road_levels=("flat",),
        first_seed=1,
    )
    summary = run_ece_r64_campaign(
        tmp_path / "ece",
        plan,
        Execution(executor="dask", n_workers=1, threads=True),
        save_traces=True,
    )
    out = tmp_path / "ece"
    for name in ("summary.json", "cases.csv", "cases.json", "detection_times.png"):
        assert (out / name).is_file(), name
    on_disk = json.loads((out / "summary.json").read_text())
    assert on_disk["n_failed"] == 0
    for key in ("mpf", "aug_kf", "cases_by_kind", "config", "versions", "files"):
        assert key in on_disk
    for m in ("mpf", "aug_kf"):
        assert set(on_disk[m]) >= {"step", "diffusion", "robustness", "false_alarms_total"}
        assert on_disk[m]["robustness"]["false_alarms"] is not None
    with (out / "cases.csv").open() as fh:
        rows = {r["case_id"]: r for r in csv.DictReader(fh)}
    step = rows["step-0000"]
    deflated = step["deflated_wheels"]
    other = "wheel_rr" if deflated == "wheel_rl" else "wheel_rl"
    # 20 % of 230 kPa at 0.05 mm/kPa: a ~2.3 mm step; both methods alarm on that wheel within
    # the 2.25 min left (the CUSUM low-pass and rate limit alone need about a minute), never on
    # the other wheel
    for m in ("mpf", "aug_kf"):
        assert step[f"{m}_detected"] == "True", step
        assert step[f"{m}_alarms"].startswith(deflated + "@")
        assert other not in step[f"{m}_alarms"]
        assert int(step[f"{m}_false_alarms"]) == 0
        assert 0.0 < float(step[f"{m}_detection_time_s"]) <= 135.0
        assert float(step[f"{m}_estimated_change_m"]) < -0.7e-3  # the tyre got smaller
    rob = rows["rob-0000"]
    assert int(rob["mpf_false_alarms"]) == 0 and int(rob["aug_kf_false_alarms"]) == 0
    assert rob["mpf_alarms"] == "" and rob["aug_kf_alarms"] == ""
    assert summary["mpf"]["step"]["detection_rate"] == 1.0
    assert summary["mpf"]["robustness"]["false_alarms"] == 0
    assert summary["mpf"]["robustness"]["monitored_hours"] > 0.0
    # detection re-run from the saved traces: the same result with the same detector, none
    # with a 100x threshold
    from tire_estimation.evaluation.campaign.study import redetect_campaigns

    assert sorted(x.name for x in (out / "traces").iterdir()) == [
        "rob-0000.npz",
        "step-0000.npz",
    ]
    again = redetect_campaigns(tmp_path / "re", [out])
    for m in ("mpf", "aug_kf"):
        assert again[m]["step"] == summary[m]["step"]
        assert again[m]["robustness"]["false_alarms"] == 0
    high = redetect_campaigns(tmp_path / "hi", [out], {"threshold_m": 0.9})
    assert high["mpf"]["step"]["detected"] == 0 and high["aug_kf"]["step"]["detected"] == 0
    args = _parser().parse_args(
        ["campaign", "redetect", str(out), "--out", "x", "--detector", "nope=1"]
    )
    with pytest.raises(CampaignError, match="--detector nope=1: unknown key"):
        args.func(args)


def _step_row(case_id: str, seed: int, mpf_det: bool, kf_det: bool) -> dict[str, Any]:
    return {
        "case_id": case_id,
        "kind": "step",
        "seed": seed,
        "minutes": 25.0,
        "error": "",
        "mpf_ok": True,
        "mpf_observed": True,
        "mpf_detected": mpf_det,
        "mpf_detected_in_time": mpf_det,
        "mpf_detection_time_s": 100.0 + seed % 100 if mpf_det else None,
        "mpf_false_alarms": 0 if mpf_det else 1,
        "mpf_calibrated_before_event": True,
        "aug_kf_ok": True,
        "aug_kf_observed": True,
        "aug_kf_detected": kf_det,
        "aug_kf_detected_in_time": kf_det,
        "aug_kf_detection_time_s": 90.0 if kf_det else None,
        "aug_kf_false_alarms": 0,
        "aug_kf_calibrated_before_event": True,
    }


def _write_shard(d: Path, rows: list[dict[str, Any]]) -> None:
    from tire_estimation.evaluation.campaign.output import write_csv

    d.mkdir()
    write_csv(d / "cases.csv", rows)
    (d / "summary.json").write_text(json.dumps(summarize_detection(rows)))


def test_merge_pools_shards_with_types_restored(tmp_path: Path) -> None:
    from tire_estimation.evaluation.campaign.output import read_csv_rows
    from tire_estimation.evaluation.campaign.study import merge_ece_r64_campaigns

    _write_shard(tmp_path / "a", [_step_row("step-0000", 1000, True, True)])
    _write_shard(
        tmp_path / "b",
        [_step_row("step-0000", 1036, False, True), _step_row("step-0001", 1037, True, False)],
    )
    # the CSV round trip keeps booleans, None and numbers
    back = read_csv_rows(tmp_path / "b" / "cases.csv")
    assert back[0]["mpf_detected"] is False and back[0]["mpf_detection_time_s"] is None
    assert back[1]["mpf_detection_time_s"] == 137.0 and back[0]["error"] == ""
    s = merge_ece_r64_campaigns(tmp_path / "all", [tmp_path / "a", tmp_path / "b"])
    assert s["n_cases"] == 3
    assert s["mpf"]["step"]["detected"] == 2 and s["mpf"]["step"]["missed"] == ["step-0000"]
    assert s["aug_kf"]["step"]["detected"] == 2
    assert s["mpf"]["false_alarms_total"] == 1
    assert s["mpf"]["step"]["detection_time_s"]["median_abs"] == pytest.approx(118.5)
    with (tmp_path / "all" / "cases.csv").open() as fh:
        assert [r["shard"] for r in csv.DictReader(fh)] == ["a", "b", "b"]
    # the same drive twice, a directory that is not a finished campaign, an existing summary
    _write_shard(tmp_path / "c", [_step_row("step-0000", 1000, True, True)])
    with pytest.raises(CampaignError, match="seed 1000"):
        merge_ece_r64_campaigns(tmp_path / "x", [tmp_path / "a", tmp_path / "c"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(CampaignError, match="not a finished campaign"):
        merge_ece_r64_campaigns(tmp_path / "y", [tmp_path / "empty"])
    with pytest.raises(CampaignError, match=r"summary\.json"):
        merge_ece_r64_campaigns(tmp_path / "all", [tmp_path / "a"])
    args = _parser().parse_args(
        ["campaign", "merge", str(tmp_path / "a"), str(tmp_path / "b"), "--out", "o"]
    )
    assert args.shards == [tmp_path / "a", tmp_path / "b"]
