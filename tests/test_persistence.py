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


class _Part:
    """A stand-in estimator: ``state_dict`` / ``load_state_dict`` with a validity check."""

    def __init__(self, value: float) -> None:
        self.value = value

    def state_dict(self) -> dict[str, float]:
        return {"value": self.value, "rear": 1.0} if self.value < 0 else {"value": self.value}

    def load_state_dict(self, d: dict[str, float]) -> None:
        if d["value"] > 100.0:
            raise ValueError("absurd value")
        self.value = d["value"]


def test_learned_state_restores_parts_independently(tmp_path: Path) -> None:
    from tire_estimation.persistence import LearnedState

    path = tmp_path / "learned.json"
    save_state(
        path, ID, LearnedState({"radius": _Part(1.0), "stiffness": _Part(500.0)}).state_dict()
    )
    radius, stiffness = _Part(0.0), _Part(0.0)
    learned = LearnedState({"radius": radius, "stiffness": stiffness})
    state, _ = load_state(path, ID)
    learned.load_state_dict(state)
    assert radius.value == 1.0  # restored although the stiffness part was rejected
    assert stiffness.value == 0.0
    assert learned.notes == {"radius": "restored", "stiffness": "rejected: absurd value"}
    # a part whose estimator is not running is kept and written back unchanged
    only_radius = LearnedState({"radius": _Part(0.0), "stiffness": None})
    only_radius.load_state_dict({"radius": {"value": 2.0}, "stiffness": {"value": 7.0}})
    assert only_radius.state_dict() == {"radius": {"value": 2.0}, "stiffness": {"value": 7.0}}
    assert "kept" in only_radius.summary()


def test_learned_state_reads_a_radius_only_file_of_the_old_format() -> None:
    from tire_estimation.persistence import LearnedState

    radius, stiffness = _Part(0.0), _Part(0.0)
    learned = LearnedState({"radius": radius, "stiffness": stiffness})
    learned.load_state_dict({"value": 3.0, "rear": 1.0})  # top-level radius state (key "rear")
    assert radius.value == 3.0
    assert learned.notes == {"radius": "restored", "stiffness": "not in the file"}
