"""Filter-seed study of the comma2k19 loop (issue 7).

Replays the bundled bag with filter seeds 0-9, without and with the GNSS latency compensation
found by the residual analysis (0.052 s), and prints per configuration: position RMSE against
the reference (median, min, max), the learned rear radius errors (mean and spread over seeds),
their median distance to the values implied by the wheel / reference speed ratios, the mean
along-track innovation and the mean NIS.

Usage (repository root, after ``source env.sh``)::

    python scripts/comma_seed_study.py [--seeds 10] [--latency 0.052]
        [--gnss-bias-fraction F] [--gnss-velocity] [--velocity-latency S] [--out FILE.json]

``--gnss-bias-fraction`` sets the estimator's GNSS error model (default: the configuration's
default 0, the paper's white error; 0.5 = half of each fix's variance as a 120 s Gauss-Markov
error).
``--gnss-velocity`` uses the u-blox Doppler velocity of the bag (``gnss_velocity_enabled``);
``--velocity-latency`` is its latency in the "after" runs (``gnss_velocity_latency_s``; the
"before" runs take 0 for both latencies).
It also prints the reported std of the radii and the RMS of their error against the implied
values.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np

from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.replay import run_replay

BAG = Path(__file__).resolve().parents[1] / "bags" / "comma2k19_rav4_seg40"
#: rear radius errors implied by the wheel / reference speed ratios, mm (docs/results.md)
IMPLIED_MM = np.array([3.34, 3.48])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--latency", type=float, default=0.052)
    parser.add_argument("--gnss-bias-fraction", type=float, default=None)
    parser.add_argument("--gnss-velocity", action="store_true")
    parser.add_argument("--velocity-latency", type=float, default=0.0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out: dict[str, list[list[float]]] = {}
    for label, latency in (("before", 0.0), ("after", args.latency)):
        rows = []
        for seed in range(args.seeds):
            with tempfile.TemporaryDirectory() as d:
                extra: dict[str, float | bool] = {}
                if args.gnss_velocity:
                    extra["gnss_velocity_enabled"] = True
                    if latency:
                        extra["gnss_velocity_latency_s"] = args.velocity_latency
                if args.gnss_bias_fraction is not None:
                    extra["gnss_bias_fraction"] = args.gnss_bias_fraction
                cfg = RadiusEstimatorConfig(gnss_latency_s=latency, seed=seed, **extra)
                m = run_replay(
                    BAG, d, config=cfg, plots=False, progress=False, stiffness=False
                ).metrics
            r = m["radii"]["final_radius_error_m"]
            sd = m["radii"]["final_radius_error_std_m"]
            t = m["residuals"]["tests"]
            rows.append(
                [
                    m["position"]["rmse_m"],
                    1e3 * r["wheel_rl"],
                    1e3 * r["wheel_rr"],
                    t["along_track_mean_m"],
                    t["mean_nis"],
                    1e3 * sd["wheel_rl"],
                    1e3 * sd["wheel_rr"],
                ]
            )
        a = np.array(rows)
        out[label] = a.tolist()
        err = np.abs(a[:, 1:3] - IMPLIED_MM)
        print(
            f"{label} (latency {latency} s): position RMSE median {np.median(a[:, 0]):.2f} m "
            f"(min {a[:, 0].min():.2f}, max {a[:, 0].max():.2f}) | "
            f"rl {a[:, 1].mean():+.2f} ± {a[:, 1].std():.2f} mm, "
            f"rr {a[:, 2].mean():+.2f} ± {a[:, 2].std():.2f} mm | "
            f"|error vs implied| median {np.median(err):.2f} mm | "
            f"along-track mean {a[:, 3].mean():+.2f} m | mean NIS {a[:, 4].mean():.2f} | "
            f"RMS error vs implied {np.sqrt(np.mean(err**2)):.2f} mm, "
            f"mean reported std {a[:, 5:7].mean():.2f} mm"
        )
    if args.out is not None:
        args.out.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
