"""NumPy reference of the compiled single-track code (``core.lateral.single_track_kernels``):
the matrix exponential, the discretizations and the linear lateral KF's predict and update as
they are written in NumPy, for the tests that compare the compiled code with them."""

from __future__ import annotations

import math

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.lateral.linear_kf import LinearLateralKF
from tire_estimation.core.lateral.single_track import SingleTrackParams, continuous_matrices


def expm_small(m: F64, order: int = 10) -> F64:
    """Matrix exponential of a small square matrix by scaling and squaring of a Taylor series."""
    norm = float(np.max(np.sum(np.abs(m), axis=1)))
    squarings = max(0, math.ceil(math.log2(norm / 0.25))) if norm > 0.25 else 0
    a = m / (2.0**squarings)
    term = np.eye(m.shape[0])
    out = term.copy()
    for k in range(1, order + 1):
        term = term @ a / k
        out = out + term
    for _ in range(squarings):
        out = out @ out
    return out


def first_order_hold(a: F64, b: F64, dt_s: float) -> tuple[F64, F64, F64]:
    """(Ad, B0, B1): x(T) = Ad x(0) + B0 delta0 + B1 (delta1 - delta0) / T."""
    aug = np.zeros((4, 4))
    aug[:2, :2] = a * dt_s
    aug[:2, 2] = b * dt_s
    aug[2, 3] = dt_s
    e = expm_small(aug)
    return e[:2, :2], e[:2, 2], e[:2, 3]


def zero_order_hold(a: F64, b: F64, dt_s: float) -> tuple[F64, F64]:
    """(Ad, Bd) of expm([[A, B], [0, 0]] T)."""
    aug = np.zeros((3, 3))
    aug[:2, :2] = a * dt_s
    aug[:2, 2] = b * dt_s
    e = expm_small(aug)
    return e[:2, :2], e[:2, 2]


def kf_predict(
    x: F64, p: F64, params: SingleTrackParams, q_density: F64, dt: float, vx: float,
    delta0: float, delta1: float,
) -> tuple[F64, F64]:  # fmt: skip
    """The linear KF's predict: first-order hold on delta, P' = F P F^T + Q T."""
    a, b = continuous_matrices(params, vx)
    f, b0, b1 = first_order_hold(a, b, dt)
    slope = (delta1 - delta0) / dt
    return f @ x + b0 * delta0 + b1 * slope, f @ p @ f.T + q_density * dt


def kf_update(
    x: F64, p: F64, params: SingleTrackParams, r_cov: F64, vx: float, delta: float,
    ay_m_s2: float, r_meas: float,
) -> tuple[F64, F64]:  # fmt: skip
    """The linear KF's update with y = [ay, r] (Joseph form)."""
    pp = params
    c = np.array(
        [
            [
                -(pp.cf_n_rad + pp.cr_n_rad) / (pp.mass_kg * vx),
                (pp.cr_n_rad * pp.lr_m - pp.cf_n_rad * pp.lf_m) / (pp.mass_kg * vx),
            ],
            [0.0, 1.0],
        ]
    )
    d = np.array([pp.cf_n_rad / pp.mass_kg, 0.0])
    innov = np.array([ay_m_s2, r_meas]) - (c @ x + d * delta)
    s = c @ p @ c.T + r_cov
    k = np.linalg.solve(s, c @ p).T
    x = x + k @ innov
    i_kc = np.eye(2) - k @ c
    return x, i_kc @ p @ i_kc.T + k @ r_cov @ k.T


class ReferenceLinearKF(LinearLateralKF):
    """:class:`LinearLateralKF` with its step in NumPy (:func:`kf_predict`, :func:`kf_update`)."""

    def _step(
        self, dt: float, vx: float, delta0: float, delta1: float, ay_m_s2: float, r_meas: float
    ) -> None:
        x, p = kf_predict(self.x, self.p, self.params, self._q_density, dt, vx, delta0, delta1)
        self.x, self.p = kf_update(x, p, self.params, self._r, vx, delta1, ay_m_s2, r_meas)
