"""A locked rear axle against a free one: the common rear radius and the axle check's verdict.

Each seed simulates the same drive twice, with free rear wheels and with a spool
(``SensorConfig.wheel_speed_rear_locked``: both rear wheels turn at the mean of their
free-rolling speeds), and runs the radius MPF with its defaults through the pipeline (on a
locked axle it takes the heading change from the gyro). Printed per run: the final error of
each rear radius and of their mean (the common radius) against the truth, relative to the
nominal radius, the rear axle's verdict and slope, and how many wheel-speed samples took
their heading change from the gyro.

``--rewire swap_rear`` (the rear wheels' speeds exchanged in the input), ``front_rear`` (the
front and rear wheels' names exchanged, ``core/radius/axle_order.py``), ``negate_right`` /
``negate_all`` (the right / every wheel's speed negated) or ``flip_gyro`` (the gyro's yaw rate
negated: an IMU frame with z down) runs each drive as it is and with that wiring instead of the
spool: the rear errors of both, the largest difference between them, and what the axle check
decided (``core/radius/axle_check.py``, ``core/radius/wheel_signs.py``). ``--sensor KEY=VALUE``
sets the simulator's sensors (``gnss_velocity_enabled=false``: positions only); ``--vehicle
YAML`` simulates another vehicle.

    python -m tire_estimation.evaluation.axle_study --scenario robustness --minutes 10 --seeds 20
    python -m tire_estimation.evaluation.axle_study --rewire flip_gyro --minutes 5 --seeds 20
    python -m tire_estimation.evaluation.axle_study --rewire negate_right --minutes 5 --seeds 20
    python -m tire_estimation.evaluation.axle_study --rewire front_rear --scenario city --seeds 20
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation import sim_runs
from tire_estimation.evaluation.sim_runs import (
    add_seed_args,
    key_values,
    run_seeds,
    simulated_radius_run,
    within,
)


def rewired(sim: Any, how: str) -> Any:
    """The simulation with the rear wheels' speeds exchanged (``swap_rear``), the front and
    rear wheels' (``front_rear``), the right wheels' speeds negated (``negate_right``), every
    wheel's negated (``negate_all``) or the gyro's yaw rate negated (``flip_gyro``)."""
    if how != "flip_gyro":
        ws = sim.wheel_speeds.wheel_speed_rad_s.copy()
        if how == "swap_rear":
            ws[:, [2, 3]] = ws[:, [3, 2]]
        elif how == "front_rear":
            ws = ws[:, [2, 3, 0, 1]]
        else:
            ws[:, [1, 3] if how == "negate_right" else slice(None)] *= -1.0
        return dataclasses.replace(
            sim, wheel_speeds=dataclasses.replace(sim.wheel_speeds, wheel_speed_rad_s=ws)
        )
    gyro = sim.imu.angular_velocity_rad_s.copy()
    gyro[:, 2] = -gyro[:, 2]
    return dataclasses.replace(sim, imu=dataclasses.replace(sim.imu, angular_velocity_rad_s=gyro))


def run_one(
    scenario: str,
    seed: int,
    minutes: float,
    locked: bool,
    rewire: str | None = None,
    sensors: dict[str, Any] | None = None,
    vehicle: Any = None,
) -> dict[str, Any]:
    """One drive: final errors, the rear axle's verdict, the gyro-heading samples; with
    ``rewire``, the drive rewired (:func:`rewired`) instead of a spool when ``locked``;
    ``sensors``: simulator settings; ``vehicle``: a ``VehicleParams`` (None: the default car)."""
    sim, pipeline, run = simulated_radius_run(
        scenario,
        seed,
        minutes,
        {},
        {**(sensors or {}), "wheel_speed_rear_locked": locked and rewire is None},
        rewrite=(lambda s: rewired(s, rewire)) if locked and rewire else None,
        vehicle=vehicle,
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
        "swapped": pipeline.axles.swapped["rear"],
        "gyro_reversed": pipeline.axles.gyro_reversed,
        "wheels_reversed": int(sum(pipeline.axles.signs.reversed)),
        "front_rear_exchanged": pipeline.axles.order.exchanged,
        "order_slope": pipeline.axles.order.slope,
        "final_radius_m": est.tolist(),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary, write ``--out`` (JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument(
        "--rewire",
        choices=("swap_rear", "front_rear", "flip_gyro", "negate_right", "negate_all"),
        default=None,
    )
    sim_runs.add_vehicle_arg(parser)
    args = parser.parse_args(argv)
    sensors, vehicle = key_values(args.sensor), sim_runs.vehicle_arg(args)
    rows = run_seeds(
        args,
        lambda seed: [
            run_one(args.scenario, seed, args.minutes, lk, args.rewire, sensors, vehicle)
            for lk in (False, True)
        ],
    )
    if args.rewire:
        plain = [r for r in rows if not r["locked"]]
        wired = [r for r in rows if r["locked"]]
        rms = [
            float(np.sqrt(np.mean((np.array([r["error_m"] for r in sel]) * 1e3) ** 2)))
            for sel in (plain, wired)
        ]
        radii = [np.array([r["final_radius_m"] for r in sel]) for sel in (plain, wired)]
        diff = float(np.abs(radii[1] - radii[0]).max() * 1e3)
        print(
            f"{args.rewire}: rear swapped back on {sum(r['swapped'] for r in wired)}, gyro "
            f"negated on {sum(r['gyro_reversed'] for r in wired)}, wheels negated "
            f"{[r['wheels_reversed'] for r in wired]} of {len(wired)}; front and rear "
            f"exchanged back on {sum(r['front_rear_exchanged'] for r in wired)} (wired right: "
            f"{sum(r['front_rear_exchanged'] for r in plain)}; order decided on "
            f"{sum(r['order_slope'] is not None for r in wired)} / "
            f"{sum(r['order_slope'] is not None for r in plain)}); rear split "
            f"observable on {sum(r['split_observable'] is True for r in wired)}; rear errors "
            f"RMS {rms[1]:.3f} mm (the same drives wired right: {rms[0]:.3f} mm), largest "
            f"difference of a final radius from the drive wired right {diff:.3f} mm"
        )
        return 0
    for locked in (False, True):
        sel = [r for r in rows if r["locked"] is locked]
        rel = np.abs([r["common_error_rel"] for r in sel]) * 100.0
        print(
            f"{'locked' if locked else 'free'}: common rear radius {within(rel, 0.1)}; rear split "
            f"unobservable on {sum(r['split_observable'] is False for r in sel)}, observable on "
            f"{sum(r['split_observable'] is True for r in sel)}; gyro heading used on "
            f"{sum(r['gyro_heading_samples'] > 0 for r in sel)}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
