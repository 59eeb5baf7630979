"""How well could a filter know the snow cornering stiffnesses 0.5-5 s after activation?

Per snow_sine drive (sim seeds FIRST..END-1), the stiffness MPF is run once from FACTOR x the
truth (MPF seeded 1000 + seed, N = 200, the snow configuration of the other snow-drive scripts
plus ``--set``) to find its activation (the first learning sample); from that sample on,
``evaluation.stiffness_bound`` gives the std of the front and rear cornering stiffness (% of the
truth) that the filter's model allows (posterior Cramer-Rao bound) with the filter's noise model
at each ``--noise`` value of ``stiffness_noise_std_fraction``, and with a constant stiffness and
no jitter (the drive's own bound). Printed beside: the filter's rear error at the same times
(docs/results.md, section 6).

    python scripts/stiffness_information_bound.py 1.5 0 2 [--noise 0.03 0.01] [--set ...]
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

# the sibling script (its folder is on sys.path when run as python scripts/...)
from snow_activation_vy import drive_args

import tire_estimation.evaluation.stiffness as ev
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.frontend import INITIAL_YAW_RATE_STD_RAD_S
from tire_estimation.evaluation.stiffness_bound import (
    bound_noise,
    deterministic_crlb,
    drive_signals,
    posterior_bound,
)

AFTER_S = (0.5, 1.0, 1.5, 2.0, 3.0, 5.0)


def _noise_option(ap: argparse.ArgumentParser) -> None:
    ap.add_argument("--noise", type=float, nargs="+", default=[0.03, 0.01])


def main() -> None:
    args, overrides = drive_args(__doc__.splitlines()[0], _noise_option)
    print("times after activation [s]:", AFTER_S)
    for seed in range(args.first, args.end):
        sim = ev.simulate("snow_sine", seed=seed, sensors=ev.NO_BIAS)
        cfg = ev.eval_config(
            200, initial_stiffness_factor=args.factor * ev.truth_over_nominal(sim), **overrides
        )
        res = ev.run(sim, cfg, 1000 + seed)
        p = StiffnessEstimator(cfg, sim.vehicle, np.random.default_rng(0)).params
        sig = drive_signals(sim, p.wheel_radius_m)
        on_ns = int(res["t"][int(np.argmax(res["active"]))])
        k0 = int(np.searchsorted(np.asarray(sim.imu.t_ns), on_ns))
        truth = sig.stiffness_n_rad[k0]
        rows = []
        for frac in args.noise:
            c = dataclasses.replace(cfg, stiffness_noise_std_fraction=frac)
            noise = bound_noise(
                c, np.asarray(p.nominal), cfg.initial_vy_std_m_s, INITIAL_YAW_RATE_STD_RAD_S
            )
            std = posterior_bound(sig, p, k0, AFTER_S, noise)
            rows.append((f"noise {frac:g} of nominal", 100.0 * std / truth[1:]))
        crlb = [
            np.sqrt(
                np.diag(
                    deterministic_crlb(
                        sig, p, k0, t, cfg.accel_noise_std_m_s2, cfg.gyro_noise_std_rad_s
                    )
                )[2:]
            )
            for t in AFTER_S
        ]
        rows.append(("constant stiffness, no jitter", 100.0 * np.array(crlb) / truth[1:]))
        err = [
            100.0 * (np.interp(on_ns + t * 1e9, res["t"], res["c"][:, 2]) / truth[2] - 1.0)
            for t in AFTER_S
        ]
        print(f"seed {seed}: filter rear error %", np.round(err, 1).tolist())
        for name, v in rows:
            cells = " ".join(f"{f:.2f}/{r:.2f}" for f, r in v)
            print(f"  bound front/rear std % ({name}): {cells}")


if __name__ == "__main__":
    main()
