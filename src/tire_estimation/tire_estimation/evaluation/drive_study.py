"""The vehicle the estimator is told against the one that drives: driven rear wheels, a wrong
nominal radius.

Each seed simulates the scenario with the simulator's car, front- (default), rear-
(``--drive rear``) or all-wheel driven, and runs the radius MPF through the pipeline, told a
``vehicle.yaml`` whose longitudinal stiffness is ``--stated-stiffness-factor`` times the
simulated one (the prior of the slip, ``core/radius/drive_slip.py``), whose nominal radius is
``--stated-radius-m`` and whose drive is ``--stated-drive`` (default: the simulated ones).
Printed per run: the error of each rear radius against the truth at the end, its reported
std, the learned slip coefficients and the mean slip removed, and the rescalings of the radii
(``core/radius/speed_scale.py``).
``--no-correction`` runs the same drives with the slip correction off, ``--no-rescale`` with the
rescaling off (what the estimator did before them); ``--sensor KEY=VALUE`` sets the simulator's
sensors (``--sensor gnss_velocity_enabled=false``: a receiver that reports positions only).

    python -m tire_estimation.evaluation.drive_study --drive rear --seeds 20 --minutes 10
    python -m tire_estimation.evaluation.drive_study --stated-radius-m 0.29 --minutes 5
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.sim_runs import (
    add_seed_args,
    key_values,
    run_seeds,
    simulated_radius_run,
)


def run_one(
    scenario: str,
    seed: int,
    minutes: float,
    drive: str,
    stated_stiffness_factor: float,
    correction: bool,
    stated_radius_m: float | None = None,
    rescale: bool = True,
    stated_drive: str | None = None,
    sensors: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """One drive: final rear errors (mm), reported std (mm), the slip correction's summary."""
    vehicle = VehicleParams(drive=drive)
    stated = dataclasses.replace(
        vehicle,
        longitudinal_stiffness_front_n=vehicle.longitudinal_stiffness_front_n
        * stated_stiffness_factor,
        longitudinal_stiffness_rear_n=vehicle.longitudinal_stiffness_rear_n
        * stated_stiffness_factor,
        nominal_tire_radius_m=stated_radius_m or vehicle.nominal_tire_radius_m,
        drive=stated_drive or drive,
    )

    def switch(pipeline: Any) -> None:
        slip = pipeline.radius.drive_slip
        slip.enabled = correction and slip.enabled
        slip.learnable = correction and slip.learnable
        pipeline.radius.speed_scale.enabled = rescale

    sim, pipeline, run = simulated_radius_run(
        scenario, seed, minutes, {}, sensors or {}, vehicle=vehicle, stated_vehicle=stated,
        before_push=switch,
    )  # fmt: skip
    trace = run.arrays()
    true = sim.truth.wheel_radius_m[-1, 2:] - stated.nominal_tire_radius_m
    err = trace["radius_error_m"][-1] - true
    std = trace["radius_error_std_m"][-1]
    slip = pipeline.radius.drive_slip.summary()
    return {
        "seed": seed,
        "error_mm": (1e3 * err).tolist(),
        "std_mm": (1e3 * std).tolist(),
        "z": (err / np.maximum(std, 1e-12)).tolist(),
        "slip": slip if correction else {"source": "off"},
        "rescales": list(pipeline.radius.speed_scale.rescales),
        "rescale_sources": list(pipeline.radius.speed_scale.rescale_sources),
        # when, in s from the drive's start
        "rescale_s": [
            (t - int(trace["t_ns"][0])) * 1e-9 for t in pipeline.radius.speed_scale.rescale_t_ns
        ],
    }


def _span(values: Sequence[float], fmt: str) -> str:
    """``min-max`` of ``values``, each written with ``fmt``."""
    return f"{min(values):{fmt}}-{max(values):{fmt}}"


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument("--drive", choices=("front", "rear", "all"), default="rear")
    parser.add_argument("--stated-stiffness-factor", type=float, default=1.0)
    parser.add_argument("--stated-radius-m", type=float, default=None)
    parser.add_argument("--stated-drive", choices=("front", "rear", "all"), default=None)
    parser.add_argument("--no-correction", action="store_true")
    parser.add_argument("--no-rescale", action="store_true")
    args = parser.parse_args(argv)
    sensors = key_values(args.sensor)
    rows = run_seeds(
        args,
        lambda seed: [
            run_one(
                args.scenario, seed, args.minutes, args.drive, args.stated_stiffness_factor,
                not args.no_correction, args.stated_radius_m, not args.no_rescale,
                args.stated_drive, sensors,
            )
        ],
    )  # fmt: skip
    err = np.array([r["error_mm"] for r in rows])
    z = np.abs([r["z"] for r in rows])
    firsts = [r["rescale_s"][0] for r in rows if r["rescale_s"]]
    print(
        f"rear radii error: mean {err.mean(axis=0)[0]:+.3f} / {err.mean(axis=0)[1]:+.3f} mm, "
        f"RMS {np.sqrt(np.mean(err**2)):.3f} mm, max |error| {np.abs(err).max():.3f} mm; "
        f"|error|/std median {np.median(z):.2f}, max {z.max():.2f}, above 3 on "
        f"{int(np.any(z > 3.0, axis=1).sum())}/{len(rows)}; radii rescaled on "
        f"{sum(bool(r['rescales']) for r in rows)}"
        + (f" (first at {_span(firsts, '.1f')} s)" if firsts else "")
    )
    detected = sum(bool(r["slip"].get("detected")) for r in rows)
    if detected:
        print(f"rear wheels found slipping under a stated front drive on {detected}/{len(rows)}")
    learned = [r["slip"] for r in rows if r["slip"].get("source") == "learned"]
    if learned:
        c1 = np.array([s["slip_per_accel_s2_per_m"] for s in learned])
        c2 = np.array([s["slip_per_speed2_s2_per_m2"] for s in learned])
        print(
            f"learned on {len(learned)}/{len(rows)}: slip per m/s^2 {c1.mean():.5f} "
            f"({_span(c1, '.5f')}), per (m/s)^2 {c2.mean():.3g} ({_span(c2, '.3g')})"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
