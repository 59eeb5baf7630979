"""A simulated drive through the radius MPF: the shared start of the radius studies."""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any


def simulated_radius_run(
    scenario: str,
    seed: int,
    minutes: float,
    radius: Mapping[str, Any],
    sensors: Mapping[str, Any],
) -> tuple[Any, Any, Any]:
    """Simulate ``scenario`` (seed, minutes, ``SensorConfig`` overrides ``sensors``) and push it
    through a pipeline with the radius MPF (``RadiusEstimatorConfig`` overrides ``radius``, the
    filter seeded with ``seed``). Returns (the simulation, the pipeline, the radius trace)."""
    from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.evaluation.runner import RadiusRecorder
    from tire_estimation.sim import SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    sim = simulate(scenario, seed=seed, minutes=minutes, sensors=SensorConfig(**sensors))
    rec = RadiusRecorder()
    cfg = RadiusEstimatorConfig.from_dict({"seed": seed, **radius})
    pipeline = EstimationPipeline(
        PipelineConfig(seed=seed, radius=cfg), sim.vehicle, observers=[rec]
    )
    pipeline.push_ordered(sim_samples(sim, tire_forces=False))
    return sim, pipeline, rec.finish(pipeline)


def key_values(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` command-line items as a mapping (values read as JSON, ``true``/``false``
    as booleans)."""
    out: dict[str, Any] = {}
    for item in items:
        key, _, value = item.partition("=")
        out[key] = json.loads(value) if value not in ("true", "false") else value == "true"
    return out
