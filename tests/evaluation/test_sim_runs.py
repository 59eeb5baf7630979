"""The helpers the seed studies share (``evaluation/sim_runs.py``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from tire_estimation.evaluation.sim_runs import add_seed_args, key_values, run_seeds, within


def test_within_counts_the_drives_whose_every_error_is_inside_the_target() -> None:
    # two radii per drive: the second drive has one radius outside
    assert within([[0.01, -0.04], [0.02, -0.07], [0.0, 0.05]], 0.05) == (
        "within 0.05 % on 2/3 (max 0.070 %)"
    )
    # one number per drive
    assert within([0.2, 0.05], 0.1) == "within 0.1 % on 1/2 (max 0.200 %)"


def test_the_seed_options_run_each_seed_and_write_every_row(tmp_path: Path) -> None:
    parser = argparse.ArgumentParser()
    add_seed_args(parser, "robustness", 5.0)
    out = tmp_path / "rows.json"
    args = parser.parse_args(
        ["--seeds", "2", "--first-seed", "3", "--sensor", "gnss_rate_hz=5", "--out", str(out)]
    )
    assert key_values(args.sensor) == {"gnss_rate_hz": 5}
    rows = run_seeds(args, lambda seed: [{"seed": seed, "k": k} for k in range(2)])
    assert [r["seed"] for r in rows] == [3, 3, 4, 4]
    assert json.loads(out.read_text()) == rows
