"""The radius studies' single runs: what they measure is what they report."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from tire_estimation.core.vehicle import load_vehicle_yaml
from tire_estimation.evaluation import consistency_study, slow_study
from tire_estimation.evaluation.sim_runs import key_values

REPO = Path(__file__).resolve().parents[2]


def test_key_values_reads_json_and_booleans() -> None:
    assert key_values(["a=1", "b=0.5", "c=true", "d=false", 'e="x"']) == {
        "a": 1,
        "b": 0.5,
        "c": True,
        "d": False,
        "e": "x",
    }


def test_a_slow_rtk_drive_learns_below_7_m_s() -> None:
    """2 min of the ``slow`` scenario (1-8 m/s) with RTK fixes: learned most of the time, the
    rear radii within 0.5 % of the truth, errors and |error|/std consistent with each other."""
    row = slow_study.run_one(0, 2.0, {"n_particles": 200})
    assert row["learned_s"] > 60.0
    assert all(abs(e) < 0.5 for e in row["error_rel_pct"])
    for err_mm, std_mm, z in zip(row["error_mm"], row["std_mm"], row["z"], strict=True):
        assert abs(err_mm / std_mm - z) < 1e-9
    # the ABS sensor's lag: the wheels measure too little distance while accelerating; while
    # steady they measure the true distance
    bias = row["odometry_bias_pct"]
    assert bias["accelerating"] < -0.1
    assert abs(bias["steady"]) < 0.03
    # the pitch of the simulator's 48-tooth ring, read off the values held below 4 m/s (the
    # decay of a held value past its tooth period makes a few changes more: 1-2 % short)
    assert 2.0 * math.pi / row["tooth_pitch_rad"] == pytest.approx(48.0, rel=0.03)


def test_the_consistency_run_reports_its_tests() -> None:
    row = consistency_study.run_one(1, 4.0, {"n_particles": 200}, {}, skip_min=2.0)
    assert row["consistent"] in (True, False)
    assert 0.5 < row["mean_nis"] < 5.0
    assert row["nees"] is not None and 0.0 < row["nees"] < 10.0


def test_the_consistency_summary_counts_a_drive_with_nothing_to_test_apart() -> None:
    def row(consistent: bool | None, suspected: list[str]) -> dict[str, Any]:
        tested = consistent is not None
        return {
            "consistent": consistent,
            "suspected": suspected,
            "first_estimate": 0.5 if suspected else None,
            "nees": 1.0 if tested else None,
            "mean_nis": 2.0 if tested else None,
            "nis_ok": tested,
            "white": tested,
        }

    lines = consistency_study.summary(
        [row(True, []), row(False, ["gnss_lever_arm"]), row(None, [])]
    )
    assert lines[0].startswith("consistent on 1/3 (1 with nothing to test) (mean NIS ok on 2,")
    assert lines[1] == "first suspected effect: gnss_lever_arm 1; its size median 0.5"


@pytest.mark.slow
def test_a_trucks_held_abs_values_leave_its_radii_unbiased() -> None:
    """A 12-t truck in town (0.52 m tyres: the ABS unit holds one tooth's speed, 1 % off with
    the simulator's pitch error, for up to several samples): the GNSS velocity is compared with
    a line through the wheel speeds, and its acceleration gate reads none of the samples
    compared. Reading the one sample at the velocity's time, and gating on it, the same drive
    ended 0.48 / 0.56 mm off with an NEES of 15."""
    vehicle = load_vehicle_yaml(REPO / "scripts" / "vehicles" / "truck.yaml")
    row = consistency_study.run_one(7, 5.0, {}, {}, scenario="city", vehicle=vehicle)
    assert all(abs(e) < 0.3 for e in row["final_error_mm"])
    assert row["nees"] is not None and row["nees"] < 2.0
