"""The lateral part of the replay's report: the lateral estimators and the stiffness MPF against
the bag's reference, and their plots.

The traces are recorded at the IMU or tyre-force rate (100 Hz: 1.4 million rows in 4 hours);
the errors are summed over chunks of rows (:func:`~tire_estimation.spill.row_chunks`) against the
reference rows of each chunk's span (:meth:`~tire_estimation.replay_streams.KeptStream.window`),
so that memory does not grow with the drive; the plots show every k-th row.
"""

from __future__ import annotations

import math
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.bag import topics
from tire_estimation.evaluation import metrics as ev
from tire_estimation.evaluation.runner import ImuLateralTrace, LateralTrace
from tire_estimation.replay_streams import ReportBag
from tire_estimation.spill import decimated, row_chunks, rows_of

#: reference rows an interpolation for a plot reads at most (evenly spaced over the drive)
PLOT_REFERENCE_ROWS = 200_000


def lateral_metrics(bag: ReportBag, lateral: LateralTrace | None) -> dict[str, Any] | None:
    """RMSE of the tyre-force KF's lateral state against the truth (or reference) odometry."""
    if lateral is None:
        return None
    truth = bag.truth_odometry
    ref = truth if truth is not None else bag.reference_odometry
    out: dict[str, Any] = {"source": "tyre_force_kf", "dropped_samples": lateral.dropped}
    if ref is None:
        out.update({"vy_rmse_m_s": None, "sideslip_rmse_deg": None, "yaw_rate_rmse_deg_s": None})
        return out
    out["against"] = topics.TRUTH_ODOMETRY if truth is not None else topics.REFERENCE_ODOMETRY
    keys = ("t_ns", "vy_m_s", "yaw_rate_rad_s", "sideslip_rad", "relay")
    sums: Counter[str] = Counter()
    for c in row_chunks(lateral, keys):
        t = c["t_ns"]
        w = ref.window(t[0], t[-1])
        part = ev.lateral_sums(
            t, c["vy_m_s"], c["yaw_rate_rad_s"], c["sideslip_rad"], c["relay"],
            w.t_ns, w.linear_velocity_m_s, w.angular_velocity_rad_s[:, 2],
        )  # fmt: skip
        sums.update(part)
    out.update(ev.lateral_from_sums(sums))
    return out


def imu_lateral_reference(
    bag: ReportBag, t_ns: np.ndarray, plot: bool = False
) -> tuple[dict[str, np.ndarray], str, str] | None:
    """Reference at ``t_ns`` (sorted): (``vx``, ``vy``, ``r`` arrays, topic, point) or None.

    ``/reference/lateral_state`` gives the CG (point ``cg``); truth or reference odometry gives
    ``base_link`` (the rear-axle centre). The reference rows around ``t_ns`` are read; for a
    plot (``plot``, times over the whole drive) at most :data:`PLOT_REFERENCE_ROWS` of them.
    """

    def rows(stream: Any) -> Any:
        if plot:
            return stream.decimated(PLOT_REFERENCE_ROWS)
        return stream.window(t_ns[0], t_ns[-1])

    if bag.reference_lateral is not None:
        lat = rows(bag.reference_lateral)
        col = {n: i for i, n in enumerate(lat.names)}
        ref = {
            key: np.interp(t_ns, lat.t_ns, lat.values[:, col[name]])
            for key, name in (("vx", "vx_cg"), ("vy", "vy_cg"), ("r", "yaw_rate"))
        }
        return ref, topics.REFERENCE_LATERAL_STATE, "cg"
    stream, topic = bag.truth_odometry, topics.TRUTH_ODOMETRY
    if stream is None:
        stream, topic = bag.reference_odometry, topics.REFERENCE_ODOMETRY
    if stream is None:
        return None
    odo = rows(stream)
    ref = {
        "vx": np.interp(t_ns, odo.t_ns, odo.linear_velocity_m_s[:, 0]),
        "vy": np.interp(t_ns, odo.t_ns, odo.linear_velocity_m_s[:, 1]),
        "r": np.interp(t_ns, odo.t_ns, odo.angular_velocity_rad_s[:, 2]),
    }
    return ref, topic, "base_link"


def imu_lateral_metrics(bag: ReportBag, name: str, trace: ImuLateralTrace) -> dict[str, Any]:
    """RMSE of vy, sideslip and yaw rate of an IMU-driven lateral estimator vs the reference.

    The estimators estimate the CG's velocity; against a base_link reference it is moved to
    the rear axle (``vy - lr r``, rigid body). Every recorded sample is scored.
    """
    out: dict[str, Any] = {
        "source": name,
        "dropped_samples": trace.dropped,
        "steps": trace.steps,
        "vy_rmse_m_s": None,
        "sideslip_rmse_deg": None,
        "yaw_rate_rmse_deg_s": None,
    }
    n = rows_of(trace, "t_ns")
    sums = np.zeros(3)
    max_beta = -math.inf
    against = None
    for c in row_chunks(trace, ("t_ns", "vx_m_s", "vy_m_s", "yaw_rate_rad_s")):
        found = imu_lateral_reference(bag, c["t_ns"])
        if found is None:
            return out
        ref, topic, point = found
        against = (topic, point)
        vx, vy, r = c["vx_m_s"], c["vy_m_s"], c["yaw_rate_rad_s"]
        if point == "base_link":
            vy = vy - bag.vehicle.lr_m * r
        e_vy = vy - ref["vy"]
        e_beta = np.degrees(
            np.arctan2(vy, np.maximum(vx, 0.1)) - np.arctan2(ref["vy"], np.maximum(ref["vx"], 0.1))
        )
        e_r = np.degrees(r - ref["r"])
        sums += [np.sum(e_vy**2), np.sum(e_beta**2), np.sum(e_r**2)]
        max_beta = max(max_beta, float(np.max(np.abs(e_beta))))
    if against is None:
        return out
    vy_ss, beta_ss, r_ss = (float(v) for v in sums)
    out.update(
        {
            "against": against[0],
            "point": against[1],
            "vy_rmse_m_s": math.sqrt(vy_ss / n),
            "sideslip_rmse_deg": math.sqrt(beta_ss / n),
            "yaw_rate_rmse_deg_s": math.sqrt(r_ss / n),
            "sideslip_max_abs_error_deg": max_beta,
            "samples": n,
        }
    )
    return out


def stiffness_metrics(bag: ReportBag, trace: ImuLateralTrace) -> dict[str, Any]:
    """Final stiffness per name (and std, nominal), learning fraction, relative RMSE vs
    ``/truth/tire_stiffness`` over the second half of the run (when the bag has it)."""
    names = trace.stiffness_names
    out: dict[str, Any] = {
        "source": "stiffness_mpf",
        "final": None,
        "rel_rmse_vs_truth": None,
        "dropped_samples": trace.dropped,
    }
    n = rows_of(trace, "stiffness")
    if not names or n == 0:
        return out
    last = next(row_chunks(trace, ("stiffness", "stiffness_std", "gyro_bias_rad_s"), 1, n - 1))
    out["final"] = dict(zip(names, last["stiffness"][-1].tolist(), strict=True))
    out["final_std"] = dict(zip(names, last["stiffness_std"][-1].tolist(), strict=True))
    if trace.nominal is not None:
        out["nominal"] = dict(zip(names, trace.nominal.tolist(), strict=True))
    active = sum(int(np.sum(c["active"])) for c in row_chunks(trace, ("active",)))
    out["learning_active_fraction"] = active / n
    out["final_gyro_bias_rad_s"] = float(last["gyro_bias_rad_s"][-1])
    # truth-free fit of the configuration to the measured IMU data (model selection)
    out["mean_log_predictive"] = trace.mean_log_predictive
    kept = bag.truth_stiffness
    if kept is None:
        return out
    truth = kept.read()
    t_first = int(next(row_chunks(trace, ("t_ns",), 1))["t_ns"][0])
    t_last = int(next(row_chunks(trace, ("t_ns",), 1, n - 1))["t_ns"][-1])
    start = t_first + (t_last - t_first) // 2
    # by name; a name the bag's truth does not carry (all NaN: cx_rear of an older bag) is not
    # scored
    known = {n: i for i, n in enumerate(truth.names) if np.isfinite(truth.values[:, i]).any()}
    cols = {j: known[name] for j, name in enumerate(names) if name in known}
    squares = np.zeros(len(names))
    count = 0
    for c in row_chunks(trace, ("t_ns", "stiffness")):
        half = c["t_ns"] >= start
        count += int(half.sum())
        for j, col in cols.items():
            true_c = np.interp(c["t_ns"][half], truth.t_ns, truth.values[:, col])
            squares[j] += np.sum((c["stiffness"][half, j] / true_c - 1.0) ** 2)
    out["rel_rmse_vs_truth"] = {
        names[j]: math.sqrt(float(squares[j]) / count) if count else math.nan for j in cols
    }
    out["rel_rmse_window"] = "second half of the run"
    return out


def _plot_rows(trace: Any) -> dict[str, np.ndarray]:
    """Every k-th row of a trace's arrays that have a row per estimate (the others empty)."""
    n = rows_of(trace, "t_ns")
    arr = trace.arrays()
    keys = [k for k in arr if rows_of(trace, k) == n]
    rows = decimated(trace, keys)
    return {k: rows[k] if k in rows else np.asarray(arr[k]) for k in arr}


def write_lateral_plots(out: Path, bag: ReportBag, traces: dict[str, ImuLateralTrace]) -> None:
    """lateral_state.png (sideslip and yaw rate of each estimator against the reference) and
    stiffness.png (learned stiffness with its std band)."""
    from tire_estimation.evaluation import plots

    series = {}
    for name, trace in traces.items():
        if rows_of(trace, "t_ns"):
            series[name] = _plot_rows(trace)
    if not series:
        return
    ref = None
    any_t = next(iter(series.values()))["t_ns"]
    found = imu_lateral_reference(bag, any_t, plot=True)
    if found is not None:
        ref_vals, topic, point = found
        vy = ref_vals["vy"]
        ref = (
            (any_t - bag.start_ns) * 1e-9,
            np.arctan2(vy, np.maximum(ref_vals["vx"], 0.1)),
            ref_vals["r"],
            f"{topic} ({point})",
            point,
        )
    plots.plot_lateral_state(
        out / "lateral_state.png", bag.start_ns, bag.vehicle.lr_m, series, ref
    )
    stiff = series.get("stiffness_mpf")
    trace = traces.get("stiffness_mpf")
    if stiff is not None and trace is not None and rows_of(trace, "stiffness"):
        plots.plot_stiffness(
            out / "stiffness.png",
            (stiff["t_ns"] - bag.start_ns) * 1e-9,
            trace.stiffness_names,
            stiff["stiffness"],
            stiff["stiffness_std"],
            _truth_stiffness(bag),
        )


def _truth_stiffness(bag: ReportBag) -> tuple[np.ndarray, tuple[str, ...], np.ndarray] | None:
    """The simulator's stiffness truth for the plot (times s from the bag start, names,
    values), decimated; None without it."""
    kept = bag.truth_stiffness
    if kept is None or kept.rows == 0:
        return None
    truth = kept.decimated()
    return (truth.t_ns - bag.start_ns) * 1e-9, tuple(truth.names), truth.values
