"""Evaluation of the stiffness MPF (Berntorp & Di Cairano 2018, Sec. VI) on the simulator.

``python -m tire_estimation.evaluation.stiffness --out DIR --runs R`` writes ``stiffness.json``:
RMSE of vY vs N on ``stiffness_step`` (Fig. 5, Algorithm 1 only), steady-state cy_front error,
and per-IMU-step time. The baselines (AUGPF, RLS, EKF) in the same run:
:mod:`tire_estimation.evaluation.stiffness_compare`.

``python -m tire_estimation.evaluation.stiffness --out DIR --scenario NAME --seeds 0 1 2
[--sim-imu-bias] [--bias-estimation] [--particles N ...] [--minutes M]`` runs the per-seed study
(:func:`study`) instead and writes ``stiffness_<NAME>.json``: lateral state (vY at the CG and
at ``base_link``, yaw rate) against the truth, final and steady stiffness errors, and the final
gyro-bias estimate, with or without the simulator's IMU biases and the filter's bias estimation.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.core.pipeline import EstimationPipeline, Output, PipelineConfig
from tire_estimation.core.samples import ImuSample, Sample
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.frontend import StiffnessFrontEnd
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.sim import SensorConfig, SimResult, simulate
from tire_estimation.sim.dynamics import GRAVITY_M_S2
from tire_estimation.sim.tires import TireModelConfig
from tire_estimation.sources import stream_samples

NO_BIAS = SensorConfig(
    accel_bias_initial_std_m_s2=0.0,
    gyro_bias_initial_std_rad_s=0.0,
    accel_bias_random_walk_m_s2_sqrt_s=0.0,
    gyro_bias_random_walk_rad_s_sqrt_s=0.0,
)
#: Bias estimation switched off (bias-free filter, paper Sec. VI-A).
NO_BIAS_ESTIMATION: dict[str, bool] = {"imu_bias_states": False}
#: Study mode: the MPF's generator is seeded with the drive's seed plus this offset (as method
#: (c) of ``evaluation/lateral_tyre.py``).
STUDY_SEED_OFFSET = 1000
#: Study mode: filter priors per scenario. ``stiffness_step`` draws the initial vY from the
#: paper's P_0 (std 1 m/s, Sec. VI-A), which the paper also gives the filter.
STUDY_PRIOR: dict[str, dict[str, float]] = {"stiffness_step": {"initial_vy_std_m_s": 1.0}}
#: Study mode: samples before this time after the first IMU sample are not scored, s.
STUDY_WARMUP_S = 1.0


def eval_config(n: int, **kw: Any) -> StiffnessEstimatorConfig:
    """Configuration used by the evaluation (bias-free, paper Sec. VI-A; sim resistances)."""
    base: dict[str, Any] = {
        "n_particles": n,
        **NO_BIAS_ESTIMATION,
        "rolling_resistance_n": 177.0,
        "drag_n_s2_m2": 0.42,
    }
    base.update(kw)
    return StiffnessEstimatorConfig(**base)


def study_config(
    vehicle: VehicleParams, n: int, bias_estimation: bool, **kw: Any
) -> StiffnessEstimatorConfig:
    """Default configuration with the simulator's resistances; bias estimation on or off.

    The rolling resistance ``c_rr m g`` and drag coefficient ``0.5 rho CdA`` are those of the
    simulator's default :class:`TireModelConfig` (as method (c) of ``lateral_tyre``).
    """
    tires = TireModelConfig()
    base: dict[str, Any] = {
        "n_particles": n,
        "rolling_resistance_n": tires.rolling_resistance_coefficient
        * vehicle.mass_kg
        * GRAVITY_M_S2,
        "drag_n_s2_m2": 0.5 * tires.air_density_kg_m3 * tires.drag_area_m2,
    }
    if not bias_estimation:
        base.update(NO_BIAS_ESTIMATION)
    base.update(kw)
    return StiffnessEstimatorConfig(**base)


class _Timed:
    """An IMU-driven estimator whose ``on_imu`` time is summed (``busy_s``)."""

    def __init__(self, est: StiffnessFrontEnd[Any]) -> None:
        self.est = est
        self.busy_s = 0.0
        self.on_wheel_speeds = est.on_wheel_speeds
        self.on_steering = est.on_steering
        self.on_velocity = est.on_velocity
        self.estimate = est.estimate

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        t0 = time.perf_counter()
        self.est.on_imu(t_ns, gyro_rad_s, accel_m_s2)
        self.busy_s += time.perf_counter() - t0


class _AfterImu:
    """Pipeline observer: calls ``after_imu(t_ns)`` after each IMU sample."""

    SAMPLE_KINDS: ClassVar[tuple[type, ...]] = (ImuSample,)

    def __init__(self, after_imu: Callable[[int], None]) -> None:
        self.after_imu = after_imu

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        if type(sample) is ImuSample:
            self.after_imu(sample.t_ns)

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        pass


def feed(sim: SimResult, est: StiffnessFrontEnd[Any], after_imu: Callable[[int], None]) -> float:
    """Push the wheel speeds, steering angles and IMU samples of ``sim`` through the pipeline
    with ``est`` as its lateral estimator, calling ``after_imu(t_ns)`` after each IMU sample.
    Returns the wall time spent in ``est.on_imu``, s."""
    timed = _Timed(est)
    pipeline = EstimationPipeline(
        PipelineConfig(),
        sim.vehicle,
        baselines={"estimator": timed},
        observers=[_AfterImu(after_imu)],
    )
    pipeline.push_ordered(
        stream_samples(wheel_speeds=sim.wheel_speeds, steering=sim.steering, imu=sim.imu)
    )
    return timed.busy_s


def truth_at(sim: SimResult, t_ns: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth at the stamps ``t_ns``: stiffness at the next truth sample (K, 3), yaw rate and
    lateral speed at the CG (both linearly interpolated), (K,)."""
    tr = sim.truth
    j = np.searchsorted(tr.t_ns, t_ns).clip(0, tr.t_ns.size - 1)
    t_tr = (tr.t_ns - tr.t_ns[0]).astype(float)
    t_est = (t_ns - tr.t_ns[0]).astype(float)
    r = np.interp(t_est, t_tr, tr.yaw_rate_rad_s)
    # base_link is at the rear axle: vy_cg = vy_base + lr r
    vy = np.interp(t_est, t_tr, tr.velocity_m_s[:, 1]) + sim.vehicle.lr_m * r
    return tr.stiffness[j], r, vy


def run(sim: SimResult, cfg: StiffnessEstimatorConfig, seed: int) -> dict[str, np.ndarray]:
    """Replay ``sim`` through the estimator; arrays on the IMU grid.

    Keys: ``t`` (ns), ``c``/``std`` stiffness and its std (K, 3), ``vy`` (CG) and ``r`` (yaw
    rate) estimates, ``gyro_bias`` (yaw-rate bias estimate, rad/s), ``active`` (learning on),
    ``cx_active`` (Cx learning on), ``ready`` (filter initialized), the truth ``truth_c``
    (stiffness at the next truth sample), ``truth_vy`` (CG) and ``truth_r`` (both linearly
    interpolated at the IMU stamps), ``t_s`` from the first IMU sample, ``step_ms`` and
    ``mean_log_predictive`` (the estimator's value at the end, nats per IMU sample),
    ``grid_handovers`` and ``grid_rejections`` (``first_learning`` = ``grid``: the grid's
    hand-overs to Algorithm 1 and its drops by the NIS gate).
    """
    est = StiffnessEstimator(cfg, sim.vehicle, np.random.default_rng(seed))
    out: dict[str, list[Any]] = {
        "t": [],
        "c": [],
        "std": [],
        "vy": [],
        "r": [],
        "gyro_bias": [],
        "active": [],
        "cx_active": [],
        "ready": [],
    }

    def record(t: int) -> None:
        e = est.estimate()
        out["t"].append(t)
        out["c"].append(e.stiffness)
        out["std"].append(e.stiffness_std)
        out["vy"].append(e.vy_m_s)
        out["r"].append(e.yaw_rate_rad_s)
        out["gyro_bias"].append(float(e.gyro_bias_rad_s[2]))
        out["active"].append(e.active)
        out["cx_active"].append(bool(e.cx_active))
        out["ready"].append(est.mpf.initialized)

    busy_s = feed(sim, est, record)
    res = {k: np.asarray(v) for k, v in out.items()}
    res["truth_c"], res["truth_r"], res["truth_vy"] = truth_at(sim, res["t"])
    res["t_s"] = (res["t"] - res["t"][0]) * 1e-9
    res["step_ms"] = np.array(1e3 * busy_s / max(len(out["t"]), 1))
    final = est.estimate().mean_log_predictive
    res["mean_log_predictive"] = np.array(np.nan if final is None else final)
    res["grid_handovers"] = np.array(est.handover_count)
    res["grid_rejections"] = np.array(est.grid_rejection_count)
    return res


def settling(t_s: np.ndarray, rel: np.ndarray, start_s: float, tol: float = 0.05) -> float:
    """Time after ``start_s`` from which |rel| stays within ``tol`` (nan if never)."""
    bad = np.nonzero((np.abs(rel) > tol) & (t_s >= start_s))[0]
    if bad.size == 0:
        return 0.0
    last = bad[-1]
    return float(t_s[last] - start_s) if last + 1 < t_s.size else float("nan")


def _rmse(err: np.ndarray) -> float:
    return float(np.sqrt(np.mean(err * err))) if err.size else float("nan")


def seed_scores(sim: SimResult, res: dict[str, np.ndarray]) -> dict[str, Any]:
    """Scores of one :func:`run` on ``sim`` (scored from :data:`STUDY_WARMUP_S` on).

    vY RMSE at the CG and at ``base_link`` (vy_cg - lr r), yaw-rate RMSE overall and over the
    last 10 s, final and steady (``stiffness_step``: 15-29.5 s and after 45 s) relative
    stiffness errors, learning fractions, the grid's hand-overs and drops (``first_learning``
    = ``grid``), and the final yaw-rate-bias estimate next to the simulator's (gyro z minus
    true yaw rate, mean over the last 10 s).
    """
    ready = res["ready"].astype(bool)
    t_s = res["t_s"]
    m = ready & (t_s >= STUDY_WARMUP_S)
    last = m & (t_s >= t_s[-1] - 10.0)
    lr = sim.vehicle.lr_m
    vy_err = res["vy"] - res["truth_vy"]
    vy_base_err = vy_err - lr * (res["r"] - res["truth_r"])
    r_err = res["r"] - res["truth_r"]
    rel = res["c"] / res["truth_c"] - 1.0
    out: dict[str, Any] = {
        "vy_rmse_cg_m_s": _rmse(vy_err[m]),
        "vy_rmse_base_link_m_s": _rmse(vy_base_err[m]),
        "yaw_rate_rmse_deg_s": float(np.degrees(_rmse(r_err[m]))),
        "yaw_rate_rmse_last_10s_deg_s": float(np.degrees(_rmse(r_err[last]))),
        "final_stiffness_rel_error": rel[ready][-1].round(4).tolist() if ready.any() else None,
        "learning_active_fraction": float(res["active"][ready].mean()) if ready.any() else 0.0,
        "cx_learning_active_fraction": (
            float(res["cx_active"][ready].mean()) if ready.any() else 0.0
        ),
        "grid_handovers": int(res["grid_handovers"]),
        "grid_rejections": int(res["grid_rejections"]),
    }
    if sim.scenario == "stiffness_step":
        steady = m & (((t_s > 15.0) & (t_s < 29.5)) | (t_s > 45.0))
        out["steady_mean_rel_error"] = rel[steady].mean(axis=0).round(4).tolist()
    imu = sim.imu
    t_tr = (sim.truth.t_ns - sim.truth.t_ns[0]).astype(float)
    t_imu = (imu.t_ns - sim.truth.t_ns[0]).astype(float)
    tail = t_imu >= t_imu[-1] - 10e9
    r_true = np.interp(t_imu[tail], t_tr, sim.truth.yaw_rate_rad_s)
    out["gyro_bias_sim_deg_s"] = float(
        np.degrees(np.mean(imu.angular_velocity_rad_s[tail, 2] - r_true))
    )
    out["gyro_bias_final_estimate_deg_s"] = (
        float(np.degrees(res["gyro_bias"][ready][-1])) if ready.any() else None
    )
    return out


def study(
    scenario: str,
    seeds: list[int],
    n: int,
    sim_imu_bias: bool,
    bias_estimation: bool,
    minutes: float = 1.0,
    overrides: dict[str, Any] | None = None,
    seed_offset: int = STUDY_SEED_OFFSET,
) -> dict[str, Any]:
    """Per-seed scores (:func:`seed_scores`) on ``scenario`` and their means.

    ``overrides``: :class:`StiffnessEstimatorConfig` fields set on top of the study
    configuration (``--set FIELD=VALUE`` on the command line).

    ``sim_imu_bias`` switches the simulator's IMU biases on (:class:`SensorConfig` defaults,
    else :data:`NO_BIAS`); ``bias_estimation`` the filter's bias Kalman filters
    (:func:`study_config`, with :data:`STUDY_PRIOR`). The MPF is seeded with seed +
    ``seed_offset`` (default :data:`STUDY_SEED_OFFSET`; ``--seed-offset``): single 40-seed
    run-away counts vary by about +-3 between offsets for the same filter.
    """
    sensors = SensorConfig() if sim_imu_bias else NO_BIAS
    per_seed: dict[str, Any] = {}
    for seed in seeds:
        sim = simulate(scenario, seed=seed, minutes=minutes, sensors=sensors)
        kw = {**STUDY_PRIOR.get(scenario, {}), **(overrides or {})}
        cfg = study_config(sim.vehicle, n, bias_estimation, **kw)
        res = run(sim, cfg, seed + seed_offset)
        per_seed[str(seed)] = {**seed_scores(sim, res), "step_ms": float(res["step_ms"])}
    keys = ("vy_rmse_cg_m_s", "vy_rmse_base_link_m_s", "yaw_rate_rmse_deg_s")
    return {
        "scenario": scenario,
        "minutes": minutes,
        "n_particles": n,
        "sim_imu_bias": sim_imu_bias,
        "bias_estimation": bias_estimation,
        "overrides": dict(overrides or {}),
        "seed_offset": seed_offset,
        "mean_over_seeds": {k: float(np.mean([v[k] for v in per_seed.values()])) for k in keys},
        "per_seed": per_seed,
    }


def truth_over_nominal(sim: SimResult) -> float:
    """The drive's true cornering stiffness over the estimator's nominal one (mean of both axles).

    The initial guess is a fraction of the estimator's nominal stiffness (the vehicle's); times
    this it becomes a fraction of the drive's truth (on ``snow_sine`` the truth is half the
    nominal).
    """
    nominal = StiffnessEstimator(eval_config(1), sim.vehicle, np.random.default_rng(0))
    return float(np.mean(sim.truth.stiffness[0, 1:] / nominal.mpf.nominal[1:]))


def sine_study(
    scenario: str,
    factor: float,
    runs: int,
    n: int = 200,
    first_seed: int = 0,
    overrides: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """``runs`` drives of ``scenario`` (``snow_sine`` / ``asphalt_sine``, sim seeds
    ``first_seed ...``), bias-free, the MPF started at ``factor`` x the true cornering stiffness
    (all three stiffnesses scaled alike).

    Per run: activation time (first learning sample), settling time of each stiffness after
    activation (:func:`settling`, within 5 % to the end), steady-state mean and maximum
    relative error over the last 5 s. Aggregates over the runs for the cornering stiffnesses
    (columns 1, 2): mean of the steady mean error, maximum of the steady maximum |error|, the
    share of runs settled within 2 s of activation, median and maximum settling time. ``Cx``
    (column 0) is reported but not aggregated into the cornering figures: with constant speed the
    sine drives do not excite it, and the filter freezes it (Sec. II-B).

    ``overrides``: :class:`StiffnessEstimatorConfig` fields set on top of :func:`eval_config`
    (``--set FIELD=VALUE`` with ``--sine-runs``).
    """
    per_run: list[dict[str, Any]] = []
    for r in range(first_seed, first_seed + runs):
        sim = simulate(scenario, seed=r, sensors=NO_BIAS)
        truth_ratio = truth_over_nominal(sim)
        cfg = eval_config(n, initial_stiffness_factor=factor * truth_ratio, **(overrides or {}))
        res = run(sim, cfg, seed=1000 + r)
        scores = sine_run_scores(res["t_s"], res["c"] / res["truth_c"] - 1.0, res["active"])
        per_run.append(
            {
                "seed": r,
                "truth_over_nominal": truth_ratio,
                "grid_handovers": int(res["grid_handovers"]),
                "grid_rejections": int(res["grid_rejections"]),
                **scores,
            }
        )
    return {
        "scenario": scenario,
        "initial_factor": factor,
        "runs": runs,
        "n_particles": n,
        "overrides": dict(overrides or {}),
        **sine_aggregate(per_run),
        "per_run": per_run,
    }


def sine_run_scores(t_s: np.ndarray, rel: np.ndarray, active: np.ndarray) -> dict[str, Any]:
    """Scores of one sine drive: ``t_s`` (K,), relative stiffness error ``rel`` (K, 3), ``active``
    (K,) learning flags.

    Activation time (first learning sample), settling time of each stiffness after it
    (:func:`settling`), steady-state (last 5 s) mean and maximum |relative error|.
    """
    on = float(t_s[np.argmax(active)]) if np.any(active) else math.nan
    ss = t_s > t_s[-1] - 5.0
    return {
        "activation_s": on,
        "settling_s": [settling(t_s, rel[:, i], on) for i in range(3)],
        "steady_mean_rel_error": rel[ss].mean(axis=0).tolist(),
        "steady_max_abs_rel_error": np.abs(rel[ss]).max(axis=0).tolist(),
    }


def sine_aggregate(per_run: list[dict[str, Any]]) -> dict[str, Any]:
    """Aggregates of :func:`sine_run_scores` over the runs (fractions; Cy front / rear).

    Mean of the steady mean error, mean |steady mean error|, maximum and p95 of the steady
    maximum |error|, share settled within 2 s, median and maximum settling time (never = inf),
    and the mean steady error of Cx.
    """
    mean_err = np.array([p["steady_mean_rel_error"] for p in per_run])
    max_err = np.array([p["steady_max_abs_rel_error"] for p in per_run])
    settle = np.array([p["settling_s"] for p in per_run], dtype=float)
    cy = slice(1, 3)
    settled = np.nan_to_num(settle[:, cy], nan=np.inf)
    return {
        "cy_steady_mean_rel_error_mean": mean_err[:, cy].mean(axis=0).tolist(),
        "cy_steady_mean_abs_rel_error_mean": np.abs(mean_err[:, cy]).mean(axis=0).tolist(),
        "cy_steady_max_abs_rel_error_max": max_err[:, cy].max(axis=0).tolist(),
        "cy_steady_max_abs_rel_error_p95": np.quantile(max_err[:, cy], 0.95, axis=0).tolist(),
        "cy_settled_within_2s_share": (settled <= 2.0).mean(axis=0).tolist(),
        "cy_settling_s_median": np.median(settled, axis=0).tolist(),
        "cy_settling_s_max": settled.max(axis=0).tolist(),
        "cx_steady_mean_rel_error_mean": float(mean_err[:, 0].mean()),
    }


def parse_set(items: list[str]) -> dict[str, float | str]:
    """``--set FIELD=VALUE`` items -> {field: number where it parses as one, else the text}.

    Raises:
        ValueError: an item without ``=``.
    """
    out: dict[str, float | str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise ValueError(f"--set needs FIELD=VALUE, got {item!r}")
        try:
            out[key.strip()] = float(value.strip())
        except ValueError:
            out[key.strip()] = value.strip()
    return out


def main(argv: list[str] | None = None) -> None:
    """Command line entry point."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--particles", type=int, nargs="+", default=[50, 100, 200, 500])
    ap.add_argument("--scenario", help="run the per-seed study on this scenario instead")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="study seeds")
    ap.add_argument("--minutes", type=float, default=1.0, help="study drive length")
    ap.add_argument(
        "--seed-offset",
        type=int,
        default=STUDY_SEED_OFFSET,
        help="study: the MPF is seeded with the drive's seed plus this",
    )
    ap.add_argument("--sim-imu-bias", action="store_true", help="study: simulator IMU biases on")
    ap.add_argument(
        "--bias-estimation", action="store_true", help="study: filter bias estimation on"
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="study and sine study: a StiffnessEstimatorConfig field (number, else text) on top "
        "of the study configuration",
    )
    ap.add_argument(
        "--sine-runs",
        type=int,
        default=0,
        help="run only the snow/asphalt sine study with this many drives per scenario and start "
        "(150 %% and 75 %% of truth) at the first --particles value; writes stiffness_sine.json",
    )
    ap.add_argument("--sine-scenarios", nargs="+", default=["snow_sine", "asphalt_sine"])
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    try:
        overrides: dict[str, Any] = dict(parse_set(args.set))
    except ValueError as exc:
        ap.error(str(exc))
    if args.sine_runs > 0:
        sine = {
            f"{scen}@{f0}": sine_study(scen, f0, args.sine_runs, args.particles[0], 0, overrides)
            for scen in args.sine_scenarios
            for f0 in (1.5, 0.75)
        }
        name = "stiffness_sine.json" if len(args.sine_scenarios) > 1 else (
            f"stiffness_sine_{args.sine_scenarios[0]}.json"
        )  # fmt: skip
        atomic_write_text(args.out / name, json.dumps(sine, indent=2))
        print(json.dumps({k: {kk: vv for kk, vv in v.items() if kk != "per_run"}
                          for k, v in sine.items()}, indent=2))  # fmt: skip
        return
    if args.scenario is not None:
        results = [
            study(
                args.scenario,
                args.seeds,
                n,
                args.sim_imu_bias,
                args.bias_estimation,
                args.minutes,
                overrides,
                args.seed_offset,
            )
            for n in args.particles
        ]
        out_file = args.out / f"stiffness_{args.scenario}.json"
        atomic_write_text(out_file, json.dumps(results, indent=2))
        print(json.dumps(results, indent=2))
        return
    report: dict[str, Any] = {"fig5_vy_rmse": {}, "cy_front": {}, "timing_ms": {}, "sine": {}}
    for n in args.particles:
        rmse, err_mean = [], []
        for r in range(args.runs):
            sim = simulate("stiffness_step", seed=r, minutes=1.0, sensors=NO_BIAS)
            res = run(sim, eval_config(n, initial_stiffness_factor=0.7), seed=100 + r)
            rmse.append(float(np.sqrt(np.mean((res["vy"] - res["truth_vy"]) ** 2))))
            rel = res["c"][:, 1] / res["truth_c"][:, 1] - 1.0
            steady = ((res["t_s"] > 15) & (res["t_s"] < 29.5)) | (res["t_s"] > 45)
            err_mean.append(float(np.mean(rel[steady])))
            report["timing_ms"][str(n)] = float(res["step_ms"])
        report["fig5_vy_rmse"][str(n)] = {"mean": float(np.mean(rmse)), "runs": rmse}
        report["cy_front"][str(n)] = {"steady_mean_rel_error": err_mean}
    for scen in ("snow_sine", "asphalt_sine"):
        for f0 in (1.5, 0.75):
            # one drive of the sine study (initial guess relative to the drive's truth)
            report["sine"][f"{scen}@{f0}"] = sine_study(scen, f0, runs=1, n=200)["per_run"][0]
    atomic_write_text(args.out / "stiffness.json", json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
