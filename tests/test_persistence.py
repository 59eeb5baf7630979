"""Persistence of learned estimates: round trip, identity check, bounded reading, and a corpus
of corrupt and hostile files restored through :func:`persistence.restore` (what the nodes do
at start): it never raises, leaves no NaN or implausible value, and names what it rejected."""

from __future__ import annotations

import copy
import json
import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.detector import DeflationDetector
from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.state_checks import radius_error_limit_m
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import StateFileError
from tire_estimation.persistence import (
    MAX_FILE_BYTES,
    Identity,
    LearnedState,
    delete_state,
    load_state,
    read_json,
    restore,
    save_state,
)

ID = Identity(vehicle_name="sim_sedan", tire_set_id="summer-2026")
VEHICLE = VehicleParams(name=ID.vehicle_name)
LIMIT_M = radius_error_limit_m(VEHICLE.nominal_tire_radius_m)  # 15.5 mm


def test_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "radii.json"
    save_state(path, ID, {"radius_error_m": [0.001, -0.0005], "dof": 12.0})
    state, reason = load_state(path, ID)
    assert state == {"radius_error_m": [0.001, -0.0005], "dof": 12.0}
    assert "found" in reason
    assert [p.name for p in path.parent.iterdir()] == ["radii.json"]


def test_save_fsyncs_the_file_and_its_directory(tmp_path: Path, monkeypatch) -> None:
    """Atomic against a killed process is not enough: the content and the rename must reach
    the disk before a power loss."""
    synced: list[Path] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        synced.append(Path(os.readlink(f"/proc/self/fd/{fd}")))
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    path = tmp_path / "radii.json"
    save_state(path, ID, {"x": 1})
    assert [p.parent for p in synced] == [tmp_path, tmp_path.parent]
    assert synced[0].name.startswith(".radii.json.") and synced[1] == tmp_path


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
    assert state is None and "unreadable" in reason and reason.startswith("rejected:")
    path.write_text(json.dumps({"format_version": 99}))
    assert load_state(path, ID)[0] is None


def test_non_finite_and_absurd_values_are_written_as_null_and_delete(tmp_path: Path) -> None:
    path = tmp_path / "radii.json"
    save_state(path, ID, {"v": [float("nan"), 1.0, 1e300, np.float32(2.0)]})
    assert json.loads(path.read_text())["state"]["v"] == [None, 1.0, None, 2.0]
    assert load_state(path, ID)[0] == {"v": [None, 1.0, None, 2.0]}  # readable again
    delete_state(path)
    assert not path.exists()
    delete_state(path)  # deleting twice is fine


def test_read_json_bounds(tmp_path: Path) -> None:
    path = tmp_path / "x.json"
    path.write_text('{"a": [1, 2.5, "[[[[{{{{", {"b": null}], "t": 1700000000000000000}')
    assert read_json(path) == {"a": [1, 2.5, "[[[[{{{{", {"b": None}], "t": 1700000000000000000}
    cases = {
        "[" * 17 + "]" * 17: "nested deeper",
        "9" * 21: "digits",
        "1e31": "outside",
        "NaN": "non-finite",
        '{"a": 1, "a": 2}': "duplicate key",
        "": "empty",
        "[1, 2": "not JSON",
    }
    for text, reason in cases.items():
        path.write_text(text)
        with pytest.raises(StateFileError, match=reason):
            read_json(path)
    path.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(StateFileError, match="UTF-8"):
        read_json(path)
    path.write_text(" " * 100 + "1")
    with pytest.raises(StateFileError, match="larger than 50 bytes"):
        read_json(path, max_bytes=50)


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
    path = tmp_path / "learned.json"
    save_state(
        path, ID, LearnedState({"radius": _Part(1.0), "stiffness": _Part(500.0)}).state_dict()
    )
    radius, stiffness = _Part(0.0), _Part(0.0)
    learned = LearnedState({"radius": radius, "stiffness": stiffness})
    state, _ = load_state(path, ID)
    assert state is not None
    learned.load_state_dict(state)
    assert radius.value == 1.0  # restored although the stiffness part was rejected
    assert stiffness.value == 0.0
    assert learned.notes == {"radius": "restored", "stiffness": "rejected: absurd value"}
    # a part whose estimator is not running is kept and written back unchanged
    only_radius = LearnedState({"radius": _Part(0.0), "stiffness": None})
    only_radius.load_state_dict({"radius": {"value": 2.0}, "stiffness": {"value": 7.0}})
    assert only_radius.state_dict() == {"radius": {"value": 2.0}, "stiffness": {"value": 7.0}}
    assert "kept" in only_radius.summary()
    # a key that names no part is rejected, not kept
    other = LearnedState({"radius": _Part(0.0)})
    other.load_state_dict({"radius": {"value": 2.0}, "junk": {"value": 1.0}})
    assert other.notes == {"radius": "restored", "junk": "rejected: unknown part"}
    assert other.state_dict() == {"radius": {"value": 2.0}}


def test_learned_state_reads_a_radius_only_file_of_the_old_format() -> None:
    radius, stiffness = _Part(0.0), _Part(0.0)
    learned = LearnedState({"radius": radius, "stiffness": stiffness})
    learned.load_state_dict({"value": 3.0, "rear": 1.0})  # top-level radius state (key "rear")
    assert radius.value == 3.0
    assert learned.notes == {"radius": "restored", "stiffness": "not in the file"}


# --- the corpus: corrupt and hostile estimator files -----------------------------------------
def _pipeline() -> EstimationPipeline:
    return EstimationPipeline(
        PipelineConfig(
            seed=0,
            radius=RadiusEstimatorConfig(n_particles=50),
            stiffness=StiffnessEstimatorConfig(n_particles=20),
        ),
        VEHICLE,
    )


def _learned(p: EstimationPipeline) -> LearnedState:
    return LearnedState({"radius": p.radius, "stiffness": p.stiffness})


def _good_state() -> dict[str, Any]:
    """A distinctive valid state: rear radius errors +1 / -0.5 mm, a learned stiffness."""
    learned = _learned(_pipeline())
    state = learned.state_dict()
    state["radius"]["rear"]["mean_m"] = [1e-3, -0.5e-3]
    state["radius"]["rear"]["dof"] = 250.0
    state["stiffness"]["mean"] = [5e3, -8e3, 4e3]
    return json.loads(json.dumps(state))


GOOD = _good_state()
PRIOR = json.loads(json.dumps(_learned(_pipeline()).state_dict()))


def _payload(state: Any, **top: Any) -> dict[str, Any]:
    return {
        "format_version": 1,
        "vehicle_name": ID.vehicle_name,
        "tire_set_id": ID.tire_set_id,
        "saved_unix_s": 1.7e9,
        "state": state,
        **top,
    }


def _text(state: Any = None, **top: Any) -> str:
    return json.dumps(_payload(GOOD if state is None else state, **top), indent=1)


def _edit(change: Callable[[dict[str, Any]], None]) -> str:
    state = copy.deepcopy(GOOD)
    change(state)
    return _text(state)


def _set(part: str, *keys_value: Any) -> str:
    *keys, value = keys_value

    def change(state: dict[str, Any]) -> None:
        d = state[part]
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return _edit(change)


def _drop(part: str, *keys: str) -> str:
    def change(state: dict[str, Any]) -> None:
        d = state[part]
        for k in keys[:-1]:
            d = d[k]
        del d[keys[-1]]

    return _edit(change)


def _replace_in(text: str, old: str, new: str) -> str:
    assert old in text
    return text.replace(old, new, 1)


@dataclass(frozen=True)
class Case:
    """A hostile file, the parts that must come back as the prior (``radius``, ``stiffness``;
    both when the whole file is rejected), and what the note must say."""

    name: str
    content: bytes | str
    prior: tuple[str, ...]
    reason: str
    rejected: bool = True


BOTH = ("radius", "stiffness")
RADIUS = ("radius",)
STIFF = ("stiffness",)
_GOOD_TEXT = _text()
_NOISE = [[1e-6, 0.0], [0.0, 1e-6]]


def _corpus() -> list[Case]:
    rng = np.random.default_rng(38)
    dof_line = '"dof": 250.0'
    return [
        # the file as a whole
        Case("empty file", "", BOTH, "empty"),
        Case("whitespace only", " \n\t ", BOTH, "empty"),
        Case("truncated JSON", _GOOD_TEXT[: len(_GOOD_TEXT) // 2], BOTH, "not JSON"),
        Case("truncated after the last brace", _GOOD_TEXT.rstrip()[:-1], BOTH, "not JSON"),
        Case("binary garbage", rng.bytes(4096), BOTH, "unreadable"),
        Case("NUL bytes", b"\x00" * 64, BOTH, "not JSON"),
        Case("huge file", _GOOD_TEXT + " " * MAX_FILE_BYTES, BOTH, "larger than"),
        Case("deeply nested arrays", "[" * 100_000 + "]" * 100_000, BOTH, "nested deeper"),
        Case(
            "deep nesting inside the state",
            _replace_in(_GOOD_TEXT, dof_line, '"dof": ' + "[" * 5000 + "]" * 5000),
            BOTH,
            "nested deeper",
        ),
        Case("deeply nested objects", '{"a":' * 50 + "1" + "}" * 50, BOTH, "nested deeper"),
        Case(
            "unterminated string of 500k escaped quotes",  # read in one pass, not quadratic
            '"' + '\\"' * (MAX_FILE_BYTES // 2 - 1),
            BOTH,
            "not JSON",
        ),
        Case(
            "500-digit integer dof",
            _replace_in(_GOOD_TEXT, dof_line, '"dof": ' + "9" * 500),
            BOTH,
            "500 digits",
        ),
        Case(
            "500-digit negative integer", _text(saved_unix_s=int("-" + "7" * 500)), BOTH, "digits"
        ),
        Case("dof 1e308", _replace_in(_GOOD_TEXT, dof_line, '"dof": 1e308'), BOTH, "outside"),
        Case("mean 1e308 m", _replace_in(_GOOD_TEXT, "0.001", "1e308"), BOTH, "outside"),
        Case(
            "number overflowing to inf",
            _replace_in(_GOOD_TEXT, dof_line, '"dof": 1e999'),
            BOTH,
            "outside",
        ),
        Case("NaN literal", _replace_in(_GOOD_TEXT, dof_line, '"dof": NaN'), BOTH, "NaN"),
        Case(
            "Infinity literal",
            _replace_in(_GOOD_TEXT, dof_line, '"dof": Infinity'),
            BOTH,
            "Infinity",
        ),
        Case(
            "-Infinity literal", _replace_in(_GOOD_TEXT, "0.001", "-Infinity"), BOTH, "-Infinity"
        ),
        Case(
            "duplicate key",
            _replace_in(_GOOD_TEXT, dof_line, '"dof": 250.0, "dof": 3.5'),
            BOTH,
            "duplicate key",
        ),
        Case("top level is an array", json.dumps([_payload(GOOD)]), BOTH, "not an object"),
        Case("top level is a number", "42", BOTH, "not an object"),
        Case("unknown format version", _text(format_version=2), BOTH, "unknown format"),
        Case("format version true", _text(format_version=True), BOTH, "unknown format"),
        Case(
            "missing state",
            json.dumps({k: v for k, v in _payload(GOOD).items() if k != "state"}),
            BOTH,
            "missing",
        ),
        Case("extra top-level key", _text(comment="hi"), BOTH, "unknown keys"),
        Case("vehicle name a number", _text(vehicle_name=7), BOTH, "no valid identity"),
        Case("state is a list", _text([GOOD]), BOTH, "hold no state"),
        Case("wrong vehicle", _text(vehicle_name="truck"), BOTH, "for vehicle", False),
        Case("wrong tire set", _text(tire_set_id="winter"), BOTH, "for tire set", False),
        Case("brackets inside strings", _text(vehicle_name="[{" * 40), BOTH, "for vehicle", False),
        # the radius part
        Case(
            "zero noise covariance",
            _set("radius", "rear", "noise_cov_m2", [[0, 0], [0, 0]]),
            RADIUS,
            "not positive definite",
        ),
        Case(
            "negative noise covariance",
            _set("radius", "rear", "noise_cov_m2", [[-1e-6, 0], [0, -1e-6]]),
            RADIUS,
            "not positive definite",
        ),
        Case(
            "indefinite mean covariance",
            _set("radius", "rear", "mean_cov_m2", [[1e-6, 2e-6], [2e-6, 1e-6]]),
            RADIUS,
            "not positive definite",
        ),
        Case(
            "asymmetric covariance",
            _set("radius", "rear", "noise_cov_m2", [[1e-6, 5e-7], [0.0, 1e-6]]),
            RADIUS,
            "not symmetric",
        ),
        Case(
            "covariance of metres",
            _set("radius", "rear", "noise_cov_m2", [[1.0, 0], [0, 1.0]]),
            RADIUS,
            "standard deviations",
        ),
        Case(
            "vanishing covariance",
            _set("radius", "rear", "noise_cov_m2", [[1e-40, 0], [0, 1e-40]]),
            RADIUS,
            "standard deviations",
        ),
        Case("dof 1e12", _set("radius", "rear", "dof", 1e12), RADIUS, "dof"),
        Case("dof 3", _set("radius", "rear", "dof", 3), RADIUS, "dof"),
        Case("dof a string", _set("radius", "rear", "dof", "many"), RADIUS, "not a number"),
        Case("dof a bool", _set("radius", "rear", "dof", True), RADIUS, "not a number"),
        Case("radius +100 mm", _set("radius", "rear", "mean_m", [0.1, 0.0]), RADIUS, "outside"),
        Case("radius -100 mm", _set("radius", "rear", "mean_m", [0.0, -0.1]), RADIUS, "outside"),
        Case("radius 1e29 m", _set("radius", "rear", "mean_m", [1e29, 0.0]), RADIUS, "outside"),
        Case(
            "mean of wrong length", _set("radius", "rear", "mean_m", [0.001]), RADIUS, "list of 2"
        ),
        Case(
            "3 x 3 covariance",
            _set("radius", "rear", "mean_cov_m2", np.eye(3).tolist()),
            RADIUS,
            "2 x 2",
        ),
        Case(
            "ragged covariance",
            _set("radius", "rear", "mean_cov_m2", [[1e-6], [0, 1e-6]]),
            RADIUS,
            "list of 2",
        ),
        Case("missing dof", _drop("radius", "rear", "dof"), RADIUS, "lacks dof"),
        Case("missing rear", _drop("radius", "rear"), RADIUS, "lacks rear"),
        Case(
            "extra key in the axle",
            _set("radius", "rear", "bias", 1.0),
            RADIUS,
            "unknown keys bias",
        ),
        Case(
            "radius state of another vehicle",
            _set("radius", "vehicle", "truck"),
            RADIUS,
            "vehicle",
        ),
        Case(
            "wheels swapped",
            _set("radius", "rear", "wheels", ["wheel_rr", "wheel_rl"]),
            RADIUS,
            "wheels",
        ),
        Case("radius state version 2", _set("radius", "version", 2), RADIUS, "version"),
        Case("rear is a string", _set("radius", "rear", "rear"), RADIUS, "not an object"),
        Case(
            "radius part null",
            _edit(lambda s: s.__setitem__("radius", None)),
            RADIUS,
            "not an object",
        ),
        Case(
            "aug_kf mean 0.5 m",
            _set("radius", "aug_kf", {"mean_m": [0.5, 0.0], "cov_m2": _NOISE}),
            RADIUS,
            "aug_kf.mean_m",
        ),
        Case(
            "old radius-only format, -100 mm",
            _text(_set_in(GOOD["radius"], "rear", "mean_m", [-0.1, 0.0])),
            BOTH,
            "outside",
        ),
        # the stiffness part
        Case(
            "stiffness 10x nominal",
            _set("stiffness", "mean", [1.5e6, 0.0, 0.0]),
            STIFF,
            "stiffness bounds",
        ),
        Case(
            "stiffness zero noise covariance",
            _set("stiffness", "noise_cov", np.zeros((3, 3)).tolist()),
            STIFF,
            "not positive definite",
        ),
        Case("stiffness dof 2", _set("stiffness", "dof", 2.0), STIFF, "dof"),
        Case(
            "stiffness of other nominal values",
            _set("stiffness", "nominal", [1.0, 1.0, 1.0]),
            STIFF,
            "nominal stiffness",
        ),
        Case(
            "stiffness names swapped",
            _set("stiffness", "names", ["cy_front", "cx_front", "cy_rear"]),
            STIFF,
            "names",
        ),
        Case(
            "stiffness mean of strings",
            _set("stiffness", "mean", ["a", "b", "c"]),
            STIFF,
            "not a number",
        ),
        # parts
        Case(
            "unknown part",
            _edit(lambda s: s.__setitem__("gearbox", {"x": 1})),
            (),
            "gearbox rejected: unknown part",
        ),
    ]


def _set_in(d: dict[str, Any], *keys_value: Any) -> dict[str, Any]:
    out = copy.deepcopy(d)
    *keys, value = keys_value
    target = out
    for k in keys[:-1]:
        target = target[k]
    target[keys[-1]] = value
    return out


CORPUS = _corpus()


def test_the_corpus_has_at_least_40_distinct_files() -> None:
    assert len(CORPUS) >= 40
    assert len({c.name for c in CORPUS}) == len(CORPUS)
    assert len({c.content for c in CORPUS}) == len(CORPUS)


def _finite(x: Any) -> bool:
    return bool(np.all(np.isfinite(np.asarray(x, dtype=float))))


@pytest.mark.parametrize("case", CORPUS, ids=[c.name for c in CORPUS])
def test_a_hostile_file_is_rejected_by_name_and_the_estimators_keep_their_prior(
    tmp_path: Path, case: Case
) -> None:
    path = tmp_path / "learned.json"
    if isinstance(case.content, bytes):
        path.write_bytes(case.content)
    else:
        path.write_text(case.content)
    p = _pipeline()
    learned = _learned(p)
    outcome = restore(path, ID, learned, "estimates")  # never raises
    assert outcome.rejected == case.rejected, outcome.note
    assert case.reason in outcome.note
    if case.rejected:
        assert "rejected" in outcome.note
    for part in ("radius", "stiffness"):
        if part not in case.prior:
            assert learned.notes[part] == "restored"
        elif learned.notes:  # read, and this part rejected (or absent from an old file)
            assert learned.notes[part].startswith(("rejected", "not in the file"))
    rear = GOOD if "radius" not in case.prior else PRIOR
    np.testing.assert_allclose(
        p.radius.estimate().radius_error_m, rear["radius"]["rear"]["mean_m"], atol=1e-4
    )
    stiffness = GOOD if "stiffness" not in case.prior else PRIOR
    np.testing.assert_allclose(
        p.stiffness.state_dict()["mean"], stiffness["stiffness"]["mean"], atol=1.0
    )
    # nothing non-finite or implausible anywhere in the filters or what they publish
    est = p.radius.estimate()
    assert _finite(est.radius_error_m) and np.all(np.abs(est.radius_error_m) <= LIMIT_M)
    assert _finite(est.radius_error_std_m) and np.all(est.radius_error_std_m < LIMIT_M)
    stats = p.radius.mpf.stats
    assert all(_finite(a) for a in (stats.mean, stats.scale, stats.gamma, stats.dof))
    assert float(stats.dof) < 1e9 and np.all(np.linalg.eigvalsh(stats.scale) > 0.0)
    st = p.stiffness.mpf.stats
    assert all(_finite(a) for a in (st.mean, st.scale, st.gamma, st.dof))
    assert np.all(np.linalg.eigvalsh(st.scale) > 0.0)
    assert not any(n.startswith(".") for n in (q.name for q in tmp_path.iterdir()))


def test_the_good_state_restores(tmp_path: Path) -> None:
    path = tmp_path / "learned.json"
    path.write_text(_GOOD_TEXT)
    p = _pipeline()
    outcome = restore(path, ID, _learned(p), "estimates")
    assert not outcome.rejected
    assert outcome.note.endswith("radius restored, stiffness restored")
    np.testing.assert_allclose(p.radius.estimate().radius_error_m, [1e-3, -0.5e-3], atol=1e-4)


def test_the_radius_band_follows_the_nominal_radius(tmp_path: Path) -> None:
    """+100 mm is implausible on a 0.31 m tyre (band 77.5 mm), plausible on a 0.5 m one (125
    mm)."""
    path = tmp_path / "learned.json"
    state = _set_in(GOOD["radius"], "rear", "mean_m", [0.1, 0.0])
    path.write_text(_text({"radius": {**state, "vehicle": "big"}}, vehicle_name="big"))
    big = VehicleParams(name="big", nominal_tire_radius_m=0.5)
    p = EstimationPipeline(
        PipelineConfig(seed=0, radius=RadiusEstimatorConfig(n_particles=50)), big
    )
    outcome = restore(path, Identity("big", ID.tire_set_id), _learned(p), "estimates")
    assert not outcome.rejected, outcome.note
    assert p.radius.estimate().radius_error_m[0] == pytest.approx(0.1, abs=1e-4)


def test_stale_temporary_files_are_removed_at_start(tmp_path: Path) -> None:
    path = tmp_path / "learned.json"
    path.write_text(_GOOD_TEXT)
    for name in (".learned.json.999999999.ab12.tmp", "learned.jsonx1y2z3w4.tmp"):
        (tmp_path / name).write_text(_GOOD_TEXT[:100])
    outcome = restore(path, ID, _learned(_pipeline()), "estimates")
    assert outcome.removed_temps == 2 and not outcome.rejected
    assert [q.name for q in tmp_path.iterdir()] == ["learned.json"]


# --- the detector's file ----------------------------------------------------------------------
def _detector_state(**wheel: Any) -> dict[str, Any]:
    rl = {
        "calib_time_s": 1200.0,
        "calib_sum_w": 300.0,
        "calib_sum_wx": 300.0 * 3e-4,
        "calibrated_m": 3e-4,
        "calibration_t_ns": 1_700_000_000_000_000_000,
        "common_sum_w": 900.0,
        "common_sum_wx": 900.0 * 3e-4,
        "common_calibrated_m": 3e-4,
        "lp_m": 1e-4,
        "xbar_m": 1e-4,
        "raw_m": 2e-4,
        "g_m": 1e-3,
        "threshold_m": 9e-3,
        "alarm_t_ns": None,
        "last_estimate_m": 2e-4,
        **wheel,
    }
    return {
        "version": 1,
        "driving_time_s": 1500.0,
        "t_last_ns": 1_700_000_000_500_000_000,
        "wheels": {"wheel_rl": rl},
        "common": {"wheel_names": [], "lp_m": 0.0, "xbar_m": 0.0, "raw_m": 0.0, "g_m": 0.0},
    }


DETECTOR_CASES = [
    (
        "500-digit calibration time",
        json.dumps(_payload(_detector_state())).replace(
            '"calib_time_s": 1200.0', '"calib_time_s": ' + "9" * 500
        ),
        "digits",
    ),
    ("calibrated +100 mm", _text(_detector_state(calibrated_m=0.1)), "calibrated_m"),
    ("calibrated 1e29 m", _text(_detector_state(calibrated_m=1e29)), "calibrated_m"),
    ("negative CUSUM", _text(_detector_state(g_m=-1.0)), "g_m"),
    ("CUSUM beyond the driving time", _text(_detector_state(g_m=5000.0)), "g_m"),
    ("negative calibration time", _text(_detector_state(calib_time_s=-5.0)), "calib_time_s"),
    (
        "weights beyond the calibration time",
        _text(_detector_state(calib_sum_w=5000.0)),
        "calib_sum_w",
    ),
    ("weighted sum of a 1 m mean", _text(_detector_state(calib_sum_wx=300.0)), "calib_sum_wx"),
    ("stamp beyond int64", _text(_detector_state(alarm_t_ns=1 << 64)), "alarm_t_ns"),
    ("stamp a float", _text(_detector_state(alarm_t_ns=1.5)), "alarm_t_ns"),
    ("unknown wheel key", _text(_detector_state(pressure_kpa=220.0)), "unknown keys"),
    ("deeply nested", "[" * 100_000, "nested deeper"),
    ("NaN literal", _text(_detector_state()).replace("0.0003", "NaN", 1), "NaN"),
]


@pytest.mark.parametrize(
    ("content", "reason"), [c[1:] for c in DETECTOR_CASES], ids=[c[0] for c in DETECTOR_CASES]
)
def test_a_hostile_detector_file_is_rejected_and_the_detector_stays_uncalibrated(
    tmp_path: Path, content: str, reason: str
) -> None:
    path = tmp_path / "deflation.json"
    path.write_text(content)
    det = DeflationDetector(DeflationDetectorConfig(), VEHICLE.nominal_tire_radius_m)
    outcome = restore(path, ID, det, "detector state")
    assert outcome.rejected and reason in outcome.note and "rejected" in outcome.note
    assert det.state_dict() == DeflationDetector().state_dict()  # the prior: nothing restored


def test_the_good_detector_state_restores(tmp_path: Path) -> None:
    path = tmp_path / "deflation.json"
    path.write_text(_text(_detector_state()))
    det = DeflationDetector(DeflationDetectorConfig(), VEHICLE.nominal_tire_radius_m)
    outcome = restore(path, ID, det, "detector state")
    assert not outcome.rejected and outcome.note.startswith("restored")
    rl = det.status().wheel("wheel_rl")
    assert rl.calibrated and rl.calibrated_radius_error_m == pytest.approx(3e-4)
    assert math.isfinite(rl.cusum_m)
