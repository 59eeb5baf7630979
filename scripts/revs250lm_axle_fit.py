"""Check the stiffness MPF's prior and model against the Revs 250 LM reference (issue 5).

Fits the MPF's tyre curve (friction-limited tanh) to each axle at the measured slips, over the
whole run and its two halves, and reports how much of the yaw acceleration the fitted forces'
yaw moment explains and the slope of ay over dvY/dt + vX r (the roll gain). Uses the measured
vY, which the estimator does not get (docs/closing_the_loop.md, Revs step 7).

    python scripts/revs250lm_axle_fit.py ../shared/data/revs_250lm [--mu 1.1]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from tire_estimation.convert.revs250lm import load_revs, revs_vehicle
from tire_estimation.evaluation.axle_fit import fit_axles, kinematic_accel_ratio


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", type=Path)
    ap.add_argument("--mu", type=float, default=1.1, help="friction coefficient (0: linear)")
    ap.add_argument("--smooth", type=int, default=25, help="Savitzky-Golay window, samples")
    args = ap.parse_args()
    # the converter's reader and the benchmark's vehicle numbers (stiffness is what is fitted)
    col = load_revs(args.data_dir)
    col["yawAngAcc"] = np.loadtxt(args.data_dir / "yawAngAcc.txt")
    car = revs_vehicle()
    n = col["t"].size
    for name, part in (
        ("all", slice(None)),
        ("first half", slice(0, n // 2)),
        ("second half", slice(n // 2, None)),
    ):
        fit = fit_axles(
            car,
            col["vx"][part],
            col["vy"][part],
            col["yawRate"][part],
            col["ayCG"][part],
            col["yawAngAcc"][part],
            col["delta"][part],
            args.mu,
            args.smooth,
        )
        print(
            f"{name:12s} Cf {fit.cornering_stiffness_front_n_rad / 1e3:6.1f}k"
            f"  Cr {fit.cornering_stiffness_rear_n_rad / 1e3:6.1f}k N/rad"
            f"  force RMSE {fit.force_rmse_front_n:4.0f} / {fit.force_rmse_rear_n:4.0f} N"
            f"  yaw-moment R2 {fit.yaw_moment_r2:5.2f}"
        )
    dt = float(np.median(np.diff(col["t"])))
    for win in (11, 25, 51, 101):
        ratio = kinematic_accel_ratio(col["ayCG"], col["vx"], col["vy"], col["yawRate"], dt, win)
        print(f"ay / (dvY/dt + vX r), window {win:3d} samples: {ratio:.4f}")


if __name__ == "__main__":
    main()
