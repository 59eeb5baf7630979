"""Scoring of one case (evaluation.campaign.score)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from tire_estimation.evaluation.campaign.score import braking_signal
from tire_estimation.evaluation.campaign.spec import (
    DIFFUSION_DEADLINE_S,
    CaseSpec,
)


def test_braking_signal_from_speed() -> None:
    t = np.arange(0.0, 30.0, 0.1)
    v = np.where(t < 10.0, 25.0, np.maximum(25.0 - 3.0 * (t - 10.0), 10.0))  # brake 3 m/s^2
    b = braking_signal(t, v)
    assert not b[t < 10.0].any()
    assert b[(t > 12.0) & (t < 14.0)].all()
    assert not b[t > 18.0].any()


def _equal_leak_run(leak_m_per_min: float) -> Any:
    """A synthetic 2-h trace (2 Hz, 20 m/s): both rear estimates (MPF and AUG-KF) lose
    ``leak_m_per_min`` of radius from 1320 s on, the same on both wheels."""
    from tire_estimation.evaluation.campaign.trace import CaseRun
    from tire_estimation.sim import START_TIME_NS

    t_s = np.arange(1, 2 * 7200 + 1) / 2.0
    t_ns = START_TIME_NS + np.round(t_s * 1e9).astype(np.int64)
    leak = -leak_m_per_min * np.clip(t_s - 1320.0, 0.0, None) / 60.0
    mu = np.column_stack([0.2e-3 + leak, -0.1e-3 + leak])
    k = t_s.size
    return CaseRun(
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
    from tire_estimation.evaluation.campaign.run import redetect_case
    from tire_estimation.evaluation.campaign.summary import split_alarms

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
