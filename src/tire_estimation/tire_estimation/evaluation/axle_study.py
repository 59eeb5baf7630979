"""A locked rear axle against a free one: the common rear radius and the axle check's verdict.

Each seed simulates the same drive twice, with free rear wheels and with a spool
(``SensorConfig.wheel_speed_rear_locked``: both rear wheels turn at the mean of their
free-rolling speeds), and runs the radius MPF with its defaults through the pipeline (on a
locked axle it takes the heading change from the gyro). Printed per run: the final error of
each rear radius and of their mean (the common radius) against the truth, relative to the
nominal radius, the rear axle's verdict and slope, and how many wheel-speed samples took
their heading change from the gyro.

    python -m tire_estimation.evaluation.axle_study --scenario robustness --minutes 10 --seeds 20
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import (
    add_seed_args,
    run_seeds,
    simulated_radius_run,
    write_rows,
)


def run_one(scenario: str, seed: int, minutes: float, locked: bool) -> dict[str, Any]:
    """One drive: final errors, the rear axle's verdict, the gyro-heading samples."""
    sim, pipeline, run = simulated_radius_run(
        scenario,
        seed,
        minutes,
        {},
        {"wheel_speed_rear_locked": locked},
    )
    nominal = sim.vehicle.nominal_tire_radius_m
    trace = run.arrays()
    assert pipeline.radius is not None and pipeline.axles is not None
    true = sim.truth.wheel_radius_m[-1, 2:] - nominal
    est = trace["radius_error_m"][-1]
    rear = pipeline.axles.status("rear")
    return {
        "seed": seed,
        "locked": locked,
        "error_m": (est - true).tolist(),
        "common_error_rel": float((est.mean() - true.mean()) / nominal),
        "split_observable": rear.split_observable,
        "slope": rear.slope,
        "gyro_heading_samples": pipeline.radius.gyro_heading_samples,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary, write ``--out`` (JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument("--out", type=Path, default=None, help="JSON file for every run")
    args = parser.parse_args(argv)
    rows = run_seeds(
        args, lambda seed: [run_one(args.scenario, seed, args.minutes, lk) for lk in (False, True)]
    )
    for locked in (False, True):
        sel = [r for r in rows if r["locked"] is locked]
        rel = np.abs([r["common_error_rel"] for r in sel]) * 100.0
        print(
            f"{'locked' if locked else 'free'}: common rear radius within 0.1 % on "
            f"{int((rel <= 0.1).sum())}/{len(sel)} (max {rel.max():.3f} %); rear split "
            f"unobservable on {sum(r['split_observable'] is False for r in sel)}, observable on "
            f"{sum(r['split_observable'] is True for r in sel)}; gyro heading used on "
            f"{sum(r['gyro_heading_samples'] > 0 for r in sel)}"
        )
    write_rows(args.out, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
