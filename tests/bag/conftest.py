"""Fixtures of the bag-layer tests: a synthetic drive and its bag (written once per module)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.bag.synthetic import make_result
from tire_estimation.bag.writer import write_sim_bag
from tire_estimation.sim.streams import SimResult


@pytest.fixture(scope="session")
def result() -> SimResult:
    return make_result(20.0)


@pytest.fixture(scope="session")
def bag(result: SimResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_sim_bag(result, tmp_path_factory.mktemp("bags") / "synthetic")
