"""sim_config.yaml of a simulated bag: read as written, every key and event checked."""

from __future__ import annotations

from pathlib import Path

import pytest

from tire_estimation.bag.sim_config import parse_events, parse_sim_config, read_sim_config
from tire_estimation.errors import BagError, ConfigError


def test_the_written_file_reads_back(bag: Path) -> None:
    config, events = read_sim_config(bag / "sim_config.yaml")
    assert config["scenario"] == "synthetic" and config["seed"] == 1
    assert [(e.kind, e.detail["wheel"]) for e in events] == [("pressure_step", "wheel_rl")]
    assert parse_sim_config(None) == ({}, ())


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        ({"t_s": 1.0}, r"events\[0\]\.kind=None: missing"),
        ({"t_s": "x", "kind": "k"}, r"events\[0\]\.t_s='x': must be a number"),
        ({"t_s": 10**400, "kind": "k"}, r"must be finite"),
        ({"t_s": 1, "kind": "k", "detial": {}}, r"did you mean events\[0\]\.detail\?"),
        ({"t_s": 1, "kind": "k", "detail": [1]}, r"events\[0\]\.detail=\[1\]: must be a mapping"),
    ],
)
def test_a_bad_event_is_named(raw: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_events([raw])


def test_a_bad_file_is_a_bag_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "sim_config.yaml"
    path.write_text("seeed: 3\n")
    with pytest.raises(BagError, match=r"sim_config\.yaml: seeed=3: unknown key; did you mean"):
        read_sim_config(path)
