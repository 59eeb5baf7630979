"""YAML 1.2 numbers in configuration values (``5e-5`` is a float)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from tire_estimation.cli import _parse_option
from tire_estimation.core import yamlio
from tire_estimation.replay import load_radius_config


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
    assert _parse_option(f"{key}=2e-5") == (key, 2e-5)
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("radius:\n  radius_random_walk_m_sqrt_s: 3e-5\n")
    assert load_radius_config(cfg).radius_random_walk_m_sqrt_s == 3e-5
