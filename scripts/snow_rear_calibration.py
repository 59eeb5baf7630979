"""How honest is the stiffness mean's own uncertainty after activation (issue 5, snow_sine)?

Per drive (sim seeds FIRST..END-1, MPF seeded 1000 + seed, N = 200, ``rao_blackwellized``, snow
friction 0.3, the simulator's Magic Formula curve, the start FACTOR x the truth) takes, at fixed
times after the first learning sample, the estimate (27a) and the std of the posterior of the
mean (``MpfEstimate.mean_std``: ``gamma E[Sigma]`` plus the spread of the particles' means) and
prints the error in units of that std (z) and the shared ``gamma``; then, per time, the mean and
RMS of z over the drives (front, rear). An honest filter has RMS z near 1 and mean z near 0
(docs/results.md, section 6).

    python scripts/snow_rear_calibration.py 1.5 0 12 [--set FIELD=VALUE ...]
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

# the sibling script (its folder is on sys.path when run as python scripts/...)
from snow_activation_vy import drive_args

import tire_estimation.evaluation.stiffness as ev
from tire_estimation.core.stiffness.estimator import StiffnessEstimator

AFTER_S = (0.25, 0.5, 1.0, 2.0, 3.0)


class _Probe(StiffnessEstimator):
    """The estimator, taking (estimate, mean std, gamma) at the first IMU sample at or after
    each of ``times_ns``."""

    times_ns: ClassVar[list[int]] = []
    taken: ClassVar[list[tuple[np.ndarray, np.ndarray, float] | None]] = []

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        super().on_imu(t_ns, gyro_rad_s, accel_m_s2)
        for k, t_k in enumerate(_Probe.times_ns):
            if _Probe.taken[k] is None and t_ns >= t_k:
                e = self.mpf.estimate()
                _Probe.taken[k] = (e.stiffness, e.mean_std, float(np.mean(self.mpf.stats.gamma)))


def main() -> None:
    args, overrides = drive_args(__doc__.splitlines()[0])
    z_all, gamma_all = [], []
    print("seed | rear z at " + " / ".join(f"+{d} s" for d in AFTER_S) + " | rear mean std [%]")
    for seed in range(args.first, args.end):
        sim = ev.simulate("snow_sine", seed=seed, sensors=ev.NO_BIAS)
        cfg = ev.eval_config(
            200, initial_stiffness_factor=args.factor * ev.truth_over_nominal(sim), **overrides
        )
        ev.StiffnessEstimator = StiffnessEstimator
        first = ev.run(sim, cfg, 1000 + seed)
        on = int(np.argmax(first["active"]))
        truth = first["truth_c"][on]
        # the same run again (same seed, same filter), sampled after the activation
        _Probe.times_ns = [int(first["t"][on]) + round(d * 1e9) for d in AFTER_S]
        _Probe.taken = [None] * len(AFTER_S)
        ev.StiffnessEstimator = _Probe
        try:
            ev.run(sim, cfg, 1000 + seed)
        finally:
            ev.StiffnessEstimator = StiffnessEstimator
        taken = [t for t in _Probe.taken if t is not None]
        if len(taken) < len(AFTER_S):
            print(seed, "drive ends too early after activation; skipped")
            continue
        z_all.append([(c - truth) / s for c, s, _ in taken])
        gamma_all.append([g for _, _, g in taken])
        rear_std = [100.0 * s[2] / truth[2] for _, s, _ in taken]
        rear_z = [z[2] for z in z_all[-1]]
        print(seed, np.round(rear_z, 1).tolist(), np.round(rear_std, 1).tolist())
    z = np.array(z_all)
    g = np.array(gamma_all)
    for k, d in enumerate(AFTER_S):
        cols = ", ".join(
            f"{name} mean z {z[:, k, i].mean():+.1f} RMS z {np.sqrt(np.mean(z[:, k, i] ** 2)):.1f}"
            for i, name in ((1, "front"), (2, "rear"))
        )
        print(f"+{d:.2f} s: gamma {g[:, k].mean():.2f}; {cols}")


if __name__ == "__main__":
    main()
