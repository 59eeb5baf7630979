"""``tire-estimation replay DIR`` / ``BAG1 BAG2 ...``: a fleet's bags on a Dask cluster, a
report per bag and the pooled table; a bag that fails is a row with its error."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import pytest

from tests.bag.synthetic import make_result
from tire_estimation.bag.writer import write_sim_bag
from tire_estimation.cli import main
from tire_estimation.errors import BagError
from tire_estimation.fleet import find_bags, is_fleet, markdown, report_names


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two synthetic drives of one car and a bag whose MCAP file is cut short."""
    root = tmp_path_factory.mktemp("fleet")
    write_sim_bag(make_result(6.0, seed=1, with_forces=False), root / "day1" / "drive_a")
    write_sim_bag(make_result(6.0, seed=2, with_forces=False), root / "day2" / "drive_b")
    shutil.copytree(root / "day1" / "drive_a", root / "day2" / "broken")
    mcap = next((root / "day2" / "broken").glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[:5000])
    return root


def test_bags_are_found_under_a_directory_and_named_apart(fleet: Path, tmp_path: Path) -> None:
    bags = find_bags([fleet])
    assert [b.name for b in bags] == ["drive_a", "broken", "drive_b"]
    assert is_fleet([fleet]) and is_fleet(bags[:2])
    assert not is_fleet([bags[0]]) and not is_fleet([tmp_path])  # a bag; no bag at all
    assert report_names([bags[0], bags[0], bags[1]]) == ["drive_a_1", "drive_a_2", "broken"]
    (tmp_path / "empty").mkdir()
    with pytest.raises(BagError, match="no rosbag2 bag"):
        find_bags([bags[0], tmp_path / "empty"])


def test_a_fleet_replays_on_a_local_cluster(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "out"
    argv = ["replay", str(fleet), "--out", str(out), "--no-stiffness", "--no-plots"]
    assert main([*argv, "--workers", "2"]) == 2  # one bag failed
    printed = capsys.readouterr()
    progress = [line for line in printed.out.splitlines() if line.startswith("[")]
    assert len(progress) == 3 and any("broken: FAILED: BagError" in p for p in progress)
    err = printed.err.strip().splitlines()
    assert len(err) == 1 and "1 of 3 bags failed" in err[0]
    for name in ("drive_a", "drive_b"):
        metrics = json.loads((out / name / "metrics.json").read_text())
        assert metrics["bag"].endswith(name)
    assert not (out / "broken" / "metrics.json").exists()
    with (out / "fleet.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert [Path(r["bag"]).name for r in rows] == ["drive_a", "drive_b", "broken"]
    assert [r["status"] for r in rows] == ["ok", "ok", "failed"]
    assert rows[0]["vehicle"] == "test_car" and "cannot read bag" in rows[2]["error"]
    text = (out / "fleet.md").read_text()
    assert "## test_car" in text and "## Failed" in text and "3 bags, 1 failed" in text


def test_a_running_scheduler_takes_the_bags(fleet: Path, tmp_path: Path) -> None:
    from tire_estimation.evaluation.campaign.execute import local_cluster

    bags = [str(fleet / "day1" / "drive_a"), str(fleet / "day2" / "drive_b")]
    with local_cluster(1, threads=True) as cluster:
        argv = ["replay", *bags, "--out", str(tmp_path), "--no-stiffness", "--no-plots"]
        assert main([*argv, "--scheduler", cluster.scheduler_address]) == 0
    assert (tmp_path / "drive_b" / "metrics.json").is_file()


def test_scheduler_without_a_fleet_is_an_error(
    fleet: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = fleet / "day1" / "drive_a"
    argv = ["replay", str(bag), "--out", str(tmp_path), "--scheduler", "tcp://127.0.0.1:1"]
    assert main(argv) == 2
    assert "--scheduler replays a fleet" in capsys.readouterr().err


def test_markdown_groups_by_vehicle_in_time_order() -> None:
    rows = [
        {"bag": "b/late", "status": "ok", "vehicle": "car", "start_ns": 2, "duration_s": 60.0,
         "wheel_rl_mm": 1.0, "wheel_rl_std_mm": 0.1, "alarms": "none", "consistent": True,
         "position_rmse_m": 1.5},
        {"bag": "b/early", "status": "ok", "vehicle": "car", "start_ns": 1, "duration_s": 60.0,
         "wheel_rl_mm": 0.5, "wheel_rl_std_mm": 0.1, "alarms": "wheel_rl@30s",
         "consistent": False, "position_rmse_m": None},
    ]  # fmt: skip
    from tire_estimation.fleet import _by_vehicle

    text = markdown(_by_vehicle(rows))
    lines = [line for line in text.splitlines() if line.startswith("| ")]
    assert lines[0].startswith("| bag | duration s | wheel_rl mm | alarms |")
    assert lines[1].startswith("| early |") and "+0.500 ± 0.100" in lines[1]
    assert "wheel_rl@30s" in lines[1] and lines[2].startswith("| late |")
    assert "## car" in text and "Failed" not in text
