"""YAML 1.2 numbers in configuration values (``5e-5`` is a float); the loader's limits."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import parse_key_value
from tire_estimation.core import yamlio
from tire_estimation.replay_config import load_radius_config


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("5e-5", 5e-5),
        ("2E+3", 2000.0),
        ("-1.5e-3", -1.5e-3),
        (".5", 0.5),
        ("0.9998", 0.9998),
        ("1.0e-5", 1e-5),
        ("7", 7),
        ("-3", -3),
        ("1_000", 1000),
    ],
)
def test_numbers(text: str, value: float) -> None:
    got = yamlio.safe_load(text)
    assert got == value and type(got) is type(value)
    assert yaml.safe_load(text) == value or text in ("5e-5", "2E+3", "-1.5e-3")  # 1.1: strings


@pytest.mark.parametrize("text", ["1e5x", "e5", "abc", "1.2.3", "0x1f-"])
def test_non_numbers_stay_strings(text: str) -> None:
    assert isinstance(yamlio.safe_load(text), str)


def test_special_values_and_documents() -> None:
    assert yamlio.safe_load(".inf") == math.inf
    assert math.isnan(yamlio.safe_load(".nan"))
    assert yamlio.safe_load("true") is True
    assert yamlio.safe_load("a: [1e-3, 2]\nb: x") == {"a": [1e-3, 2], "b": "x"}


def test_cli_option_and_replay_config_take_exponents(tmp_path: Path) -> None:
    key = "radius_random_walk_m_sqrt_s"
    assert parse_key_value(f"{key}=2e-5") == (key, 2e-5)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("radius:\n  radius_random_walk_m_sqrt_s: 3e-5\n")
    assert load_radius_config(cfg).radius_random_walk_m_sqrt_s == 3e-5


def _error(text: str) -> str:
    with pytest.raises(yaml.YAMLError) as exc:
        yamlio.safe_load(text)
    message = yamlio.describe(exc.value)
    assert "\n" not in message and len(message) < 200
    return message


def test_aliases_are_bounded_and_not_recursive() -> None:
    levels = ["a: &a [" + ", ".join(["x"] * 10) + "]"] + [
        f"{c}: &{c} [" + ", ".join([f"*{p}"] * 10) + "]"
        for p, c in zip("abcd", "bcde", strict=True)
    ]
    assert "aliases expand to more than 100000 values" in _error("\n".join(levels))
    assert len(yamlio.safe_load("\n".join(levels[:4]))["d"]) == 10  # 11 111 values: fine
    assert "alias *r inside the value it names" in _error("a: &r [1, *r]")
    assert "alias *m inside the value it names" in _error("a: &m {b: *m}")
    merged = yamlio.safe_load("base: &b {x: 1, y: 2}\nc:\n  <<: *b\n  y: 3\n")
    assert merged["c"] == {"x": 1, "y": 3}  # a merge key's values may be overridden


def test_depth_duplicates_size_and_long_integers_are_refused() -> None:
    assert "nested too deep" in _error("a: " + "[" * 51 + "]" * 51)
    assert yamlio.safe_load("a: " + "[" * 49 + "]" * 49) is not None
    assert _error("a: 1\nb: 2\na: 3\n") == "line 3, column 1: key 'a' given twice"
    assert "longer than 1 MB" in _error("#" * (yamlio.MAX_BYTES + 1))
    assert "radius.n_particles is an integer of too many digits" in _error(
        "radius:\n  n_particles: " + "9" * 5000
    )
    assert _error("a: [1, 2").startswith("line 1, column 9: expected ',' or ']'")


def test_load_file_says_why_in_one_line(tmp_path: Path) -> None:
    from tire_estimation.errors import ConfigError

    def reason(content: bytes | None) -> str:
        path = tmp_path / "f.yaml"
        path.unlink(missing_ok=True)
        if content is not None:
            path.write_bytes(content)
        with pytest.raises(ConfigError) as exc:
            yamlio.load_file(path, "--config")
        assert exc.value.field == "--config"
        return exc.value.reason

    assert reason(None) == "file not found"
    assert reason(b"\xff\xfe\x00") == "not UTF-8 text (byte 0)"
    assert (
        reason(b"a: 1\x00")
        == "not valid YAML: character #x0000 at position 4 is not allowed in YAML"
    )
    assert reason(b"# x\n" * 300_000) == "larger than 1 MB"
    with pytest.raises(ConfigError, match="is a directory"):
        yamlio.load_file(tmp_path, "--config")
    (tmp_path / "ok.yaml").write_text("a: 5e-5\n")
    assert yamlio.load_file(tmp_path / "ok.yaml", "--config") == {"a": 5e-5}
