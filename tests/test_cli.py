"""The tire-estimation command line: simulate, info, replay, and its one-line errors."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from tire_estimation.cli import main

CONTRACT_KEYS = {
    "bag", "duration_s", "wall_s", "realtime_factor", "radii", "position", "detection",
    "stiffness", "lateral", "residuals",
}  # fmt: skip


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cli") / "ece"
    assert main(["simulate", "ece_r64", "--minutes", "3", "--seed", "2", "--out", str(out)]) == 0
    return out


def test_simulate_and_info(short_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert (short_bag / "vehicle.yaml").is_file()
    assert main(["info", str(short_bag)]) == 0
    text = capsys.readouterr().out
    assert "/vehicle/wheel_speeds" in text and "pressure_step" in text
    assert "duration:  180.0 s" in text


def test_simulate_another_vehicle(tmp_path: Path) -> None:
    vehicle = tmp_path / "truck.yaml"
    vehicle.write_text(
        "vehicle:\n  name: truck\n  nominal_tire_radius_m: 0.52\n  track_width_m: 2.05\n"
        "  wheelbase_m: 5.0\n  cg_to_front_axle_m: 2.0\n  cg_to_rear_axle_m: 3.0\n"
    )
    out = tmp_path / "bag"
    argv = ["simulate", "city", "--minutes", "0.2", "--vehicle", str(vehicle), "--out", str(out)]
    assert main(argv) == 0
    written = yaml.safe_load((out / "vehicle.yaml").read_text())["vehicle"]
    assert written["name"] == "truck" and written["nominal_tire_radius_m"] == 0.52
    # the simulated truth rolls on the stated tyres
    from tire_estimation.bag.reader import read_bag

    radii = read_bag(out).truth_wheel_radii
    assert radii is not None
    assert abs(float(np.nanmean(radii.values)) - 0.52) < 0.002


def test_simulate_unknown_scenario_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["simulate", "moon_drive", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "moon_drive" in err[0]


def test_replay_writes_the_contract_report(short_bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "report"
    config = tmp_path / "cfg.yaml"
    config.write_text(yaml.safe_dump({"radius": {"n_particles": 200, "run_aug_kf": True}}))
    assert main(["replay", str(short_bag), "--out", str(out), "--config", str(config),
                 "--no-progress"]) == 0  # fmt: skip
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) >= CONTRACT_KEYS
    radii = metrics["radii"]
    assert set(radii["final_radius_error_m"]) == {"wheel_rl", "wheel_rr"}
    assert set(radii["rmse_vs_truth_m"]) == {"wheel_rl", "wheel_rr"}
    assert all(0 <= v < 3e-3 for v in radii["rmse_vs_truth_m"].values())
    assert radii["baseline"]["name"] == "AUG-KF"
    # a flat simulated road: the altitude's grade, confirmed by the IMU, and about zero
    grade = radii["road_grade"]
    assert grade["source_counts"]["altitude"] > 0.9 * sum(grade["source_counts"].values()) > 0
    assert grade["rms_deg"] < 1.0
    assert metrics["position"]["rmse_m"] < 5.0
    assert metrics["estimator"]["config"]["n_particles"] == 200
    assert isinstance(metrics["residuals"]["consistent"], bool)
    assert metrics["realtime_factor"] > 0
    assert {"radius_errors.png", "trajectory.png", "innovations.png"} <= set(metrics["plots"])
    for png in metrics["plots"]:
        assert (out / png).stat().st_size > 10_000


def _replay_error(bag: Path, out: Path, capsys: pytest.CaptureFixture[str]) -> str:
    (out).mkdir(parents=True, exist_ok=True)
    (out / "metrics.json").write_text("{}")  # a stale report must not survive a failed run
    code = main(["replay", str(bag), "--out", str(out), "--no-plots", "--no-progress"])
    assert code == 2
    assert not (out / "metrics.json").exists()
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tire-estimation: error:")
    return lines[0]


def test_replay_wrong_path(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _replay_error(tmp_path / "nope", tmp_path / "out", capsys)
    assert "nope" in msg


def test_replay_corrupt_bag(short_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    bad = tmp_path / "corrupt"
    shutil.copytree(short_bag, bad)
    for mcap in bad.glob("*.mcap"):
        mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 3])
    _replay_error(bad, tmp_path / "out", capsys)


def test_replay_absurd_vehicle(
    short_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    bad = tmp_path / "absurd"
    shutil.copytree(short_bag, bad)
    data = yaml.safe_load((bad / "vehicle.yaml").read_text())
    data["vehicle"]["nominal_tire_radius_m"] = 31.0
    (bad / "vehicle.yaml").write_text(yaml.safe_dump(data))
    msg = _replay_error(bad, tmp_path / "out", capsys)
    assert "nominal_tire_radius_m" in msg


def test_replay_missing_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tire_estimation.bag.writer import write_sim_bag
    from tire_estimation.sim import SensorConfig, simulate

    result = simulate("city", seed=1, minutes=0.2, sensors=SensorConfig())
    bag = write_sim_bag(result, tmp_path / "city")
    # drop the GNSS topic by rewriting the bag without it
    from rosbags.rosbag2 import Reader, Writer

    stripped = tmp_path / "nognss"
    with Reader(bag) as reader, Writer(stripped, version=9) as writer:
        conns = {}
        for conn in reader.connections:
            if conn.topic != "/gnss/fix":
                conns[conn.id] = writer.add_connection(conn.topic, conn.msgtype,
                                                       typestore=None, msgdef=conn.msgdef.data,
                                                       rihs01=conn.digest)  # fmt: skip
        for conn, t, raw in reader.messages():
            if conn.id in conns:
                writer.write(conns[conn.id], t, raw)
    shutil.copy(bag / "vehicle.yaml", stripped / "vehicle.yaml")
    msg = _replay_error(stripped, tmp_path / "out", capsys)
    assert "/gnss/fix" in msg


def test_replay_bad_config_names_the_field(
    short_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "cfg.yaml"
    config.write_text(yaml.safe_dump({"radius": {"forgetting_factor": 7}}))
    code = main(["replay", str(short_bag), "--out", str(tmp_path / "o"), "--config", str(config)])
    assert code == 2
    assert "forgetting_factor" in capsys.readouterr().err
