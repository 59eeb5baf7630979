"""Radius estimator configurations on the comma2k19 minute, over filter seeds (issue 7).

Each argument is one configuration: comma-separated ``FIELD=VALUE`` overrides of
:class:`RadiusEstimatorConfig` (``true`` / ``false`` for booleans). For each it replays the
bundled bag with filter seeds 0 .. ``--seeds`` - 1 (no stiffness MPF, no plots) and prints the
GNSS velocities used and skipped while accelerating, the position RMSE against the reference
(median, min-max), the learned rear radius errors (mean ± std over seeds) and their RMS and
largest error against the values implied by the wheel / reference speed ratios.

Usage (repository root, after ``source env.sh``)::

    python scripts/comma_config_sweep.py gnss_velocity_enabled=false \\
        gnss_velocity_max_accel_m_s2=100 [--seeds 10]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.replay import run_replay

BAG = Path(__file__).resolve().parents[1] / "bags" / "comma2k19_rav4_seg40"
#: rear radius errors implied by the wheel / reference speed ratios, mm (docs/results.md)
IMPLIED_MM = np.array([3.34, 3.48])


def _overrides(spec: str) -> dict[str, bool | float]:
    out: dict[str, bool | float] = {}
    for item in filter(None, spec.split(",")):
        key, _, value = item.partition("=")
        low = value.strip().lower()
        out[key.strip()] = low == "true" if low in ("true", "false") else float(value)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("configs", nargs="+", help="FIELD=VALUE[,FIELD=VALUE...] ('' = default)")
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    for spec in args.configs:
        kw = _overrides(spec)
        rows = []
        for seed in range(args.seeds):
            with tempfile.TemporaryDirectory() as d:
                cfg = RadiusEstimatorConfig(seed=seed, **kw)  # type: ignore[arg-type]
                m = run_replay(
                    BAG, d, config=cfg, plots=False, progress=False, stiffness=False
                ).metrics
            r = m["radii"]["final_radius_error_m"]
            vel = m.get("gnss_velocity") or {}
            rows.append(
                [
                    m["position"]["rmse_m"],
                    1e3 * r["wheel_rl"],
                    1e3 * r["wheel_rr"],
                    vel.get("updates", 0),
                    vel.get("skipped_accelerating", 0),
                ]
            )
        a = np.array(rows, dtype=float)
        err = a[:, 1:3] - IMPLIED_MM
        print(
            f"{spec or 'default'}: velocities used {a[:, 3].mean():.0f}, skipped "
            f"{a[:, 4].mean():.0f} | position RMSE median {np.median(a[:, 0]):.2f} m "
            f"({a[:, 0].min():.2f}-{a[:, 0].max():.2f}) | rl {a[:, 1].mean():+.2f} ± "
            f"{a[:, 1].std():.2f}, rr {a[:, 2].mean():+.2f} ± {a[:, 2].std():.2f} mm | error vs "
            f"implied RMS {np.sqrt(np.mean(err**2)):.2f}, max {np.abs(err).max():.2f} mm",
            flush=True,
        )


if __name__ == "__main__":
    main()
