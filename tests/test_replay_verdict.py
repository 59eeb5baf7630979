"""The replay's consistency verdict says why in words when the model does not fit."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import main


def _replay(bag: Path, out: Path) -> dict:
    cfg = out.parent / f"{out.name}.yaml"
    cfg.write_text(yaml.safe_dump({"radius": {"n_particles": 100}}))
    argv = ["replay", str(bag), "--out", str(out), "--config", str(cfg)]
    assert main([*argv, "--no-progress", "--no-plots", "--no-stiffness"]) == 0
    return json.loads((out / "metrics.json").read_text())["residuals"]


def test_a_late_gnss_is_explained(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "late"
    argv = ["simulate", "robustness", "--minutes", "3", "--seed", "5", "--out", str(bag)]
    assert main([*argv, "--sensor", "gnss_latency_s=0.5"]) == 0
    capsys.readouterr()
    res = _replay(bag, tmp_path / "out")
    printed = capsys.readouterr().out
    assert res["consistent"] is False
    assert res["why"] and all(isinstance(w, str) and len(w) > 20 for w in res["why"])
    assert printed.count("    why: ") == len(res["why"])


def test_an_overstated_noise_alone_says_the_std_may_be_too_large() -> None:
    """The summary's meaning of a False verdict: "too large" only when the mean NIS far below
    its band is the one failure; with an effect or a high NIS it keeps "too small"."""
    from tire_estimation.replay import _only_overstated_noise

    tests = {
        "mean_nis_ok": False,
        "mean_nis": 0.03,
        "mean_nis_bounds_95": [1.84, 2.17],
        "white_decimated": True,
        "score_threshold": 4.0,
    }
    weak = [{"effect": "rear_brake_slip", "score": 2.7, "material": True}]
    assert _only_overstated_noise({"tests": tests, "suspected_effects": weak})
    strong = [{"effect": "gnss_latency", "score": 5.5, "material": True}]
    assert not _only_overstated_noise({"tests": tests, "suspected_effects": strong})
    high = dict(tests, mean_nis=2.5)
    assert not _only_overstated_noise({"tests": high, "suspected_effects": weak})
    correlated = dict(tests, white_decimated=False)
    assert not _only_overstated_noise({"tests": correlated, "suspected_effects": []})


def test_the_summary_names_a_lost_wheel_a_reversing_car_and_a_failed_initialization(
    tmp_path: Path,
) -> None:
    """The summary lines for the report's wheel-signal, reversing and initialization fields
    (the fields themselves are tested with the estimator)."""
    from tire_estimation.replay import ReplayReport

    bag = tmp_path / "bag"
    argv = ["simulate", "robustness", "--minutes", "1", "--seed", "2", "--out", str(bag)]
    assert main(argv) == 0
    out = tmp_path / "out"
    argv = ["replay", str(bag), "--out", str(out), "--no-progress", "--no-plots", "--no-stiffness"]
    assert main(argv) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    radii = metrics["radii"]
    assert radii["signal_lost_s"] == {} and radii["failed_initializations"]["count"] == 0
    assert radii["wheels_not_reported"] == []
    assert abs(radii["wheel_speed_lag_s"] - 0.005) < 1e-6  # half the 100 Hz period
    # at highway speed the ABS unit sees edges in every period: no held value, no pitch
    assert radii["wheel_speed_tooth_pitch_rad"] == 0.0
    assert metrics["clock_check"]["lag_s"] == 0.0 and metrics["clock_check"]["offset"] is False
    plain = ReplayReport(out, metrics).summary()
    assert "WHEEL SIGNAL LOST" not in plain and "POSE NOT INITIALIZED" not in plain
    assert "CLOCKS" not in plain and "RADII RESCALED" not in plain
    assert radii["rescales"] == []  # a clean drive's GNSS speed agrees with the wheels'
    assert radii["rescale_sources"] == []
    assert radii["fix_covariance"] == {"scale": 1.0, "changes": []}
    assert radii["gyro_reversed"] is False and radii["axles"]["rear"]["swapped"] is False
    assert radii["wheels_reversed"] == [] and radii["front_rear_exchanged"] is False
    assert radii["road_grade"]["imu_offset_deg"] == 0.0  # within what the grade check allows
    metrics["clock_check"] = {
        "lag_s": 18.0, "correlation": 0.99, "correlation_at_zero": 0.6, "offset": True
    }  # fmt: skip
    assert "CLOCKS: the GNSS speed matches the wheel speed +18.0 s later" in (
        ReplayReport(out, metrics).summary()
    )
    radii["signal_lost_s"] = {"wheel_rl": 12.5}
    radii["rescales"] = [1.057]
    radii["gyro_reversed"] = True
    radii["axles"]["rear"]["swapped"] = True
    radii["wheels_reversed"] = ["wheel_fr", "wheel_rr"]
    radii["front_rear_exchanged"] = True
    radii["rescale_sources"] = ["fixes"]
    radii["rescales_refused"] = [3.226]
    radii["fix_covariance"] = {"scale": 11.2, "changes": [11.2]}
    radii["failed_initializations"] = {"count": 7, "median_distance_ratio": 0.31}
    for learn in radii["learning"].values():
        learn["learned_s"], learn["paused_s"] = 0.0, {"reversing": 50.0}
    text = ReplayReport(out, metrics).summary()
    radii["failed_initializations"] = {"count": 1, "median_distance_ratio": 0.02}
    assert "POSE NOT INITIALIZED" not in ReplayReport(out, metrics).summary()  # one glitch
    assert "WHEEL SIGNAL LOST: wheel_rl" in text and "12.5 s" in text
    assert "radii were not learned then" in text and "not reported" not in plain
    radii["signal_lost_s"] = {"wheel_fl": 3.0}
    radii["wheels_not_reported"] = ["wheel_fr"]
    front = ReplayReport(out, metrics).summary()
    # a front wheel's loss does not pause the learning of the rear radii
    assert "WHEEL SIGNAL LOST: wheel_fl" in front and "radii were not learned then" not in front
    assert "front wheels not reported (wheel_fr): the rear radii do not need them" in front
    radii["wheels_not_reported"] = ["wheel_fl", "wheel_rr"]
    assert "WHEELS NOT REPORTED: wheel_rr never had a speed" in (
        ReplayReport(out, metrics).summary()
    )
    assert "RADII RESCALED 1 time(s) (+5.7 % from the fixes)" in text
    assert "RADII NOT RESCALED: the GNSS distance was 3.23 times the wheels'" in text
    assert "RADII NOT RESCALED" not in plain and radii["rescales_refused"] == [3.226]
    assert "FIX COVARIANCE SCALED: the fixes' innovations across the track showed" in text
    assert "position_covariance too small" in text and "times 11.2 (std times 3.3)" in text
    assert "FIX COVARIANCE" not in plain and radii["fix_covariance"]["changes"] == [11.2]
    assert "WIRING: the rear wheels' left and right speeds arrived exchanged; the gyro's" in text
    assert "wheel_fr, wheel_rr turned backward while the GNSS moved forward" in text
    assert "the front and rear wheels' names arrived exchanged (the wheels named rear" in text
    assert "WIRING" not in plain
    # the verdict of a run whose model the estimator changed judges the fixes after the change
    assert "earlier left out" not in plain
    metrics["residuals"]["consistent"] = True
    metrics["residuals"].setdefault("tests", {})["fixes_before_model_change"] = 600
    assert "after the estimator's latest change to its model (radii rescaled or fix " in (
        ReplayReport(out, metrics).summary()
    )
    assert "fix covariance scaled): 600 earlier left out" in ReplayReport(out, metrics).summary()
    assert "POSE NOT INITIALIZED 7 times" in text and "covered 0.31 of the distance" in text
    assert text.count("NEVER LEARNED") == 2 and "REP-103" in text


def test_a_rear_driven_car_learns_its_slip_and_says_so(tmp_path: Path) -> None:
    """A rear-driven car (vehicle.yaml ``drive: rear``) whose vehicle.yaml states twice its
    tyres' longitudinal stiffness: the replay learns the slip against the front wheels and
    the rear radii end near the truth (without the correction: -1.1 to -1.6 mm on 10-min
    drives, ``core/radius/drive_slip.py``)."""
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.core.vehicle import VehicleParams
    from tire_estimation.replay import ReplayReport
    from tire_estimation.sim import simulate

    sim = simulate("robustness", seed=4, minutes=4, vehicle=VehicleParams(drive="rear"))
    bag = write_sim_bag(sim, tmp_path / "bag")
    (bag / "vehicle.yaml").write_text(
        yaml.safe_dump(
            {"vehicle": {**sim.vehicle.to_dict(), "longitudinal_stiffness_rear_n": 300_000.0}}
        )
    )
    out = tmp_path / "out"
    argv = ["replay", str(bag), "--out", str(out), "--no-progress", "--no-plots", "--no-stiffness"]
    assert main(argv) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    slip = metrics["radii"]["drive_slip"]
    assert slip["drive"] == "rear" and slip["source"] == "learned"
    # the simulator's m / C_x is 0.01 s^2/m; the prior from the stated stiffness 0.005
    assert 0.007 < slip["slip_per_accel_s2_per_m"] < 0.012
    assert 0.001 < slip["mean_slip"] < 0.004
    errors = metrics["radii"]["final_error_vs_truth_m"]
    assert max(abs(errors["wheel_rl"]), abs(errors["wheel_rr"])) < 0.4e-3
    assert "DRIVEN REAR WHEELS" in ReplayReport(out, metrics).summary()
    # a car said to be front-driven whose rear wheels slip: the yaml, or the wheel names
    slip["detected"] = True
    assert "set drive: rear, unless the front and rear wheel names are exchanged" in (
        ReplayReport(out, metrics).summary()
    )


def test_a_gnss_on_another_clock_is_realigned_before_the_estimation(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A receiver stamping 18 s ahead (GPS time against UTC): found over the first minutes,
    taken out of the GNSS stamps, the drive estimated on one clock and said so. Without it the
    rear radii were 0.66 mm off at 11 reported stds and the pose 351 m off (RMSE)."""
    bag = tmp_path / "gps_time"
    argv = ["simulate", "robustness", "--minutes", "4", "--seed", "1", "--out", str(bag)]
    assert main([*argv, "--sensor", "gnss_clock_offset_s=18"]) == 0
    capsys.readouterr()
    out = tmp_path / "out"
    _replay(bag, out)
    printed = capsys.readouterr().out
    metrics = json.loads((out / "metrics.json").read_text())
    clock = metrics["clock_check"]
    assert clock["corrected_s"] == pytest.approx(18.0, abs=0.05)
    assert clock["leading"]["offset"] is True and clock["offset"] is False
    assert abs(clock["lag_s"]) < 0.5  # what is left after the correction
    assert "CLOCKS CORRECTED" in printed and "+18.0" in printed
    radii = metrics["radii"]
    for wheel, error_m in radii["final_error_vs_truth_m"].items():
        assert abs(error_m) < 3.0 * radii["final_radius_error_std_m"][wheel] + 1e-4, wheel
    assert metrics["position"]["rmse_m"] < 5.0
