"""Aggregation of case rows (evaluation.campaign.summary)."""

from __future__ import annotations

from typing import Any

import pytest

from tire_estimation.evaluation.campaign.summary import summarize_calibration, summarize_detection


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


def test_split_alarms_into_false_warnings_and_wrong_wheel() -> None:
    from tire_estimation.evaluation.campaign.summary import split_alarms

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
