"""Is the radius filter's uncertainty honest, and does the residual verdict carry information?

Each seed simulates a drive (default ``robustness``, the simulator's default GNSS: white plus
slowly varying error) with optional injected effects (``--sensor KEY=VALUE``, a
:class:`~tire_estimation.sim.SensorConfig` field) and runs the radius MPF (``--set KEY=VALUE``
overrides its configuration) through the pipeline. Per run: the residual verdict of the replay
(:func:`~tire_estimation.evaluation.residuals.analyze_trace`: mean NIS within its band, the
decimated innovations white, no effect signature significant), the mean NIS, and the NEES of
the rear radii, ``mean over time and wheels of ((estimate - truth) / std)^2`` after the first
``--skip-min`` minutes (1 when the reported std is the error's).

    python -m tire_estimation.evaluation.consistency_study --seeds 20 --minutes 10

``--vehicle vehicle.yaml`` simulates another vehicle (geometry, antenna, tyres) than the
simulator's default car.
"""

from __future__ import annotations

import argparse
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation.sim_runs import (
    add_key_value_arg,
    add_seed_args,
    add_vehicle_arg,
    key_values,
    run_seeds,
    simulated_radius_run,
    vehicle_arg,
)


def run_one(
    seed: int,
    minutes: float,
    overrides: Mapping[str, Any],
    sensors: Mapping[str, Any],
    scenario: str = "robustness",
    skip_min: float = 3.0,
    vehicle: Any = None,
) -> dict[str, Any]:
    """One drive (of ``vehicle``, a ``VehicleParams``; None: the simulator's default car):
    verdict, mean NIS, whiteness p values, NEES of the rear radii."""
    from tire_estimation.evaluation.residuals import analyze_trace

    sim, _pipeline, trace = simulated_radius_run(
        scenario, seed, minutes, overrides, sensors, vehicle=vehicle
    )
    nominal = sim.vehicle.nominal_tire_radius_m
    a = trace.arrays()
    t = a["t_ns"]
    truth = np.column_stack(
        [np.interp(t, sim.truth.t_ns, sim.truth.wheel_radius_m[:, i]) - nominal for i in (2, 3)]
    )
    late = (t - t[0]) * 1e-9 >= 60.0 * skip_min
    z = (a["radius_error_m"][late] - truth[late]) / np.maximum(
        a["radius_error_std_m"][late], 1e-12
    )
    res = analyze_trace(trace)
    tests = res["tests"]
    lb = tests.get("ljung_box_decimated", {})
    return {
        "seed": seed,
        "consistent": res["consistent"],
        "suspected": [e["effect"] for e in res["suspected_effects"]],
        "first_estimate": (
            res["suspected_effects"][0].get("estimate") if res["suspected_effects"] else None
        ),
        "mean_nis": tests.get("mean_nis"),
        "nis_ok": tests.get("mean_nis_ok"),
        "white": tests.get("white_decimated"),
        "p_along": lb.get("p_along"),
        "p_cross": lb.get("p_cross"),
        "nees": float(np.mean(z**2)) if z.size else None,
        "final_error_mm": (1e3 * (a["radius_error_m"][-1] - truth[-1])).tolist(),
    }


def summary(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """The study's two summary lines over the drives' :func:`run_one` rows (a drive with
    nothing to test, ``consistent`` None, is counted apart)."""
    nees = np.array([r["nees"] for r in rows if r["nees"] is not None])
    nis = np.array([r["mean_nis"] for r in rows if r["mean_nis"] is not None])
    untested = sum(r["consistent"] is None for r in rows)
    firsts = Counter(
        r["suspected"][0] for r in rows if r["consistent"] is False and r["suspected"]
    )
    sizes = [r["first_estimate"] for r in rows if r["first_estimate"] is not None]
    return [
        f"consistent on {sum(r['consistent'] is True for r in rows)}/{len(rows)}"
        + (f" ({untested} with nothing to test)" if untested else "")
        + f" (mean NIS ok on {sum(bool(r['nis_ok']) for r in rows)}, white on "
        f"{sum(bool(r['white']) for r in rows)}); NEES median {np.median(nees):.2f} (range "
        f"{nees.min():.2f}-{nees.max():.2f}); mean NIS median {np.median(nis):.2f}",
        "first suspected effect: "
        + (", ".join(f"{name} {k}" for name, k in firsts.most_common()) or "none")
        + (f"; its size median {np.median(sizes):.3g}" if sizes else ""),
    ]


def main(argv: Sequence[str] | None = None) -> int:
    """Command line: run the seeds, print each run and a summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_seed_args(parser, "robustness", 10.0)
    parser.add_argument("--skip-min", type=float, default=3.0)
    add_key_value_arg(parser, "--set", "radius estimator setting (JSON value)")
    add_vehicle_arg(parser)
    args = parser.parse_args(argv)
    overrides, sensors = key_values(args.set), key_values(args.sensor)
    vehicle = vehicle_arg(args)
    rows = run_seeds(
        args,
        lambda seed: [
            run_one(seed, args.minutes, overrides, sensors, args.scenario, args.skip_min, vehicle)
        ],
    )
    print("\n".join(summary(rows)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
