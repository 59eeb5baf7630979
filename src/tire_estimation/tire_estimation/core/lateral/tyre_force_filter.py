"""The Kalman filter and the linearity relay of Tuononen (Sensors 2009, 9, 8761-8775).

A linear Kalman filter on ``x = [vy_cg m/s, r rad/s, Fy_front N, Fy_rear N]`` (eq. 1-8 with the
transition of eq. 21 and the identity measurement of eq. 22), and the relay with hysteresis
(Fig. 7) on the axle-force deviation of eq. (29) that switches the single-track
pseudo-measurement variance between its linear and nonlinear values (section 3.5). The
front-end that feeds them is :class:`.tyre_force_kf.TyreForceEstimator`.
"""

from __future__ import annotations

import numpy as np

from tire_estimation.core.arrays import F64
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


def axle_force_deviation(single_track_n: F64, measured_n: F64) -> float:
    """Eq. (29): |Fy,f,onetrack - Fy,f,measured| + |Fy,r,onetrack - Fy,r,measured|, N.

    Args:
        single_track_n: (2,) [front, rear] axle forces of the single-track model, N.
        measured_n: (2,) [front, rear] measured (sensor + virtual) axle forces, N.
    """
    d = np.asarray(single_track_n, dtype=float) - np.asarray(measured_n, dtype=float)
    # Tuononen 2009 eq. (29)
    return float(abs(d[0]) + abs(d[1]))


def transition_matrix(
    dt_s: float, vx_m_s: float, mass_kg: float, yaw_inertia_kg_m2: float, lf_m: float, lr_m: float
) -> F64:
    """(4, 4) state transition of eq. (21) for x = [vy, r, Fy_f, Fy_r] over ``dt_s``."""
    ts = dt_s
    # Tuononen 2009 eq. (21): discretized eq. (19)-(20), forces as identity (random walk)
    return np.array(
        [
            [1.0, -ts * vx_m_s, ts / mass_kg, ts / mass_kg],
            [0.0, 1.0, lf_m / yaw_inertia_kg_m2 * ts, -lr_m / yaw_inertia_kg_m2 * ts],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


#: Measurement matrix of eq. (22): every state is measured (vy, r by the single-track model).
MEASUREMENT_MATRIX: F64 = np.eye(4)


class TyreForceKF:
    """The Kalman filter of Tuononen 2009 eq. (1)-(8), (21)-(22) on x = [vy_cg, r, Ff, Fr].

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
        self.mass_kg = mass_kg
        self.yaw_inertia_kg_m2 = yaw_inertia_kg_m2
        self.lf_m = lf_m
        self.lr_m = lr_m
        self.q: F64 = np.diag(np.asarray(q_diag, dtype=float))
        self.x: F64 = np.zeros(4)
        self.p: F64 = np.eye(4)

    def reset(self, x0: F64, p0_diag: F64) -> None:
        """Set the state (4,) and a diagonal covariance (4,)."""
        self.x = np.asarray(x0, dtype=float).copy()
        self.p = np.diag(np.asarray(p0_diag, dtype=float))

    def predict(self, dt_s: float, vx_m_s: float, yaw_moment_nm: float = 0.0) -> None:
        """Time update over ``dt_s`` with forward speed ``vx_m_s`` (eq. 1, 5).

        ``yaw_moment_nm``: known extra yaw moment (N m) held over the step (0 in the paper).
        """
        a = transition_matrix(
            dt_s, vx_m_s, self.mass_kg, self.yaw_inertia_kg_m2, self.lf_m, self.lr_m
        )
        # eq. (1): x_k^- = A x_k-1  (+ the known moment input on the yaw rate, beyond eq. 21)
        self.x = a @ self.x
        self.x[1] += dt_s * yaw_moment_nm / self.yaw_inertia_kg_m2
        # a priori covariance: P_k^- = A P A^T + Q
        self.p = a @ self.p @ a.T + self.q

    def update(self, z: F64, h: F64, r_diag: F64) -> None:
        """Measurement update with z (n,), H (n, 4) and diagonal R (n,) (eq. 2, 7, 8)."""
        r = np.diag(np.asarray(r_diag, dtype=float))
        s = h @ self.p @ h.T + r
        # eq. (7): K = P^- H^T (H P^- H^T + R)^-1
        k = np.linalg.solve(s, h @ self.p).T
        # eq. (8): x_k = x_k^- + K (z_k - H x_k^-)
        self.x = self.x + k @ (z - h @ self.x)
        # a posteriori covariance (Joseph form, keeps P symmetric positive definite)
        i_kh = np.eye(4) - k @ h
        self.p = i_kh @ self.p @ i_kh.T + k @ r @ k.T
        self.p = 0.5 * (self.p + self.p.T)


__all__ = [
    "MEASUREMENT_MATRIX",
    "HysteresisRelay",
    "TyreForceKF",
    "axle_force_deviation",
    "transition_matrix",
]
