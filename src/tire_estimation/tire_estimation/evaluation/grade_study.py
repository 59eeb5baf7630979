"""Rear radii on hilly roads: the defaults against the road-grade correction, over seeds.

Each seed simulates a drive over sinusoidal hills (``SensorConfig.road_grade_amplitude_rad``,
``road_grade_wavelength_m``) and runs the radius MPF with its defaults and with
``road_grade_correction_gain`` 1 (the wheels roll the slope distance, the GNSS sees the
horizontal one). Printed per run: each rear radius's final error against the truth, in mm and
relative to the nominal radius; then the count within ``--target-pct``.

    python -m tire_estimation.evaluation.grade_study --seeds 20 --amplitude 0.045
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import add_seed_args, run_seeds, write_rows

#: the configurations compared: name -> radius configuration overrides
CONFIGS: dict[str, dict[str, float]] = {
    "default": {},
    "grade_gain_1": {"road_grade_correction_gain": 1.0},
}


def run_seed(
    scenario: str, seed: int, minutes: float, amplitude_rad: float, wavelength_m: float
) -> list[dict[str, Any]]:
    """Both configurations on one simulated drive."""
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.evaluation.runner import run_radius
    from tire_estimation.sim import SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    sensors = SensorConfig(
        road_grade_amplitude_rad=amplitude_rad, road_grade_wavelength_m=wavelength_m
    )
    sim = simulate(scenario, seed=seed, minutes=minutes, sensors=sensors)
    nominal = sim.vehicle.nominal_tire_radius_m
    rows = []
    for name, overrides in CONFIGS.items():
        cfg = RadiusEstimatorConfig.from_dict({**overrides, "seed": seed})
        trace = run_radius(cfg, sim.vehicle, sim_samples(sim, tire_forces=False)).arrays()
        t_end = trace["t_ns"][-1]
        true = np.array(
            [np.interp(t_end, sim.truth.t_ns, sim.truth.wheel_radius_m[:, j]) for j in (2, 3)]
        )
        err = trace["radius_error_m"][-1] - (true - nominal)
        rows.append(
            {"seed": seed, "config": name, "error_mm": (1e3 * err).tolist(),
             "error_pct": (100.0 * err / nominal).tolist()}
        )  # fmt: skip
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary, write ``--out`` (JSON)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument("--amplitude", type=float, default=0.045, help="grade amplitude, rad")
    parser.add_argument("--wavelength", type=float, default=2000.0, help="hill wavelength, m")
    parser.add_argument("--target-pct", type=float, default=0.05)
    parser.add_argument("--out", type=Path, default=None, help="JSON file for every run")
    args = parser.parse_args(argv)
    rows = run_seeds(
        args,
        lambda seed: run_seed(args.scenario, seed, args.minutes, args.amplitude, args.wavelength),
    )
    for name in CONFIGS:
        sel = [r for r in rows if r["config"] == name]
        worst = np.abs([r["error_pct"] for r in sel]).max(axis=1)
        err = np.array([r["error_mm"] for r in sel])
        print(
            f"{name}: both rear radii within {args.target_pct} % on "
            f"{int((worst <= args.target_pct).sum())}/{len(sel)} (max {worst.max():.3f} %); "
            f"mean error {err[:, 0].mean():+.3f} / {err[:, 1].mean():+.3f} mm, RMS "
            f"{np.sqrt(np.mean(err**2)):.3f} mm"
        )
    write_rows(args.out, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
