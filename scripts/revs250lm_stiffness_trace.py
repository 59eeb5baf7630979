"""Run the stiffness MPF on a converted Revs bag and keep its trace (issue 5).

The replay's pipeline (`core.pipeline.EstimationPipeline`) with the replay's configuration
sections and seed, the stiffness MPF alone; the filter can start ``--start-s`` seconds into the
bag. Saves every trace array (stiffness and its std per step, vY, sideslip, ...) to an ``.npz``
and prints the stiffness at a few times.

    python scripts/revs250lm_stiffness_trace.py BAG CONFIG.yaml OUT.npz [--start-s 60]
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bag.reader import read_bag
from tire_estimation.core.pipeline import EstimationPipeline, PipelineConfig
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.evaluation.runner import ImuLateralRecorder
from tire_estimation.replay import load_config_sections, replay_topics, section_config
from tire_estimation.sources import stream_samples


def _from(stream: Any, first_ns: int) -> Any:
    """``stream`` without its samples stamped before ``first_ns``."""
    keep = stream.t_ns >= first_ns
    cut = {}
    for f in dataclasses.fields(stream):
        v = getattr(stream, f.name)
        if isinstance(v, np.ndarray) and v.shape[:1] == keep.shape:
            cut[f.name] = v[keep]
    return dataclasses.replace(stream, **cut)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("config", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--start-s", type=float, default=0.0, help="start this far into the bag")
    args = ap.parse_args()
    sections = load_config_sections(args.config)
    cfg = section_config(StiffnessEstimatorConfig, "stiffness", sections.get("stiffness", {}))
    seed = sections.get("radius", {}).get("seed", 0)
    bag = read_bag(args.bag, topics=lambda infos: replay_topics(infos, True))
    if bag.imu is None or bag.steering is None or bag.vehicle_velocity is None:
        raise SystemExit(f"{args.bag}: needs IMU, steering and /vehicle/velocity")
    first = int(bag.imu.t_ns[0] + args.start_s * 1e9)
    imu, steer, vel = (_from(s, first) for s in (bag.imu, bag.steering, bag.vehicle_velocity))
    pipeline = EstimationPipeline(PipelineConfig(seed=seed, stiffness=cfg), bag.vehicle)
    assert pipeline.stiffness is not None
    rec = ImuLateralRecorder(pipeline.stiffness)
    pipeline.observers.append(rec)
    pipeline.push_ordered(stream_samples(imu=imu, steering=steer, velocity=vel))
    arrays = rec.finish(0.0).arrays()
    np.savez(args.out, **arrays)
    t_s = (arrays["t_ns"] - arrays["t_ns"][0]) * 1e-9
    for at in (2.0, 5.0, 10.0, 60.0, float(t_s[-1])):
        i = min(int(np.searchsorted(t_s, at)), t_s.size - 1)
        c = arrays["stiffness"][i]
        print(f"t {t_s[i]:6.1f} s  Cy_f {c[1] / 1e3:6.1f}k  Cy_r {c[2] / 1e3:6.1f}k N/rad")


if __name__ == "__main__":
    main()
