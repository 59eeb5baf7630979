"""The lateral speed at activation and the stiffness error after it (issue 5, snow_sine).

Per drive (sim seeds FIRST..END-1, MPF seeded 1000 + seed, N = 200, ``rao_blackwellized``, snow
friction 0.3, the simulator's Magic Formula curve, the start FACTOR x the truth) prints the vY
error (estimate minus truth, at the CG) 0.5 s before, at, and 0.2 s after the first learning
sample, the Cy front / rear errors 0.5 s and 2 s after it, and the true vY RMS over the first
0.5 s; then the correlation of the vY error with the rear error (docs/results.md, section 6).

    python scripts/snow_activation_vy.py 1.5 0 30 [--set FIELD=VALUE ...]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np

from tire_estimation.evaluation.stiffness import (
    NO_BIAS,
    eval_config,
    parse_set,
    run,
    simulate,
    sine_run_scores,
    truth_over_nominal,
)

SNOW = {
    "niw_update": "rao_blackwellized",
    "friction_coefficient": 0.3,
    "tyre_shape": "magic_formula",
    "magic_formula_curvature_e": -0.5,
}


def drive_args(
    description: str, extra: Callable[[argparse.ArgumentParser], None] | None = None
) -> tuple[argparse.Namespace, dict[str, object]]:
    """FACTOR FIRST END [--set FIELD=VALUE ...] of the snow-drive scripts: the arguments and
    the configuration overrides (SNOW, then ``--set``); ``extra`` adds a script's own options."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("factor", type=float, help="start, fraction of the true stiffness")
    ap.add_argument("first", type=int)
    ap.add_argument("end", type=int)
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    if extra is not None:
        extra(ap)
    args = ap.parse_args()
    return args, {**SNOW, **parse_set(args.set)}


def main() -> None:
    args, overrides = drive_args(__doc__.splitlines()[0])
    rows = []
    print("seed | vY err -0.5 s / 0 s / +0.2 s [m/s] | Cy err +0.5 s f / r, +2 s r | vY RMS")
    for seed in range(args.first, args.end):
        sim = simulate("snow_sine", seed=seed, sensors=NO_BIAS)
        cfg = eval_config(
            200, initial_stiffness_factor=args.factor * truth_over_nominal(sim), **overrides
        )
        res = run(sim, cfg, 1000 + seed)
        t = res["t_s"]
        rel = res["c"] / res["truth_c"] - 1.0
        # the first learning sample, as the sine study scores it
        on = sine_run_scores(t, rel, res["active"])["activation_s"]
        vy_err = res["vy"] - res["truth_vy"]

        def at(d: float, t: np.ndarray = t, on: float = on) -> int:
            return min(int(np.searchsorted(t, on + d)), t.size - 1)

        first = slice(at(0.0), at(0.5))
        row = [
            vy_err[at(-0.5)],
            vy_err[at(0.0)],
            vy_err[at(0.2)],
            rel[at(0.5), 1],
            rel[at(0.5), 2],
            rel[at(2.0), 2],
            float(np.sqrt(np.mean(res["truth_vy"][first] ** 2))),
        ]
        rows.append(row)
        print(seed, np.round(row, 4).tolist(), flush=True)
    r = np.array(rows)
    for k, name in ((0, "-0.5 s"), (1, "0 s"), (2, "+0.2 s")):
        print(
            f"vY err {name}: mean {r[:, k].mean():+.4f} m/s, range {r[:, k].min():+.4f} .. "
            f"{r[:, k].max():+.4f}, positive on {(r[:, k] > 0).sum()} of {len(r)}; "
            f"corr with rear err +0.5 s {np.corrcoef(r[:, k], r[:, 4])[0, 1]:.2f}, "
            f"+2 s {np.corrcoef(r[:, k], r[:, 5])[0, 1]:.2f}"
        )
    print(
        f"mean Cy err +0.5 s front / rear {100 * r[:, 3].mean():+.1f} / "
        f"{100 * r[:, 4].mean():+.1f} %, rear +2 s {100 * r[:, 5].mean():+.1f} %; "
        f"true vY RMS {r[:, 6].mean():.4f} m/s"
    )


if __name__ == "__main__":
    main()
