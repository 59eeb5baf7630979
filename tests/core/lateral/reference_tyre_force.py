"""NumPy reference of the compiled tyre-force KF step (``core.lateral.tyre_force_kernels``):
eq. (1), (5), (21) and (2), (7), (8), (22) of Tuononen 2009 as they are written in NumPy, for the
tests that compare the compiled code with them."""

from __future__ import annotations

import numpy as np

from tire_estimation.core.arrays import F64


def transition_matrix(
    dt_s: float, vx_m_s: float, mass_kg: float, yaw_inertia_kg_m2: float, lf_m: float, lr_m: float
) -> F64:
    """(4, 4) state transition of eq. (21) for x = [vy, r, Fy_f, Fy_r] over ``dt_s``."""
    ts = dt_s
    return np.array(
        [
            [1.0, -ts * vx_m_s, ts / mass_kg, ts / mass_kg],
            [0.0, 1.0, lf_m / yaw_inertia_kg_m2 * ts, -lr_m / yaw_inertia_kg_m2 * ts],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def predict(
    x: F64, p: F64, consts: F64, dt_s: float, vx_m_s: float, moment_nm: float
) -> tuple[F64, F64]:
    """Eq. (1), (5): ``A x`` (+ the yaw moment's input), ``A P A^T + Q``."""
    m, iz, lf, lr = consts[:4]
    a = transition_matrix(dt_s, vx_m_s, m, iz, lf, lr)
    x = a @ x
    x[1] += dt_s * moment_nm / iz
    return x, a @ p @ a.T + np.diag(consts[4:8])


def update(x: F64, p: F64, rows: list[int], z: F64, r_diag: F64) -> tuple[F64, F64]:
    """Eq. (7), (8) and the Joseph form with ``H`` the rows ``rows`` of the identity."""
    h = np.eye(4)[rows]
    r = np.diag(r_diag)
    s = h @ p @ h.T + r
    k = np.linalg.solve(s, h @ p).T
    x = x + k @ (z - h @ x)
    i_kh = np.eye(4) - k @ h
    p = i_kh @ p @ i_kh.T + k @ r @ k.T
    return x, 0.5 * (p + p.T)
