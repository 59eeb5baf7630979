"""Tests of the evaluation campaigns (tire_estimation.evaluation.campaign)."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tire_estimation.errors import TireEstimationError
from tire_estimation.evaluation.campaign import (
    DIFFUSION_DEADLINE_S,
    STEP_DEADLINE_S,
    CampaignError,
    CaseSpec,
    EceCampaignPlan,
    add_campaign_parser,
    braking_signal,
    calibration_cases,
    ece_r64_cases,
    execute_cases,
    run_case,
    run_ece_r64_campaign,
    summarize_calibration,
    summarize_detection,
)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="tire-estimation")
    sub = parser.add_subparsers(dest="command", required=True)
    add_campaign_parser(sub)
    return parser


# ------------------------------------------------------------------ case generation (fast)


def test_ece_cases_are_deterministic_and_balanced() -> None:
    plan = EceCampaignPlan(step_cases=36, robustness_cases=6, diffusion_cases=8)
    a, b = ece_r64_cases(plan), ece_r64_cases(plan)
    assert [c.to_dict() for c in a] == [c.to_dict() for c in b]
    steps = [c for c in a if c.kind == "step"]
    assert len(steps) == 36
    # the full factor grid (2 rear wheels x 3 tyres x 3 GNSS x 2 roads) is covered exactly once
    combos = {
        (c.labels["wheel"], c.labels["tyre"], c.labels["gnss"], c.labels["road"]) for c in steps
    }
    assert len(combos) == 36
    assert {c.deflated_wheels[0] for c in steps} == {"wheel_rl", "wheel_rr"}
    assert len({c.seed for c in a}) == len(a)  # every case has its own seed
    for c in steps:
        assert c.options["deflation_fraction"] == 0.2
        assert c.deadline_s == STEP_DEADLINE_S
        # the CUSUM calibration completes before the step
        assert c.detector_calibration_s <= 0.8 * c.event_s
    diffs = [c for c in a if c.kind == "diffusion"]
    assert {len(c.deflated_wheels) for c in diffs} == {1, 2, 3, 4}
    for c in diffs:
        assert c.deadline_s == DIFFUSION_DEADLINE_S
        assert {"wheel_rl", "wheel_rr"} & set(c.deflated_wheels)  # observable in rear mode
    assert all(not c.deflated_wheels and c.event_s is None for c in a if c.kind == "robustness")


def test_front_wheels_only_with_all_mode() -> None:
    rear = ece_r64_cases(EceCampaignPlan(step_cases=20, robustness_cases=0, diffusion_cases=0))
    assert all(c.deflated_wheels[0].startswith("wheel_r") for c in rear)
    allw = ece_r64_cases(
        EceCampaignPlan(step_cases=72, robustness_cases=0, diffusion_cases=0, wheels="all")
    )
    assert {c.deflated_wheels[0] for c in allw} == {"wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"}
    assert all(c.estimator["wheels"] == "all" for c in allw)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"step_cases": -1},
        {"wheels": "front"},
        {"braking_source": "pedal"},
        {"gnss_levels": ("superb",)},
        {"tyre_sensitivities_mm_per_kpa": (0.0,)},
        {"step_minutes": 10.0, "deflation_min": 12.0},
    ],
)
def test_bad_plans_raise_campaign_errors(kwargs: dict[str, Any]) -> None:
    with pytest.raises(CampaignError):
        ece_r64_cases(EceCampaignPlan(**kwargs))
    assert issubclass(CampaignError, TireEstimationError)


def test_calibration_cases_and_bad_arguments() -> None:
    cases = calibration_cases(seeds=3, minutes=12.0, first_seed=5)
    assert [c.seed for c in cases] == [5, 6, 7]
    assert all(c.options == {"deflation_fraction": 0.0} and c.kind == "calibration" for c in cases)
    with pytest.raises(CampaignError):
        calibration_cases(seeds=0)
    with pytest.raises(CampaignError):
        calibration_cases(gnss="bad")
    with pytest.raises(CampaignError):
        execute_cases(cases, executor="carrier-pigeon")


def test_calibration_sensor_overrides_reach_the_drives() -> None:
    """``--sensor KEY=VALUE`` overrides the simulator's SensorConfig over the GNSS level; an
    unknown field or a bad value is a CampaignError."""
    from tire_estimation.evaluation.campaign import GNSS_LEVELS, _sensor_options

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
    from tire_estimation.evaluation.campaign import GNSS_LEVELS, ROAD_LEVELS, _cmd_ece_r64

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


def test_braking_signal_from_speed() -> None:
    t = np.arange(0.0, 30.0, 0.1)
    v = np.where(t < 10.0, 25.0, np.maximum(25.0 - 3.0 * (t - 10.0), 10.0))  # brake 3 m/s^2
    b = braking_signal(t, v)
    assert not b[t < 10.0].any()
    assert b[(t > 12.0) & (t < 14.0)].all()
    assert not b[t > 18.0].any()


def test_summaries_from_synthetic_rows() -> None:
    rows: list[dict[str, Any]] = [
        {
            "case_id": "s0",
            "kind": "step",
            "minutes": 30.0,
            "error": "",
            "mpf_ok": True,
            "mpf_detected": True,
            "mpf_detected_in_time": True,
            "mpf_detection_time_s": 120.0,
            "mpf_false_alarms": 0,
            "mpf_calibrated_before_event": True,
            "aug_kf_ok": True,
            "aug_kf_detected": False,
            "aug_kf_detected_in_time": False,
            "aug_kf_false_alarms": 0,
            "aug_kf_calibrated_before_event": True,
        },
        {
            "case_id": "r0",
            "kind": "robustness",
            "minutes": 60.0,
            "error": "",
            "mpf_ok": True,
            "mpf_false_alarms": 1,
            "mpf_monitored_h": 0.5,
            "aug_kf_ok": True,
            "aug_kf_false_alarms": 0,
            "aug_kf_monitored_h": 0.5,
        },
    ]
    s = summarize_detection(rows)
    assert s["mpf"]["step"]["detection_rate"] == 1.0
    assert s["aug_kf"]["step"]["detection_rate"] == 0.0
    assert s["aug_kf"]["step"]["missed"] == ["s0"]
    assert s["mpf"]["robustness"]["false_alarms_per_hour"] == pytest.approx(2.0)
    assert s["aug_kf"]["robustness"]["false_alarms"] == 0
    cal = summarize_calibration(
        [
            {
                "case_id": "c0",
                "seed": 0,
                "error": "",
                "mpf_ok": True,
                "mpf_rel_err_at_m": 1e-4,
                "mpf_abs_err_rl_at_m": 3e-4,
                "mpf_abs_err_rr_at_m": 2e-4,
                "mpf_meets_targets_at": True,
                "aug_kf_ok": True,
                "aug_kf_rel_err_at_m": 3e-4,
                "aug_kf_abs_err_rl_at_m": 7e-4,
                "aug_kf_abs_err_rr_at_m": 4e-4,
                "aug_kf_meets_targets_at": False,
            }
        ],
        600.0,
    )
    assert cal["mpf"]["seeds_meeting_all_targets"] == 1
    assert cal["aug_kf"]["seeds_meeting_all_targets"] == 0
    assert cal["aug_kf"]["seeds_relative_within_target"] == 0
    assert cal["mpf"]["relative_error_at_mm"]["max_abs"] == pytest.approx(0.1)


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


# ------------------------------------------------------------------ small end-to-end campaign


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
        tmp_path / "ece", plan, executor="dask", n_workers=1, threads=True, save_traces=True
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
    from tire_estimation.evaluation.campaign import redetect_campaigns

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
    with pytest.raises(CampaignError, match="not a DeflationDetectorConfig field"):
        args.func(args)


def test_calibration_case_reports_errors_against_truth() -> None:
    spec = calibration_cases(seeds=1, minutes=2.0, first_seed=3)[0]
    row = run_case(spec, accuracy_at_s=90.0)
    assert row["error"] == ""
    for m in ("mpf", "aug_kf"):
        assert row[f"{m}_ok"] is True
        for key in ("rel_err_at_m", "abs_err_rl_at_m", "abs_err_rr_at_m", "final_rel_err_m"):
            assert np.isfinite(row[f"{m}_{key}"]), key
            assert abs(row[f"{m}_{key}"]) < 5e-3  # within the prior's reach after 1.5 min
        assert isinstance(row[f"{m}_meets_targets_at"], bool)


def test_failing_case_is_reported_not_raised() -> None:
    spec = CaseSpec(case_id="bad", kind="step", scenario="no_such_scenario", seed=0, minutes=1.0)
    row = run_case(spec)
    assert "ScenarioError" in row["error"]
    s = summarize_detection([row])
    assert s["n_failed"] == 1


@pytest.mark.parametrize("executor", ["serial", "processes"])
def test_executors_keep_case_order(executor: str) -> None:
    specs = [
        CaseSpec(case_id=f"bad-{i}", kind="step", scenario="nope", seed=i, minutes=1.0)
        for i in range(3)
    ]
    rows = execute_cases(specs, executor=executor, n_workers=2)
    assert [r["case_id"] for r in rows] == ["bad-0", "bad-1", "bad-2"]
    assert all("ScenarioError" in r["error"] for r in rows)


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
    from tire_estimation.evaluation.campaign import write_csv

    d.mkdir()
    write_csv(d / "cases.csv", rows)
    (d / "summary.json").write_text(json.dumps(summarize_detection(rows)))


def test_merge_pools_shards_with_types_restored(tmp_path: Path) -> None:
    from tire_estimation.evaluation.campaign import merge_ece_r64_campaigns, read_csv_rows

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


def test_split_alarms_into_false_warnings_and_wrong_wheel() -> None:
    from tire_estimation.evaluation.campaign import split_alarms

    step = {"event_s": 840.0, "deflated_wheels": "wheel_rr"}
    # both wheels before the step: two false warnings (the driver is warned with no tyre low)
    assert split_alarms({**step, "mpf_alarms": "wheel_rl@784;wheel_rr@784"}, "mpf") == (2, 0)
    # right wheel, then the other one 3 min later: one wrong-wheel alarm
    assert split_alarms({**step, "mpf_alarms": "wheel_rr@926;wheel_rl@1108"}, "mpf") == (0, 1)
    assert split_alarms({**step, "aug_kf_alarms": ""}, "aug_kf") == (0, 0)
    # a drive without deflation: every alarm is a false warning
    rob = {"event_s": None, "deflated_wheels": "", "mpf_alarms": "wheel_rl@2000"}
    assert split_alarms(rob, "mpf") == (1, 0)
    rows = [
        {**step, "case_id": "a", "kind": "step", "minutes": 25.0, "error": "", "mpf_ok": True,
         "mpf_observed": True, "mpf_detected": True, "mpf_detection_time_s": 86.0,
         "mpf_false_alarms": 1,
         "mpf_alarms": "wheel_rr@926;wheel_rl@1108", "aug_kf_ok": False},
        {**rob, "case_id": "b", "kind": "robustness", "minutes": 60.0, "error": "",
         "mpf_ok": True, "mpf_false_alarms": 1, "mpf_monitored_h": 0.5, "aug_kf_ok": False},
    ]  # fmt: skip
    s = summarize_detection(rows)
    assert s["mpf"]["step"]["wrong_wheel_alarms"] == 1 and s["mpf"]["step"]["false_warnings"] == 0
    assert s["mpf"]["false_warnings_total"] == 1 and s["mpf"]["wrong_wheel_alarms_total"] == 1
    assert s["mpf"]["false_alarms_total"] == 2


def _equal_leak_run(leak_m_per_min: float) -> Any:
    """A synthetic 2-h trace (2 Hz, 20 m/s): both rear estimates (MPF and AUG-KF) lose
    ``leak_m_per_min`` of radius from 1320 s on, the same on both wheels."""
    from tire_estimation.evaluation.campaign import _Run
    from tire_estimation.sim import START_TIME_NS

    t_s = np.arange(1, 2 * 7200 + 1) / 2.0
    t_ns = START_TIME_NS + np.round(t_s * 1e9).astype(np.int64)
    leak = -leak_m_per_min * np.clip(t_s - 1320.0, 0.0, None) / 60.0
    mu = np.column_stack([0.2e-3 + leak, -0.1e-3 + leak])
    k = t_s.size
    return _Run(
        t_ns=t_ns,
        t_s=t_s,
        wheel_names=("wheel_rl", "wheel_rr"),
        mpf_m=mu,
        mpf_std_m=np.full((k, 2), 3e-4),
        kf_wheels=("wheel_rl", "wheel_rr"),
        kf_m=mu.copy(),
        kf_std_m=np.full((k, 2), 1e-4),
        speed_m_s=np.full(k, 20.0),
        active=np.ones((k, 2), dtype=bool),
        truth_t_ns=t_ns,
        truth_radius_m=np.column_stack([np.full(k, 0.3)] * 2 + [0.3 + mu[:, 0], 0.3 + mu[:, 1]]),
        truth_ax_m_s2=np.zeros(k),
        nominal_m=0.3,
        sim_s=0.0,
        est_s=0.0,
    )


def test_common_channel_alarm_counts_as_a_vehicle_level_detection() -> None:
    from tire_estimation.evaluation.campaign import redetect_case, split_alarms

    run = _equal_leak_run(0.03e-3)  # 0.03 mm/min on both rear tyres: 1.8 mm after 60 min
    common = {"common_mode_fraction": 1.0, "common_channel": True}
    diff = CaseSpec(
        case_id="diff-x",
        kind="diffusion",
        scenario="diffusion",
        seed=1,
        minutes=120.0,
        deflated_wheels=("wheel_rl", "wheel_rr"),
        event_s=1320.0,
        deadline_s=DIFFUSION_DEADLINE_S,
        detector_calibration_s=1200.0,
        detector=common,
    )
    row = redetect_case(diff, run)
    for m in ("mpf", "aug_kf"):
        assert row[f"{m}_alarms"].startswith("all_wheels@"), row[f"{m}_alarms"]
        assert row[f"{m}_alarms"].count("@") == 1  # no wheel named
        assert row[f"{m}_detected"] is True and row[f"{m}_detected_in_time"] is True
        # without noise: the 600-s low-passed mean decrease passes 0.35 mm after about 20 min,
        # then about 4.5 min of CUSUM to 9 mm
        assert 22.0 * 60 < row[f"{m}_detection_time_s"] < 27.0 * 60
        assert row[f"{m}_false_alarms"] == 0
        assert row[f"{m}_max_common_cusum_over_threshold"] > 1.0
        assert split_alarms(row, m) == (0, 0)
    # relative per-wheel test without the common channel: the equal loss is not seen
    relative = redetect_case(
        dataclasses.replace(diff, detector={"common_mode_fraction": 1.0, "common_channel": False}),
        run,
    )
    assert relative["mpf_alarms"] == "" and relative["mpf_detected"] is False
    assert relative["mpf_max_common_cusum_over_threshold"] is None
    # only wheel_rl deflated but the common channel alarms: still a right (vehicle) warning
    one = redetect_case(dataclasses.replace(diff, deflated_wheels=("wheel_rl",)), run)
    assert one["mpf_detected"] is True and one["mpf_false_alarms"] == 0
    assert split_alarms(one, "mpf") == (0, 0)
    # the same alarm on a drive without deflation is a false warning
    rob = redetect_case(
        dataclasses.replace(diff, kind="robustness", deflated_wheels=(), event_s=None), run
    )
    assert rob["mpf_alarms"].startswith("all_wheels@") and rob["mpf_false_alarms"] == 1
    assert split_alarms(rob, "mpf") == (1, 0)
    assert rob["mpf_max_cusum_over_threshold"] == rob["mpf_max_common_cusum_over_threshold"]
