"""Does the Revs 250 LM reference tell the tanh tyre from a Magic Formula shape? (issue 5).

Fits, per axle at the measured slips (forces from ay and the yaw acceleration, as
``evaluation.axle_fit``), the friction-limited tanh tyre and Pacejka's Magic Formula (fixed
C 1.3, E -0.5, or C and E fitted) and prints the fitted stiffness and the force RMSE, then the
same for the total lateral force ``m ay`` (no yaw acceleration in it). Uses the measured vY,
which the estimator does not get (docs/stiffness_limits.md, "Revs: what sets the stiffness
scale").

    python scripts/revs250lm_tyre_shape_fit.py ../shared/data/revs_250lm
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from tire_estimation.convert.revs250lm import load_revs, revs_vehicle
from tire_estimation.core.stiffness.model import SingleTrackParams
from tire_estimation.evaluation.axle_fit import axle_forces_from_motion, reference_slip_angles

F64 = NDArray[np.float64]


def tanh_tyre(alpha: F64, stiffness: float, peak: float) -> F64:
    """``peak tanh(C alpha / peak)``, N."""
    return peak * np.tanh(stiffness * alpha / peak)


def magic_formula(alpha: F64, stiffness: float, peak: float, c: float, e: float) -> F64:
    """``D sin(C atan(B a - E (B a - atan B a)))`` with slope ``B C D`` = stiffness, N."""
    bx = stiffness / (c * peak) * alpha
    return peak * np.sin(c * np.arctan(bx - e * (bx - np.arctan(bx))))


def fit(res: Callable[[F64], F64], x0: list[float], lo: list[float], hi: list[float]) -> tuple:
    r = least_squares(res, x0, bounds=(lo, hi))
    return r.x, float(np.sqrt(np.mean(r.fun**2)))


def _axle_fits(a: F64, f: F64, peak: float) -> list[tuple]:
    """(label, residual, x0, lower, upper) of the three shapes for one axle."""
    return [
        ("tanh", lambda x: tanh_tyre(a, x[0] * 1e5, peak) - f, [1.0], [0.1], [10.0]),
        (
            "MF C 1.3 E -0.5",
            lambda x: magic_formula(a, x[0] * 1e5, peak, 1.3, -0.5) - f,
            [1.0],
            [0.1],
            [10.0],
        ),
        (
            "MF C, E fitted",
            lambda x: magic_formula(a, x[0] * 1e5, peak, x[1], x[2]) - f,
            [1.0, 1.3, 0.0],
            [0.1, 1.0, -5.0],
            [10.0, 1.9, 0.99],
        ),
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data_dir", type=Path)
    ap.add_argument("--mu", type=float, default=1.1, help="friction coefficient of the peak")
    ap.add_argument("--smooth", type=int, default=25, help="Savitzky-Golay window, samples")
    args = ap.parse_args()
    col = load_revs(args.data_dir)
    rdot = np.loadtxt(args.data_dir / "yawAngAcc.txt")
    car = revs_vehicle()
    af, ar = reference_slip_angles(col["vx"], col["vy"], col["yawRate"], col["delta"], car)
    ff, fr = axle_forces_from_motion(col["ayCG"], rdot, col["delta"], car)
    ay = col["ayCG"]
    af, ar, ff, fr, ay = (savgol_filter(x, args.smooth, 2) for x in (af, ar, ff, fr, ay))
    p = SingleTrackParams.from_vehicle(car, friction_coefficient=args.mu)
    peak_f = p.saturation_slip_front_rad * float(p.nominal[1])
    peak_r = p.saturation_slip_rear_rad * float(p.nominal[2])
    for name, a, f, peak in (("front", af, ff, peak_f), ("rear", ar, fr, peak_r)):
        rows = _axle_fits(a, f, peak)
        for label, res, x0, lo, hi in rows:
            x, rmse = fit(res, x0, lo, hi)
            extra = f"  C {x[1]:.2f} E {x[2]:.2f}" if x.size == 3 else ""
            print(
                f"{name:5s} {label:16s} stiffness {x[0] * 100:6.1f}k N/rad{extra}"
                f"  force RMSE {rmse:4.0f} N"
            )
    m, delta = car.mass_kg, col["delta"]
    for label, shape in (("tanh", None), ("MF C 1.3 E -0.5", (1.3, -0.5))):

        def total(x: F64, shape: tuple[float, float] | None = shape) -> F64:
            if shape is None:
                fy_f, fy_r = tanh_tyre(af, x[0] * 1e5, peak_f), tanh_tyre(ar, x[1] * 1e5, peak_r)
            else:
                fy_f = magic_formula(af, x[0] * 1e5, peak_f, *shape)
                fy_r = magic_formula(ar, x[1] * 1e5, peak_r, *shape)
            return fy_f * np.cos(delta) + fy_r - m * ay

        x, rmse = fit(total, [0.7, 1.2], [0.1, 0.1], [10.0, 10.0])
        print(
            f"total {label:16s} Cf {x[0] * 100:6.1f}k Cr {x[1] * 100:6.1f}k N/rad"
            f"  force RMSE {rmse:4.0f} N"
        )


if __name__ == "__main__":
    main()
