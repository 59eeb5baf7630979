"""The replay scores the pose against ``/reference/odometry`` with the contract's origin."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import main

ROOT = Path(__file__).resolve().parents[1]
KEY = "tire_estimation.reference_origin_lla"


def _replay(bag: Path, out: Path) -> dict:
    argv = ["replay", str(bag), "--out", str(out), "--no-progress", "--no-stiffness", "--no-plots"]
    assert main(argv) == 0
    return json.loads((out / "metrics.json").read_text())["position"]


def _with_origin(tmp_path: Path, origin: str | None) -> Path:
    bag = tmp_path / "bag"
    shutil.copytree(ROOT / "bags" / "comma2k19_rav4_seg40", bag)
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    custom = meta["rosbag2_bagfile_information"]["custom_data"]
    if origin is None:
        custom.pop(KEY)
    else:
        custom[KEY] = origin
    meta_path.write_text(yaml.safe_dump(meta))
    return bag


def test_without_the_origin_key_the_first_fix_is_the_origin(tmp_path: Path) -> None:
    """No key: the same figure as with the key set to the first fix; a key 100 m north of it
    moves the error by about 100 m."""
    from tire_estimation.bag.reader import read_bag

    gnss = read_bag(ROOT / "bags" / "comma2k19_rav4_seg40").gnss
    assert gnss is not None
    lat, lon, alt = float(gnss.lat_deg[0]), float(gnss.lon_deg[0]), float(gnss.alt_m[0])
    without = _replay(_with_origin(tmp_path / "a", None), tmp_path / "a_out")
    assert without["against"] == "/reference/odometry"
    first_fix = _replay(
        _with_origin(tmp_path / "b", f"{lat!r} {lon!r} {alt!r}"), tmp_path / "b_out"
    )
    assert without["rmse_m"] == first_fix["rmse_m"]
    shifted = f"{lat + 100.0 / 111_000.0!r} {lon!r} {alt!r}"
    moved = _replay(_with_origin(tmp_path / "c", shifted), tmp_path / "c_out")
    assert 90.0 < moved["rmse_m"] < 110.0


def test_a_malformed_origin_is_one_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = _with_origin(tmp_path, "north pole")
    argv = ["replay", str(bag), "--out", str(tmp_path / "o"), "--no-progress", "--no-stiffness"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reference_origin_lla" in err[0]
