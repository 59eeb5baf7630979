"""A corpus of bad command lines and bad files: each ends in one line on stderr and exit 2.

For every case: exit status 2, exactly one stderr line of at most 300 characters, no
traceback, no report of an earlier run left in ``--out`` (``metrics.json`` and the plots), and
for a misspelled key the message names the nearest valid one. The cases run in-process through
:func:`tire_estimation.cli.main` on a small synthetic bag.

``python -m tests.test_cli_errors`` runs the corpus without pytest and prints how many cases
end in a traceback, a multi-line or over-long message, silent acceptance (the setting is
ignored), a stale report or a message without the expected words.
"""

from __future__ import annotations

import contextlib
import difflib
import io
import os
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from tire_estimation.cli import main

MAX_LINE = 300
#: what a replay writes in --out; a failed run must leave none of them from an earlier run
REPORT_FILES = (
    "metrics.json",
    "radius_errors.png",
    "trajectory.png",
    "innovations.png",
    "detection.png",
    "lateral_state.png",
    "stiffness.png",
)
#: a YAML "billion laughs": nine aliases per level, 9**6 leaves (a 4 MB repr) when expanded
_LEVELS = ["&a [" + ", ".join(["lol"] * 9) + "]"] + [
    f"&{c} [{', '.join(['*' + p] * 9)}]" for p, c in zip("abcde", "bcdef", strict=True)
]
ALIAS_BOMB = "".join(f"{level[1]}: {level}\n" for level in _LEVELS)
FLOW_BOMB = "[" + ", ".join(_LEVELS) + "]"


class World:
    """A synthetic bag and factories of bad variants of it, configs and output folders."""

    def __init__(self, root: Path) -> None:
        from tests.bag.synthetic import make_result
        from tire_estimation.bag.writer import write_sim_bag

        self.root = root
        self.base = write_sim_bag(make_result(4.0), root / "base")
        self.vehicle_text = (self.base / "vehicle.yaml").read_text()
        self.sim_text = (self.base / "sim_config.yaml").read_text()
        self._n = 0

    def _new(self, stem: str) -> Path:
        self._n += 1
        return self.root / f"{stem}{self._n}"

    def bag(self, **files: str | bytes) -> str:
        """A bag whose ``vehicle.yaml`` / ``sim_config.yaml`` (keyword ``vehicle`` / ``sim``)
        are replaced; the other files are links to the base bag's."""
        if not files:
            return str(self.base)
        names = {"vehicle": "vehicle.yaml", "sim": "sim_config.yaml"}
        bag = self._new("bag")
        bag.mkdir()
        replaced = {names[k]: v for k, v in files.items()}
        for f in self.base.iterdir():
            if f.name not in replaced:
                (bag / f.name).symlink_to(f)
        for name, content in replaced.items():
            if isinstance(content, bytes):
                (bag / name).write_bytes(content)
            else:
                (bag / name).write_text(content)
        return str(bag)

    def file(self, content: str | bytes, suffix: str = ".yaml") -> str:
        path = self._new("file").with_suffix(suffix)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content)
        return str(path)

    def dir(self) -> str:
        path = self._new("dir")
        path.mkdir()
        return str(path)

    def out(self) -> str:
        """An output folder holding the report of an earlier run."""
        out = self._new("out")
        out.mkdir()
        for name in REPORT_FILES:
            (out / name).write_text("{}" if name.endswith(".json") else "png")
        return str(out)

    def replay(self, *extra: str, bag: str | None = None, config: str | None = None) -> list[str]:
        argv = ["replay", bag or self.bag(), "--out", self.out(), "--no-plots", "--no-progress"]
        if config is not None:
            argv += ["--config", config]
        return argv + list(extra)


@dataclass(frozen=True)
class Case:
    """One bad command line: ``build(world)`` gives argv; ``expect``: words of the message."""

    id: str
    build: Callable[[World], list[str]]
    expect: tuple[str, ...] = ()


CASES: list[Case] = []


def case(id: str, build: Callable[[World], list[str]], *expect: str) -> None:
    assert all(c.id != id for c in CASES), id
    CASES.append(Case(id, build, expect))


def config_case(id: str, text: str | bytes, *expect: str) -> None:
    case(id, lambda w: w.replay(config=w.file(text)), *expect)


def vehicle_case(id: str, text: str | bytes, *expect: str) -> None:
    case(id, lambda w: w.replay(bag=w.bag(vehicle=text)), *expect)


def sim_case(id: str, text: str | bytes, *expect: str) -> None:
    case(id, lambda w: w.replay(bag=w.bag(sim=text)), *expect)


def misspell(name: str, valid: list[str]) -> str:
    """A misspelling of ``name`` whose nearest valid name is ``name``."""
    for candidate in (name[:-1], name + name[-1], name[:2] + name[3:], name.replace("_", "", 1)):
        if candidate in valid or not candidate:
            continue
        if difflib.get_close_matches(candidate, valid, n=1) == [name]:
            return candidate
    raise AssertionError(f"no unambiguous misspelling of {name}")


def vehicle_yaml(**changes: object) -> str:
    """vehicle.yaml of the synthetic bag with ``changes`` in its ``vehicle`` mapping (a
    string value is written as is, so that it can hold YAML)."""
    import yaml

    from tire_estimation.core.vehicle import VehicleParams

    data = VehicleParams(name="test_car").to_dict()
    lines = yaml.safe_dump({"vehicle": data}, sort_keys=False, default_flow_style=None)
    lines = lines.splitlines()
    out = []
    for line in lines:
        key = line.strip().split(":")[0]
        if line.startswith("  ") and key in changes:
            continue
        out.append(line)
    body = [out[0]] + [f"  {k}: {v}" for k, v in changes.items()] + out[1:]
    return "\n".join(body) + "\n"


def _section_fields() -> dict[str, list[str]]:
    from tire_estimation.core.deflation.config import DeflationDetectorConfig
    from tire_estimation.core.lateral.linear_kf import LinearLateralKFConfig
    from tire_estimation.params import estimator_sections, parameter_specs

    sections = {prefix: cls for prefix, cls, _ in estimator_sections()}
    sections["detector"] = DeflationDetectorConfig
    sections["linear_kf"] = LinearLateralKFConfig
    return {p: [s.field for s in parameter_specs(cls, p)] for p, cls in sections.items()}


SECTIONS = _section_fields()
VEHICLE_FIELDS = SECTIONS["vehicle"]

# --------------------------------------------------------------------------- the command line
case("no_command", lambda w: [])
case("unknown_command", lambda w: ["replayy"], "replay")
case("replay_no_arguments", lambda w: ["replay"])
case("replay_no_out", lambda w: ["replay", w.bag()], "--out")
case("replay_rank_seeds_text", lambda w: w.replay("--rank-seeds", "abc"), "--rank-seeds")
case("replay_unknown_flag", lambda w: w.replay("--bogus"), "--bogus")
case("replay_misspelled_flag", lambda w: w.replay("--no-plotz"), "did you mean --no-plots")
case(
    "replay_option_of_another_command",
    lambda w: w.replay("--overwrite"),
    "--overwrite is an option of tire-estimation simulate",
)
case("replay_config_without_value", lambda w: w.replay("--config"), "--config")
case("simulate_no_arguments", lambda w: ["simulate"])
case("simulate_seed_text", lambda w: ["simulate", "ece_r64", "--out", w.dir(), "--seed", "x"])
case("simulate_option_no_equals", lambda w: ["simulate", "city", "--out", "x", "--option", "a"])
case(
    "simulate_option_bad_yaml",
    lambda w: ["simulate", "city", "--out", w.dir(), "--option", "deflate_wheel=[1"],
    "deflate_wheel",
)
case(
    "simulate_sensor_undefined_alias",
    lambda w: ["simulate", "city", "--out", w.dir(), "--sensor", "gnss_rate_hz=*x"],
    "gnss_rate_hz",
)
case(
    "simulate_option_deep_yaml",
    lambda w: ["simulate", "city", "--out", w.dir(), "--option", "x=" + "[" * 3000],
)
case(
    "simulate_option_alias_bomb",
    lambda w: ["simulate", "city", "--out", w.dir(), "--option", "deflate_wheel=" + FLOW_BOMB],
)
case("convert_no_dataset", lambda w: ["convert"])
case("convert_unknown_dataset", lambda w: ["convert", "comma2k20", "x", "--out", w.dir()])
case("campaign_no_study", lambda w: ["campaign"])
case("campaign_seeds_text", lambda w: ["campaign", "calibration", "--out", "o", "--seeds", "x"])
case("campaign_tyres_text", lambda w: ["campaign", "ece-r64", "--out", "o", "--tyres", "a,b"])
case(
    "campaign_estimator_bad_yaml",
    lambda w: ["campaign", "calibration", "--out", w.dir(), "--estimator", "n_particles=[1"],
    "n_particles",
)
case("info_no_bag", lambda w: ["info"])

# --------------------------------------------------------------------------- replay --config
case("config_not_found", lambda w: w.replay(config=str(w.root / "nope.yaml")), "nope.yaml")
case("config_is_a_directory", lambda w: w.replay(config=w.dir()), "--config")
config_case("config_binary", bytes(range(128, 256)) * 8, "--config", "UTF-8")
config_case("config_nul_byte", "radius:\n  n_particles: 100\x00\n", "--config")
config_case("config_invalid_yaml", "radius: [1, 2\n", "--config", "line")
config_case("config_tab_indent", "radius:\n\tn_particles: 100\n", "--config", "line")
config_case("config_list", "- 1\n- 2\n", "--config")
config_case("config_scalar", "5\n", "--config")
config_case("config_section_scalar", "radius: 5\n", "radius", "mapping")
config_case("config_section_list", "radius: [1, 2]\n", "radius", "mapping")
config_case("config_section_string", "stiffness: fast\n", "stiffness", "mapping")
config_case("config_detector_list", "detector: [1]\n", "detector", "mapping")
config_case("config_tyre_force_number", "tyre_force: 1\n", "tyre_force", "mapping")
config_case("config_linear_kf_bool", "linear_kf: true\n", "linear_kf", "mapping")
config_case("config_vehicle_number", "vehicle: 3\n", "vehicle", "mapping")
config_case("config_integer_key", "1: 2\n", "1")
config_case("config_null_key", "~: 2\n", "None")
config_case("config_node_scalar", "estimator_node: 5\n", "estimator_node")
config_case(
    "config_ros_parameters_list", "estimator_node:\n  ros__parameters: [1]\n", "ros__parameters"
)
config_case(
    "config_ros_parameters_misspelled",
    "estimator_node:\n  ros__parameter:\n    radius.n_particles: 100\n",
    "did you mean estimator_node.ros__parameters",
)
config_case(
    "config_node_misspelled",
    "estimator_nod:\n  ros__parameters:\n    radius.n_particles: 100\n",
    "did you mean estimator_node",
)
config_case(
    "config_other_node",
    "detector_node:\n  ros__parameters:\n    detector.threshold_m: 0.01\n",
    "detector_node",
)
config_case("config_section_misspelled", "radus:\n  n_particles: 100\n", "did you mean radius")
config_case(
    "config_flat_section_misspelled",
    "radiuss.n_particles: 100\n",
    "did you mean radius.n_particles",
)
config_case(
    "config_node_option_misspelled", "stiffness_enable: false\n", "did you mean stiffness_enabled"
)
config_case(
    "config_node_option_misspelled_in_params_file",
    "estimator_node:\n  ros__parameters:\n    sensor_qoss: reliable\n",
    "did you mean sensor_qos",
)
config_case(
    "config_duplicate_key", "radius:\n  n_particles: 100\n  n_particles: 200\n", "n_particles"
)
config_case(
    "config_duplicate_section", "radius:\n  n_particles: 100\nradius:\n  seed: 3\n", "radius"
)
config_case(
    "config_flat_and_nested_twice",
    "radius:\n  n_particles: 100\nradius.n_particles: 200\n",
    "radius.n_particles",
)
config_case("config_alias_bomb", ALIAS_BOMB + "radius:\n  wheels: *f\n", "alias")
config_case("config_recursive_alias", "radius: &r [*r]\n", "alias")
config_case("config_deep_nesting", "radius: " + "[" * 3000 + "]" * 3000 + "\n", "deep")
config_case("config_too_large", "# padding\n" * 200_000, "--config", "MB")
case("config_dev_zero", lambda w: w.replay(config="/dev/zero"), "--config")
config_case(
    "config_long_value",
    "radius:\n  wheels: [" + ", ".join(["wheel_x"] * 20_000) + "]\n",
    "radius.wheels",
)
config_case("config_wrong_type_int", "radius:\n  n_particles: many\n", "radius.n_particles")
config_case("config_wrong_type_bool", "stiffness_enabled: maybe\n", "stiffness_enabled", "bool")
config_case(
    "config_huge_integer", "radius:\n  n_particles: 1" + "0" * 400 + "\n", "radius.n_particles"
)
config_case(
    "config_integer_too_many_digits",
    "radius:\n  n_particles: 1" + "0" * 5000 + "\n",
    "radius.n_particles",
)
config_case(
    "config_detector_wrong_type", "detector:\n  threshold_m: [1]\n", "detector.threshold_m"
)
config_case(
    "config_stiffness_wrong_type", "stiffness:\n  n_particles: 1.5\n", "stiffness.n_particles"
)
for _section in ("radius", "stiffness", "tyre_force", "detector", "linear_kf", "vehicle", ""):
    _fields = SECTIONS[_section]
    for _field in sorted({_fields[0], _fields[len(_fields) // 2], _fields[-1]}):
        _bad = misspell(_field, _fields)
        _full = f"{_section}.{_field}" if _section else _field
        _bad_full = f"{_section}.{_bad}" if _section else _bad
        if _section:
            config_case(
                f"config_nested_{_section}_{_bad}",
                f"{_section}:\n  {_bad}: 1\n",
                f"did you mean {_full}",
            )
        config_case(f"config_flat_{_bad_full}", f"{_bad_full}: 1\n", f"did you mean {_full}")
        config_case(
            f"config_params_file_{_bad_full}",
            f"estimator_node:\n  ros__parameters:\n    {_bad_full}: 1\n",
            f"did you mean {_full}",
        )

# --------------------------------------------------------------------------- replay: --out
case("out_is_a_file", lambda w: ["replay", w.bag(), "--out", w.file("x"), "--no-plots"], "--out")
case(
    "out_under_a_file",
    lambda w: ["replay", w.bag(), "--out", w.file("x") + "/report", "--no-plots"],
    "--out",
)
case("out_cannot_be_created", lambda w: ["replay", w.bag(), "--out", "/sys/te_out"], "--out")
case("out_read_only", lambda w: ["replay", w.bag(), "--out", "/sys/kernel", "--no-plots"], "--out")
case(
    "out_name_too_long",
    lambda w: ["replay", w.bag(), "--out", str(w.root / ("r" * 300)), "--no-plots"],
    "--out",
)
case(
    "out_path_too_long",
    lambda w: ["replay", w.bag(), "--out", str(w.root / "/".join(["d" * 200] * 25))],
    "--out",
)
case("out_empty", lambda w: ["replay", w.bag(), "--out", "", "--no-plots"], "--out")
case("rank_seeds_zero", lambda w: w.replay("--rank-effects", "--rank-seeds", "0"), "rank_seeds")
case("rank_seeds_negative", lambda w: w.replay("--rank-effects", "--rank-seeds", "-1"))
case("rank_seeds_without_rank_effects", lambda w: w.replay("--rank-seeds", "2"), "rank-effects")
case(
    "write_config_is_a_directory",
    lambda w: w.replay("--rank-effects", "--write-config", w.dir()),
    "--write-config",
)
case(
    "write_config_under_a_file",
    lambda w: w.replay("--rank-effects", "--write-config", w.file("x") + "/c.yaml"),
    "--write-config",
)
case("bag_not_found", lambda w: w.replay(bag=str(w.root / "nobag")), "nobag")
case("bag_is_a_text_file", lambda w: w.replay(bag=w.file("hello", ".mcap")))
case("bag_is_an_empty_directory", lambda w: w.replay(bag=w.dir()), "metadata.yaml")

# --------------------------------------------------------------------------- vehicle.yaml
vehicle_case("vehicle_binary", bytes(range(128, 256)) * 8, "vehicle.yaml", "UTF-8")
vehicle_case("vehicle_nul_byte", "vehicle:\n  name: a\x00b\n", "vehicle.yaml")
vehicle_case("vehicle_invalid_yaml", "vehicle:\n  mass_kg: [1\n", "vehicle.yaml", "line")
vehicle_case("vehicle_huge_integer", vehicle_yaml(mass_kg="1" + "0" * 400), "vehicle.mass_kg")
vehicle_case(
    "vehicle_integer_too_many_digits",
    vehicle_yaml(mass_kg="1" + "0" * 5000),
    "vehicle.mass_kg",
)
vehicle_case(
    "vehicle_huge_integer_in_position",
    vehicle_yaml(gnss_antenna_position_m="[1" + "0" * 400 + ", 0, 0]"),
    "vehicle.gnss_antenna_position_m",
)
vehicle_case("vehicle_deep_nesting", "vehicle:\n  name: " + "[" * 3000 + "]" * 3000, "deep")
vehicle_case("vehicle_alias_bomb", ALIAS_BOMB + vehicle_yaml(name="*f"), "alias")
vehicle_case("vehicle_recursive_alias", "vehicle: &v\n  name: *v\n", "alias")
vehicle_case(
    "vehicle_top_level_misspelled",
    vehicle_yaml().replace("vehicle:", "vehicles:", 1),
    "did you mean vehicle",
)
vehicle_case("vehicle_extra_top_level_key", vehicle_yaml() + "tires:\n  size: 17\n", "tires")
vehicle_case("vehicle_not_a_mapping", "vehicle: 5\n", "vehicle")
vehicle_case("vehicle_empty_file", "", "vehicle")
vehicle_case("vehicle_mass_text", vehicle_yaml(mass_kg="heavy"), "vehicle.mass_kg", "number")
vehicle_case(
    "vehicle_position_scalar",
    vehicle_yaml(gnss_antenna_position_m="3"),
    "vehicle.gnss_antenna_position_m",
)
vehicle_case(
    "vehicle_position_two_numbers",
    vehicle_yaml(imu_position_m="[0, 0]"),
    "vehicle.imu_position_m",
)
vehicle_case("vehicle_name_number", vehicle_yaml(name="5"), "vehicle.name")
vehicle_case("vehicle_drive_list", vehicle_yaml(drive="[front]"), "vehicle.drive")
vehicle_case(
    "vehicle_duplicate_key", vehicle_yaml(mass_kg="1500") + "  mass_kg: 1600\n", "mass_kg"
)
vehicle_case(
    "vehicle_integer_and_text_keys", vehicle_yaml() + "  1: 2\n  colour: red\n", "vehicle."
)
vehicle_case("vehicle_too_large", vehicle_yaml() + "# padding\n" * 200_000, "vehicle.yaml", "MB")
for _field in ("mass_kg", "nominal_tire_radius_m", "drive", "imu_position_m", "name"):
    _bad = misspell(_field, VEHICLE_FIELDS)
    vehicle_case(
        f"vehicle_misspelled_{_bad}",
        vehicle_yaml().replace(f"  {_field}:", f"  {_bad}:", 1),
        f"did you mean vehicle.{_field}",
    )
case(
    "info_vehicle_binary",
    lambda w: ["info", w.bag(vehicle=bytes(range(128, 256)) * 8)],
    "vehicle.yaml",
)
case(
    "info_vehicle_huge_integer",
    lambda w: ["info", w.bag(vehicle=vehicle_yaml(mass_kg="1" + "0" * 400))],
    "vehicle.mass_kg",
)

# --------------------------------------------------------------------------- sim_config.yaml
sim_case("sim_binary", bytes(range(128, 256)) * 8, "sim_config.yaml", "UTF-8")
sim_case("sim_invalid_yaml", "events: [1\n", "sim_config.yaml", "line")
sim_case("sim_events_number", "events: 5\n", "events")
sim_case("sim_events_text", "events: abc\n", "events")
sim_case("sim_event_not_a_mapping", "events: [5]\n", "events[0]")
sim_case("sim_event_time_text", "events:\n- {t_s: soon, kind: pressure_step}\n", "t_s")
sim_case("sim_event_time_infinite", "events:\n- {t_s: .inf, kind: pressure_step}\n", "t_s")
sim_case(
    "sim_event_time_huge_integer",
    "events:\n- {t_s: 1" + "0" * 400 + ", kind: pressure_step}\n",
    "t_s",
)
sim_case("sim_event_without_kind", "events:\n- {t_s: 1.0}\n", "kind")
sim_case("sim_event_detail_number", "events:\n- {t_s: 1.0, kind: x, detail: 5}\n", "detail")
sim_case("sim_event_detail_list", "events:\n- {t_s: 1.0, kind: x, detail: [1, 2]}\n", "detail")
sim_case(
    "sim_event_key_misspelled",
    "events:\n- {t_s: 1.0, kind: x, detial: {}}\n",
    "did you mean events[0].detail",
)
sim_case(
    "sim_event_time_misspelled",
    "events:\n- {ts: 1.0, kind: pressure_step}\n",
    "did you mean events[0].t_s",
)
sim_case("sim_top_level_misspelled", "seeed: 3\n", "did you mean seed")
sim_case("sim_list", "- 1\n", "sim_config.yaml")
sim_case("sim_seed_text", "seed: abc\n", "seed")
sim_case("sim_scenario_number", "scenario: 5\n", "scenario")
sim_case("sim_config_number", "config: 5\n", "config")
sim_case("sim_origin_text", "origin_lla: abc\n", "origin_lla")
sim_case("sim_duplicate_key", "seed: 1\nseed: 2\n", "seed")
sim_case("sim_deep_nesting", "config: " + "[" * 3000 + "]" * 3000 + "\n", "deep")
sim_case("sim_alias_bomb", ALIAS_BOMB.replace("\n", "\n  ").join(["config:\n  ", "\n"]), "alias")
sim_case("sim_too_large", "# padding\n" * 200_000, "sim_config.yaml", "MB")
case("info_sim_events_number", lambda w: ["info", w.bag(sim="events: 5\n")], "events")

# --------------------------------------------------------------------------- simulate
case("simulate_unknown_scenario", lambda w: ["simulate", "moon", "--out", w.dir() + "/b"])
case(
    "simulate_scenario_misspelled",
    lambda w: ["simulate", "ece_r46", "--out", w.dir() + "/b"],
    "did you mean ece_r64",
)
case(
    "simulate_option_misspelled",
    lambda w: ["simulate", "ece_r64", "--out", w.dir() + "/b", "--option", "deflate_whel=x"],
    "did you mean deflate_wheel",
)
case(
    "simulate_sensor_misspelled",
    lambda w: ["simulate", "city", "--out", w.dir() + "/b", "--sensor", "gnss_rate_h=1"],
    "did you mean gnss_rate_hz",
)
case(
    "simulate_sensor_wrong_type",
    lambda w: ["simulate", "city", "--out", w.dir() + "/b", "--sensor", "gnss_rate_hz=fast"],
    "gnss_rate_hz",
)
case(
    "simulate_vehicle_key_misspelled",
    lambda w: [
        "simulate", "city", "--out", w.dir() + "/b",
        "--vehicle", w.file("vehicle:\n  nominal_tire_radius: 0.3\n"),
    ],
    "did you mean vehicle.nominal_tire_radius_m",
)  # fmt: skip
case(
    "simulate_vehicle_missing",
    lambda w: ["simulate", "city", "--out", w.dir() + "/b", "--vehicle", w.dir() + "/none.yaml"],
    "none.yaml",
)
case("simulate_minutes_zero", lambda w: ["simulate", "city", "--out", "b", "--minutes", "0"])
case("simulate_minutes_nan", lambda w: ["simulate", "city", "--out", "b", "--minutes", "nan"])
case("simulate_seed_negative", lambda w: ["simulate", "city", "--out", "b", "--seed", "-1"])
case(
    "simulate_out_under_a_file",
    lambda w: ["simulate", "city", "--minutes", "0.05", "--out", w.file("x") + "/b"],
    "--out",
)
case(
    "simulate_out_exists",
    lambda w: ["simulate", "city", "--minutes", "0.05", "--out", w.file("x")],
    "--out",
)
case(
    "simulate_out_name_too_long",
    lambda w: ["simulate", "city", "--minutes", "0.05", "--out", str(w.root / ("b" * 300))],
    "--out",
)
case(
    "simulate_out_cannot_be_created",
    lambda w: ["simulate", "city", "--minutes", "0.05", "--out", "/sys/te_bag/b"],
    "--out",
)

# --------------------------------------------------------------------------- info, convert
case("info_not_found", lambda w: ["info", str(w.root / "nobag")], "nobag")
case("info_not_a_bag", lambda w: ["info", w.dir()], "metadata.yaml")
case(
    "convert_source_missing",
    lambda w: ["convert", "comma2k19", str(w.root / "noseg"), "--out", w.dir() + "/b"],
    "noseg",
)
case(
    "convert_out_under_a_file",
    lambda w: ["convert", "husky", str(w.root / "nodata"), "--out", w.file("x") + "/b"],
    "--out",
)
case(
    "convert_out_name_too_long",
    lambda w: ["convert", "revs250lm", str(w.root / "nodata"), "--out", str(w.root / ("b" * 300))],
    "--out",
)

# --------------------------------------------------------------------------- campaign
case(
    "campaign_estimator_misspelled",
    lambda w: ["campaign", "calibration", "--out", w.dir(), "--estimator", "n_particle=100"],
    "did you mean n_particles",
)
case(
    "campaign_sensor_misspelled",
    lambda w: ["campaign", "calibration", "--out", w.dir(), "--sensor", "gnss_rate_h=1"],
    "did you mean gnss_rate_hz",
)
case(
    "campaign_detector_misspelled",
    lambda w: ["campaign", "redetect", w.dir(), "--out", w.dir(), "--detector", "drift=0.1"],
    "did you mean drift_m",
)
case(
    "campaign_out_under_a_file",
    lambda w: ["campaign", "calibration", "--seeds", "1", "--out", w.file("x") + "/o"],
    "--out",
)


# --------------------------------------------------------------------------- running a case
@dataclass(frozen=True)
class Outcome:
    """What the command did: exit status, stderr, and the exception that escaped (if any)."""

    code: int | None
    stderr: str
    escaped: BaseException | None

    @property
    def lines(self) -> list[str]:
        return self.stderr.strip().splitlines()


def run(argv: list[str]) -> Outcome:
    """``main(argv)`` with stdout and stderr captured (an escaping exception is returned)."""
    err, out = io.StringIO(), io.StringIO()
    code: int | None = None
    escaped: BaseException | None = None
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException as exc:  # a traceback is what the corpus counts
            if isinstance(exc, KeyboardInterrupt):
                raise
            escaped = exc
    return Outcome(code, err.getvalue(), escaped)


def problems(c: Case, argv: list[str], outcome: Outcome) -> list[str]:
    """What is wrong with the outcome of case ``c`` (empty: a clean one-line error)."""
    found = []
    if outcome.escaped is not None or "Traceback" in outcome.stderr:
        found.append("traceback")
    elif outcome.code == 0:
        found.append("accepted")
    elif outcome.code != 2:
        found.append(f"exit {outcome.code}")
    lines = outcome.lines
    if outcome.escaped is None and len(lines) > 1:
        found.append("multi-line")
    if any(len(line) > MAX_LINE for line in lines):
        found.append("too long")
    if outcome.escaped is None and outcome.code != 0 and not lines:
        found.append("no message")
    message = " ".join(lines)
    if outcome.escaped is None and outcome.code != 0:
        missing = [e for e in c.expect if e not in message]
        if missing:
            found.append("missing " + ", ".join(repr(m) for m in missing))
    if "--out" in argv:
        out = argv[argv.index("--out") + 1] if argv.index("--out") + 1 < len(argv) else ""
        try:
            left = [f for f in REPORT_FILES if out and (Path(out) / f).is_file()]
        except OSError:  # a name too long
            left = []
        if "metrics.json" in left:
            found.append("stale metrics.json")
        if any(f.endswith(".png") for f in left):
            found.append("stale plots")
    return found


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory) -> World:
    return World(tmp_path_factory.mktemp("cli_errors"))


def test_the_corpus_is_large_and_knows_the_report_files() -> None:
    from tire_estimation import replay

    assert len(CASES) >= 100
    assert set(REPORT_FILES) == set(replay.REPORT_FILES)


@pytest.mark.parametrize("c", CASES, ids=[c.id for c in CASES])
def test_bad_input_is_one_line_and_exit_2(
    c: Case, world: World, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(world.root)
    argv = c.build(world)
    outcome = run(argv)
    assert problems(c, argv, outcome) == [], (outcome.code, outcome.stderr[:2000])
    assert outcome.lines[0].startswith("tire-estimation")


def measure() -> int:
    """Run every case; print the ones with problems and the counts of each problem."""
    from collections import Counter

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        os.chdir(root)
        w = World(root)
        counts: Counter[str] = Counter()
        for c in CASES:
            argv = c.build(w)
            found = problems(c, argv, run(argv))
            for p in found:
                counts[p.split(" ")[0] if p.startswith("missing") else p] += 1
            if found:
                print(f"{c.id}: {'; '.join(found)}", flush=True)
    print(f"\n{len(CASES)} cases:", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return 0


if __name__ == "__main__":
    sys.exit(measure())
