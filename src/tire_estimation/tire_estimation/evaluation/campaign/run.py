"""One case end to end: simulate, estimate (MPF + AUG-KF in one run) and score
(:func:`run_case`), or score again from a saved trace (:func:`redetect_case`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.evaluation.campaign.score import score_case
from tire_estimation.evaluation.campaign.spec import PF_SEED_OFFSET, CaseSpec
from tire_estimation.evaluation.campaign.trace import CaseRun, save_run


def _simulate_and_estimate(spec: CaseSpec) -> CaseRun:
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.wheels import REAR_WHEELS
    from tire_estimation.evaluation.runner import run_radius
    from tire_estimation.sim import START_TIME_NS, SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    t0 = time.perf_counter()
    sensors = SensorConfig(**spec.sensors)
    sim = simulate(
        spec.scenario, seed=spec.seed, minutes=spec.minutes, sensors=sensors, **spec.options
    )
    t1 = time.perf_counter()
    cfg = RadiusEstimatorConfig.from_dict(
        {**spec.estimator, "run_aug_kf": True, "seed": spec.seed + PF_SEED_OFFSET}
    )
    trace = run_radius(cfg, sim.vehicle, sim_samples(sim, tire_forces=False))
    t2 = time.perf_counter()
    a = trace.arrays()
    names = trace.wheel_names or (REAR_WHEELS if cfg.wheels == "rear" else ())
    k = a["t_ns"].size
    kf = a["baseline_radius_error_m"]
    kf_std = a["baseline_radius_error_std_m"]
    if kf.shape[0] != k:
        kf = np.full((k, len(REAR_WHEELS)), np.nan)
        kf_std = np.full((k, len(REAR_WHEELS)), np.nan)
    return CaseRun(
        t_ns=a["t_ns"],
        t_s=(a["t_ns"] - START_TIME_NS) * 1e-9,
        wheel_names=tuple(names),
        mpf_m=np.asarray(a["radius_error_m"], dtype=float).reshape(k, len(names)),
        mpf_std_m=np.asarray(a["radius_error_std_m"], dtype=float).reshape(k, len(names)),
        kf_wheels=REAR_WHEELS,
        kf_m=np.asarray(kf, dtype=float).reshape(k, len(REAR_WHEELS)),
        kf_std_m=np.asarray(kf_std, dtype=float).reshape(k, len(REAR_WHEELS)),
        speed_m_s=np.asarray(a["speed_m_s"], dtype=float),
        active=np.asarray(a["active"], dtype=bool).reshape(k, len(names)),
        truth_t_ns=sim.truth.t_ns,
        truth_radius_m=sim.truth.wheel_radius_m,
        truth_ax_m_s2=sim.truth.acceleration_m_s2[:, 0],
        nominal_m=float(sim.vehicle.nominal_tire_radius_m),
        sim_s=t1 - t0,
        est_s=t2 - t1,
    )


def _case_row(spec: CaseSpec) -> dict[str, Any]:
    row: dict[str, Any] = {
        "case_id": spec.case_id,
        "kind": spec.kind,
        "scenario": spec.scenario,
        "seed": spec.seed,
        "minutes": spec.minutes,
        "deflated_wheels": ",".join(spec.deflated_wheels),
        "event_s": spec.event_s,
        "deadline_s": spec.deadline_s,
        **{f"label_{k}": v for k, v in spec.labels.items()},
        "error": "",
    }
    return row


def run_case(spec: CaseSpec, accuracy_at_s: float = 600.0) -> dict[str, Any]:
    """Simulate, estimate (MPF + AUG-KF) and evaluate one case; a flat JSON-ready row.

    Never raises for a failing case: the row then has ``error`` set (so one bad case does not
    lose a campaign).
    """
    row = _case_row(spec)
    try:
        run = _simulate_and_estimate(spec)
        if spec.trace_dir:
            save_run(run, Path(spec.trace_dir) / f"{spec.case_id}.npz")
        row["sim_s"] = round(run.sim_s, 2)
        row["estimate_s"] = round(run.est_s, 2)
        row["trace_samples"] = int(run.t_ns.size)
        score_case(spec, run, row, accuracy_at_s)
    except Exception as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
    return row


def redetect_case(spec: CaseSpec, run: CaseRun) -> dict[str, Any]:
    """The row of :func:`run_case` from a saved trace (no simulation), e.g. with other
    detector settings in ``spec.detector``."""
    row = _case_row(spec)
    row["trace_samples"] = int(run.t_ns.size)
    try:
        score_case(spec, run, row, 600.0)
    except Exception as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
    return row
