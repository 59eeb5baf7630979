"""How much of the snow_sine stiffness error is the filter's tanh tyre shape (experiment).

Runs ``sine_study`` on ``snow_sine`` with the friction-limited tanh tyre (the estimator's) or,
with ``--shape magic_formula``, with the simulator's own Magic Formula shape (C 1.3, E -0.5 of
``sim.tires.TireModelConfig``, normalized to slope 1 at small slip) patched into the filter. The
filter cannot know that shape on a real car: this only sizes the shape's share of the error
(docs/results.md, section 6, "A friction-limited tyre").

    python scripts/stiffness_tyre_shape_check.py --shape magic_formula --factor 1.5 --runs 20
"""

from __future__ import annotations

import argparse

import numpy as np
from numpy.typing import NDArray

import tire_estimation.core.stiffness_model as sm
from tire_estimation.evaluation.stiffness import sine_study
from tire_estimation.sim.tires import TireModelConfig, magic_formula

F64 = NDArray[np.float64]


def magic_formula_slip(alpha_rad: F64, saturation_slip_rad: float | F64) -> F64:
    """``alpha_s f(alpha / alpha_s)`` with ``f`` the simulator's Magic Formula at slope 1, rad.

    :func:`tire_estimation.sim.tires.magic_formula` with stiffness 1 and peak ``alpha_s``.
    """
    if np.ndim(saturation_slip_rad) == 0 and saturation_slip_rad <= 0.0:
        return alpha_rad
    tyre = TireModelConfig()
    return _MF(alpha_rad, 1.0, tyre.lateral_shape_c, saturation_slip_rad, tyre.lateral_curvature_e)


_MF = np.vectorize(magic_formula, otypes=[float])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--shape", choices=("tanh", "magic_formula"), default="tanh")
    ap.add_argument("--factor", type=float, default=1.5)
    ap.add_argument("--runs", type=int, default=20)
    args = ap.parse_args()
    if args.shape == "magic_formula":
        sm.lateral_slip_function = magic_formula_slip  # type: ignore[assignment]
    overrides = {"niw_update": "rao_blackwellized", "friction_coefficient": 0.3}
    res = sine_study("snow_sine", args.factor, args.runs, n=200, overrides=overrides)
    mean = np.array([p["steady_mean_rel_error"][1:] for p in res["per_run"]]) * 100
    top = np.array([p["steady_max_abs_rel_error"][1:] for p in res["per_run"]]) * 100
    print(f"{args.shape}, from {args.factor:.0%}, {args.runs} runs (front / rear, %):")
    print(f"  mean of the steady mean error {mean.mean(0).round(2)}")
    print(f"  mean |steady error|           {np.abs(mean).mean(0).round(2)}")
    print(f"  max of the steady max |error| {top.max(0).round(2)}")
    print(f"  runs above 3 %                {int((top.max(1) > 3.0).sum())}")


if __name__ == "__main__":
    main()
