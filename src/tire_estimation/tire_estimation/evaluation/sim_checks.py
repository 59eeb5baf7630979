"""Simulator check figures for docs/results.md (``python -m ...evaluation.sim_checks``).

Each figure compares what a simulated sensor reports with the simulator's truth, or a physical
response with its expectation, on seeded runs; the JSON printed is what docs/results.md quotes.
"""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

import numpy as np

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.sim import SensorConfig, simulate
from tire_estimation.sim.streams import SimResult


def _truth_at(result: SimResult, t_ns: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.interp(t_ns, result.truth.t_ns, values)


def wheel_speed_check(result: SimResult) -> dict[str, Any]:
    """Rear wheel speed x true radius vs the true rolling speed of that wheel (free rolling)."""
    tr = result.truth
    half = 0.5 * result.vehicle.track_width_m
    ws = result.wheel_speeds
    out: dict[str, Any] = {}
    vx = _truth_at(result, ws.t_ns, tr.velocity_m_s[:, 0])
    r = _truth_at(result, ws.t_ns, tr.yaw_rate_rad_s)
    for col, name, y in ((2, "wheel_rl", half), (3, "wheel_rr", -half)):
        radius = _truth_at(result, ws.t_ns, tr.wheel_radius_m[:, col])
        # rear wheel centre speed along x: v = vx - r * y (rigid body, rear axle at base_link)
        v_roll = vx - r * y
        moving = v_roll > 5.0
        rel = ws.wheel_speed_rad_s[moving, col] * radius[moving] / v_roll[moving] - 1.0
        out[name] = {
            "mean_relative_error": float(np.mean(rel)),
            "std_relative_error": float(np.std(rel)),
            "p99_abs_relative_error": float(np.quantile(np.abs(rel), 0.99)),
        }
    return out


def gnss_check(result: SimResult, sensors: SensorConfig) -> dict[str, Any]:
    """GNSS horizontal error vs the truth antenna position, against the configuration."""
    g, tr = result.gnss, result.truth
    ltp = LocalTangentPlane(*result.origin_lla)
    e, n, _ = ltp.to_enu(g.lat_deg, g.lon_deg, g.alt_m)
    te = _truth_at(result, g.t_ns, tr.position_enu_m[:, 0])
    tn = _truth_at(result, g.t_ns, tr.position_enu_m[:, 1])
    yaw = _truth_at(result, g.t_ns, np.unwrap(tr.yaw_rad))
    ax, ay, _ = result.vehicle.gnss_antenna_position_m
    te = te + ax * np.cos(yaw) - ay * np.sin(yaw)
    tn = tn + ax * np.sin(yaw) + ay * np.cos(yaw)
    err = np.column_stack([e - te, n - tn])
    white = np.diff(err, axis=0) / np.sqrt(2.0)  # the slow part cancels in 0.1 s differences
    return {
        "configured_white_std_m": sensors.gnss_white_std_m,
        "configured_correlated_std_m": sensors.gnss_gm_std_m,
        "configured_total_std_m": float(np.hypot(sensors.gnss_white_std_m, sensors.gnss_gm_std_m)),
        "measured_white_std_m": float(np.std(white)),
        "measured_total_std_m_east_north": [float(v) for v in np.std(err, axis=0)],
        "reported_std_m": float(np.sqrt(np.mean(g.position_covariance_m2[:, 0, 0]))),
    }


def yaw_check(result: SimResult) -> dict[str, Any]:
    """Truth yaw rate vs the numerical derivative of the truth heading."""
    tr = result.truth
    t_s = tr.t_ns * 1e-9
    d_yaw = np.gradient(np.unwrap(tr.yaw_rad), t_s)
    diff = d_yaw - tr.yaw_rate_rad_s
    return {
        "rms_rad_s": float(np.sqrt(np.mean(diff**2))),
        "max_rad_s": float(np.max(np.abs(diff))),
    }


def stiffness_step_check(seed: int) -> dict[str, Any]:
    """Lateral response before/after the 50 % stiffness drop at 30 s (stiffness_step)."""
    res = simulate("stiffness_step", seed=seed)
    t_s = (res.truth.t_ns - res.truth.t_ns[0]) * 1e-9
    vy = res.truth.velocity_m_s[:, 1]
    before = (t_s > 10) & (t_s < 30)
    after = (t_s > 40) & (t_s < 60)
    cy = res.truth.stiffness[:, 1]
    return {
        "cy_front_before_n_rad": float(np.mean(cy[before])),
        "cy_front_after_n_rad": float(np.mean(cy[after])),
        "vy_rms_before_m_s": float(np.sqrt(np.mean(vy[before] ** 2))),
        "vy_rms_after_m_s": float(np.sqrt(np.mean(vy[after] ** 2))),
    }


def main(argv: list[str] | None = None) -> int:
    """Print the check figures as JSON."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--minutes", type=float, default=10.0)
    args = parser.parse_args(argv)
    sensors = SensorConfig()
    runs = []
    for seed in range(args.seeds):
        t0 = time.perf_counter()
        res = simulate("robustness", seed=seed, minutes=args.minutes, sensors=sensors)
        wall = time.perf_counter() - t0
        runs.append(
            {
                "seed": seed,
                "simulate_wall_s": wall,
                "wheel_speed": wheel_speed_check(res),
                "gnss": gnss_check(res, sensors),
                "yaw": yaw_check(res),
                "stiffness_step": stiffness_step_check(seed),
            }
        )
    print(json.dumps({"scenario": "robustness", "minutes": args.minutes, "runs": runs}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
