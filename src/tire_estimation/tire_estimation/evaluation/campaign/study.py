"""Campaign runs writing a result directory: the calibration study, the ECE R-64
campaign, the merge of shards and the detection re-run on saved traces."""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.evaluation.campaign.execute import Execution, execute_cases
from tire_estimation.evaluation.campaign.output import (
    plot_calibration,
    plot_detection,
    prepare_out,
    read_csv_rows,
    versions,
    write_csv,
)
from tire_estimation.evaluation.campaign.run import redetect_case
from tire_estimation.evaluation.campaign.spec import (
    GNSS_LEVELS,
    ROAD_LEVELS,
    CampaignError,
    CaseSpec,
    EceCampaignPlan,
    calibration_cases,
    ece_r64_cases,
)
from tire_estimation.evaluation.campaign.summary import (
    summarize_calibration,
    summarize_detection,
)
from tire_estimation.evaluation.campaign.trace import load_run


def run_calibration_study(
    out: Path | str,
    seeds: int = 20,
    minutes: float = 12.0,
    at_min: float = 10.0,
    first_seed: int = 0,
    gnss: str = "calibration",
    execution: Execution | None = None,
    overwrite: bool = False,
    estimator: dict[str, Any] | None = None,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    sensors: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Issue-3 study: ``summary.json``, ``cases.csv``, ``calibration_errors.png`` in ``out``
    (the cases run as ``execution`` says, default :class:`Execution`)."""
    if not 0.0 < at_min <= minutes:
        raise CampaignError(f"at_min={at_min!r}: must be within (0, minutes={minutes}]")
    out_dir = prepare_out(out, overwrite)
    cases = calibration_cases(seeds, minutes, first_seed, gnss, estimator, sensors)
    t0 = time.perf_counter()
    ex = execution or Execution()
    rows = execute_cases(cases, ex, progress, accuracy_at_s=60.0 * at_min)
    summary = summarize_calibration(rows, 60.0 * at_min)
    summary["config"] = {
        "seeds": seeds,
        "first_seed": first_seed,
        "minutes": minutes,
        "at_min": at_min,
        "gnss": {gnss: GNSS_LEVELS[gnss]},
        "estimator_overrides": estimator or {},
        "sensor_overrides": sensors or {},
        "executor": ex.executor,
        "n_workers": ex.n_workers,
    }
    summary["wall_time_s"] = time.perf_counter() - t0
    summary["versions"] = versions()
    write_csv(out_dir / "cases.csv", rows)
    plot_calibration(out_dir / "calibration_errors.png", rows, 60.0 * at_min)
    summary["files"] = ["summary.json", "cases.csv", "calibration_errors.png"]
    atomic_write_text(out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def run_ece_r64_campaign(
    out: Path | str,
    plan: EceCampaignPlan,
    execution: Execution | None = None,
    overwrite: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    save_traces: bool = False,
) -> dict[str, Any]:
    """Issue-4 campaign: ``summary.json``, ``cases.csv``, ``cases.json`` and PNGs in ``out``.

    The cases run as ``execution`` says (default :class:`Execution`); ``save_traces`` keeps
    every case's estimator traces in ``out/traces`` (about 2 MB per 25-min case) for
    :func:`redetect_campaigns`.
    """
    out_dir = prepare_out(out, overwrite)
    cases = ece_r64_cases(plan)
    if not cases:
        raise CampaignError("the campaign has no cases")
    if save_traces:
        trace_dir = out_dir / "traces"
        trace_dir.mkdir(exist_ok=True)
        cases = [dataclasses.replace(c, trace_dir=str(trace_dir.resolve())) for c in cases]
    atomic_write_text(out_dir / "cases.json", json.dumps([c.to_dict() for c in cases], indent=1))
    t0 = time.perf_counter()
    ex = execution or Execution()
    rows = execute_cases(cases, ex, progress)
    summary = summarize_detection(rows)
    plan_d = dataclasses.asdict(plan)
    plan_d["deflation_s"] = plan.deflation_s
    summary["config"] = {
        "plan": plan_d,
        "executor": ex.executor,
        "n_workers": ex.n_workers,
        "scheduler": ex.scheduler,
        "braking": (
            "deceleration of the estimator's speed, low-passed (1 s), > 1 m/s^2"
            if plan.braking_source == "estimate"
            else "true longitudinal deceleration > 1 m/s^2"
        ),
        "gnss_levels": GNSS_LEVELS,
        "road_levels": ROAD_LEVELS,
        "road_roughness": "not modelled by the simulator; 'hilly' varies the road grade",
    }
    summary["wall_time_s"] = time.perf_counter() - t0
    summary["versions"] = versions()
    write_csv(out_dir / "cases.csv", rows)
    summary["files"] = ["summary.json", "cases.csv", "cases.json", *plot_detection(out_dir, rows)]
    atomic_write_text(out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def _write_pooled(
    out: Path | str, rows: list[dict[str, Any]], config: dict[str, Any], overwrite: bool
) -> dict[str, Any]:
    """``summary.json``, ``cases.csv`` and the plots of pooled detection rows in ``out``."""
    out_dir = prepare_out(out, overwrite)
    summary = summarize_detection(rows)
    summary["config"] = config
    summary["versions"] = versions()
    write_csv(out_dir / "cases.csv", rows)
    summary["files"] = ["summary.json", "cases.csv", *plot_detection(out_dir, rows)]
    atomic_write_text(out_dir / "summary.json", json.dumps(summary, indent=2) + "\n")
    return summary


def merge_ece_r64_campaigns(
    out: Path | str, shards: Sequence[Path | str], overwrite: bool = False
) -> dict[str, Any]:
    """One ``summary.json`` (and ``cases.csv``, PNGs) over several campaign directories.

    A long campaign can run as shards (different ``--first-seed``, on different machines or one
    after the other, each complete on its own); this pools their per-case rows. Two shards that
    contain the same simulator seed are refused (the same drive counted twice). Each row gets a
    ``shard`` column with its directory name.
    """
    rows: list[dict[str, Any]] = []
    seen: dict[int, str] = {}
    configs = []
    for shard in shards:
        d = Path(shard)
        csv_path, summary_path = d / "cases.csv", d / "summary.json"
        if not csv_path.is_file() or not summary_path.is_file():
            raise CampaignError(f"{d}: not a finished campaign (no cases.csv / summary.json)")
        summary = json.loads(summary_path.read_text())
        if summary.get("study") != "ece_r64":
            raise CampaignError(f"{d}: not an ece-r64 campaign ({summary.get('study')!r})")
        configs.append({"shard": d.name, **summary.get("config", {})})
        for r in read_csv_rows(csv_path):
            seed = int(r["seed"])
            if seed in seen:
                raise CampaignError(f"seed {seed} is in both {seen[seed]} and {d}")
            seen[seed] = str(d)
            rows.append({"shard": d.name, **r})
    if not rows:
        raise CampaignError("the shards have no cases")
    config = {"merged_from": [str(Path(x)) for x in shards], "shards": configs}
    return _write_pooled(out, rows, config, overwrite)


def redetect_campaigns(
    out: Path | str,
    campaigns: Sequence[Path | str],
    detector: dict[str, Any] | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Detection re-run on the saved traces of finished campaigns (``--save-traces``).

    No simulation and no estimator: every case of each campaign's ``cases.json`` is evaluated
    again from ``traces/<case_id>.npz`` with the detector settings of the campaign overridden by
    ``detector`` (DeflationDetectorConfig fields). Writes ``summary.json``, ``cases.csv`` and
    the plots to ``out``. Several campaign directories are pooled as by
    :func:`merge_ece_r64_campaigns` (duplicate seeds refused).
    """
    detector = dict(detector or {})
    rows: list[dict[str, Any]] = []
    seen: dict[int, str] = {}
    for camp in campaigns:
        d = Path(camp)
        specs_path = d / "cases.json"
        if not specs_path.is_file():
            raise CampaignError(f"{d}: no cases.json")
        for item in json.loads(specs_path.read_text()):
            spec = CaseSpec.from_dict(item)
            trace = d / "traces" / f"{spec.case_id}.npz"
            if not trace.is_file():
                raise CampaignError(f"{trace}: missing (run the campaign with --save-traces)")
            if spec.seed in seen:
                raise CampaignError(f"seed {spec.seed} is in both {seen[spec.seed]} and {d}")
            seen[spec.seed] = str(d)
            spec = dataclasses.replace(spec, detector={**spec.detector, **detector})
            rows.append({"shard": d.name, **redetect_case(spec, load_run(trace))})
    if not rows:
        raise CampaignError("the campaigns have no cases")
    config = {
        "redetected_from": [str(Path(x)) for x in campaigns],
        "detector": detector,
    }
    return _write_pooled(out, rows, config, overwrite)
