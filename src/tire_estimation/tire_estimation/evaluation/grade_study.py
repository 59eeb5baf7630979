"""Rear radii on hilly roads: the road-grade correction off, on the GNSS altitude alone and
the default (the altitude's grade checked against the IMU's), over seeds.

Each seed simulates a drive over sinusoidal hills (``SensorConfig.road_grade_amplitude_rad``,
``road_grade_wavelength_m``; the wheels roll the slope distance, the GNSS sees the horizontal
one) and runs the radius MPF in each configuration of :data:`CONFIGS`. Printed per run: each
rear radius's final error against the truth, in mm and relative to the nominal radius, its
reported std and the fixes per grade source; then the count within ``--target-pct``.

    python -m tire_estimation.evaluation.grade_study --seeds 20 --amplitude 0.045
"""

from __future__ import annotations

import argparse
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import (
    add_seed_args,
    key_values,
    run_seeds,
    within,
)

#: the configurations compared: name -> radius configuration overrides
CONFIGS: dict[str, dict[str, float | str]] = {
    "no_correction": {"road_grade_correction_gain": 0.0},
    "altitude_grade": {"road_grade_correction_gain": 1.0, "road_grade_source": "altitude"},
    "default": {},
}


def run_seed(
    scenario: str,
    seed: int,
    minutes: float,
    amplitude_rad: float,
    wavelength_m: float,
    names: Sequence[str] = tuple(CONFIGS),
    sensors: Mapping[str, Any] | None = None,
) -> list[dict[str, Any]]:
    """The configurations ``names`` on one simulated drive (``SensorConfig`` overrides
    ``sensors`` besides the grade)."""
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.evaluation.runner import RadiusRecorder, radius_pipeline
    from tire_estimation.sim import SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    grade = {"road_grade_amplitude_rad": amplitude_rad, "road_grade_wavelength_m": wavelength_m}
    sim_sensors = SensorConfig(**{**(sensors or {}), **grade})
    sim = simulate(scenario, seed=seed, minutes=minutes, sensors=sim_sensors)
    nominal = sim.vehicle.nominal_tire_radius_m
    rows = []
    for name in names:
        overrides = CONFIGS[name]
        cfg = RadiusEstimatorConfig.from_dict({**overrides, "seed": seed})
        recorder = RadiusRecorder()
        pipeline = radius_pipeline(cfg, sim.vehicle, recorder)
        pipeline.push_ordered(sim_samples(sim, tire_forces=False))
        trace = recorder.finish(pipeline).arrays()
        counts = pipeline.radius.estimate().road_grade_counts if pipeline.radius else {}
        t_end = trace["t_ns"][-1]
        true = np.array(
            [np.interp(t_end, sim.truth.t_ns, sim.truth.wheel_radius_m[:, j]) for j in (2, 3)]
        )
        err = trace["radius_error_m"][-1] - (true - nominal)
        rows.append(
            {"seed": seed, "config": name, "error_mm": (1e3 * err).tolist(),
             "error_pct": (100.0 * err / nominal).tolist(),
             "std_mm": (1e3 * trace["radius_error_std_m"][-1]).tolist(),
             "grade_sources": dict(counts)}
        )  # fmt: skip
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary, write ``--out`` (JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument("--amplitude", type=float, default=0.045, help="grade amplitude, rad")
    parser.add_argument("--wavelength", type=float, default=2000.0, help="hill wavelength, m")
    parser.add_argument("--target-pct", type=float, default=0.05)
    parser.add_argument(
        "--configs", nargs="+", choices=tuple(CONFIGS), default=list(CONFIGS),
        help="the configurations to run (default: all)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    rows = run_seeds(
        args,
        lambda seed: run_seed(
            args.scenario,
            seed,
            args.minutes,
            args.amplitude,
            args.wavelength,
            args.configs,
            key_values(args.sensor),
        ),
    )
    for name in args.configs:
        sel = [r for r in rows if r["config"] == name]
        pct = [r["error_pct"] for r in sel]
        err = np.array([r["error_mm"] for r in sel])
        z = err / np.array([r["std_mm"] for r in sel])
        print(
            f"{name}: both rear radii {within(pct, args.target_pct)}; "
            f"mean error {err[:, 0].mean():+.3f} / {err[:, 1].mean():+.3f} mm, RMS "
            f"{np.sqrt(np.mean(err**2)):.3f} mm; RMS error / reported std "
            f"{np.sqrt(np.mean(z**2)):.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
