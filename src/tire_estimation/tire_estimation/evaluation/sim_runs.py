"""Simulated drives through the radius MPF: the shared start and seed loop of the radius
studies (``axle_study``, ``grade_study``, ``slow_study``, ``consistency_study``)."""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.atomic_io import atomic_write_text


def simulated_radius_run(
    scenario: str,
    seed: int,
    minutes: float,
    radius: Mapping[str, Any],
    sensors: Mapping[str, Any],
    vehicle: Any = None,
    stated_vehicle: Any = None,
    before_push: Callable[[Any], None] | None = None,
    rewrite: Callable[[Any], Any] | None = None,
) -> tuple[Any, Any, Any]:
    """Simulate ``scenario`` (seed, minutes, ``SensorConfig`` overrides ``sensors``, the
    simulator's ``vehicle`` or its default) and push it through a pipeline with the radius MPF
    (``RadiusEstimatorConfig`` overrides ``radius``, the filter seeded with ``seed``) that is
    told ``stated_vehicle`` (default: the simulated one); ``before_push(pipeline)`` runs before
    the samples are pushed; ``rewrite(sim)`` returns the simulation whose samples are pushed (a
    sensor's wiring changed; the truth stays). Returns (the simulation, the pipeline, the radius
    trace)."""
    from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.evaluation.runner import RadiusRecorder
    from tire_estimation.sim import SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    sim = simulate(
        scenario, seed=seed, minutes=minutes, sensors=SensorConfig(**sensors), vehicle=vehicle
    )
    rec = RadiusRecorder()
    cfg = RadiusEstimatorConfig.from_dict({"seed": seed, **radius})
    pipeline = EstimationPipeline(
        PipelineConfig(seed=seed, radius=cfg),
        sim.vehicle if stated_vehicle is None else stated_vehicle,
        observers=[rec],
        outputs=False,
    )
    if before_push is not None:
        before_push(pipeline)
    pushed = sim if rewrite is None else rewrite(sim)
    pipeline.push_ordered(sim_samples(pushed, tire_forces=False))
    return sim, pipeline, rec.finish(pipeline)


def key_values(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` command-line items as a mapping (values read as JSON, ``true``/``false``
    as booleans)."""
    out: dict[str, Any] = {}
    for item in items:
        key, _, value = item.partition("=")
        out[key] = json.loads(value) if value not in ("true", "false") else value == "true"
    return out


def add_seed_args(parser: argparse.ArgumentParser, scenario: str, minutes: float) -> None:
    """``--scenario``, ``--minutes``, ``--seeds`` (default 20), ``--first-seed`` (0), the
    repeatable ``--sensor KEY=VALUE`` (``SensorConfig`` of the simulated drives; read with
    :func:`key_values`) and ``--out`` (a JSON file for every run, :func:`run_seeds`)."""
    parser.add_argument("--scenario", default=scenario)
    parser.add_argument("--minutes", type=float, default=minutes)
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=0)
    add_key_value_arg(
        parser, "--sensor", "SensorConfig field of the simulated drives (JSON value)"
    )
    parser.add_argument("--out", type=Path, default=None, help="JSON file for every run")


def add_vehicle_arg(parser: argparse.ArgumentParser) -> None:
    """``--vehicle YAML``: the simulated vehicle (:func:`vehicle_arg` loads it)."""
    parser.add_argument(
        "--vehicle", default=None, metavar="YAML", help="vehicle.yaml of the simulated vehicle"
    )


def vehicle_arg(args: argparse.Namespace) -> Any:
    """The ``VehicleParams`` of ``--vehicle``, or None (the simulator's default car)."""
    if args.vehicle is None:
        return None
    from tire_estimation.core.vehicle import load_vehicle_yaml

    return load_vehicle_yaml(args.vehicle)


def add_key_value_arg(parser: argparse.ArgumentParser, flag: str, help_text: str) -> None:
    """A repeatable ``flag KEY=VALUE`` option (read with :func:`key_values`)."""
    parser.add_argument(flag, action="append", default=[], metavar="KEY=VALUE", help=help_text)


def run_seeds(
    args: argparse.Namespace, run: Callable[[int], Sequence[dict[str, Any]]]
) -> list[dict[str, Any]]:
    """The rows of ``run(seed)`` for the ``args.seeds`` seeds from ``args.first_seed``, each
    printed as one JSON line as it comes, all written to ``args.out`` when it is set."""
    rows: list[dict[str, Any]] = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        for row in run(seed):
            rows.append(row)
            print(json.dumps(row), flush=True)
    write_rows(getattr(args, "out", None), rows)
    return rows


def within(errors_pct: Any, target_pct: float) -> str:
    """``within T % on n/N (max M %)``: the drives (rows of ``errors_pct``, one radius or more
    each, %) whose every error is within ``target_pct``, and the largest error."""
    rel = np.abs(np.asarray(errors_pct, dtype=float)).reshape(len(errors_pct), -1)
    ok = int(np.all(rel <= target_pct, axis=1).sum())
    return f"within {target_pct:g} % on {ok}/{len(rel)} (max {rel.max():.3f} %)"


def write_rows(path: Path | None, rows: Sequence[dict[str, Any]]) -> None:
    """Every run as JSON in ``path`` (nothing when ``None``)."""
    if path is not None:
        atomic_write_text(path, json.dumps(rows, indent=1))
