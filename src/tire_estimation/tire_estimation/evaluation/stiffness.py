"""Evaluation of the stiffness MPF (Berntorp & Di Cairano 2018, Sec. VI) on the simulator.

``python -m tire_estimation.evaluation.stiffness --out DIR --runs R`` writes ``stiffness.json``:
RMSE of vY vs N on ``stiffness_step`` (Fig. 5, Algorithm 1 only), steady-state cy_front error,
and per-IMU-step time. Baselines (AUGPF, RLS, EKF) are not implemented yet.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.core.stiffness_config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness_estimator import StiffnessEstimator
from tire_estimation.sim import SensorConfig, SimResult, simulate

NO_BIAS = SensorConfig(
    accel_bias_initial_std_m_s2=0.0,
    gyro_bias_initial_std_rad_s=0.0,
    accel_bias_random_walk_m_s2_sqrt_s=0.0,
    gyro_bias_random_walk_rad_s_sqrt_s=0.0,
)


def eval_config(n: int, **kw: Any) -> StiffnessEstimatorConfig:
    """Configuration used by the evaluation (bias-free, paper Sec. VI-A; sim resistances)."""
    base: dict[str, Any] = {
        "n_particles": n,
        "accel_bias_std_m_s2": 0.0,
        "gyro_bias_std_rad_s": 0.0,
        "accel_bias_walk_m_s2_sqrt_s": 0.0,
        "gyro_bias_walk_rad_s_sqrt_s": 0.0,
        "rolling_resistance_n": 177.0,
        "drag_n_s2_m2": 0.42,
    }
    base.update(kw)
    return StiffnessEstimatorConfig(**base)


def run(sim: SimResult, cfg: StiffnessEstimatorConfig, seed: int) -> dict[str, np.ndarray]:
    """Replay ``sim`` through the estimator; arrays on the IMU grid.

    Keys: ``t`` (ns), ``c``/``std`` stiffness and its std (K, 3), ``vy`` (CG) and ``r`` (yaw
    rate) estimates, ``active`` (learning on), ``ready`` (filter initialized), the truth
    ``truth_c``/``truth_vy`` (CG), ``t_s`` from the first IMU sample and ``step_ms``.
    """
    est = StiffnessEstimator(cfg, sim.vehicle, np.random.default_rng(seed))
    ws, st, imu = sim.wheel_speeds, sim.steering, sim.imu
    ev: list[tuple[int, int, Any]] = [
        (int(t), 0, v) for t, v in zip(ws.t_ns, ws.wheel_speed_rad_s, strict=False)
    ]
    ev += [(int(t), 1, float(v)) for t, v in zip(st.t_ns, st.angle_rad, strict=False)]
    ev += [
        (int(t), 2, (g, a))
        for t, g, a in zip(
            imu.t_ns, imu.angular_velocity_rad_s, imu.linear_acceleration_m_s2, strict=False
        )
    ]
    ev.sort(key=lambda e: (e[0], e[1]))
    out: dict[str, list[Any]] = {
        "t": [],
        "c": [],
        "std": [],
        "vy": [],
        "r": [],
        "active": [],
        "ready": [],
    }
    dt_total = 0.0
    for t, kind, v in ev:
        if kind == 0:
            est.on_wheel_speeds(t, v)
        elif kind == 1:
            est.on_steering(t, v)
        else:
            t0 = time.perf_counter()
            est.on_imu(t, v[0], v[1])
            dt_total += time.perf_counter() - t0
            e = est.estimate()
            out["t"].append(t)
            out["c"].append(e.stiffness)
            out["std"].append(e.stiffness_std)
            out["vy"].append(e.vy_m_s)
            out["r"].append(e.yaw_rate_rad_s)
            out["active"].append(e.active)
            out["ready"].append(est.mpf.initialized)
    res = {k: np.asarray(v) for k, v in out.items()}
    tr = sim.truth
    j = np.searchsorted(tr.t_ns, res["t"]).clip(0, tr.t_ns.size - 1)
    res["truth_c"] = tr.stiffness[j]
    # base_link is at the rear axle: vy_cg = vy_base + lr r
    res["truth_vy"] = tr.velocity_m_s[j, 1] + sim.vehicle.lr_m * tr.yaw_rate_rad_s[j]
    res["t_s"] = (res["t"] - res["t"][0]) * 1e-9
    res["step_ms"] = np.array(1e3 * dt_total / max(len(out["t"]), 1))
    return res


def settling(t_s: np.ndarray, rel: np.ndarray, start_s: float, tol: float = 0.05) -> float:
    """Time after ``start_s`` from which |rel| stays within ``tol`` (nan if never)."""
    bad = np.nonzero((np.abs(rel) > tol) & (t_s >= start_s))[0]
    if bad.size == 0:
        return 0.0
    last = bad[-1]
    return float(t_s[last] - start_s) if last + 1 < t_s.size else float("nan")


def main(argv: list[str] | None = None) -> None:
    """Command line entry point."""
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--particles", type=int, nargs="+", default=[50, 100, 200, 500])
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
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
            sim = simulate(scen, seed=0, sensors=NO_BIAS)
            res = run(sim, eval_config(200, initial_stiffness_factor=f0), seed=7)
            rel = res["c"] / res["truth_c"] - 1.0
            on = res["t_s"][np.argmax(res["active"])] if np.any(res["active"]) else float("nan")
            ss = res["t_s"] > res["t_s"][-1] - 5.0
            report["sine"][f"{scen}@{f0}"] = {
                "activation_s": float(on),
                "settling_s": [settling(res["t_s"], rel[:, i], float(on)) for i in range(3)],
                "steady_mean_rel_error": rel[ss].mean(axis=0).tolist(),
                "steady_max_abs_rel_error": np.abs(rel[ss]).max(axis=0).tolist(),
            }
    (args.out / "stiffness.json").write_text(json.dumps(report, indent=2))
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
