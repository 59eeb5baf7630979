"""IMU mounting study: simulated drives whose IMU is turned on its mount, against the same drives
with the IMU in base_link axes (``core/imu_mounting.py``).

Per seed and angle: the fitted mounting yaw, whether it was corrected and when, the final rear
radius errors and the stiffness MPF's final relative errors, beside the drive with the IMU
mounted right::

    python -m tire_estimation.evaluation.imu_mounting_study --seeds 10 --minutes 5 \\
        --angles 0 30 90 -90 180
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import add_seed_args, key_values, run_seeds


def run_one(
    scenario: str, seed: int, minutes: float, angle_deg: float, sensors: Mapping[str, Any]
) -> dict[str, Any]:
    """One drive with the IMU turned by ``angle_deg``: the check's result, the rear radius
    errors (mm) and the stiffness MPF's final relative errors (%) against the truth."""
    from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
    from tire_estimation.sim import SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    cfg = SensorConfig(**{**sensors, "imu_mounting_yaw_deg": angle_deg})
    sim = simulate(scenario, seed=seed, minutes=minutes, sensors=cfg)
    pipeline = EstimationPipeline(
        PipelineConfig(
            seed=seed,
            radius=RadiusEstimatorConfig(seed=seed),
            stiffness=StiffnessEstimatorConfig(),
        ),
        sim.vehicle,
        outputs=False,
    )
    pipeline.push_ordered(sim_samples(sim, tire_forces=False))
    assert pipeline.radius is not None and pipeline.stiffness is not None
    mount = pipeline.imu_mounting.result
    est = pipeline.radius.estimate()
    truth = sim.truth
    true_err = truth.wheel_radius_m[-1, 2:4] - sim.vehicle.nominal_tire_radius_m
    stiff = pipeline.stiffness.estimate()
    # the default car is front-driven: its Cx is the front axle's
    true_stiff = dict(zip(("cx_front", "cy_front", "cy_rear"), truth.stiffness[-1], strict=True))
    rel = {
        name: 100.0 * (float(v) / true_stiff[name] - 1.0)
        for name, v in zip(stiff.names, stiff.stiffness, strict=True)
        if name in true_stiff
    }
    return {
        "seed": seed,
        "angle_deg": angle_deg,
        "yaw_deg": mount.yaw_deg,
        "decided": mount.decided,
        "corrected": mount.corrected,
        "upside_down": mount.upside_down,
        "decided_s": None
        if mount.decided_t_ns is None
        else (mount.decided_t_ns - int(truth.t_ns[0])) * 1e-9,
        "radius_error_mm": (1e3 * (est.radius_error_m[-2:] - true_err)).tolist(),
        "stiffness_error_pct": rel,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds and angles, print each run and a summary per angle."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 5.0)
    parser.add_argument("--angles", type=float, nargs="+", default=[0.0, 30.0, 90.0, 180.0])
    args = parser.parse_args(argv)
    sensors = key_values(args.sensor)
    rows = run_seeds(
        args,
        lambda seed: [run_one(args.scenario, seed, args.minutes, a, sensors) for a in args.angles],
    )
    clean = {r["seed"]: r for r in rows if r["angle_deg"] == 0.0}
    for angle in args.angles:
        sel = [r for r in rows if r["angle_deg"] == angle]
        # upside down (turned about x before the yaw): turned back first, the yaw seen is -angle
        found = [
            r["yaw_deg"] - (-angle if r["upside_down"] else angle) for r in sel if r["decided"]
        ]
        off = np.abs((np.array(found) + 180.0) % 360.0 - 180.0) if found else np.array([np.nan])
        diff = [
            np.abs(np.subtract(r["radius_error_mm"], clean[r["seed"]]["radius_error_mm"])).max()
            for r in sel
            if r["seed"] in clean
        ]
        stiff = np.abs([v for r in sel for v in r["stiffness_error_pct"].values()])
        print(
            f"{angle:+.0f} deg: upside down on {sum(r['upside_down'] for r in sel)}; decided on "
            f"{len(found)}/{len(sel)} (angle off by at most "
            f"{off.max():.2f} deg), corrected on {sum(r['corrected'] for r in sel)}, at "
            f"{max((r['decided_s'] or 0.0) for r in sel):.0f} s at the latest; rear errors "
            f"RMS {np.sqrt(np.mean(np.square([r['radius_error_mm'] for r in sel]))):.3f} mm, "
            f"largest difference from the drive mounted right "
            f"{max(diff) if diff else float('nan'):.3f} mm; stiffness |error| median "
            f"{np.median(stiff):.1f} %, max {stiff.max():.1f} %"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
