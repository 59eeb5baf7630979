"""The radius studies' single runs: what they measure is what they report."""

from __future__ import annotations

from tire_estimation.evaluation import consistency_study, slow_study
from tire_estimation.evaluation.sim_runs import key_values


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


def test_the_consistency_run_reports_its_tests() -> None:
    row = consistency_study.run_one(1, 4.0, {"n_particles": 200}, {}, skip_min=2.0)
    assert row["consistent"] in (True, False)
    assert 0.5 < row["mean_nis"] < 5.0
    assert row["nees"] is not None and 0.0 < row["nees"] < 10.0
