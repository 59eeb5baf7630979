"""Evaluation of the lateral state from measured tyre forces (issue 6, Tuononen 2009).

Runs, on a simulated drive (:class:`~tire_estimation.sim.streams.SimResult`),

* (a) the tyre-force Kalman filter
  (:class:`~tire_estimation.core.lateral.tyre_force_kf.TyreForceEstimator`),
* (b) the linear single-track reference model alone (eq. 23-28, open loop, same inputs),
* (c) the lateral state of the tyre-stiffness MPF (Berntorp & Di Cairano 2018,
  :class:`~tire_estimation.core.stiffness.estimator.StiffnessEstimator`, key
  :data:`STIFFNESS_MPF_SLOT`), fed like :func:`tire_estimation.evaluation.stiffness.run` from
  the same drive's wheel speeds (its vx input), steering and IMU; it does not use the tyre
  forces. Its configuration is the default one (bias estimation on, as the simulated IMU has
  biases) plus the simulator's known rolling resistance and drag
  (:func:`stiffness_mpf_config`), N = :data:`DEFAULT_MPF_PARTICLES` particles unless told,
  random generator seeded with the drive's seed + :data:`MPF_SEED_OFFSET`. Its state refers to
  the CG and is moved to ``base_link`` (rear axle) before scoring,

and scores vy and yaw rate of ``base_link`` against the truth, overall and in the nonlinear
phases (where the filter's relay says ``nonlinear``); the three methods share the scoring times
(the tyre-force steps; the MPF's IMU-rate estimates are interpolated onto them). Also: the relay
switching time series, a plot, and the sensitivity of (a) and (b) to errors in lf, lr and a
tyre-force sensor gain.

Command line::

    python -m tire_estimation.evaluation.lateral_tyre --out DIR --seeds N [--minutes M]
        [--particles N_MPF] [--no-sensitivity]

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
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.core.arrays import F64
from tire_estimation.core.lateral.tyre_force_kf import TyreForceKFConfig
from tire_estimation.core.pipeline import EstimationPipeline, Output, PipelineConfig
from tire_estimation.core.samples import Sample, TireForces
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation import stiffness as stiffness_eval
from tire_estimation.sim.dynamics import GRAVITY_M_S2
from tire_estimation.sim.streams import SimResult
from tire_estimation.sim.tires import TireModelConfig
from tire_estimation.sources import stream_samples

#: Key of the third method (the stiffness MPF's lateral state, issue 6 part (c)).
STIFFNESS_MPF_SLOT = "stiffness_mpf"
#: Particles of the stiffness MPF in the evaluation (StiffnessEstimatorConfig's default).
DEFAULT_MPF_PARTICLES = StiffnessEstimatorConfig().n_particles
#: The MPF's random generator is seeded with the drive's seed plus this offset.
MPF_SEED_OFFSET = 1000
#: Samples before this time after the first tyre-force sample are not scored, s.
WARMUP_S = 1.0


@dataclass
class LateralTrace:
    """Estimates after every tyre-force step, shapes (K,).

    ``kf_*``: the tyre-force KF; ``st_*``: the single-track model alone; ``truth_*``: truth of
    base_link interpolated at ``t_s``; ``nonlinear``: relay state; ``deviation_n``: eq. (29)
    after the low-pass; ``relay_t_s``/``relay_state``: the relay switching instants and new
    states; ``stats``: dropped samples by ``<stream>:<kind>``. ``mpf_*``: the stiffness MPF's
    estimates moved to base_link and interpolated at ``t_s`` (nan outside the span where the
    MPF had an estimate; ``None`` when it was not run), ``mpf_info``: its set-up and a few
    diagnostics.
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
    mpf_vy_m_s: F64 | None = None
    mpf_yaw_rate_rad_s: F64 | None = None
    mpf_info: dict[str, Any] = field(default_factory=dict)


def run(
    sim: SimResult,
    config: TyreForceKFConfig | None = None,
    vehicle: VehicleParams | None = None,
    force_gain: float = 1.0,
) -> LateralTrace:
    """The tyre-force KF (:class:`TyreForceEstimator`) in the pipeline over ``sim``; methods (a)
    and (b).

    Args:
        sim: simulated drive with tyre forces.
        config: filter configuration (default: :class:`TyreForceKFConfig`()).
        vehicle: vehicle parameters given to the estimator (default ``sim.vehicle``; pass a
            perturbed copy for the sensitivity study).
        force_gain: gain applied to the measured lateral forces Fy (sensor gain error), 1.
    """
    if sim.tire_forces is None:
        raise ValueError("the simulation has no tyre forces (SensorConfig.tire_force_enabled)")
    tf = dataclasses.replace(sim.tire_forces, fy_n=sim.tire_forces.fy_n * force_gain)
    t0 = int(tf.t_ns[0])
    rows: list[tuple[float, ...]] = []

    class _Rows:
        SAMPLE_KINDS: ClassVar[tuple[type, ...]] = (TireForces,)

        def on_sample(self, pipeline: EstimationPipeline, sample: Sample, e: Any) -> None:
            if type(sample) is not TireForces or e is None or pipeline.tyre_force is None:
                return
            s = pipeline.tyre_force.single_track_estimate()
            rows.append(
                (
                    (sample.t_ns - t0) * 1e-9,
                    e.vy_m_s,
                    e.yaw_rate_rad_s,
                    s.vy_m_s,
                    s.yaw_rate_rad_s,
                    1.0 if e.linearity == "nonlinear" else 0.0,
                    pipeline.tyre_force.axle_force_deviation_n,
                )
            )

        def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
            pass

    pipeline = EstimationPipeline(
        PipelineConfig(tyre_force=config or TyreForceKFConfig()),
        vehicle or sim.vehicle,
        observers=[_Rows()],
    )
    pipeline.push_ordered(
        stream_samples(
            wheel_speeds=sim.wheel_speeds, steering=sim.steering, imu=sim.imu, tire_forces=tf
        )
    )
    est = pipeline.tyre_force
    assert est is not None
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


def stiffness_mpf_config(
    vehicle: VehicleParams, n_particles: int = DEFAULT_MPF_PARTICLES
) -> StiffnessEstimatorConfig:
    """Default :class:`StiffnessEstimatorConfig` with the simulator's known resistances.

    Everything else (noise, bias estimation, forgetting, priors) keeps its default; the
    rolling resistance ``c_rr m g`` and the drag coefficient ``0.5 rho CdA`` are those of the
    simulator's default :class:`TireModelConfig` (``sim/dynamics.py``), which ``lane_change``
    does not change.
    """
    tires = TireModelConfig()
    return StiffnessEstimatorConfig(
        n_particles=n_particles,
        rolling_resistance_n=tires.rolling_resistance_coefficient * vehicle.mass_kg * GRAVITY_M_S2,
        drag_n_s2_m2=0.5 * tires.air_density_kg_m3 * tires.drag_area_m2,
    )


def add_stiffness_mpf(
    trace: LateralTrace,
    sim: SimResult,
    config: StiffnessEstimatorConfig | None = None,
    seed: int = 0,
) -> LateralTrace:
    """Method (c): ``trace`` with the stiffness MPF's vy and yaw rate of base_link at ``t_s``.

    Args:
        trace: result of :func:`run` on ``sim`` (gives the scoring times).
        sim: the same simulated drive (wheel speeds, steering and IMU are used).
        config: estimator configuration (default :func:`stiffness_mpf_config`).
        seed: seed of the MPF's random generator.
    """
    cfg = config or stiffness_mpf_config(sim.vehicle)
    res = stiffness_eval.run(sim, cfg, seed)
    assert sim.tire_forces is not None
    t0 = int(sim.tire_forces.t_ns[0])
    ready = res["ready"].astype(bool)
    t_mpf = (res["t"][ready] - t0) * 1e-9
    vy_cg, r = res["vy"][ready], res["r"][ready]
    # Berntorp & Di Cairano 2018, eq. (1) and (4): vY is the lateral velocity of the CG.
    # base_link is at the rear axle, lr behind the CG (SingleTrackParams.from_vehicle); rigid
    # body: v_base = v_cg + r z x (-lr, 0, 0)  ->  vy_base = vy_cg - lr r
    vy_base = vy_cg - sim.vehicle.lr_m * r
    nan = float("nan")
    inside = (
        (trace.t_s >= t_mpf[0]) & (trace.t_s <= t_mpf[-1])
        if t_mpf.size
        else np.zeros(trace.t_s.shape, dtype=bool)
    )
    vy = np.full(trace.t_s.shape, nan)
    yaw = np.full(trace.t_s.shape, nan)
    if t_mpf.size:
        vy[inside] = np.interp(trace.t_s[inside], t_mpf, vy_base)
        yaw[inside] = np.interp(trace.t_s[inside], t_mpf, r)
    truth_c = res["truth_c"][ready]
    info: dict[str, Any] = {
        "n_particles": cfg.n_particles,
        "rng_seed": int(seed),
        "learning_active_fraction": float(res["active"][ready].mean()) if t_mpf.size else 0.0,
        "final_stiffness_rel_error": (
            (res["c"][ready][-1] / truth_c[-1] - 1.0).round(4).tolist() if t_mpf.size else None
        ),
    }
    return dataclasses.replace(trace, mpf_vy_m_s=vy, mpf_yaw_rate_rad_s=yaw, mpf_info=info)


def _rmse(err: F64) -> float | None:
    return float(np.sqrt(np.mean(err * err))) if err.size else None


def scores(trace: LateralTrace) -> dict[str, Any]:
    """vy (m/s) and yaw-rate (deg/s) RMSE of the KF, the single-track model and the MPF.

    Keys ``overall`` and ``nonlinear`` (relay nonlinear), each with ``tyre_force_kf``,
    ``single_track`` and ``stiffness_mpf`` (``None`` when the trace has no MPF estimates; else
    also its number of scored samples, which are those of the others where the MPF had an
    estimate); plus the share of time nonlinear and the number of relay switches. The first
    :data:`WARMUP_S` are not scored.
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
        if trace.mpf_vy_m_s is not None and trace.mpf_yaw_rate_rad_s is not None:
            m = mask & np.isfinite(trace.mpf_vy_m_s) & np.isfinite(trace.mpf_yaw_rate_rad_s)
            r_rmse = _rmse(trace.mpf_yaw_rate_rad_s[m] - trace.truth_yaw_rate_rad_s[m])
            res[STIFFNESS_MPF_SLOT] = {
                "vy_rmse_m_s": _rmse(trace.mpf_vy_m_s[m] - trace.truth_vy_m_s[m]),
                "yaw_rate_rmse_deg_s": None if r_rmse is None else math.degrees(r_rmse),
                "samples": int(m.sum()),
            }
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
    """vy and yaw rate (KF, single track, MPF if run, truth) and the relay, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(11, 8))
    t = trace.t_s
    ax = axes[0]
    ax.plot(t, trace.truth_vy_m_s, "k", lw=1.5, label="truth")
    ax.plot(t, trace.kf_vy_m_s, "C0", lw=1, label="tyre-force KF")
    ax.plot(t, trace.st_vy_m_s, "C1", lw=1, ls="--", label="single track")
    if trace.mpf_vy_m_s is not None:
        ax.plot(t, trace.mpf_vy_m_s, "C4", lw=1, ls=":", label="stiffness MPF")
    ax.set_ylabel("vy base_link [m/s]")
    ax.legend(loc="upper right", fontsize=8)
    ax = axes[1]
    ax.plot(t, np.degrees(trace.truth_yaw_rate_rad_s), "k", lw=1.5, label="truth")
    ax.plot(t, np.degrees(trace.kf_yaw_rate_rad_s), "C0", lw=1, label="tyre-force KF")
    ax.plot(t, np.degrees(trace.st_yaw_rate_rad_s), "C1", lw=1, ls="--", label="single track")
    if trace.mpf_yaw_rate_rad_s is not None:
        yaw_mpf = np.degrees(trace.mpf_yaw_rate_rad_s)
        ax.plot(t, yaw_mpf, "C4", lw=1, ls=":", label="stiffness MPF")
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
    mpf_particles: int = DEFAULT_MPF_PARTICLES,
) -> dict[str, Any]:
    """Score the methods on ``lane_change`` for each seed; mean over seeds; PNGs to ``out_dir``.

    ``mpf_particles`` is N of the stiffness MPF (method (c)); 0 skips it (slot ``None``).
    """
    from tire_estimation.sim import simulate

    per_seed: dict[str, Any] = {}
    mpf_config: StiffnessEstimatorConfig | None = None
    for seed in seeds:
        sim = simulate("lane_change", seed=int(seed), minutes=minutes)
        trace = run(sim, config)
        if mpf_particles > 0:
            mpf_config = stiffness_mpf_config(sim.vehicle, mpf_particles)
            trace = add_stiffness_mpf(trace, sim, mpf_config, int(seed) + MPF_SEED_OFFSET)
        entry: dict[str, Any] = scores(trace)
        if mpf_particles > 0:
            entry["stiffness_mpf_info"] = trace.mpf_info
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
        mpf_entries = [per_seed[s][phase][STIFFNESS_MPF_SLOT] for s in per_seed]
        summary[phase][STIFFNESS_MPF_SLOT] = (
            {
                key: _mean([e[key] for e in mpf_entries])
                for key in ("vy_rmse_m_s", "yaw_rate_rmse_deg_s")
            }
            if mpf_entries and all(e is not None for e in mpf_entries)
            else None
        )
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
        "stiffness_mpf_config": None if mpf_config is None else dataclasses.asdict(mpf_config),
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
    parser.add_argument(
        "--particles",
        type=int,
        default=DEFAULT_MPF_PARTICLES,
        help=f"particles N of the stiffness MPF, method (c); 0 skips it "
        f"(default {DEFAULT_MPF_PARTICLES})",
    )
    args = parser.parse_args(argv)
    if args.particles < 0:
        parser.error("--particles must be >= 0")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    result = evaluate(
        range(args.seeds),
        args.minutes,
        out,
        with_sensitivity=not args.no_sensitivity,
        mpf_particles=args.particles,
    )
    atomic_write_text(out / "lateral_tyre.json", json.dumps(result, indent=2))
    print(json.dumps(result["summary_mean_over_seeds"], indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
