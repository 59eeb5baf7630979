"""The Kalman filter and the linearity relay of Tuononen (Sensors 2009, 9, 8761-8775).

A linear Kalman filter on ``x = [vy_cg m/s, r rad/s, Fy_front N, Fy_rear N]`` (eq. 1-8 with the
transition of eq. 21 and the identity measurement of eq. 22), and the relay with hysteresis
(Fig. 7) on the axle-force deviation of eq. (29) that switches the single-track
pseudo-measurement variance between its linear and nonlinear values (section 3.5). The
front-end that feeds them is :class:`.tyre_force_kf.TyreForceEstimator`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64
from tire_estimation.core.lateral import tyre_force_kernels as kernels
from tire_estimation.errors import ConfigError

# Fig. 7 relay thresholds on the eq. (29) deviation after the low-pass below. The paper gives
# no numbers; these fit the simulator's tyre sensors (150 N noise per wheel) on the
# ``lane_change`` scenario: straight driving stays below the off threshold, the lane changes
# cross the on threshold.
#: the relay switches to nonlinear when the deviation exceeds this, N.
RELAY_ON_THRESHOLD_N = 500.0
#: the relay switches back to linear when the deviation falls below this, N (the hysteresis).
RELAY_OFF_THRESHOLD_N = 250.0
#: first-order low-pass of the signed per-axle differences before eq. (29), s (beyond the
#: paper: with 150 N sensors the noise alone gives the unfiltered eq. 29 a ~500 N floor; 0.2 s
#: removes it and delays the relay by less than the 0.5 s rise of a lane change).
DEVIATION_FILTER_TIME_CONSTANT_S = 0.2

# Initial covariance P0 of eq. (1)-(8) at every (re)initialization. The state starts at the
# single-track steady state and the measured axle forces, so P0 is the spread of that start:
#: initial P of vy, (m/s)^2 (0.1 m/s).
INITIAL_VY_VARIANCE_M2_S2 = 0.01
#: initial P of the yaw rate, (rad/s)^2 (~1.8 deg/s).
INITIAL_YAW_RATE_VARIANCE_RAD2_S2 = 1e-3
#: initial P of each axle force, N^2 (1 kN: the first update takes the measured force).
INITIAL_FORCE_VARIANCE_N2 = 1e6


class HysteresisRelay:
    """Relay with hysteresis (Tuononen 2009, Fig. 7): on above ``on``, off below ``off``.

    Between the thresholds it keeps its state, so a deviation that briefly drops during a lane
    change does not switch the pseudo-measurement variance back to the low value.
    """

    def __init__(self, on_threshold: float, off_threshold: float, state: bool = False) -> None:
        if off_threshold > on_threshold:
            raise ConfigError("off_threshold", off_threshold, "must be <= on_threshold")
        self.on_threshold = float(on_threshold)
        self.off_threshold = float(off_threshold)
        self.state = bool(state)

    def update(self, value: float) -> bool:
        """Feed one input value; return the new state (True = on = nonlinear)."""
        # Fig. 7: switch on when value > on threshold, off when value < off threshold
        if not self.state and value > self.on_threshold:
            self.state = True
        elif self.state and value < self.off_threshold:
            self.state = False
        return self.state


def axle_force_deviation(
    single_track_n: Sequence[float] | F64, measured_n: Sequence[float] | F64
) -> float:
    """Eq. (29): |Fy,f,onetrack - Fy,f,measured| + |Fy,r,onetrack - Fy,r,measured|, N.

    Args:
        single_track_n: (2,) [front, rear] axle forces of the single-track model, N.
        measured_n: (2,) [front, rear] measured (sensor + virtual) axle forces, N.
    """
    # Tuononen 2009 eq. (29)
    return float(abs(single_track_n[0] - measured_n[0]) + abs(single_track_n[1] - measured_n[1]))


class TyreForceKF:
    """The Kalman filter of Tuononen 2009 eq. (1)-(8), (21)-(22) on x = [vy_cg, r, Ff, Fr]
    (the compiled step of :mod:`.tyre_force_kernels`).

    Args:
        mass_kg, yaw_inertia_kg_m2, lf_m, lr_m: vehicle parameters (Table 1).
        q_diag: (4,) process noise variances per step [(m/s)^2, (rad/s)^2, N^2, N^2].
    """

    def __init__(
        self,
        mass_kg: float,
        yaw_inertia_kg_m2: float,
        lf_m: float,
        lr_m: float,
        q_diag: F64,
    ) -> None:
        self._consts = kernels.kf_constants(mass_kg, yaw_inertia_kg_m2, lf_m, lr_m, q_diag)
        self.x: F64 = np.zeros(4)
        self.p: F64 = np.eye(4)

    def reset(self, x0: F64, p0_diag: F64) -> None:
        """Set the state (4,) and a diagonal covariance (4,)."""
        self.x = np.asarray(x0, dtype=float).copy()
        self.p = np.diag(np.asarray(p0_diag, dtype=float))

    def predict(self, dt_s: float, vx_m_s: float, yaw_moment_nm: float = 0.0) -> None:
        """Time update over ``dt_s`` with forward speed ``vx_m_s`` (eq. 1, 5, 21);
        ``yaw_moment_nm``: known extra yaw moment (N m) held over the step (0 in the paper)."""
        kernels.predict(self.x, self.p, self._consts, dt_s, vx_m_s, yaw_moment_nm)

    def update(self, rows: NDArray[np.intp], z: F64, r_diag: F64) -> bool:
        """Measurement update (eq. 2, 7, 8) with the state rows ``rows`` (n,) measured as ``z``
        (n,) with diagonal R ``r_diag`` (n,) (eq. 22: the identity, rows of unmeasured axles
        left out); False when the state or covariance is no longer finite."""
        return bool(kernels.update(self.x, self.p, rows, z, r_diag))


__all__ = [
    "HysteresisRelay",
    "TyreForceKF",
    "axle_force_deviation",
]
