"""Slow driving with RTK-grade GNSS: do the rear radii learn at 1-8 m/s?

Each seed simulates the ``slow`` scenario (car-park manoeuvring at 1-8 m/s, tight turns) with
RTK-grade fixes (``RTK_SENSORS``: 1.5 cm white plus 1.5 cm slowly varying per horizontal axis,
about 2 cm in all) and runs the radius MPF with its defaults (plus ``--set`` overrides) through
the pipeline. Printed per run: the error of each rear radius against the truth after
``--at-min`` minutes and at the end, relative to the nominal radius, its reported std, and the
seconds learned; and what the wheel-speed sensor does to the distance the rear wheels measure
(``odometry_bias_pct``: the rear wheel speeds times the true radii, integrated above 1 m/s,
over the true distance, minus 1, in %, while steady, accelerating and braking by more than
0.1 m/s^2), the bias no radius can remove. ``--sensor`` sets simulator sensor settings.

    python -m tire_estimation.evaluation.slow_study --seeds 20 --minutes 5
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import (
    add_key_value_arg,
    add_seed_args,
    key_values,
    run_seeds,
    simulated_radius_run,
    within,
)

#: RTK-grade GNSS for the simulator: ~2 cm horizontal per axis, 10 Hz, Doppler velocity on.
RTK_SENSORS: dict[str, Any] = {
    "gnss_white_std_m": 0.015,
    "gnss_white_vertical_std_m": 0.03,
    "gnss_gm_std_m": 0.015,
    "gnss_gm_vertical_std_m": 0.03,
}


#: |longitudinal acceleration| that separates steady driving from accelerating and braking, m/s^2
STEADY_ACCEL_M_S2 = 0.1


def odometry_bias_pct(sim: Any, min_speed_m_s: float = 1.0) -> dict[str, float]:
    """Rear-axle distance from the measured wheel speeds and the true radii over the true
    distance of ``base_link``, minus 1, in %, above ``min_speed_m_s``: over the whole drive
    and while steady, accelerating and braking (:data:`STEADY_ACCEL_M_S2`)."""
    truth, wheels = sim.truth, sim.wheel_speeds
    t_true = truth.t_ns.astype(float)
    t = wheels.t_ns.astype(float)
    speed = np.interp(t, t_true, np.hypot(truth.velocity_m_s[:, 0], truth.velocity_m_s[:, 1]))
    accel = np.interp(t, t_true, truth.acceleration_m_s2[:, 0])
    radius = np.column_stack([np.interp(t, t_true, truth.wheel_radius_m[:, i]) for i in (2, 3)])
    rear = 0.5 * np.sum(wheels.wheel_speed_rad_s[:, 2:] * radius, axis=1)
    moving = speed > min_speed_m_s
    parts = {
        "all": moving,
        "steady": moving & (np.abs(accel) <= STEADY_ACCEL_M_S2),
        "accelerating": moving & (accel > STEADY_ACCEL_M_S2),
        "braking": moving & (accel < -STEADY_ACCEL_M_S2),
    }
    return {
        k: float(100.0 * (rear[m].sum() / speed[m].sum() - 1.0)) if m.any() else float("nan")
        for k, m in parts.items()
    }


def run_one(
    seed: int,
    minutes: float,
    overrides: Mapping[str, Any],
    scenario: str = "slow",
    sensors: Mapping[str, Any] = RTK_SENSORS,
) -> dict[str, Any]:
    """One drive: final rear errors relative to nominal, reported std, learned seconds."""
    sim, pipeline, run = simulated_radius_run(scenario, seed, minutes, overrides, sensors)
    nominal = sim.vehicle.nominal_tire_radius_m
    trace = run.arrays()
    assert pipeline.radius is not None
    true = sim.truth.wheel_radius_m[-1, 2:] - nominal
    est = trace["radius_error_m"][-1]
    std = trace["radius_error_std_m"][-1]
    err = est - true
    return {
        "seed": seed,
        "error_rel_pct": (100.0 * err / nominal).tolist(),
        "error_mm": (1e3 * err).tolist(),
        "std_mm": (1e3 * std).tolist(),
        "z": (err / np.maximum(std, 1e-12)).tolist(),
        "learned_s": pipeline.radius.active_time_s,
        "odometry_bias_pct": odometry_bias_pct(sim),
        # the ABS unit's tooth pitch read off its held values (0: not found)
        "tooth_pitch_rad": pipeline.radius.timing.tooth_pitch_rad,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "slow", 5.0)
    parser.add_argument(
        "--gnss",
        choices=("rtk", "default"),
        default="rtk",
        help="RTK-grade fixes (RTK_SENSORS) or the simulator's default GNSS",
    )
    parser.add_argument("--tolerance-pct", type=float, default=0.05)
    add_key_value_arg(parser, "--set", "radius estimator setting (JSON value)")
    args = parser.parse_args(argv)
    overrides = key_values(args.set)
    sensors = {**(RTK_SENSORS if args.gnss == "rtk" else {}), **key_values(args.sensor)}
    rows = run_seeds(
        args, lambda seed: [run_one(seed, args.minutes, overrides, args.scenario, sensors)]
    )
    rel = np.abs([r["error_rel_pct"] for r in rows])
    z = np.abs([r["z"] for r in rows])
    learned_s = np.mean([r["learned_s"] for r in rows])
    print(
        f"both rear radii {within(rel, args.tolerance_pct)}, RMS "
        f"{np.sqrt(np.mean(rel**2)):.3f} %; |error|/std median "
        f"{np.median(z):.2f}, max {z.max():.2f}; learned {learned_s:.0f} s"
    )
    bias = {
        k: np.mean([r["odometry_bias_pct"][k] for r in rows]) for k in rows[0]["odometry_bias_pct"]
    }
    print(
        "rear wheel distance over the true distance - 1, mean over the runs: "
        + ", ".join(f"{k} {v:+.3f} %" for k, v in bias.items())
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
