"""``tire-estimation replay BAG --out DIR``: run the estimators over a bag, write a report.

The bag is read, decoded and estimated in one pass, in windows of log time (only the topics
used; memory does not grow with the drive), its streams are fed in header-stamp order to the
same :class:`~tire_estimation.core.pipeline.EstimationPipeline` the node uses, and
``DIR/metrics.json`` (contract v1) plus PNG plots are written. A run first removes the report
of an earlier run from ``DIR`` (``metrics.json`` and the plots, :data:`REPORT_FILES`), removes
what it wrote if it fails, and writes ``metrics.json`` last and atomically: a report in ``DIR``
is always that of the last run, complete.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tire_estimation.atomic_io import atomic_write_json, atomic_write_text
from tire_estimation.bag import topics
from tire_estimation.bag.reader import TopicInfo
from tire_estimation.bag.stream import WINDOW_S, BagStream, stream_bag
from tire_estimation.core import yamlio
from tire_estimation.core.clock_check import ClockCheck, leading_check
from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.imu_mounting import GRAVITY_SAMPLES, MountingResult
from tire_estimation.core.input_checks import merged_counts
from tire_estimation.core.lateral.linear_kf import LinearLateralKF, LinearLateralKFConfig
from tire_estimation.core.lateral.tyre_force_kf import TyreForceKFConfig
from tire_estimation.core.pipeline import EstimationPipeline, Observer, PipelineConfig
from tire_estimation.core.radius.axle_check import LOST_SPEED_SHARE, AxleCheck
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import REAR_WHEELS
from tire_estimation.errors import BagError, ConfigError
from tire_estimation.evaluation import metrics as ev
from tire_estimation.evaluation.residuals import analyze_trace as analyze_residuals
from tire_estimation.evaluation.residuals import explain as explain_residuals
from tire_estimation.evaluation.runner import (
    DeflationRecorder,
    ImuLateralRecorder,
    ImuLateralTrace,
    LateralTrace,
    RadiusRecorder,
    RadiusTrace,
    TyreForceRecorder,
    radius_pipeline,
)
from tire_estimation.node_config import EstimatorNodeOptions, periods_of
from tire_estimation.paths import REPLAY_REPORT_FILES, check_new_path, prepare_out_dir
from tire_estimation.replay_config import (
    NODE_NAME,
    load_config_sections,
    section_config,
)
from tire_estimation.replay_lateral import (
    imu_lateral_metrics,
    lateral_metrics,
    stiffness_metrics,
    write_lateral_plots,
)
from tire_estimation.replay_streams import ReportBag
from tire_estimation.sources import bag_samples
from tire_estimation.spill import CHUNK_ROWS, Spill, Spilled, decimated, drain, plot_index, rows_of

#: what a run writes in its output directory (and removes from it first)
REPORT_FILES = REPLAY_REPORT_FILES


@dataclass
class ReplayReport:
    """What a replay produced (``metrics`` is what ``metrics.json`` holds)."""

    out_dir: Path
    metrics: dict[str, Any]

    def summary(self) -> str:
        """A few human-readable lines for the terminal."""
        m = self.metrics
        r = m["radii"]
        rtf = float(m["realtime_factor"])
        # two significant digits below 10x (a --rank-effects run is slower than real time)
        rtf_text = f"{rtf:.0f}x" if rtf >= 10.0 else f"{rtf:.2g}x"
        lines = [
            f"replayed {m['bag']} ({m['duration_s']:.0f} s of data in {m['wall_s']:.1f} s, "
            f"{rtf_text} real time)"
        ]
        truth = r.get("rmse_vs_truth_m") or {}
        final_truth = r.get("final_error_vs_truth_m") or {}
        learning = r.get("learning") or {}
        clock = m.get("clock_check") or {}
        if clock.get("corrected_s"):
            lead = clock.get("leading") or {}
            lines.append(
                f"  CLOCKS CORRECTED: over the first minutes the GNSS speed matched the wheel "
                f"speed {clock['corrected_s']:+.2f} s later (correlation "
                f"{lead.get('correlation', float('nan')):.2f}): the GNSS stamps were moved back "
                "by that much before the estimation (a receiver stamping in GPS time, or two "
                "unsynchronized computers); fix the stamps at the source"
            )
        if clock.get("offset"):
            lines.append(
                f"  CLOCKS: the GNSS speed matches the wheel speed {clock['lag_s']:+.1f} s later "
                f"(correlation {clock['correlation']:.2f}, {clock['correlation_at_zero']:.2f} at "
                "no lag): the fixes and the wheel speeds are stamped by clocks that far apart, "
                "and every estimate below assumes one clock"
            )
        mount = m.get("imu_mounting") or {}
        if mount.get("upside_down"):
            lines.append(
                "  IMU AXES: the IMU's z axis points down (mounted upside down, or publishing "
                "the aerospace axes x forward, y right, z down: its specific force reads -g on "
                f"z): its samples were turned by 180 deg about x after the first {GRAVITY_SAMPLES}"
                " samples, and the IMU-driven lateral estimators restarted then: publish the "
                "IMU in base_link axes (REP-103)"
            )
        if mount.get("corrected"):
            lines.append(
                f"  IMU AXES: the IMU's horizontal axes are turned {mount['yaw_deg']:+.1f} deg "
                "from base_link's (its specific force against the wheels' acceleration, "
                f"correlation {mount['correlation']:.2f}); its samples were rotated into "
                f"base_link from {mount['decided_s']:.0f} s on and the IMU-driven lateral "
                "estimators restarted then: publish the IMU in base_link axes (REP-103)"
            )
        failed = r.get("failed_initializations") or {}
        ratio = failed.get("median_distance_ratio")
        # one failure is a GNSS glitch; repeated ones with one ratio are the wheel speeds
        if failed.get("count", 0) >= FAILED_INITIALIZATIONS_TO_FLAG and ratio is not None:
            lines.append(
                f"  POSE NOT INITIALIZED {failed['count']} times: the wheel odometry covered "
                f"{ratio:.2f} of the distance between two fixes (0.5-2 accepted): check the wheel "
                "speeds' unit (rad/s) and sign, vehicle.yaml's nominal_tire_radius_m, and that "
                "the fixes and the wheel speeds are stamped by one clock"
            )
        for w, est in r["final_radius_error_m"].items():
            if est is None:
                lines.append(f"  {w}: no estimate (the radius MPF never initialized)")
                continue
            learn = learning.get(w)
            if learn is not None and learn["learned_s"] <= 0.0:
                why = ", ".join(f"{k} {v:.0f} s" for k, v in learn["paused_s"].items())
                if "low speed" in learn["paused_s"]:
                    why += "; radius.min_speed_m_s sets the speed floor"
                if "reversing" in learn["paused_s"]:
                    why += (
                        "; negative wheel speeds: reversing, or wheel speeds signed other than "
                        "REP-103's forward-positive"
                    )
                lines.append(
                    f"  {w}: NEVER LEARNED: the estimate below is the prior (paused: {why})"
                )
            std = r["final_radius_error_std_m"][w]
            # the learned rolling radius, its offset from nominal, and (with truth) the error
            text = f"  {w}: offset from nominal {1e3 * est:+.3f} mm ± {1e3 * std:.3f} mm"
            nominal = r.get("nominal_radius_m")
            if nominal is not None:
                text = f"  {w}: radius {1e3 * (nominal + est):.3f} mm, {text.split(': ', 1)[1]}"
            if final_truth.get(w) is not None:
                true_err = est - final_truth[w]
                text += (
                    f" | true offset {1e3 * true_err:+.3f} mm, error {1e3 * final_truth[w]:+.3f}"
                    f" mm, RMSE {1e3 * truth[w]:.3f} mm"
                )
            lines.append(text)
        rear = (r.get("axles") or {}).get("rear")
        if rear is not None and rear["split_observable"] is False:
            known = [v for v in r["final_radius_error_m"].values() if v is not None]
            common = f"{1e3 * sum(known) / len(known):+.3f} mm" if known else "none"
            lines.append(
                f"  REAR AXLE: the left-right split is {rear['reason']}: {common} (mean of the "
                "two estimates above, which do not tell the two tyres apart)"
            )
        swapped = [a for a, st in (r.get("axles") or {}).items() if st.get("swapped")]
        reversed_wheels = r.get("wheels_reversed") or []
        exchanged = r.get("front_rear_exchanged")
        if swapped or r.get("gyro_reversed") or reversed_wheels or exchanged:
            what = [f"the {a} wheels' left and right speeds arrived exchanged" for a in swapped]
            if r.get("gyro_reversed"):
                what.append("the gyro's yaw rate turns against the GNSS course (REP-103: z up)")
            if reversed_wheels:
                what.append(
                    f"{', '.join(reversed_wheels)} turned backward while the GNSS moved forward "
                    "(a speed sign reversed)"
                )
            if exchanged:
                what.append(
                    "the front and rear wheels' names arrived exchanged (the wheels named rear "
                    "ran faster in the turns, as front wheels do); the radii learned again"
                )
            lines.append(
                f"  WIRING: {'; '.join(what)}; corrected from then on (the GNSS or the turns "
                "told which input was wrong): fix the driver's wheel order or signs, or the IMU "
                "frame"
            )
        slip = r.get("drive_slip") or {}
        if slip:
            how = (
                "learned against the free-rolling front wheels"
                if slip["source"] == "learned"
                else "from vehicle.yaml's mass_kg and longitudinal stiffness, not learned ("
                + (
                    "no free-rolling axle"
                    if slip["drive"] == "all"
                    else "too little straight driving above 5 m/s with the front wheels reported"
                )
                + ")"
            )
            said = (
                " (vehicle.yaml says drive: front, but the rear wheels slip with the "
                "acceleration: set drive: rear, unless the front and rear wheel names are "
                "exchanged)"
                if slip.get("detected")
                else ""
            )
            lines.append(
                f"  DRIVEN REAR WHEELS{said}: their traction slip is removed before the radii "
                f"are learned, {how}: {1e3 * slip['slip_per_accel_s2_per_m']:.2f} per mille per "
                f"m/s^2, mean {100 * slip['mean_slip']:.3f} %"
            )
        rescales = r.get("rescales") or []
        if rescales:
            sources = list(r.get("rescale_sources") or []) + [""] * len(rescales)
            sizes = ", ".join(
                f"{100 * (f - 1):+.1f} %" + (f" from the {src}" if src else "")
                for f, src in zip(rescales, sources, strict=False)
            )
            lines.append(
                f"  RADII RESCALED {len(rescales)} time(s) ({sizes}): the GNSS speed or the "
                "distance between its fixes on straight runs disagreed with the wheels' by more "
                "than 2 %; check vehicle.yaml's nominal_tire_radius_m, "
                "or the tyres were changed since the radii were saved"
            )
        fix_cov = r.get("fix_covariance") or {}
        if fix_cov.get("changes"):
            scale = float(fix_cov["scale"])
            lines.append(
                "  FIX COVARIANCE SCALED: the fixes' innovations across the track showed their "
                f"stated position_covariance too {'small' if scale > 1.0 else 'large'} (30-s "
                f"windows); the filter used it times {scale:.3g} (std times "
                f"{math.sqrt(scale):.2g}): correct the GNSS driver's covariance at the source"
            )
        refused = r.get("rescales_refused") or []
        if refused:
            lines.append(
                f"  RADII NOT RESCALED: the GNSS distance was {refused[-1]:.2f} times the "
                f"wheels' ({len(refused)} time(s)), beyond what a tyre radius can be off: the "
                "wheel speeds' unit (rad/s) or vehicle.yaml's nominal_tire_radius_m (a radius, "
                "not a diameter) is wrong"
            )
        for w, lost_s in (r.get("signal_lost_s") or {}).items():
            # a lost rear wheel pauses the learning; a lost front wheel only what needs it
            then = (
                "the radii were not learned then (the pose used the other rear wheel and the gyro)"
                if w in REAR_WHEELS
                else "the checks that compare the front axle with the rear paused"
            )
            lines.append(
                f"  WHEEL SIGNAL LOST: {w} read below {100 * LOST_SPEED_SHARE:.0f} % of the other "
                f"wheels' speed, or nothing, for {lost_s:.1f} s; {then}"
            )
        unreported = r.get("wheels_not_reported") or []
        rear_missing = [w for w in unreported if w in REAR_WHEELS]
        if rear_missing:
            lines.append(
                f"  WHEELS NOT REPORTED: {', '.join(rear_missing)} never had a speed on "
                "/vehicle/wheel_speeds: nothing was learned (the radius model needs both rear "
                "wheels; a robot's wheels are named wheel_rl / wheel_rr)"
            )
        elif unreported:
            lines.append(
                f"  front wheels not reported ({', '.join(unreported)}): the rear radii do not "
                "need them; a driven rear axle's slip is then not learned but taken from "
                "vehicle.yaml"
            )
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
        for name, lat in (m.get("lateral_by_source") or {}).items():
            if lat.get("vy_rmse_m_s") is None:
                continue
            lines.append(
                f"  lateral ({name}) vs {lat['against']}: vy RMSE "
                f"{lat['vy_rmse_m_s']:.3f} m/s, sideslip {lat['sideslip_rmse_deg']:.2f} deg, "
                f"yaw rate {lat['yaw_rate_rmse_deg_s']:.2f} deg/s"
            )
        stiff = m.get("stiffness")
        if stiff and stiff.get("final"):
            text = ", ".join(f"{k} {v / 1e3:.1f}k" for k, v in stiff["final"].items())
            lines.append(f"  stiffness (final): {text}")
            rel = stiff.get("rel_rmse_vs_truth")
            if rel:
                errs = ", ".join(f"{k} {100 * v:.1f} %" for k, v in rel.items())
                lines.append(
                    f"  stiffness relative RMSE vs truth ({stiff['rel_rmse_window']}): {errs}"
                )
        lines.extend(_detection_lines(m.get("detection") or {}, m.get("events") or []))
        loop = m.get("closed_loop")
        if loop is not None:
            lines.extend(_closed_loop_lines(loop))
        res = m["residuals"]
        if res["consistent"] is not None:
            meaning = (
                "the GNSS innovations fit the filter's noise model: the reported std is honest"
                if res["consistent"]
                else "the GNSS innovations do not fit the filter's noise model: an effect the "
                "model lacks, or wrong noise settings; the reported std may be too small"
            )
            if res["consistent"] is False and _only_overstated_noise(res):
                meaning = (
                    "the GNSS innovations are far smaller than the filter's noise model "
                    "predicts: the reported std may be too large"
                )
            lines.append(f"  innovations consistent: {res['consistent']} ({meaning})")
            left_out = res.get("tests", {}).get("fixes_before_model_change")
            if left_out:
                lines.append(
                    f"    judged on the fixes after the estimator's latest change to its model "
                    f"(radii rescaled or fix covariance scaled): {left_out} earlier left out"
                )
            lines.extend(f"    why: {why}" for why in res.get("why", []))
        elif res.get("tests", {}).get("note"):
            lines.append(f"  innovations not tested: {res['tests']['note']}")
        lines.append(f"  report: {self.out_dir / 'metrics.json'}")
        return "\n".join(lines)


#: the summary flags the two-fix initialization from this many failures on
FAILED_INITIALIZATIONS_TO_FLAG = 3


def _only_overstated_noise(res: dict[str, Any]) -> bool:
    """Whether the only failed test of an inconsistent verdict is a mean NIS far below its
    band (the stated noise larger than the innovations), with no effect significant."""
    tests = res.get("tests", {})
    bounds = tests.get("mean_nis_bounds_95")
    if tests.get("mean_nis_ok") is not False or bounds is None:
        return False
    low = float(tests["mean_nis"]) < float(bounds[0])
    others_pass = tests.get("white_decimated", True) and tests.get("white_normalized", True)
    threshold = float(tests.get("score_threshold", 4.0))
    no_effect = all(
        e["score"] < threshold or not e.get("material", True)
        for e in res.get("suspected_effects", [])
    )
    return bool(low and others_pass and no_effect and tests.get("likelihood_ratio_ok", True))


def _closed_loop_lines(loop: dict[str, Any]) -> list[str]:
    """The effects added by ``--write-config`` and the fit before and after."""
    effects = ", ".join(f"{e['effect']} {e['estimate']:g} {e['unit']}" for e in loop["effects"])
    lines = [f"  closed loop: {effects or 'no effect added'} -> {loop['config_file']}"]
    for name, why in loop.get("not_sized", {}).items():
        lines.append(f"    left out {name}: {why}")
    b, a = loop["before"], loop["after"]
    for label, key, fmt in (
        ("position RMSE", "position_rmse_m", "{:.2f} m"),
        ("mean NIS", "mean_nis", "{:.2f}"),
        ("consistent", "consistent", "{}"),
    ):
        if b[key] is None and a[key] is None:
            continue
        before = "n/a" if b[key] is None else fmt.format(b[key])
        after = "n/a" if a[key] is None else fmt.format(a[key])
        lines.append(f"    {label}: {before} before, {after} after")
    for w, v in b["final_radius_error_m"].items():
        after_v = a["final_radius_error_m"].get(w)
        if after_v is not None:
            lines.append(
                f"    {w}: radius error {1e3 * v:+.3f} mm before, {1e3 * after_v:+.3f} mm after"
            )
    return lines


def _detection_lines(det: dict[str, Any], events: list[dict[str, Any]]) -> list[str]:
    """The deflation detector's outcome in a few lines (with the delay after a simulated
    pressure loss the bag records)."""
    if not det.get("ran"):
        return [f"  deflation detector: did not run ({det.get('note', 'no radius estimates')})"]
    lines = [f"  deflation detector: {det['note']}"]
    losses = [e for e in events if e.get("kind") in ("pressure_step", "diffusion_start")]
    for alarm in det["alarms"]:
        wheel, t_s = alarm["wheel"], alarm["t_s"]
        what = "tyre not identified (all wheels)" if wheel == "all" else wheel
        text = f"  DEFLATION WARNING: {what} at {t_s:.0f} s"
        before = [e for e in losses if e["t_s"] <= t_s]
        if before:
            e = before[-1]
            text += (
                f", {t_s - e['t_s']:.0f} s after the {e['kind'].replace('_', ' ')} on "
                f"{e.get('wheel', '?')} at {e['t_s']:.0f} s"
            )
        lines.append(text)
    if det["armed"] and not det["alarms"]:
        lines.append("  no deflation warning")
    return lines


#: a replay of at least this many samples (a few seconds of work) shows a progress bar
PROGRESS_MIN_SAMPLES = 50_000


def _progress_printer(total: int, enabled: bool) -> Any:
    if not enabled or total < PROGRESS_MIN_SAMPLES:
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


def _with_progress(samples: Iterator[Any], update: Any) -> Iterator[Any]:
    """``samples``, calling ``update(n)`` every 10 000."""
    for n, sample in enumerate(samples):
        if n % 10_000 == 0:
            update(n)
        yield sample


def _truth_radius_error(
    bag: ReportBag,
) -> tuple[np.ndarray, tuple[str, ...], np.ndarray] | None:
    if bag.truth_wheel_radii is None:
        return None
    tr = bag.truth_wheel_radii.read()
    return tr.t_ns, tuple(tr.names), tr.values


def _reference_origin(bag: ReportBag) -> tuple[float, float, float] | None:
    """ENU origin of ``/reference/odometry`` (contract): the metadata key
    ``tire_estimation.reference_origin_lla`` ("lat lon alt") when the bag has it, else the
    bag's first ``/gnss/fix``."""
    text = bag.custom_data.get("tire_estimation.reference_origin_lla")
    if text:
        try:
            # "lat lon alt" (contract) or a YAML list of the three
            parsed = yamlio.safe_load(str(text))
            values = parsed if isinstance(parsed, list) else str(text).split()
            lat, lon, alt = (float(v) for v in values)
        except (ValueError, TypeError, yaml.YAMLError) as exc:
            raise BagError(
                f"{bag.path}: metadata tire_estimation.reference_origin_lla={text!r} is not "
                "'lat lon alt'"
            ) from exc
        return lat, lon, alt
    if bag.gnss is not None:
        first = bag.gnss.read(0, 1)
        return float(first.lat_deg[0]), float(first.lon_deg[0]), float(first.alt_m[0])
    return None


def _by_chunks(t_ns: np.ndarray, values_at: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """``values_at`` over ``t_ns`` (sorted) a chunk of times at a time, joined."""
    parts = [values_at(t_ns[a : a + CHUNK_ROWS]) for a in range(0, t_ns.size, CHUNK_ROWS)]
    return np.concatenate(parts)


def _reference_positions(
    bag: ReportBag, trace_t_ns: np.ndarray, ltp: LocalTangentPlane | None
) -> tuple[np.ndarray | None, str]:
    """Truth (or reference) base_link east/north at the trace times in the estimator frame."""
    if ltp is None or trace_t_ns.size == 0:
        return None, "none"
    fix = bag.truth_fix
    if fix is not None:

        def truth_at(t: np.ndarray) -> np.ndarray:
            w = fix.window(t[0], t[-1])
            e, n, _ = ltp.to_enu(w.lat_deg, w.lon_deg, w.alt_m)
            return np.column_stack([np.interp(t, w.t_ns, e), np.interp(t, w.t_ns, n)])

        return _by_chunks(trace_t_ns, truth_at), topics.TRUTH_FIX
    ref = bag.reference_odometry
    origin = _reference_origin(bag)
    if ref is not None and origin is not None:
        ref_ltp = LocalTangentPlane(*origin)

        def reference_at(t: np.ndarray) -> np.ndarray:
            w = ref.window(t[0], t[-1])
            lat, lon, alt = ref_ltp.to_lla(
                w.position_m[:, 0], w.position_m[:, 1], w.position_m[:, 2]
            )
            e, n, _ = ltp.to_enu(lat, lon, alt)
            return np.column_stack([np.interp(t, w.t_ns, e), np.interp(t, w.t_ns, n)])

        return _by_chunks(trace_t_ns, reference_at), topics.REFERENCE_ODOMETRY
    return None, "none"


def _remove_report(out: Path) -> None:
    """Remove the files of a replay report (:data:`REPORT_FILES`) from ``out``."""
    for name in REPORT_FILES:
        try:
            (out / name).unlink(missing_ok=True)
        except IsADirectoryError as exc:
            raise ConfigError("--out", str(out), f"{name} there is a directory") from exc
        except OSError as exc:
            raise ConfigError("--out", str(out), f"cannot remove {name}: {exc.strerror}") from exc


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


def replay_topics(infos: Mapping[str, TopicInfo], run_stiffness: bool) -> tuple[str, ...]:
    """The topics a replay decodes, given the bag's topics: the inputs, the truth and reference
    it evaluates against, the truth odometry (75 000 messages in a 25-min simulated bag) only
    when a lateral estimator will run, the one user of its velocities, and the measured velocity
    only when the bag has no wheel speeds."""

    def present(topic: str) -> bool:
        return topic in infos and infos[topic].count > 0

    lateral = present(topics.TIRE_FORCES_TOPIC) or (
        run_stiffness
        and present(topics.IMU_DATA)
        and present(topics.STEERING)
        and (present(topics.WHEEL_SPEEDS) or present(topics.VEHICLE_VELOCITY))
    )
    # the measured velocity is an input only of a vehicle without wheel speeds
    velocity = () if present(topics.WHEEL_SPEEDS) else (topics.VEHICLE_VELOCITY,)
    return (
        topics.WHEEL_SPEEDS,
        topics.STEERING,
        topics.IMU_DATA,
        topics.GNSS_FIX,
        topics.GNSS_VELOCITY,
        *velocity,
        topics.TRUTH_FIX,
        topics.TRUTH_WHEEL_RADII,
        topics.TRUTH_TIRE_STIFFNESS,
        topics.REFERENCE_ODOMETRY,
        topics.REFERENCE_LATERAL_STATE,
        topics.TIRE_FORCES_TOPIC,
    ) + ((topics.TRUTH_ODOMETRY,) if lateral else ())


def run_replay(
    bag_path: Path | str,
    out_dir: Path | str,
    *,
    config_path: Path | None = None,
    config: RadiusEstimatorConfig | None = None,
    plots: bool = True,
    progress: bool = True,
    stiffness: bool | None = None,
    rank_effects: bool = False,
    rank_seeds: int = 1,
    observers: Sequence[Observer] = (),
    write_config: Path | None = None,
    window_s: float = WINDOW_S,
) -> ReplayReport:
    """Replay ``bag_path`` through the estimators; write ``out_dir/metrics.json`` + PNGs.

    What runs depends on the bag, as in the node: the radius MPF on wheel speeds + GNSS, the
    tyre-force KF on ``/vehicle/tire_forces``, the stiffness MPF on IMU + steering + wheel
    speeds or ``/vehicle/velocity`` (``stiffness``: None = the node option
    ``stiffness_enabled`` of the configuration, default true; the linear single-track KF runs
    beside it as the lateral baseline). A bag that feeds none of them is an error. The
    deflation detector runs on the radius MPF's published radii and odometry, as the detector
    node does (``detector`` section of the configuration).

    The bag is read, decoded and estimated in one pass, ``window_s`` of log time decoded at a
    time (:mod:`tire_estimation.bag.stream`; ``math.inf``: the whole bag at once); the traces
    and the reference streams the report needs over the whole drive are kept on disk in a
    temporary directory, so that memory does not grow with the length of the bag.

    ``observers`` see every sample and output of the pipeline (what the node publishes).

    ``rank_effects`` completes the residual analysis with the profile likelihood of every
    switchable effect (:func:`~tire_estimation.evaluation.residuals.assess`: the radius MPF is
    re-run over the bag with each effect switched on over its grid, about 20 re-runs).
    ``rank_seeds`` > 1 runs the base model and every re-run with the filter seeds ``seed`` ..
    ``seed + rank_seeds - 1`` and profiles their mean NLL (``rank_seeds`` times the re-runs):
    on a short bag a single particle-filter run's likelihood depends on its seed.
    """
    out = prepare_out_dir(Path(out_dir))
    _remove_report(out)
    try:
        with tempfile.TemporaryDirectory(prefix="tire_estimation_replay_") as tmp:
            return _run(
                bag_path, out, config_path, config, plots, progress, stiffness, rank_effects,
                rank_seeds, observers, write_config, window_s, Spill(Path(tmp)),
            )  # fmt: skip
    except BaseException:
        # a failed run leaves no report, not even the plots it had written
        with contextlib.suppress(ConfigError):
            _remove_report(out)
        raise


#: the input topics (progress counts their messages)
_INPUT_TOPICS = (
    topics.WHEEL_SPEEDS,
    topics.STEERING,
    topics.IMU_DATA,
    topics.GNSS_FIX,
    topics.GNSS_VELOCITY,
    topics.TIRE_FORCES_TOPIC,
    topics.VEHICLE_VELOCITY,
)
#: what the radius MPF's re-runs (``--rank-effects``) read
_RADIUS_TOPICS = (
    topics.WHEEL_SPEEDS,
    topics.STEERING,
    topics.IMU_DATA,
    topics.GNSS_FIX,
    topics.GNSS_VELOCITY,
)


def _leading_clock_check(
    bag_path: Path | str, window_s: float, options: Any, vehicle: Any
) -> dict[str, Any]:
    """The clock check over the first minutes of the wheel speeds and GNSS velocities
    (:func:`~tire_estimation.core.clock_check.leading_check`)."""
    lead = stream_bag(
        bag_path,
        topics=[topics.WHEEL_SPEEDS, topics.GNSS_VELOCITY],
        window_s=window_s,
        joints=options.names,
    )
    return leading_check(
        (s for block in lead.blocks() for s in bag_samples(block)), vehicle.nominal_tire_radius_m
    )


def _run(
    bag_path: Path | str,
    out: Path,
    config_path: Path | None,
    config: RadiusEstimatorConfig | None,
    plots: bool,
    progress: bool,
    stiffness: bool | None,
    rank_effects: bool,
    rank_seeds: int,
    observers: Sequence[Observer],
    write_config: Path | None,
    window_s: float,
    spill: Spill,
) -> ReplayReport:
    """:func:`run_replay` once ``out`` is ready and empty of an earlier report."""
    if not isinstance(rank_seeds, int) or isinstance(rank_seeds, bool) or rank_seeds < 1:
        raise ConfigError("rank_seeds", rank_seeds, "must be an integer >= 1")
    if rank_seeds > 1 and not rank_effects:
        raise ConfigError("rank_seeds", rank_seeds, "needs rank_effects (--rank-effects)")
    if write_config is not None:
        if Path(write_config).is_dir():
            raise ConfigError("--write-config", str(write_config), "is a directory")
        check_new_path(Path(write_config), "--write-config", overwrite=True)
    sections = load_config_sections(config_path)
    cfg = (
        config
        if config is not None
        else section_config(RadiusEstimatorConfig, "radius", sections.get("radius", {}))
    )
    tyre_cfg = section_config(TyreForceKFConfig, "tyre_force", sections.get("tyre_force", {}))
    stiff_cfg = section_config(
        StiffnessEstimatorConfig, "stiffness", sections.get("stiffness", {})
    )
    options = section_config(EstimatorNodeOptions, "", sections.get("", {}))
    det_cfg = section_config(DeflationDetectorConfig, "detector", sections.get("detector", {}))
    lin_cfg = section_config(LinearLateralKFConfig, "linear_kf", sections.get("linear_kf", {}))
    run_stiffness = options.stiffness_enabled if stiffness is None else stiffness

    wall0 = time.perf_counter()
    stream = stream_bag(
        bag_path,
        topics=lambda infos: replay_topics(infos, run_stiffness),
        window_s=window_s,
        joints=options.names,
    )
    meta = stream.meta
    t_open = time.perf_counter() - wall0

    def has(topic: str) -> bool:
        return topic in stream.topics and topic in meta.topics and meta.topics[topic].count > 0

    has_wheels = has(topics.WHEEL_SPEEDS)
    has_gnss = has(topics.GNSS_FIX)
    has_speed = has_wheels or has(topics.VEHICLE_VELOCITY)
    has_lateral_inputs = has(topics.IMU_DATA) and has(topics.STEERING) and has_speed
    has_forces = has(topics.TIRE_FORCES_TOPIC)
    # a bag with wheel speeds is a radius bag: it needs its GNSS. Without wheel speeds (a
    # measured-velocity export such as the Revs data) only the lateral estimators run.
    no_gnss = f"{bag_path}: no usable GNSS fix on {topics.GNSS_FIX}"
    if has_wheels and not has_gnss:
        raise BagError(no_gnss)
    if not has_wheels and not ((run_stiffness and has_lateral_inputs) or has_forces):
        need = [topics.WHEEL_SPEEDS, topics.GNSS_FIX]
        if run_stiffness:
            need = [topics.WHEEL_SPEEDS]
        raise BagError(
            f"{bag_path}: no messages on {' and '.join(need)} (the radius MPF needs "
            f"{topics.WHEEL_SPEEDS} and {topics.GNSS_FIX}; the stiffness MPF alone needs "
            f"{topics.IMU_DATA}, {topics.STEERING} and {topics.VEHICLE_VELOCITY})"
        )

    run_radius_mpf = has_wheels and has_gnss
    run_stiffness_mpf = run_stiffness and has_lateral_inputs
    # the GNSS stamped by another clock (GPS time, an unsynchronized computer): the lag the
    # first minutes show is taken out of its stamps before the estimation
    leading = None
    stamp_shift: dict[str, float] = {}
    if has_wheels and has(topics.GNSS_VELOCITY):
        leading = _leading_clock_check(bag_path, window_s, options, meta.vehicle)
        if leading["offset"]:
            stamp_shift = {t: -leading["lag_s"] for t in (topics.GNSS_FIX, topics.GNSS_VELOCITY)}
            stream = stream_bag(
                bag_path,
                topics=lambda infos: replay_topics(infos, run_stiffness),
                window_s=window_s,
                joints=options.names,
                stamp_shift_s=stamp_shift,
            )
    pipe_cfg = PipelineConfig(
        seed=cfg.seed,
        radius=cfg if run_radius_mpf else None,
        stiffness=stiff_cfg if run_stiffness_mpf else None,
        tyre_force=tyre_cfg if has_forces and options.tyre_force_enabled else None,
        detector=det_cfg if run_radius_mpf else None,
        periods=periods_of(options),
        reorder_delay_s=options.reorder_delay_s,
    )
    baselines: dict[str, Any] = {}
    if run_stiffness_mpf:
        baselines["linear_kf"] = LinearLateralKF(lin_cfg, meta.vehicle)
    # the node's outputs are made only for observers that want them (the detector is fed the
    # same values either way)
    pipeline = EstimationPipeline(pipe_cfg, meta.vehicle, baselines, outputs=bool(observers))
    radius_rec, force_rec, detect_rec = RadiusRecorder(), TyreForceRecorder(), DeflationRecorder()
    imu_recs: dict[str, ImuLateralRecorder] = {}
    if pipeline.stiffness is not None:
        imu_recs["stiffness_mpf"] = ImuLateralRecorder(pipeline.stiffness)
    for name, est in baselines.items():
        imu_recs[name] = ImuLateralRecorder(est)
    clock_check = ClockCheck(meta.vehicle.nominal_tire_radius_m)
    pipeline.add_observers(radius_rec, force_rec, detect_rec, *imu_recs.values(), clock_check)
    pipeline.add_observers(*observers)

    # what the report needs over the whole drive goes to disk block by block
    bag = ReportBag(meta, spill)
    held: list[tuple[Any, str, tuple[str, ...]]] = [
        (radius_rec.trace, spill.prefix("radius"), RadiusTrace.LATEST),
        (force_rec.trace, spill.prefix("tyre_force"), ()),
        (detect_rec, spill.prefix("detection"), ("alarms",)),
        *((rec.trace, spill.prefix(name), ()) for name, rec in imu_recs.items()),
    ]

    def drain_all() -> None:
        for obj, prefix, keep in held:
            drain(obj, spill, prefix, keep)

    def samples() -> Iterator[Any]:
        for block in stream.blocks():
            bag.add(block)
            drain_all()
            yield from bag_samples(block)

    total = sum(meta.topics[t].count for t in _INPUT_TOPICS if has(t))
    update = _progress_printer(total, progress)
    fed = samples() if update is None else _with_progress(samples(), update)
    pipeline.push_ordered(fed)
    radius_rec.flush(pipeline)
    drain_all()
    t_est = time.perf_counter()
    t_read = t_open + stream.read_s
    if run_radius_mpf and not pipeline.received["gnss_fix"]:
        raise BagError(no_gnss)  # every fix refused by the input checks
    bag.meta = dataclasses.replace(meta, dropped=stream.dropped, notes=stream.notes)
    radius_rec.trace = Spilled(radius_rec.trace, spill, held[0][1])  # type: ignore[assignment]
    force_rec.trace = Spilled(force_rec.trace, spill, held[1][1])  # type: ignore[assignment]
    detection_view = Spilled(detect_rec, spill, held[2][1])
    for rec, (_, prefix, _) in zip(imu_recs.values(), held[3:], strict=True):
        rec.trace = Spilled(rec.trace, spill, prefix)  # type: ignore[assignment]
    trace = radius_rec.finish(pipeline)
    lateral = force_rec.finish(pipeline) if pipeline.tyre_force is not None else None
    estimate_s = t_est - wall0 - t_read
    imu_lateral = {name: rec.finish(estimate_s) for name, rec in imu_recs.items()}
    detection = _detection_metrics(bag, pipeline, detection_view)

    def rerun(config: RadiusEstimatorConfig) -> RadiusTrace:
        radius_stream = stream_bag(
            bag_path,
            topics=[t for t in _RADIUS_TOPICS if t in stream.topics],
            window_s=window_s,
            stamp_shift_s=stamp_shift,
        )
        return _radius_run(config, meta.vehicle, radius_stream, spill)

    residual_report = None
    closed_loop = None
    if rank_effects and len(trace.innov_t_ns):
        residual_report = _assess_effects(cfg, trace, rerun, rank_seeds)
        if write_config is not None:
            closed_loop = _close_loop(
                bag, cfg, trace, residual_report, rank_seeds, write_config, rerun
            )
    elif write_config is not None and len(trace.innov_t_ns):
        closed_loop = _close_loop_from_sensors(bag, cfg, trace, write_config, rerun)
    t_run = time.perf_counter()
    metrics = build_metrics(
        bag, trace, cfg, lateral, imu_lateral, residual_report, detection, pipeline.axles
    )
    if closed_loop is not None:
        metrics["closed_loop"] = closed_loop
    metrics["clock_check"] = clock_check.result()
    metrics["imu_mounting"] = imu_mounting_metrics(pipeline.imu_mounting.result, bag.start_ns)
    # the lag found over the first minutes and taken out of the GNSS stamps (0: none)
    metrics["clock_check"]["corrected_s"] = -stamp_shift.get(topics.GNSS_FIX, 0.0)
    metrics["clock_check"]["leading"] = leading
    metrics["wall_s"] = time.perf_counter() - wall0
    metrics["timing_s"] = {"read": t_read, "estimate": t_run - wall0 - t_read}
    metrics["realtime_factor"] = metrics["duration_s"] / max(metrics["wall_s"], 1e-9)
    if plots:
        write_plots(out, bag, trace)
        write_detection_plot(out, bag, detection_view, det_cfg)
        if "stiffness_mpf" in imu_lateral:
            write_lateral_plots(out, bag, imu_lateral)
    metrics["plots"] = sorted(p.name for p in out.glob("*.png")) if plots else []
    atomic_write_json(out / "metrics.json", _clean(metrics), allow_nan=False)
    return ReplayReport(out, _clean(metrics))


def _radius_run(
    config: RadiusEstimatorConfig, vehicle: VehicleParams, stream: BagStream, spill: Spill
) -> RadiusTrace:
    """The radius MPF alone (seed ``config.seed``) over the bag of ``stream``: its trace,
    kept on disk as the replay's."""
    recorder = RadiusRecorder()
    pipeline = radius_pipeline(config, vehicle, recorder)
    prefix = spill.prefix("rerun")

    def samples() -> Iterator[Any]:
        for block in stream.blocks():
            drain(recorder.trace, spill, prefix, RadiusTrace.LATEST)
            yield from bag_samples(block, radius_only=True)

    pipeline.push_ordered(samples())
    recorder.flush(pipeline)
    drain(recorder.trace, spill, prefix, RadiusTrace.LATEST)
    recorder.trace = Spilled(recorder.trace, spill, prefix)  # type: ignore[assignment]
    return recorder.finish(pipeline)


def _detection_metrics(
    bag: ReportBag, pipeline: EstimationPipeline, rec: DeflationRecorder | Spilled
) -> dict[str, Any] | None:
    """What the deflation detector did: its alarms, whether each wheel's calibration
    completed, and the largest CUSUM statistic over its threshold (None: it did not run)."""
    monitor = pipeline.monitor
    if monitor is None:
        return None
    status = monitor.detector.status()
    cfg = monitor.detector.config
    wheels: dict[str, Any] = {}
    ratio = np.full(len(rec.wheel_names), np.nan)
    if len(rec.t_ns):
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.asarray(rec.cusum_m) / np.asarray(rec.threshold_m)
        calibrated = np.asarray(rec.calibration_state) == 2
        if calibrated.any():
            ratio = np.nanmax(np.where(calibrated[:, None], r, np.nan), axis=0)
    for w in status.wheels:
        col = rec.wheel_names.index(w.wheel_name) if w.wheel_name in rec.wheel_names else -1
        wheels[w.wheel_name] = {
            "calibrated": w.calibrated,
            "calibrated_at_s": None
            if w.calibration_t_ns is None
            else (w.calibration_t_ns - bag.start_ns) * 1e-9,
            "calibration_progress": w.calibration_progress,
            "max_cusum_over_threshold": None if col < 0 else ratio[col],
            "alarm": w.alarm,
        }
    armed = any(w.calibrated for w in status.wheels)
    window = f"{3.6 * cfg.min_speed_m_s:.0f}-{3.6 * cfg.max_speed_m_s:.0f} km/h"
    note = (
        "armed: calibration completed"
        if armed
        else (
            f"not armed: the calibration needs {cfg.calibration_time_s:.0f} s of driving at "
            f"{window} without braking, this bag gave {status.calibrated_driving_time_s:.0f} s "
            "(detector.calibration_time_s sets it)"
        )
    )
    return {
        "ran": True,
        "armed": armed,
        "note": note,
        "alarms": [{"wheel": w, "t_s": (t - bag.start_ns) * 1e-9} for w, t in rec.alarms],
        "calibration": {
            "required_s": cfg.calibration_time_s,
            "driving_time_s": status.calibrated_driving_time_s,
            "done_at_s": None
            if rec.calibration_done_t_ns is None
            else (rec.calibration_done_t_ns - bag.start_ns) * 1e-9,
        },
        "wheels": wheels,
        "dropped": dict(monitor.detector.dropped),
        "config": dataclasses.asdict(cfg),
    }


def write_detection_plot(
    out: Path, bag: ReportBag, rec: DeflationRecorder | Spilled, cfg: DeflationDetectorConfig
) -> None:
    """detection.png: the CUSUM statistic per wheel against its threshold."""
    from tire_estimation.evaluation import plots

    t_ns = np.asarray(rec.t_ns)
    if not t_ns.size:
        return
    shown = plot_index(t_ns.size)
    t_s = (t_ns[shown] - bag.start_ns) * 1e-9
    done = rec.calibration_done_t_ns
    plots.plot_detection(
        out / "detection.png",
        t_s,
        rec.wheel_names,
        np.asarray(rec.cusum_m, dtype=float)[shown],
        np.asarray(rec.threshold_m, dtype=float)[shown],
        None if done is None else (done - bag.start_ns) * 1e-9,
        [(w, (t - bag.start_ns) * 1e-9) for w, t in rec.alarms],
        [(e.t_s, e.kind) for e in bag.events],
    )


def imu_mounting_metrics(result: MountingResult, start_ns: int) -> dict[str, Any]:
    """The IMU's mounting yaw as the check found it (``core/imu_mounting.py``); ``decided_s``
    from the bag's start."""
    decided_s = None if result.decided_t_ns is None else (result.decided_t_ns - start_ns) * 1e-9
    return {
        "yaw_deg": result.yaw_deg,
        "correlation": result.correlation,
        "decided": result.decided,
        "corrected": result.corrected,
        "decided_s": decided_s,
        "mirror_correlation": result.mirror_correlation,
        "upside_down": result.upside_down,
    }


def build_metrics(
    bag: ReportBag,
    trace: RadiusTrace,
    cfg: RadiusEstimatorConfig,
    lateral: LateralTrace | None = None,
    imu_lateral: dict[str, ImuLateralTrace] | None = None,
    residual_report: dict[str, Any] | None = None,
    detection: dict[str, Any] | None = None,
    axles: AxleCheck | None = None,
) -> dict[str, Any]:
    """The contract's metrics.json content (minus the wall-clock fields).

    ``residual_report`` (from :func:`_assess_effects`) replaces the regression-only residual
    analysis when given.

    ``lateral`` is the tyre-force KF's when it ran, else the stiffness MPF's; every lateral
    estimator that ran is in ``lateral_by_source`` (the linear single-track KF is the baseline).
    """
    imu_lateral = imu_lateral or {}
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
    radii["nominal_radius_m"] = nominal
    if axles is not None:
        radii["axles"] = {a: dataclasses.asdict(axles.status(a)) for a in ("front", "rear")}
        radii["signal_lost_s"] = axles.lost_signals()
        radii["wheels_not_reported"] = list(axles.unreported_wheels())
        # inputs whose sign convention was found reversed and corrected (axle_check.py)
        radii["gyro_reversed"] = axles.gyro_reversed
        radii["wheels_reversed"] = axles.signs.reversed_wheels
        radii["front_rear_exchanged"] = axles.order.exchanged
    grade = arr["road_grade_rad"]
    # the grade the correction used: fixes per source (the GNSS altitude confirmed by the IMU,
    # the IMU's where they disagreed, none) and its size over the drive
    radii["road_grade"] = {
        "source_counts": dict(trace.road_grade_counts),
        # the IMU grade's offset (bias, mounting pitch) taken out (0: none beyond the check's)
        "imu_offset_deg": math.degrees(trace.road_grade_imu_offset_rad),
        "rms_deg": float(np.degrees(np.sqrt(np.mean(grade**2)))) if grade.size else 0.0,
        "max_abs_deg": float(np.degrees(np.abs(grade).max())) if grade.size else 0.0,
    }
    # half the wheel speeds' median sample period, brought back before the prediction
    radii["wheel_speed_lag_s"] = trace.wheel_speed_lag_s
    # an edge-timed ABS unit's tooth pitch read off its held values (0: none held); below
    # pitch / (T / 2) the lag brought back is a tooth period
    radii["wheel_speed_tooth_pitch_rad"] = trace.wheel_speed_tooth_pitch_rad
    # the traction slip removed from driven rear wheels (empty: the rear wheels roll freely)
    radii["drive_slip"] = dict(trace.drive_slip)
    # the factors both rear radii were scaled by when the GNSS showed a gross error, and
    # what showed it ("velocity": the Doppler speed, "fixes": straight runs between fixes)
    radii["rescales"] = list(trace.radius_rescales)
    radii["rescale_sources"] = list(trace.radius_rescale_sources)
    radii["rescales_refused"] = list(trace.radius_rescales_refused)
    radii["fix_covariance"] = {
        "scale": trace.fix_covariance_scale,
        "changes": list(trace.fix_covariance_changes),
    }
    radii["learning"] = ev.learning_metrics(
        arr["t_ns"], trace.wheel_names, arr["active"], trace.reason
    )
    ratios = list(getattr(trace, "init_distance_ratios", []) or [])
    radii["failed_initializations"] = {
        "count": len(ratios),
        "median_distance_ratio": float(np.median(ratios)) if ratios else None,
    }
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
    if residual_report is None and arr["innov_t_ns"].size:
        residual_report = analyze_residuals(trace)
    elif residual_report is None:
        residual_report = {
            "consistent": None,
            "tests": {
                "note": "no GNSS innovations: the radius MPF did not run or never initialized "
                "its pose"
            },
            "suspected_effects": [],
        }
    residual_report["why"] = explain_residuals(residual_report)
    by_source: dict[str, Any] = {}
    if lateral is not None:
        by_source["tyre_force_kf"] = lateral_metrics(bag, lateral)
    for name, imu_trace in imu_lateral.items():
        by_source[name] = imu_lateral_metrics(bag, name, imu_trace)
    primary = by_source.get("tyre_force_kf") or by_source.get("stiffness_mpf")
    stiff = imu_lateral.get("stiffness_mpf")
    return {
        "bag": str(bag.path),
        "duration_s": bag.duration_s,
        "scenario": bag.scenario,
        "seed": bag.seed,
        "estimator": {"name": "radius_mpf", "config": cfg.to_dict()},
        "radii": radii,
        "position": {"rmse_m": pos_rmse, "against": against},
        "detection": detection
        or {"ran": False, "armed": False, "alarms": [], "note": "the radius MPF did not run"},
        "stiffness": stiffness_metrics(bag, stiff) if stiff is not None else None,
        "lateral": primary,
        "lateral_by_source": by_source or None,
        "residuals": residual_report,
        # input samples dropped by the bag reader's checks and by the radius estimator, by
        # <stream>:<kind> (the names of the node's /diagnostics)
        "dropped_samples": dict(sorted(merged_counts(bag.dropped, trace.dropped).items())),
        "resample_count": trace.resample_count,
        "gnss_velocity": trace.gnss_velocity,
        "events": [
            {"t_s": e.t_s, "kind": e.kind, **{k: v for k, v in e.detail.items()}}
            for e in bag.events
        ],
    }


#: at most this many effects are added to the model by ``--write-config``
MAX_CLOSED_LOOP_EFFECTS = 3


def _fit_summary(bag: ReportBag, trace: RadiusTrace, report: dict[str, Any]) -> dict[str, Any]:
    """What a run of the radius MPF says: final radii, position RMSE, consistency, fit."""
    from tire_estimation.evaluation.residuals import neg_log_likelihood

    arr = trace.arrays()
    ltp = LocalTangentPlane(*trace.origin_lla) if trace.origin_lla is not None else None
    ref_en, against = _reference_positions(bag, arr["t_ns"], ltp)
    pos = ev.position_rmse_m(arr["pose"][:, :2], ref_en) if ref_en is not None else None
    final = (
        dict(zip(trace.wheel_names, arr["radius_error_m"][-1].tolist(), strict=True))
        if arr["t_ns"].size
        else {}
    )
    accepted = arr["nis"][arr["accepted"]] if arr["nis"].size else arr["nis"]
    return {
        "final_radius_error_m": final,
        "position_rmse_m": pos,
        "position_against": against,
        "mean_nis": float(np.mean(accepted)) if accepted.size else None,
        "neg_log_likelihood": neg_log_likelihood(trace),
        "consistent": report.get("consistent"),
    }


def _close_loop(
    bag: ReportBag,
    cfg: RadiusEstimatorConfig,
    trace: RadiusTrace,
    report: dict[str, Any],
    n_seeds: int,
    path: Path,
    rerun: Callable[[RadiusEstimatorConfig], RadiusTrace],
) -> dict[str, Any]:
    """Add the most significant effect to the model at its profile estimate, rank the rest
    again against that model, and repeat (at most :data:`MAX_CLOSED_LOOP_EFFECTS`, while an
    effect's likelihood-ratio score is at or above the threshold); write the resulting
    parameters to ``path`` as a params file the replay (``--config``) and the node
    (``--params-file``) load; return the fit before and after."""
    from tire_estimation.evaluation import residuals

    before = _fit_summary(bag, trace, report)
    added: list[dict[str, Any]] = []
    cfg_k, trace_k, report_k = cfg, trace, report
    threshold = float(report["tests"].get("likelihood_ratio_threshold", residuals.SCORE_THRESHOLD))
    not_sized: dict[str, str] = {}
    for _ in range(MAX_CLOSED_LOOP_EFFECTS):
        done = {e["effect"] for e in added} | set(not_sized)
        significant = [
            e
            for e in report_k.get("ranked_effects", [])
            if e["score"] >= threshold and e["effect"] not in done
        ]
        # an estimate on the rim of its scan grid is a monotone profile: the data do not size
        # the effect (it trades off against what the model already has), so it is not added
        for e in significant:
            grid = residuals.DEFAULT_GRIDS.get(e["effect"], ())
            if grid and e["estimate"] in (min(grid), max(grid)) and e["estimate"] != 0.0:
                not_sized[e["effect"]] = (
                    f"profile optimum at the rim of the scan grid ({e['estimate']:g} "
                    f"{e['unit']}, score {e['score']:.1f}): not sized by these data"
                )
        significant = [e for e in significant if e["effect"] not in not_sized]
        if not significant:
            break
        top = significant[0]
        field = residuals.BY_NAME[top["effect"]].config_field
        added.append(
            {**{k: top[k] for k in ("effect", "score", "estimate", "unit")}, "field": field}
        )
        cfg_k = RadiusEstimatorConfig.from_dict({**cfg_k.to_dict(), field: top["estimate"]})
        trace_k = rerun(cfg_k)
        report_k = _assess_effects(cfg_k, trace_k, rerun, n_seeds)
    header = "# Effects found in the residuals of " + str(bag.path) + " and sized by their\n"
    header += "# profile likelihood (tire-estimation replay --rank-effects --write-config):\n"
    after = _fit_summary(bag, trace_k, report_k)
    threshold_words = "the likelihood-ratio threshold"
    return _write_closed_loop(
        path, header, cfg_k, added, not_sized, threshold_words, before, after
    )


def _close_loop_from_sensors(
    bag: ReportBag,
    cfg: RadiusEstimatorConfig,
    trace: RadiusTrace,
    path: Path,
    rerun: Callable[[RadiusEstimatorConfig], RadiusTrace],
) -> dict[str, Any]:
    """Add every effect the sensor agreement finds significant and material to the model at
    its size (net of what ``cfg`` declares: the new value is the declared one plus the size),
    re-run once, write the params file and return the fit before and after."""
    from tire_estimation.evaluation import residuals

    report = residuals.analyze_trace(trace)
    added: list[dict[str, Any]] = []
    values = cfg.to_dict()
    not_sized: dict[str, str] = {}
    for e in report["suspected_effects"]:
        if e.get("source") != "sensor agreement":
            continue
        if e["score"] < residuals.SCORE_THRESHOLD or not e.get("material"):
            continue
        effect = residuals.BY_NAME[e["effect"]]
        lo, hi = effect.limits
        value = values[effect.config_field] + e["estimate"]
        if not lo <= value <= hi:
            not_sized[e["effect"]] = f"{value:g} {effect.unit} is outside {lo:g} .. {hi:g}"
            continue
        values[effect.config_field] = value
        added.append(
            {
                **{k: e[k] for k in ("effect", "score", "unit")},
                "estimate": value,
                "field": effect.config_field,
            }
        )
    cfg_after = RadiusEstimatorConfig.from_dict(values)
    trace_after = rerun(cfg_after) if added else trace
    header = "# Effects found in " + str(bag.path) + " by the sensor agreement (the wheel\n"
    header += "# speeds, the gyro and the fixes against the GNSS velocity) at their sizes\n"
    header += "# (tire-estimation replay --write-config):\n"
    before = _fit_summary(bag, trace, report)
    after = _fit_summary(bag, trace_after, residuals.analyze_trace(trace_after))
    return _write_closed_loop(
        path, header, cfg_after, added, not_sized, "the threshold", before, after
    )


def _write_closed_loop(
    path: Path,
    header: str,
    cfg: RadiusEstimatorConfig,
    added: list[dict[str, Any]],
    not_sized: dict[str, str],
    threshold: str,
    before: dict[str, Any],
    after: dict[str, Any],
) -> dict[str, Any]:
    """Write the params file of ``--write-config`` (the whole radius section that differs from
    the defaults: the run's own settings and the added effects, so that ``--config FILE`` alone
    reproduces the "after" run, with the effects named in comments) and return the report's
    ``closed_loop`` block."""
    defaults = RadiusEstimatorConfig().to_dict()
    params = {f"radius.{k}": v for k, v in cfg.to_dict().items() if v != defaults.get(k)}
    text = header
    for e in added:
        text += f"#   {e['effect']}: {e['estimate']:g} {e['unit']} (score {e['score']:.1f})\n"
    for name, why in not_sized.items():
        text += f"#   left out: {name}: {why}\n"
    if not added:
        text += f"#   none sized above {threshold}: the model is not changed\n"
    text += yaml.safe_dump({NODE_NAME: {"ros__parameters": params}}, sort_keys=True)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(path, text)
    except OSError as exc:
        raise ConfigError("--write-config", str(path), f"cannot write: {exc}") from exc
    return {
        "config_file": str(path),
        "effects": added,
        "not_sized": not_sized,
        "before": before,
        "after": after,
    }


def _assess_effects(
    cfg: RadiusEstimatorConfig,
    trace: RadiusTrace,
    run_config: Callable[[RadiusEstimatorConfig], RadiusTrace],
    n_seeds: int = 1,
) -> dict[str, Any]:
    """Residual analysis with the profile-likelihood ranking of the switchable effects.

    The base model and every re-run (``run_config``: the radius MPF alone over the bag) use
    the ``n_seeds`` filter seeds from ``cfg.seed`` on (``trace`` is the base run of
    ``cfg.seed``); the profile is their mean NLL.
    """
    from tire_estimation.evaluation import residuals

    seeds = [cfg.seed + k for k in range(n_seeds)]

    def run(values: dict[str, Any], seed: int) -> RadiusTrace:
        return run_config(RadiusEstimatorConfig.from_dict({**values, "seed": seed}))

    def rerun(effect: str, value: float) -> list[RadiusTrace]:
        values = {**cfg.to_dict(), **residuals.effect_overrides(effect, value)}
        return [run(values, seed) for seed in seeds]

    base = [trace] + [run(cfg.to_dict(), seed) for seed in seeds[1:]]
    grids = dict(residuals.DEFAULT_GRIDS)
    if not len(trace.vel_t_ns):
        # the velocity latency is a candidate only when the run used the GNSS velocity
        grids.pop("gnss_velocity_latency")
    # the value each candidate has in the configured model (its grid point of the base runs)
    current = {e.name: e.value(cfg) for e in residuals.EFFECTS}
    report = residuals.assess(base, rerun, grids, current=current)
    report["tests"]["rank_seeds"] = seeds
    return report


def write_plots(out: Path, bag: ReportBag, trace: RadiusTrace) -> None:
    """radius_errors.png, trajectory.png, innovations.png in ``out`` (series of more than
    :data:`~tire_estimation.spill.PLOT_POINTS` points shown every k-th)."""
    from tire_estimation.evaluation import plots

    keys = ["t_ns", "radius_error_m", "radius_error_std_m", "pose"]
    with_baseline = rows_of(trace, "baseline_radius_error_m") == rows_of(trace, "t_ns")
    if with_baseline:
        keys.append("baseline_radius_error_m")
    arr = decimated(trace, keys)
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
            arr["baseline_radius_error_m"] if with_baseline and t_s.size else None,
            events,
        )
    ltp = LocalTangentPlane(*trace.origin_lla) if trace.origin_lla is not None else None
    if ltp is not None and bag.gnss is not None:
        fixes = bag.gnss.decimated()
        e, n, _ = ltp.to_enu(fixes.lat_deg, fixes.lon_deg, fixes.alt_m)
        # the truth or the bag's reference at the estimate's times (as the position RMSE)
        ref_en, against = _reference_positions(bag, arr["t_ns"], ltp)
        plots.plot_trajectory(
            out / "trajectory.png",
            arr["pose"][:, :2],
            np.column_stack([e, n]),
            ref_en,
            t_s=(arr["t_ns"] - bag.start_ns) * 1e-9,
            reference_label=against,
        )
    innov = decimated(trace, ["innov_t_ns", "innov_m", "innov_cov_m2", "nis", "accepted"])
    if innov["innov_t_ns"].size:
        plots.plot_innovations(
            out / "innovations.png",
            (innov["innov_t_ns"] - bag.start_ns) * 1e-9,
            innov["innov_m"],
            innov["innov_cov_m2"],
            innov["nis"],
            innov["accepted"],
        )
