"""``tire-estimation replay BAG --out DIR``: run the estimators over a bag, write a report.

The bag is decoded once (only the topics used), its streams are fed in header-stamp order to
the same :class:`~tire_estimation.core.radius_estimator.RadiusEstimator` the node uses, and
``DIR/metrics.json`` (contract v1) plus PNG plots are written. ``metrics.json`` is written last
and atomically; a failed run removes any stale one, so no partial report looks like a result.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tire_estimation.bag import topics
from tire_estimation.bag.reader import BagData, read_bag
from tire_estimation.core.config import RadiusEstimatorConfig
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.radius_estimator import RadiusEstimator
from tire_estimation.core.tyre_force_kf import TyreForceEstimator, TyreForceKFConfig
from tire_estimation.errors import BagError, ConfigError
from tire_estimation.evaluation import metrics as ev
from tire_estimation.evaluation.residuals import analyze_trace as analyze_residuals
from tire_estimation.evaluation.runner import (
    LateralTrace,
    RadiusTrace,
    run_lateral_estimator,
    run_radius_estimator,
)

NODE_NAME = "estimator_node"


def load_config_sections(path: Path | None) -> dict[str, dict[str, Any]]:
    """Sections of a parameter YAML: ``{"radius": {...}, "tyre_force": {...}, ...}``.

    Accepted layouts: the ROS params file (``estimator_node: ros__parameters: radius.x: v``),
    a mapping with one sub-mapping per section, or flat ``section.x`` keys.
    """
    sections: dict[str, dict[str, Any]] = {}
    if path is None:
        return sections
    try:
        data = yaml.safe_load(Path(path).read_text()) or {}
    except FileNotFoundError as exc:
        raise ConfigError("--config", str(path), "file not found") from exc
    except yaml.YAMLError as exc:
        raise ConfigError("--config", str(path), f"not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError("--config", str(path), "must hold a mapping")
    if NODE_NAME in data:
        data = (data[NODE_NAME] or {}).get("ros__parameters", {}) or {}
    for key, value in data.items():
        if not isinstance(key, str):
            continue
        if isinstance(value, dict):
            sections.setdefault(key, {}).update(value)
        elif "." in key:
            section, name = key.split(".", 1)
            sections.setdefault(section, {})[name] = value
    return sections


def load_radius_config(
    path: Path | None, overrides: dict[str, Any] | None = None
) -> RadiusEstimatorConfig:
    """The ``radius`` section as :class:`RadiusEstimatorConfig` (unknown keys raise)."""
    values = dict(load_config_sections(path).get("radius", {}))
    values.update(overrides or {})
    return RadiusEstimatorConfig.from_dict(values)


@dataclass
class ReplayReport:
    """What a replay produced (``metrics`` is what ``metrics.json`` holds)."""

    out_dir: Path
    metrics: dict[str, Any]

    def summary(self) -> str:
        """A few human-readable lines for the terminal."""
        m = self.metrics
        r = m["radii"]
        lines = [
            f"replayed {m['bag']} ({m['duration_s']:.0f} s of data in {m['wall_s']:.1f} s, "
            f"{m['realtime_factor']:.0f}x real time)"
        ]
        truth = r.get("rmse_vs_truth_m") or {}
        final_truth = r.get("final_error_vs_truth_m") or {}
        for w, est in r["final_radius_error_m"].items():
            if est is None:
                lines.append(f"  {w}: no estimate")
                continue
            std = r["final_radius_error_std_m"][w]
            text = f"  {w}: radius error {1e3 * est:+.3f} mm ± {1e3 * std:.3f} mm"
            if final_truth.get(w) is not None:
                true_err = est - final_truth[w]
                text += (
                    f" | truth {1e3 * true_err:+.3f} mm, final error {1e3 * final_truth[w]:+.3f}"
                    f" mm, RMSE {1e3 * truth[w]:.3f} mm"
                )
            lines.append(text)
        base = r.get("baseline")
        if base and base.get("final_error_vs_truth_m"):
            errs = ", ".join(
                f"{w} {1e3 * e:+.3f}"
                for w, e in base["final_error_vs_truth_m"].items()
                if e is not None
            )
            lines.append(f"  AUG-KF baseline final error vs truth (mm): {errs}")
        pos = m["position"]["rmse_m"]
        if pos is not None:
            lines.append(f"  position RMSE vs {m['position']['against']}: {pos:.2f} m")
        lat = m.get("lateral")
        if lat and lat.get("vy_rmse_m_s") is not None:
            lines.append(
                f"  lateral (tyre-force KF) vs {lat['against']}: vy RMSE "
                f"{lat['vy_rmse_m_s']:.3f} m/s, sideslip {lat['sideslip_rmse_deg']:.2f} deg, "
                f"yaw rate {lat['yaw_rate_rmse_deg_s']:.2f} deg/s"
            )
        res = m["residuals"]
        lines.append(f"  innovations consistent: {res['consistent']}")
        lines.append(f"  report: {self.out_dir / 'metrics.json'}")
        return "\n".join(lines)


def _progress_printer(total: int, enabled: bool) -> Any:
    if not enabled or total < 200_000:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    bar = tqdm(total=total, unit="msg", unit_scale=True, desc="replay", file=sys.stderr)
    last = [0]

    def update(n: int) -> None:
        bar.update(n - last[0])
        last[0] = n
        if n + 10_000 >= total:
            bar.close()

    return update


def _truth_radius_error(bag: BagData) -> tuple[np.ndarray, tuple[str, ...], np.ndarray] | None:
    tr = bag.truth_wheel_radii
    if tr is None or tr.t_ns.size == 0:
        return None
    return tr.t_ns, tuple(tr.names), tr.values


def _reference_positions(
    bag: BagData, trace_t_ns: np.ndarray, ltp: LocalTangentPlane | None
) -> tuple[np.ndarray | None, str]:
    """Truth (or reference) base_link east/north at the trace times in the estimator frame."""
    if ltp is None or trace_t_ns.size == 0:
        return None, "none"
    fix = bag.truth_fix
    if fix is not None and fix.t_ns.size:
        e, n, _ = ltp.to_enu(fix.lat_deg, fix.lon_deg, fix.alt_m)
        en = np.column_stack(
            [np.interp(trace_t_ns, fix.t_ns, e), np.interp(trace_t_ns, fix.t_ns, n)]
        )
        return en, topics.TRUTH_FIX
    ref = bag.reference_odometry
    origin = bag.custom_data.get("tire_estimation.reference_origin_lla")
    if ref is not None and ref.t_ns.size and origin:
        lat0, lon0, alt0 = (float(v) for v in yaml.safe_load(origin))
        ref_ltp = LocalTangentPlane(lat0, lon0, alt0)
        lat, lon, alt = ref_ltp.to_lla(
            ref.position_m[:, 0], ref.position_m[:, 1], ref.position_m[:, 2]
        )
        e, n, _ = ltp.to_enu(lat, lon, alt)
        en = np.column_stack(
            [np.interp(trace_t_ns, ref.t_ns, e), np.interp(trace_t_ns, ref.t_ns, n)]
        )
        return en, topics.REFERENCE_ODOMETRY
    return None, "none"


def _atomic_json(path: Path, payload: dict[str, Any]) -> None:
    fd, tmp = tempfile.mkstemp(prefix=".metrics", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            json.dump(payload, fh, indent=2, allow_nan=False)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _clean(obj: Any) -> Any:
    """JSON-safe copy: numpy scalars to Python, non-finite floats to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        return float(obj) if math.isfinite(float(obj)) else None
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist())
    return obj


def run_replay(
    bag_path: Path | str,
    out_dir: Path | str,
    *,
    config_path: Path | None = None,
    config: RadiusEstimatorConfig | None = None,
    plots: bool = True,
    progress: bool = True,
) -> ReplayReport:
    """Replay ``bag_path`` through the radius estimator; write ``out_dir/metrics.json`` + PNGs."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stale = out / "metrics.json"
    stale.unlink(missing_ok=True)
    cfg = config if config is not None else load_radius_config(config_path)
    tyre_cfg = TyreForceKFConfig.from_dict(load_config_sections(config_path).get("tyre_force", {}))

    wall0 = time.perf_counter()
    bag = read_bag(
        bag_path,
        topics=(
            topics.WHEEL_SPEEDS,
            topics.STEERING,
            topics.IMU_DATA,
            topics.GNSS_FIX,
            topics.TRUTH_FIX,
            topics.TRUTH_WHEEL_RADII,
            topics.REFERENCE_ODOMETRY,
            topics.TIRE_FORCES_TOPIC,
            topics.TRUTH_ODOMETRY,
        ),
        require=(topics.WHEEL_SPEEDS, topics.GNSS_FIX),
    )
    if bag.wheel_speeds is None or bag.wheel_speeds.t_ns.size == 0:
        raise BagError(f"{bag_path}: no wheel speed samples on {topics.WHEEL_SPEEDS}")
    if bag.gnss is None or bag.gnss.t_ns.size == 0:
        raise BagError(f"{bag_path}: no usable GNSS fix on {topics.GNSS_FIX}")
    t_read = time.perf_counter()

    estimator = RadiusEstimator(cfg, bag.vehicle, np.random.default_rng(cfg.seed))
    total = bag.wheel_speeds.t_ns.size + bag.gnss.t_ns.size
    total += bag.steering.t_ns.size if bag.steering is not None else 0
    total += bag.imu.t_ns.size if bag.imu is not None else 0
    trace = run_radius_estimator(
        estimator,
        bag.wheel_speeds,
        bag.gnss,
        bag.steering,
        bag.imu,
        progress=_progress_printer(total, progress),
    )
    lateral = None
    if bag.tire_forces is not None and bag.tire_forces.t_ns.size:
        lateral = run_lateral_estimator(
            TyreForceEstimator(tyre_cfg, bag.vehicle),
            bag.tire_forces,
            bag.wheel_speeds,
            bag.steering,
            bag.imu,
        )
    t_run = time.perf_counter()
    metrics = build_metrics(bag, trace, cfg, lateral)
    metrics["wall_s"] = time.perf_counter() - wall0
    metrics["timing_s"] = {"read": t_read - wall0, "estimate": t_run - t_read}
    metrics["realtime_factor"] = metrics["duration_s"] / max(metrics["wall_s"], 1e-9)
    if plots:
        write_plots(out, bag, trace)
    metrics["plots"] = sorted(p.name for p in out.glob("*.png")) if plots else []
    _atomic_json(stale, _clean(metrics))
    return ReplayReport(out, _clean(metrics))


def build_metrics(
    bag: BagData,
    trace: RadiusTrace,
    cfg: RadiusEstimatorConfig,
    lateral: LateralTrace | None = None,
) -> dict[str, Any]:
    """The contract's metrics.json content (minus the wall-clock fields)."""
    arr = trace.arrays()
    nominal = bag.vehicle.nominal_tire_radius_m
    truth = _truth_radius_error(bag)
    radii = ev.radius_metrics(
        arr["t_ns"],
        bag.start_ns,
        trace.wheel_names,
        arr["radius_error_m"],
        arr["radius_error_std_m"],
        truth,
        nominal,
    )
    if truth is not None and arr["t_ns"].size:
        radii["error_vs_truth_at_10min_m"] = ev.errors_at(
            arr["t_ns"],
            bag.start_ns,
            600.0,
            trace.wheel_names,
            arr["radius_error_m"],
            truth,
            nominal,
        )
    if arr["radius_noise_std_m"].size:
        radii["final_radius_noise_std_m"] = dict(
            zip(trace.wheel_names, arr["radius_noise_std_m"][-1].tolist(), strict=True)
        )
    if arr["baseline_radius_error_m"].size:
        radii["baseline"] = {
            "name": "AUG-KF",
            **ev.radius_metrics(
                arr["t_ns"],
                bag.start_ns,
                trace.wheel_names,
                arr["baseline_radius_error_m"],
                arr["baseline_radius_error_std_m"],
                truth,
                nominal,
            ),
        }
    ltp = LocalTangentPlane(*trace.origin_lla) if trace.origin_lla is not None else None
    ref_en, against = _reference_positions(bag, arr["t_ns"], ltp)
    pos_rmse = ev.position_rmse_m(arr["pose"][:, :2], ref_en) if ref_en is not None else None
    residual_report = analyze_residuals(trace)
    return {
        "bag": str(bag.path),
        "duration_s": bag.duration_s,
        "scenario": bag.scenario,
        "seed": bag.seed,
        "estimator": {"name": "radius_mpf", "config": cfg.to_dict()},
        "radii": radii,
        "position": {"rmse_m": pos_rmse, "against": against},
        "detection": {"alarms": []},
        "stiffness": None,
        "lateral": _lateral_metrics(bag, lateral),
        "residuals": residual_report,
        "dropped_samples": trace.dropped,
        "resample_count": trace.resample_count,
        "events": [
            {"t_s": e.t_s, "kind": e.kind, **{k: v for k, v in e.detail.items()}}
            for e in bag.events
        ],
    }


def _lateral_metrics(bag: BagData, lateral: LateralTrace | None) -> dict[str, Any] | None:
    if lateral is None:
        return None
    arr = lateral.arrays()
    ref = bag.truth_odometry if bag.truth_odometry is not None else bag.reference_odometry
    out: dict[str, Any] = {"source": "tyre_force_kf", "dropped_samples": lateral.dropped}
    if ref is None:
        out.update({"vy_rmse_m_s": None, "sideslip_rmse_deg": None, "yaw_rate_rmse_deg_s": None})
        return out
    out["against"] = (
        topics.TRUTH_ODOMETRY if bag.truth_odometry is not None else topics.REFERENCE_ODOMETRY
    )
    out.update(
        ev.lateral_metrics(
            arr["t_ns"],
            arr["vy_m_s"],
            arr["yaw_rate_rad_s"],
            arr["sideslip_rad"],
            arr["relay"],
            ref.t_ns,
            ref.linear_velocity_m_s,
            ref.angular_velocity_rad_s[:, 2],
        )
    )
    return out


def write_plots(out: Path, bag: BagData, trace: RadiusTrace) -> None:
    """radius_errors.png, trajectory.png, innovations.png in ``out``."""
    from tire_estimation.evaluation import plots

    arr = trace.arrays()
    t_s = (arr["t_ns"] - bag.start_ns) * 1e-9
    nominal = bag.vehicle.nominal_tire_radius_m
    truth = _truth_radius_error(bag)
    truth_plot = None
    if truth is not None:
        truth_plot = ((truth[0] - bag.start_ns) * 1e-9, truth[1], truth[2] - nominal)
    events = [(e.t_s, e.kind) for e in bag.events]
    if t_s.size:
        plots.plot_radius_errors(
            out / "radius_errors.png",
            t_s,
            trace.wheel_names,
            arr["radius_error_m"],
            arr["radius_error_std_m"],
            truth_plot,
            arr["baseline_radius_error_m"] if arr["baseline_radius_error_m"].size else None,
            events,
        )
    ltp = LocalTangentPlane(*trace.origin_lla) if trace.origin_lla is not None else None
    if ltp is not None and bag.gnss is not None:
        e, n, _ = ltp.to_enu(bag.gnss.lat_deg, bag.gnss.lon_deg, bag.gnss.alt_m)
        truth_en = None
        if bag.truth_fix is not None:
            te, tn, _ = ltp.to_enu(
                bag.truth_fix.lat_deg, bag.truth_fix.lon_deg, bag.truth_fix.alt_m
            )
            truth_en = np.column_stack([te, tn])
        plots.plot_trajectory(
            out / "trajectory.png", arr["pose"][:, :2], np.column_stack([e, n]), truth_en
        )
    if arr["innov_t_ns"].size:
        plots.plot_innovations(
            out / "innovations.png",
            (arr["innov_t_ns"] - bag.start_ns) * 1e-9,
            arr["innov_m"],
            arr["innov_cov_m2"],
            arr["nis"],
            arr["accepted"],
        )
