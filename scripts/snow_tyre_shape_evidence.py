"""Can a snow sine drive tell the tyre's curve? (issue 5, docs/results.md section 6).

Two truth-free-in-principle ways to find the curve that ``tyre_shape`` needs, tried on
``snow_sine`` drives that no earlier choice used (sim seeds 100-111 by default):

1. Evidence: the stiffness MPF's log model evidence ``sum_k log p(y_k | y_1:k-1)``
   (``StiffnessMpf.log_evidence``) of each candidate curve, from the estimator's nominal prior
   (``initial_stiffness_factor`` 1, no truth in the start), with several MPF seeds per drive.
   Prints the sum over drives (seed mean) against the tanh, its drive-to-drive and seed-to-seed
   spread, and the steady stiffness error (this one against the truth).
2. Regression (``--regression``): the per-axle forces from ay and the differentiated gyro
   (``evaluation.axle_fit``) against the slip angles of the *true* vY, fitted with the tanh and
   with the Magic Formula whose C and E are free (an upper bound on what the data hold).

    python scripts/snow_tyre_shape_evidence.py --drives 100 112 --mpf-seeds 1 2 3
    python scripts/snow_tyre_shape_evidence.py --drives 100 112 --mpf-seeds 1 --seed-base 1000 \\
        --wide
    python scripts/snow_tyre_shape_evidence.py --drives 100 104 --regression
"""

from __future__ import annotations

import argparse
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from tire_estimation.core.stiffness.model import SingleTrackParams, lateral_slip_function
from tire_estimation.evaluation.axle_fit import axle_forces_from_motion, reference_slip_angles
from tire_estimation.evaluation.stiffness import (
    NO_BIAS,
    eval_config,
    run,
    simulate,
    sine_run_scores,
)

F64 = NDArray[np.float64]
SNOW_MU = 0.3
#: Candidate curves: label -> StiffnessEstimatorConfig fields (the simulator's tyre is C 1.3,
#: E -0.5, ``sim/tires.py``).
CANDIDATES: dict[str, dict[str, Any]] = {
    "tanh": {},
    "MF C 1.3 E -0.5": {"tyre_shape": "magic_formula", "magic_formula_curvature_e": -0.5},
    "MF C 1.1 E -0.5": {
        "tyre_shape": "magic_formula",
        "magic_formula_curvature_e": -0.5,
        "magic_formula_shape_c": 1.1,
    },
    "MF C 1.3 E 0": {"tyre_shape": "magic_formula", "magic_formula_curvature_e": 0.0},
}
#: ``--wide``: the tanh, C 1.3 with E from -1 to 0.25, and C 1.1 / 1.5 with E -0.5.
WIDE_CANDIDATES: dict[str, dict[str, Any]] = {
    "tanh": {},
    **{
        f"MF C 1.3 E {e:g}": {"tyre_shape": "magic_formula", "magic_formula_curvature_e": e}
        for e in (-1.0, -0.75, -0.5, -0.25, 0.0, 0.25)
    },
    **{
        f"MF C {c:g} E -0.5": {
            "tyre_shape": "magic_formula",
            "magic_formula_curvature_e": -0.5,
            "magic_formula_shape_c": c,
        }
        for c in (1.1, 1.5)
    },
}


def evidence(
    drives: range,
    mpf_seeds: list[int],
    n: int,
    candidates: dict[str, dict[str, Any]],
    seed_base: int,
) -> None:
    """Part 1: log evidence per candidate, drive and MPF seed (``seed * seed_base + drive``)."""
    logz = {k: np.zeros((len(drives), len(mpf_seeds))) for k in candidates}
    err = {k: np.zeros((len(drives), len(mpf_seeds), 2)) for k in candidates}
    for i, s in enumerate(drives):
        sim = simulate("snow_sine", seed=s, sensors=NO_BIAS)
        for j, ms in enumerate(mpf_seeds):
            for label, fields in candidates.items():
                cfg = eval_config(
                    n, niw_update="rao_blackwellized", friction_coefficient=SNOW_MU, **fields
                )
                res = run(sim, cfg, seed=ms * seed_base + s)
                # mean_log_predictive (per IMU update) times the records: the evidence up to
                # the factor records / updates, the same for every candidate of a drive
                logz[label][i, j] = float(res["mean_log_predictive"]) * res["t_s"].size
                rel = res["c"] / res["truth_c"] - 1.0
                err[label][i, j] = sine_run_scores(res["t_s"], rel, res["active"])[
                    "steady_mean_rel_error"
                ][1:]
        print(f"drive {s} done", flush=True)
    print("| curve | sum over drives vs tanh [nats] | sd over drives | sd over MPF seeds | "
          "steady error front / rear |")  # fmt: skip
    print("|---|---|---|---|---|")
    for label in candidates:
        diff = logz[label] - logz["tanh"]
        per_drive = diff.mean(axis=1)
        seed_sd = diff.std(axis=1, ddof=1).mean() if len(mpf_seeds) > 1 else float("nan")
        e = err[label].mean(axis=(0, 1)) * 100
        print(
            f"| {label} | {per_drive.sum():+.1f} | {per_drive.std(ddof=1):.1f} | {seed_sd:.1f} | "
            f"{e[0]:+.2f} % / {e[1]:+.2f} % |"
        )


def regression(drives: range, n: int) -> None:
    """Part 2: least-squares curve fit to the axle forces at the true slip angles."""
    slips: list[tuple[F64, F64]] = []
    forces: list[tuple[F64, F64]] = []
    peaks = (0.0, 0.0)
    for s in drives:
        sim = simulate("snow_sine", seed=s, sensors=NO_BIAS)
        cfg = eval_config(n, niw_update="rao_blackwellized", friction_coefficient=SNOW_MU)
        res = run(sim, cfg, seed=10000 + s)
        t, tr = res["t"], sim.truth
        t_rel = (t - tr.t_ns[0]).astype(float)
        vx = np.interp(t_rel, (tr.t_ns - tr.t_ns[0]).astype(float), tr.velocity_m_s[:, 0])
        delta = np.interp(t.astype(float), sim.steering.t_ns.astype(float), sim.steering.angle_rad)
        j = np.searchsorted(sim.imu.t_ns, t)
        dt_s = float(np.median(np.diff(t))) * 1e-9
        ay = savgol_filter(sim.imu.linear_acceleration_m_s2[j, 1], 25, 2)
        rdot = savgol_filter(sim.imu.angular_velocity_rad_s[j, 2], 25, 2, deriv=1, delta=dt_s)
        af, ar = reference_slip_angles(vx, res["truth_vy"], res["truth_r"], delta, sim.vehicle)
        ff, fr = axle_forces_from_motion(ay, rdot, delta, sim.vehicle)
        keep = res["active"].astype(bool)
        slips.append((af[keep], ar[keep]))
        forces.append((ff[keep], fr[keep]))
        p = SingleTrackParams.from_vehicle(sim.vehicle, friction_coefficient=SNOW_MU)
        peaks = (
            p.saturation_slip_front_rad * float(p.nominal[1]),
            p.saturation_slip_rear_rad * float(p.nominal[2]),
        )
        truth = sim.truth.stiffness[0]

    def residual(x: F64, shape: str) -> F64:
        out = []
        for (af, ar), (ff, fr) in zip(slips, forces, strict=True):
            for a, f, c, peak in ((af, ff, x[0] * 1e5, peaks[0]), (ar, fr, x[1] * 1e5, peaks[1])):
                extra = (shape, x[2], x[3]) if shape == "magic_formula" else ()
                out.append(c * lateral_slip_function(a, peak / c, *extra) - f)
        return np.concatenate(out)

    fits = (
        ("tanh", [0.5, 0.6], [0.05, 0.05], [5.0, 5.0]),
        ("magic_formula", [0.5, 0.6, 1.3, 0.0], [0.05, 0.05, 1.0, -5.0], [5.0, 5.0, 1.9, 0.99]),
    )
    print(f"truth Cy front / rear {truth[1]:.0f} / {truth[2]:.0f} N/rad")
    for shape, x0, lo, hi in fits:
        r = least_squares(lambda x, s=shape: residual(x, s), x0, bounds=(lo, hi))
        extra = f", C {r.x[2]:.2f}, E {r.x[3]:.2f}" if shape == "magic_formula" else ""
        print(
            f"{shape}: Cy {r.x[0] * 1e5:.0f} / {r.x[1] * 1e5:.0f} N/rad{extra}, "
            f"force RMSE {np.sqrt(np.mean(r.fun**2)):.1f} N"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--drives", type=int, nargs=2, default=[100, 112], metavar=("FIRST", "END"))
    ap.add_argument("--mpf-seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--particles", type=int, default=200)
    ap.add_argument("--seed-base", type=int, default=10000, help="MPF seed = S * this + drive")
    ap.add_argument("--wide", action="store_true", help="the wider grid of candidate curves")
    ap.add_argument("--regression", action="store_true", help="run part 2 instead of part 1")
    args = ap.parse_args()
    drives = range(*args.drives)
    if args.regression:
        regression(drives, args.particles)
    else:
        candidates = WIDE_CANDIDATES if args.wide else CANDIDATES
        evidence(drives, args.mpf_seeds, args.particles, candidates, args.seed_base)


if __name__ == "__main__":
    main()
