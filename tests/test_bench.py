"""The per-sample benchmarks count the samples they time."""

from __future__ import annotations

from pathlib import Path

from tire_estimation.bag.reader import read_bag
from tire_estimation.bag.writer import write_sim_bag
from tire_estimation.bench import tyre_force_costs
from tire_estimation.sim import simulate

ROOT = Path(__file__).resolve().parents[1]


def test_the_tyre_force_cost_is_per_tyre_force_sample(tmp_path: Path) -> None:
    bag = tmp_path / "lc"
    write_sim_bag(simulate("lane_change", seed=0, minutes=0.2), bag)
    n = read_bag(bag).topics["/vehicle/tire_forces"].count
    out = tyre_force_costs(bag)
    assert out["tire_force_samples"] == n > 1000
    assert 0.0 < out["tyre_force_kf_us"] < 1e5


def test_a_bag_without_tyre_forces_has_no_tyre_force_cost() -> None:
    assert tyre_force_costs(ROOT / "bags" / "ece_r64_6min") == {}
