"""Persistence of learned estimates: round trip, identity check, corrupt files."""

from __future__ import annotations

import json
from pathlib import Path

from tire_estimation.persistence import Identity, delete_state, load_state, save_state

ID = Identity(vehicle_name="sim_sedan", tire_set_id="summer-2026")


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "radii.json"
    save_state(path, ID, {"radius_error_m": [0.001, -0.0005], "dof": 12.0})
    state, reason = load_state(path, ID)
    assert state == {"radius_error_m": [0.001, -0.0005], "dof": 12.0}
    assert "restored" in reason


def test_other_tire_set_or_vehicle_is_not_restored(tmp_path: Path) -> None:
    path = tmp_path / "radii.json"
    save_state(path, ID, {"x": 1})
    state, reason = load_state(path, Identity("sim_sedan", "winter-2026"))
    assert state is None and "tire set" in reason
    state, reason = load_state(path, Identity("truck", "summer-2026"))
    assert state is None and "vehicle" in reason


def test_corrupt_and_missing_files(tmp_path: Path) -> None:
    path = tmp_path / "radii.json"
    assert load_state(path, ID)[0] is None
    path.write_text("{not json")
    state, reason = load_state(path, ID)
    assert state is None and "unreadable" in reason
    path.write_text(json.dumps({"format_version": 99}))
    assert load_state(path, ID)[0] is None


def test_non_finite_values_are_written_as_null_and_delete(tmp_path: Path) -> None:
    path = tmp_path / "radii.json"
    save_state(path, ID, {"v": [float("nan"), 1.0]})
    assert json.loads(path.read_text())["state"]["v"] == [None, 1.0]
    delete_state(path)
    assert not path.exists()
    delete_state(path)  # deleting twice is fine
