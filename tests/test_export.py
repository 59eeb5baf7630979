"""``tire-estimation export``: persisted or replayed radii as diff_drive_controller or vehicle
parameters; bad sources end in one line on stderr and exit 2."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from tire_estimation.cli import main
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.vehicle import VehicleParams, dump_vehicle_yaml
from tire_estimation.persistence import Identity, save_state

VEH = VehicleParams(name="robot_7", nominal_tire_radius_m=0.25, track_width_m=0.6)
#: learned rear radius errors (wheel_rl, wheel_rr), m
LEARNED = [2.0e-3, -1.5e-3]


def _radius_state(front: bool = False) -> dict[str, Any]:
    config = RadiusEstimatorConfig(n_particles=50, wheels="all" if front else "rear")
    state = RadiusEstimator(config, VEH, np.random.default_rng(1)).state_dict()
    state["rear"]["mean_m"] = list(LEARNED)
    state["rear"]["mean_cov_m2"] = [[1e-8, 0.0], [0.0, 4e-8]]
    if front:
        state["front"]["mean_m"] = [1e-3, 0.5e-3]
    return state


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    vehicle = tmp_path / "vehicle.yaml"
    dump_vehicle_yaml(VEH, vehicle)
    saved = tmp_path / "learned_radii.json"
    save_state(saved, Identity(VEH.name, "default"), {"radius": _radius_state()})
    return {"vehicle": vehicle, "saved": saved, "root": tmp_path}


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    code = main(["export", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_persisted_radii_become_diff_drive_controller_parameters(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _run(capsys, str(files["saved"]), "--vehicle", str(files["vehicle"]))
    assert (code, err) == (0, "")
    doc = yaml.safe_load(out)
    params = doc["diff_drive_controller"]["ros__parameters"]
    assert params == {
        "wheel_radius": 0.25,
        "left_wheel_radius_multiplier": pytest.approx((0.25 + LEARNED[0]) / 0.25, abs=1e-9),
        "right_wheel_radius_multiplier": pytest.approx((0.25 + LEARNED[1]) / 0.25, abs=1e-9),
    }
    assert out.startswith("# learned effective tyre radii of vehicle 'robot_7'")

    # another controller name, to a file
    target = files["root"] / "radii.yaml"
    code, _, _ = _run(
        capsys, str(files["saved"]), "--vehicle", str(files["vehicle"]),
        "--controller", "base_controller", "--out", str(target),
    )  # fmt: skip
    assert code == 0
    assert list(yaml.safe_load(target.read_text())) == ["base_controller"]


def test_vehicle_format_has_every_estimated_wheel_and_the_speed_scale_factor(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    saved = files["root"] / "all_wheels.json"
    save_state(saved, Identity(VEH.name, "winter"), {"radius": _radius_state(front=True)})
    code, out, _ = _run(
        capsys, str(saved), "--vehicle", str(files["vehicle"]), "--tire-set", "winter",
        "--format", "vehicle",
    )  # fmt: skip
    assert code == 0
    doc = yaml.safe_load(out)["effective_tire_radii"]
    assert doc["vehicle"] == "robot_7" and doc["nominal_radius_m"] == 0.25
    wheels = doc["wheels"]
    assert list(wheels) == ["wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"]
    assert wheels["wheel_rl"]["radius_m"] == pytest.approx(0.252, abs=1e-9)
    assert wheels["wheel_rr"]["multiplier"] == pytest.approx(0.2485 / 0.25, abs=1e-9)
    assert wheels["wheel_fl"]["radius_m"] == pytest.approx(0.251, abs=1e-9)
    # the std as a restarted node reports it: the restore spreads the particles over the saved
    # uncertainty (saved 0.1 mm, reported 0.13 mm)
    assert 0.5e-4 < wheels["wheel_rl"]["radius_std_m"] < 2e-4
    assert doc["speed_scale_factor"] == pytest.approx((0.252 + 0.2485) / 2 / 0.25, abs=1e-9)


def test_a_replay_report_exports_with_the_bag_vehicle(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    bag = files["root"] / "bag"
    bag.mkdir()
    dump_vehicle_yaml(VEH, bag / "vehicle.yaml")
    metrics = files["root"] / "metrics.json"
    metrics.write_text(
        json.dumps({
            "bag": str(bag),
            "radii": {
                "final_radius_error_m": {"wheel_rl": -1e-3, "wheel_rr": 3e-3},
                "final_radius_error_std_m": {"wheel_rl": 1e-4, "wheel_rr": 1e-4},
            },
        })
    )  # fmt: skip
    code, out, _ = _run(capsys, str(metrics), "--format", "vehicle")
    assert code == 0
    doc = yaml.safe_load(out)["effective_tire_radii"]
    assert doc["speed_scale_factor"] == pytest.approx(1.004)
    assert "from the replay report" in out


def _bad_sources(files: dict[str, Path]) -> dict[str, tuple[list[str], str]]:
    root, vehicle = files["root"], str(files["vehicle"])
    other = root / "other.yaml"
    dump_vehicle_yaml(VehicleParams(name="truck"), other)
    implausible = _radius_state()
    implausible["rear"]["mean_m"] = [0.1, 0.0]  # 10 cm off a 25 cm tyre (band 25 %)
    save_state(root / "implausible.json", Identity(VEH.name, "default"), {"radius": implausible})
    save_state(root / "stiffness_only.json", Identity(VEH.name, "default"), {"stiffness": {}})
    no_radius = {"bag": "", "radii": {"final_radius_error_m": {"wheel_rl": None, "wheel_rr": 0.0},
                                      "final_radius_error_std_m": {"wheel_rl": None,
                                                                   "wheel_rr": 1e-4}}}  # fmt: skip
    (root / "no_radius.json").write_text(json.dumps(no_radius))
    (root / "nan.json").write_text('{"radii": {"final_radius_error_m": NaN}}')
    (root / "list.json").write_text("[1, 2]")
    saved = str(files["saved"])
    (root / "exists.yaml").write_text("x: 1\n")
    return {
        "no --vehicle": ([saved], "--vehicle"),
        "another vehicle": ([saved, "--vehicle", str(other)], "for vehicle 'robot_7'"),
        "another tire set": ([saved, "--vehicle", vehicle, "--tire-set", "x"], "tire set"),
        "implausible radius": ([str(root / "implausible.json"), "--vehicle", vehicle], "rejected"),
        "no radius part": ([str(root / "stiffness_only.json"), "--vehicle", vehicle], "radius"),
        "replay without radius": (
            [str(root / "no_radius.json"), "--vehicle", vehicle],
            "wheel_rl",
        ),
        "replay, no bag vehicle": ([str(root / "no_radius.json")], "--vehicle"),
        "NaN in the report": ([str(root / "nan.json"), "--vehicle", vehicle], "non-finite"),
        "not a source": ([str(root / "list.json"), "--vehicle", vehicle], "neither"),
        "missing file": ([str(root / "absent.json"), "--vehicle", vehicle], "No such file"),
        "out exists": (
            [saved, "--vehicle", vehicle, "--out", str(root / "exists.yaml")],
            "--overwrite",
        ),
        "bad format": ([saved, "--vehicle", vehicle, "--format", "urdf"], "invalid choice"),
    }


@pytest.mark.parametrize(
    "case",
    [
        "no --vehicle", "another vehicle", "another tire set", "implausible radius",
        "no radius part", "replay without radius", "replay, no bag vehicle",
        "NaN in the report", "not a source", "missing file", "out exists", "bad format",
    ],
)  # fmt: skip
def test_bad_sources_end_in_one_line_and_exit_2(
    files: dict[str, Path], capsys: pytest.CaptureFixture[str], case: str
) -> None:
    argv, words = _bad_sources(files)[case]
    try:
        code, out, err = _run(capsys, *argv)
    except SystemExit as exc:  # argparse's own errors
        code, (out, err) = int(exc.code or 0), capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and len(err) <= 301, err
    assert err.startswith("tire-estimation") and words in err, err
    assert (files["root"] / "exists.yaml").read_text() == "x: 1\n"
