"""Evaluation of the lateral state from measured tyre forces (issue 6, Tuononen 2009).

Runs, on a simulated drive (:class:`~tire_estimation.sim.streams.SimResult`),

* (a) the tyre-force Kalman filter
  (:class:`~tire_estimation.core.tyre_force_kf.TyreForceEstimator`),
* (b) the linear single-track reference model alone (eq. 23-28, open loop, same inputs),
* (c) the lateral state of the stiffness MPF -- not implemented yet: the slot
  :data:`STIFFNESS_MPF_SLOT` is reported as ``null``,

and scores vy and yaw rate of ``base_link`` against the truth, overall and in the nonlinear
phases (where the filter's relay says ``nonlinear``). Also: the relay switching time series, a
plot, and the sensitivity of the estimates to errors in lf, lr and a tyre-force sensor gain.

Command line::

    python -m tire_estimation.evaluation.lateral_tyre --out DIR --seeds N [--minutes M]

writes ``DIR/lateral_tyre.json`` and ``DIR/lateral_tyre_seed<k>.png``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.tyre_force_kf import TyreForceEstimator, TyreForceKFConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim.streams import SimResult

F64 = NDArray[np.float64]

#: Name of the not-yet-existing third method (the stiffness MPF's lateral state, issue (c)).
STIFFNESS_MPF_SLOT = "stiffness_mpf"
#: Samples before this time after the first tyre-force sample are not scored, s.
WARMUP_S = 1.0
#: Order of the streams on equal stamps: inputs that the force step holds come first.
_WHEELS, _STEER, _IMU, _FORCES = 0, 1, 2, 3


@dataclass
class LateralTrace:
    """Estimates after every tyre-force step, shapes (K,).

    ``kf_*``: the tyre-force KF; ``st_*``: the single-track model alone; ``truth_*``: truth of
    base_link interpolated at ``t_s``; ``nonlinear``: relay state; ``deviation_n``: eq. (29)
    after the low-pass; ``relay_t_s``/``relay_state``: the relay switching instants and new
    states; ``stats``: dropped samples by kind.
    """

    t_s: F64
    kf_vy_m_s: F64
    kf_yaw_rate_rad_s: F64
    st_vy_m_s: F64
    st_yaw_rate_rad_s: F64
    truth_vy_m_s: F64
    truth_yaw_rate_rad_s: F64
    nonlinear: NDArray[np.bool_]
    deviation_n: F64
    relay_t_s: F64
    relay_state: NDArray[np.bool_]
    stats: dict[str, int] = field(default_factory=dict)


def run(
    sim: SimResult,
    config: TyreForceKFConfig | None = None,
    vehicle: VehicleParams | None = None,
    force_gain: float = 1.0,
) -> LateralTrace:
    """Drive a :class:`TyreForceEstimator` over ``sim`` in stamp order; methods (a) and (b).

    Args:
        sim: simulated drive with tyre forces.
        config: filter configuration (default: :class:`TyreForceKFConfig`()).
        vehicle: vehicle parameters given to the estimator (default ``sim.vehicle``; pass a
            perturbed copy for the sensitivity study).
        force_gain: gain applied to the measured lateral forces Fy (sensor gain error), 1.
    """
    if sim.tire_forces is None:
        raise ValueError("the simulation has no tyre forces (SensorConfig.tire_force_enabled)")
    est = TyreForceEstimator(config or TyreForceKFConfig(), vehicle or sim.vehicle)
    tf = sim.tire_forces
    streams = (
        (sim.wheel_speeds.t_ns, _WHEELS),
        (sim.steering.t_ns, _STEER),
        (sim.imu.t_ns, _IMU),
        (tf.t_ns, _FORCES),
    )
    t_all = np.concatenate([t for t, _ in streams])
    kind = np.concatenate([np.full(t.size, k) for t, k in streams])
    index = np.concatenate([np.arange(t.size) for t, _ in streams])
    order = np.lexsort((kind, t_all))
    t0 = int(tf.t_ns[0])
    rows: list[tuple[float, ...]] = []
    fy = tf.fy_n * force_gain
    for o in order:
        k, i, t = int(kind[o]), int(index[o]), int(t_all[o])
        if k == _WHEELS:
            est.on_wheel_speeds(t, sim.wheel_speeds.wheel_speed_rad_s[i])
        elif k == _STEER:
            est.on_steering(t, float(sim.steering.angle_rad[i]))
        elif k == _IMU:
            est.on_imu(t, sim.imu.angular_velocity_rad_s[i], sim.imu.linear_acceleration_m_s2[i])
        else:
            e = est.on_tire_forces(t, tf.fx_n[i], fy[i], tf.fz_n[i], tf.valid[i])
            if e is None:
                continue
            s = est.single_track_estimate()
            rows.append(
                (
                    (t - t0) * 1e-9,
                    e.vy_m_s,
                    e.yaw_rate_rad_s,
                    s.vy_m_s,
                    s.yaw_rate_rad_s,
                    1.0 if e.linearity == "nonlinear" else 0.0,
                    est.axle_force_deviation_n,
                )
            )
    a = np.asarray(rows, dtype=float).reshape(-1, 7)
    truth_t = (sim.truth.t_ns - t0) * 1e-9
    nonlinear = a[:, 5] > 0.5
    switch = np.flatnonzero(np.diff(nonlinear.astype(int)) != 0) + 1
    return LateralTrace(
        t_s=a[:, 0],
        kf_vy_m_s=a[:, 1],
        kf_yaw_rate_rad_s=a[:, 2],
        st_vy_m_s=a[:, 3],
        st_yaw_rate_rad_s=a[:, 4],
        truth_vy_m_s=np.interp(a[:, 0], truth_t, sim.truth.velocity_m_s[:, 1]),
        truth_yaw_rate_rad_s=np.interp(a[:, 0], truth_t, sim.truth.yaw_rate_rad_s),
        nonlinear=nonlinear,
        deviation_n=a[:, 6],
        relay_t_s=a[switch, 0],
        relay_state=nonlinear[switch],
        stats=dict(est.stats),
    )


def _rmse(err: F64) -> float | None:
    return float(np.sqrt(np.mean(err * err))) if err.size else None


def scores(trace: LateralTrace) -> dict[str, Any]:
    """vy (m/s) and yaw-rate (deg/s) RMSE of the KF and the single-track model.

    Keys ``overall`` and ``nonlinear`` (relay nonlinear), each with ``tyre_force_kf``,
    ``single_track`` and the empty slot ``stiffness_mpf``; plus the share of time nonlinear and
    the number of relay switches. The first :data:`WARMUP_S` are not scored.
    """
    scored = trace.t_s >= trace.t_s[0] + WARMUP_S if trace.t_s.size else trace.t_s > 0
    out: dict[str, Any] = {}
    for phase, mask in (("overall", scored), ("nonlinear", scored & trace.nonlinear)):
        res: dict[str, Any] = {}
        for name, vy, r in (
            ("tyre_force_kf", trace.kf_vy_m_s, trace.kf_yaw_rate_rad_s),
            ("single_track", trace.st_vy_m_s, trace.st_yaw_rate_rad_s),
        ):
            r_rmse = _rmse(r[mask] - trace.truth_yaw_rate_rad_s[mask])
            res[name] = {
                "vy_rmse_m_s": _rmse(vy[mask] - trace.truth_vy_m_s[mask]),
                "yaw_rate_rmse_deg_s": None if r_rmse is None else math.degrees(r_rmse),
            }
        res[STIFFNESS_MPF_SLOT] = None
        res["samples"] = int(mask.sum())
        out[phase] = res
    out["nonlinear_fraction"] = float(trace.nonlinear[scored].mean()) if scored.any() else 0.0
    out["relay_switches"] = int(trace.relay_t_s.size)
    out["dropped"] = dict(trace.stats)
    return out


def perturbed_vehicle(
    vehicle: VehicleParams, lf_factor: float = 1.0, lr_factor: float = 1.0
) -> VehicleParams:
    """``vehicle`` with lf and/or lr scaled (the wheelbase follows lf + lr)."""
    lf = vehicle.cg_to_front_axle_m * lf_factor
    lr = vehicle.cg_to_rear_axle_m * lr_factor
    return dataclasses.replace(
        vehicle, cg_to_front_axle_m=lf, cg_to_rear_axle_m=lr, wheelbase_m=lf + lr
    )


#: Parameter errors of the sensitivity study: name -> (lf factor, lr factor, Fy gain).
SENSITIVITY_CASES: dict[str, tuple[float, float, float]] = {
    "nominal": (1.0, 1.0, 1.0),
    "lf_minus_10pct": (0.9, 1.0, 1.0),
    "lf_plus_10pct": (1.1, 1.0, 1.0),
    "lr_minus_10pct": (1.0, 0.9, 1.0),
    "lr_plus_10pct": (1.0, 1.1, 1.0),
    "fy_gain_plus_5pct": (1.0, 1.0, 1.05),
}


def sensitivity(sim: SimResult, config: TyreForceKFConfig | None = None) -> dict[str, Any]:
    """KF and single-track RMSE (overall) with lf, lr and the Fy sensor gain in error."""
    out: dict[str, Any] = {}
    for name, (kf_lf, kf_lr, gain) in SENSITIVITY_CASES.items():
        vehicle = perturbed_vehicle(sim.vehicle, kf_lf, kf_lr)
        s = scores(run(sim, config, vehicle, gain))
        out[name] = {"overall": s["overall"], "nonlinear": s["nonlinear"]}
    return out


def plot(trace: LateralTrace, path: str | Path, title: str = "") -> None:
    """vy and yaw rate (KF, single track, truth) and the relay input/state, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(11, 8))
    t = trace.t_s
    ax = axes[0]
    ax.plot(t, trace.truth_vy_m_s, "k", lw=1.5, label="truth")
    ax.plot(t, trace.kf_vy_m_s, "C0", lw=1, label="tyre-force KF")
    ax.plot(t, trace.st_vy_m_s, "C1", lw=1, ls="--", label="single track")
    ax.set_ylabel("vy base_link [m/s]")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    ax.plot(t, np.degrees(trace.truth_yaw_rate_rad_s), "k", lw=1.5, label="truth")
    ax.plot(t, np.degrees(trace.kf_yaw_rate_rad_s), "C0", lw=1, label="tyre-force KF")
    ax.plot(t, np.degrees(trace.st_yaw_rate_rad_s), "C1", lw=1, ls="--", label="single track")
    ax.set_ylabel("yaw rate [deg/s]")
    ax = axes[2]
    ax.plot(t, trace.deviation_n, "C2", lw=1, label="axle-force deviation (eq. 29)")
    ax.set_ylabel("deviation [N]")
    ax2 = ax.twinx()
    ax2.fill_between(t, 0, trace.nonlinear.astype(float), color="C3", alpha=0.2, step="post")
    ax2.set_ylim(0, 1.05)
    ax2.set_yticks([0, 1], ["linear", "nonlinear"])
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper left", fontsize=8)
    for a in axes[:2]:
        ylo, yhi = a.get_ylim()
        a.fill_between(t, ylo, yhi, where=trace.nonlinear, color="C3", alpha=0.1, lw=0)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _mean(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None]
    return float(np.mean(v)) if v else None


def evaluate(
    seeds: Sequence[int],
    minutes: float = 1.0,
    out_dir: str | Path | None = None,
    config: TyreForceKFConfig | None = None,
    with_sensitivity: bool = True,
) -> dict[str, Any]:
    """Score the methods on ``lane_change`` for each seed; mean over seeds; PNGs to ``out_dir``."""
    from tire_estimation.sim import simulate

    per_seed: dict[str, Any] = {}
    for seed in seeds:
        sim = simulate("lane_change", seed=int(seed), minutes=minutes)
        trace = run(sim, config)
        entry: dict[str, Any] = scores(trace)
        entry["relay_switching"] = {
            "t_s": [round(float(x), 3) for x in trace.relay_t_s],
            "nonlinear": [bool(x) for x in trace.relay_state],
        }
        if with_sensitivity:
            entry["sensitivity"] = sensitivity(sim, config)
        if out_dir is not None:
            plot(trace, Path(out_dir) / f"lateral_tyre_seed{seed}.png", f"lane_change seed {seed}")
        per_seed[str(seed)] = entry
    summary: dict[str, Any] = {}
    for phase in ("overall", "nonlinear"):
        summary[phase] = {
            name: {
                key: _mean([per_seed[s][phase][name][key] for s in per_seed])
                for key in ("vy_rmse_m_s", "yaw_rate_rmse_deg_s")
            }
            for name in ("tyre_force_kf", "single_track")
        }
        summary[phase][STIFFNESS_MPF_SLOT] = None
    if with_sensitivity:
        summary["sensitivity"] = {
            case: {
                name: {
                    key: _mean(
                        [per_seed[s]["sensitivity"][case]["overall"][name][key] for s in per_seed]
                    )
                    for key in ("vy_rmse_m_s", "yaw_rate_rmse_deg_s")
                }
                for name in ("tyre_force_kf", "single_track")
            }
            for case in SENSITIVITY_CASES
        }
    return {
        "scenario": "lane_change",
        "minutes": minutes,
        "seeds": [int(s) for s in seeds],
        "config": (config or TyreForceKFConfig()).to_dict(),
        "summary_mean_over_seeds": summary,
        "per_seed": per_seed,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m tire_estimation.evaluation.lateral_tyre --out DIR --seeds N``."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="output directory (JSON and PNGs)")
    parser.add_argument("--seeds", type=int, default=3, help="number of seeds 0..N-1")
    parser.add_argument("--minutes", type=float, default=1.0, help="drive length per seed")
    parser.add_argument("--no-sensitivity", action="store_true", help="skip the lf/lr/gain runs")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = evaluate(
        range(args.seeds), args.minutes, out, with_sensitivity=not args.no_sensitivity
    )
    (out / "lateral_tyre.json").write_text(json.dumps(result, indent=2))
    print(json.dumps(result["summary_mean_over_seeds"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
