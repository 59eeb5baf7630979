"""The ``campaign`` sub-command (calibration, ece-r64, merge, redetect) of the
``tire-estimation`` CLI, also stand-alone (:func:`main`)."""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tire_estimation.cli import parse_key_value
from tire_estimation.core.validation import reject_unknown_keys
from tire_estimation.errors import ConfigError, TireEstimationError, one_line
from tire_estimation.evaluation.campaign.execute import Execution
from tire_estimation.evaluation.campaign.spec import (
    GNSS_LEVELS,
    ROAD_LEVELS,
    TYRE_SENSITIVITIES_MM_PER_KPA,
    CampaignError,
    EceCampaignPlan,
)
from tire_estimation.evaluation.campaign.study import (
    merge_ece_r64_campaigns,
    redetect_campaigns,
    run_calibration_study,
    run_ece_r64_campaign,
)
from tire_estimation.paths import out_argument


def _print_progress(row: dict[str, Any], n: int, total: int) -> None:
    bits = [f"[{n}/{total}] {row['case_id']}"]
    if row.get("error"):
        bits.append(f"ERROR {row['error']}")
    elif row["kind"] == "calibration":
        for m in ("mpf", "aug_kf"):
            rel = row.get(f"{m}_rel_err_at_m")
            if rel is not None:
                bits.append(
                    f"{m}: rel {1e3 * rel:+.3f} rl {1e3 * row[f'{m}_abs_err_rl_at_m']:+.3f} "
                    f"rr {1e3 * row[f'{m}_abs_err_rr_at_m']:+.3f} mm"
                )
    else:
        for m in ("mpf", "aug_kf"):
            t = row.get(f"{m}_detection_time_s")
            bits.append(
                f"{m}: {'det ' + format(t / 60, '.1f') + ' min' if t is not None else 'no det'}"
                f", fa {row.get(f'{m}_false_alarms', '?')}"
            )
    bits.append(f"({row.get('sim_s', 0) + row.get('estimate_s', 0):.0f} s)")
    print("  ".join(bits), flush=True)


def _estimator_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.core.radius.config import RadiusEstimatorConfig

    d = dict(items or [])
    try:
        RadiusEstimatorConfig.from_dict(d)
    except ConfigError as exc:
        raise CampaignError(f"--estimator {exc}") from exc
    return d


def _sensor_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.sim import SensorConfig

    d = dict(items or [])
    try:
        reject_unknown_keys(d, (f.name for f in dataclasses.fields(SensorConfig)))
        SensorConfig(**d)
    except ConfigError as exc:
        raise CampaignError(f"--sensor {exc}") from exc
    return d


def _add_sensor_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sensor",
        action="append",
        type=parse_key_value,
        metavar="KEY=VALUE",
        help="SensorConfig override of the simulated drives, e.g. gnss_velocity_enabled=true "
        "(repeatable)",
    )


def _float_list(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as exc:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas: {text!r}"
        ) from exc


def _str_list(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def _add_exec_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, type=out_argument, help="result directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    p.add_argument(
        "--executor",
        choices=("dask", "processes", "serial"),
        default="dask",
        help="dask.distributed (default), a local process pool, or serial",
    )
    p.add_argument("--workers", type=int, default=2, help="local workers (default 2)")
    p.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)"
    )
    p.add_argument(
        "--threads", action="store_true", help="Dask LocalCluster with threads, no processes"
    )
    p.add_argument(
        "--dashboard-address",
        default=None,
        metavar="HOST:PORT",
        help="dashboard of the Dask LocalCluster (default 127.0.0.1:0, this machine only; "
        "':8787' opens it to the network, without authentication)",
    )
    p.add_argument(
        "--estimator",
        action="append",
        type=parse_key_value,
        metavar="KEY=VALUE",
        help="RadiusEstimatorConfig override (repeatable)",
    )


def _execution(args: argparse.Namespace) -> Execution:
    """The execution options of :func:`_add_exec_args`."""
    return Execution(
        args.executor, args.workers, args.scheduler, args.threads, args.dashboard_address
    )


def _p95(stats: dict[str, Any]) -> float:
    return float(stats.get("p95_abs", float("nan")))


def _cmd_calibration(args: argparse.Namespace) -> int:
    summary = run_calibration_study(
        args.out,
        seeds=args.seeds,
        minutes=args.minutes,
        at_min=args.at_min,
        first_seed=args.first_seed,
        gnss=args.gnss,
        execution=_execution(args),
        overwrite=args.overwrite,
        estimator=_estimator_options(args.estimator),
        progress=_print_progress,
        sensors=_sensor_options(args.sensor),
    )
    for m in ("mpf", "aug_kf"):
        s = summary[m]
        print(
            f"{m}: {s['seeds_meeting_all_targets']}/{s['n']} seeds meet both targets at "
            f"{args.at_min:g} min; |rel| p95 {_p95(s['relative_error_at_mm']):.3f} mm, "
            f"|abs| p95 {_p95(s['absolute_error_at_mm']):.3f} mm"
        )
    print(f"wrote {args.out}/summary.json")
    return 0


def _cmd_ece_r64(args: argparse.Namespace) -> int:
    plan = EceCampaignPlan(
        step_cases=args.step_cases,
        robustness_cases=args.robustness_cases,
        diffusion_cases=args.diffusion_cases,
        step_minutes=args.minutes,
        deflation_min=args.deflation_min,
        robustness_minutes=args.robustness_minutes,
        diffusion_minutes=args.diffusion_minutes,
        diffusion_start_min=args.diffusion_start_min,
        detector_calibration_s=60.0 * args.calibration_min,
        wheels=args.wheels,
        braking_source=args.braking,
        first_seed=args.first_seed,
        estimator=_estimator_options(args.estimator),
        tyre_sensitivities_mm_per_kpa=tuple(args.tyres),
        gnss_levels=tuple(args.gnss),
        road_levels=tuple(args.roads),
        sensors=_sensor_options(args.sensor),
    )
    summary = run_ece_r64_campaign(
        args.out,
        plan,
        execution=_execution(args),
        overwrite=args.overwrite,
        progress=_print_progress,
        save_traces=args.save_traces,
    )
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json")
    return 0


def _print_detection_summary(summary: dict[str, Any]) -> None:
    for m in ("mpf", "aug_kf"):
        s = summary[m]
        st, rb = s["step"], s["robustness"]
        print(
            f"{m}: step {st['detected']}/{st['n']} detected ({st['detected_in_time']} within "
            f"10 min), diffusion {s['diffusion']['detected']}/{s['diffusion']['n']}, "
            f"robustness {rb['false_alarms']} false alarms in {rb['monitored_hours']:.2f} h, "
            f"false alarms total {s['false_alarms_total']} (false warnings "
            f"{s['false_warnings_total']}, wrong wheel {s['wrong_wheel_alarms_total']})"
        )


def _cmd_redetect(args: argparse.Namespace) -> int:
    summary = redetect_campaigns(
        args.out, args.campaigns, _detector_options(args.detector), overwrite=args.overwrite
    )
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json ({summary['n_cases']} cases)")
    return 0


def _detector_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.core.deflation.config import DeflationDetectorConfig

    names = {f.name for f in dataclasses.fields(DeflationDetectorConfig)}
    out = dict(items or [])
    try:
        reject_unknown_keys(out, names)
    except ConfigError as exc:
        raise CampaignError(f"--detector {exc}") from exc
    return out


def _cmd_merge(args: argparse.Namespace) -> int:
    summary = merge_ece_r64_campaigns(args.out, args.shards, overwrite=args.overwrite)
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json ({summary['n_cases']} cases)")
    return 0


def add_campaign_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``campaign {calibration,ece-r64}`` to ``subparsers`` (handlers ``(args) -> int``)."""
    camp = subparsers.add_parser(
        "campaign", help="evaluation campaigns on simulated drives (calibration, ECE R-64)"
    )
    sub = camp.add_subparsers(dest="campaign_command", required=True)

    cal = sub.add_parser(
        "calibration", help="MPF vs AUG-KF radius accuracy after calibration over many seeds"
    )
    cal.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    cal.add_argument("--first-seed", type=int, default=0)
    cal.add_argument("--minutes", type=float, default=12.0, help="drive length (default 12)")
    cal.add_argument("--at-min", type=float, default=10.0, help="evaluation time (default 10)")
    cal.add_argument(
        "--gnss",
        choices=tuple(GNSS_LEVELS),
        default="calibration",
        help="GNSS level (default: calibration, 1.5 m total per axis)",
    )
    _add_sensor_arg(cal)
    _add_exec_args(cal)
    cal.set_defaults(func=_cmd_calibration)

    ece = sub.add_parser("ece-r64", help="ECE R-64 detection campaign (MPF vs AUG-KF + CUSUM)")
    ece.add_argument("--step-cases", type=int, default=12)
    ece.add_argument("--robustness-cases", type=int, default=4)
    ece.add_argument("--diffusion-cases", type=int, default=4)
    ece.add_argument("--minutes", type=float, default=35.0, help="step-case drive length")
    ece.add_argument(
        "--deflation-min", type=float, default=None, help="step time (default 63 %%, <= 22 min)"
    )
    ece.add_argument("--robustness-minutes", type=float, default=60.0)
    ece.add_argument("--diffusion-minutes", type=float, default=60.0)
    ece.add_argument("--diffusion-start-min", type=float, default=None)
    ece.add_argument(
        "--calibration-min",
        type=float,
        default=20.0,
        help="CUSUM calibration driving time (ECE R-64: 20), capped at 80 %% of the time "
        "before the event",
    )
    ece.add_argument("--wheels", choices=("rear", "all"), default="rear")
    ece.add_argument("--braking", choices=("estimate", "truth"), default="estimate")
    ece.add_argument(
        "--tyres",
        type=_float_list,
        default=TYRE_SENSITIVITIES_MM_PER_KPA,
        help="tyre radius sensitivities, mm/kPa, comma separated (default 0.015,0.03,0.05)",
    )
    ece.add_argument(
        "--gnss",
        type=_str_list,
        default=("good", "standard", "poor"),
        help=f"GNSS levels, comma separated, of {','.join(GNSS_LEVELS)}",
    )
    ece.add_argument(
        "--roads",
        type=_str_list,
        default=tuple(ROAD_LEVELS),
        help=f"road levels, comma separated, of {','.join(ROAD_LEVELS)}",
    )
    ece.add_argument("--first-seed", type=int, default=1000)
    ece.add_argument(
        "--save-traces",
        action="store_true",
        help="keep each case's estimator traces in OUT/traces (for campaign redetect)",
    )
    _add_sensor_arg(ece)
    _add_exec_args(ece)
    ece.set_defaults(func=_cmd_ece_r64)

    mrg = sub.add_parser(
        "merge", help="pool finished ece-r64 campaign directories (shards) into one summary"
    )
    mrg.add_argument("shards", nargs="+", type=Path, help="campaign directories")
    mrg.add_argument("--out", type=out_argument, required=True, help="result directory")
    mrg.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    mrg.set_defaults(func=_cmd_merge)

    red = sub.add_parser(
        "redetect",
        help="re-run only the detection on the saved traces of campaigns (--save-traces)",
    )
    red.add_argument("campaigns", nargs="+", type=Path, help="campaign directories")
    red.add_argument("--out", type=out_argument, required=True, help="result directory")
    red.add_argument(
        "--detector",
        type=parse_key_value,
        action="append",
        metavar="KEY=VALUE",
        help="DeflationDetectorConfig override (repeatable)",
    )
    red.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    red.set_defaults(func=_cmd_redetect)
    return camp


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry point (``python -m tire_estimation.evaluation.campaign``)."""
    from tire_estimation.cli import Parser  # one-line argument errors

    parser = Parser(prog="tire-estimation")
    subparsers = parser.add_subparsers(dest="command", required=True)
    add_campaign_parser(subparsers)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except TireEstimationError as exc:
        print(one_line(f"tire-estimation: error: {exc}"), file=sys.stderr)
        return 2
