"""Compiled (Numba, ``cache=True``) step of the tyre-force Kalman filter (Tuononen 2009).

The predict of eq. (1), (5) with the transition of eq. (21) and the update of eq. (2), (7), (8)
with the identity measurement of eq. (22) (rows of unmeasured axles left out), on
``x = [vy_cg, r, Fy_f, Fy_r]``, in one call per tyre-force sample instead of some thirty NumPy
calls on 4x4 arrays. The NumPy reference is tests/core/lateral/reference_tyre_force.py; the
two agree to rounding.

Constants (:func:`kf_constants`): ``[m, Iz, lf, lr, q_vy, q_r, q_Ff, q_Fr]`` (the process
noise variances per step).
"""

from __future__ import annotations

import numba
import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.lateral.single_track_kernels import _matmul4

#: length of :func:`kf_constants`
N_CONSTANTS = 8


def kf_constants(
    mass_kg: float, yaw_inertia_kg_m2: float, lf_m: float, lr_m: float, q_diag: F64
) -> F64:
    """``[m, Iz, lf, lr]`` and the four process-noise variances per step, (8,)."""
    return np.concatenate(
        [[mass_kg, yaw_inertia_kg_m2, lf_m, lr_m], np.asarray(q_diag, dtype=float)]
    )


@numba.njit(cache=True, error_model="numpy")
def predict(x: F64, p: F64, consts: F64, dt_s: float, vx_m_s: float, moment_nm: float) -> None:
    """Time update of ``x`` (4,) and ``p`` (4, 4) in place over ``dt_s`` at ``vx_m_s``, with
    a known yaw moment ``moment_nm`` held over the step."""
    m, iz, lf, lr = consts[0], consts[1], consts[2], consts[3]
    ts = dt_s
    # Tuononen 2009 eq. (21): discretized eq. (19)-(20), forces as identity (random walk)
    a = np.eye(4)
    a[0, 1] = -ts * vx_m_s
    a[0, 2] = ts / m
    a[0, 3] = ts / m
    a[1, 2] = lf / iz * ts
    a[1, 3] = -lr / iz * ts
    # eq. (1): x_k^- = A x_k-1 (+ the known moment input on the yaw rate, beyond eq. 21)
    x0 = a[0, 0] * x[0] + a[0, 1] * x[1] + a[0, 2] * x[2] + a[0, 3] * x[3]
    x1 = a[1, 1] * x[1] + a[1, 2] * x[2] + a[1, 3] * x[3]
    x[0] = x0
    x[1] = x1 + dt_s * moment_nm / iz
    # eq. (5): P_k^- = A P A^T + Q
    ap = np.empty((4, 4))
    _matmul4(a, p, ap)
    at = a.T.copy()
    _matmul4(ap, at, p)
    for i in range(4):
        p[i, i] += consts[4 + i]


@numba.njit(cache=True, error_model="numpy")
def _solve(s: F64, b: F64) -> F64:
    """``s^-1 b`` of an (n, n) ``s`` and (n, k) ``b``: Gaussian elimination with partial
    pivoting (n <= 4)."""
    n = s.shape[0]
    k = b.shape[1]
    a = s.copy()
    y = b.copy()
    for c in range(n):
        piv = c
        for r in range(c + 1, n):
            if abs(a[r, c]) > abs(a[piv, c]):
                piv = r
        if piv != c:
            for j in range(n):
                a[c, j], a[piv, j] = a[piv, j], a[c, j]
            for j in range(k):
                y[c, j], y[piv, j] = y[piv, j], y[c, j]
        for r in range(c + 1, n):
            f = a[r, c] / a[c, c]
            for j in range(c, n):
                a[r, j] -= f * a[c, j]
            for j in range(k):
                y[r, j] -= f * y[c, j]
    for c in range(n - 1, -1, -1):
        for j in range(k):
            acc = y[c, j]
            for i in range(c + 1, n):
                acc -= a[c, i] * y[i, j]
            y[c, j] = acc / a[c, c]
    return y


@numba.njit(cache=True, error_model="numpy")
def update(x: F64, p: F64, rows: np.ndarray, z: F64, r_diag: F64) -> bool:
    """Measurement update of ``x``, ``p`` in place with the rows ``rows`` (n,) of the identity
    measurement, ``z`` (n,) and diagonal ``R`` (n,); False when the result is not finite."""
    n = rows.shape[0]
    s = np.empty((n, n))
    hp = np.empty((n, 4))
    for i in range(n):
        for j in range(n):
            s[i, j] = p[rows[i], rows[j]]
        s[i, i] += r_diag[i]
        for j in range(4):
            hp[i, j] = p[rows[i], j]
    # eq. (7): K = P^- H^T (H P^- H^T + R)^-1, here K^T = S^-1 H P^-
    kt = _solve(s, hp)
    # eq. (8): x_k = x_k^- + K (z_k - H x_k^-)
    innov = np.empty(n)
    for i in range(n):
        innov[i] = z[i] - x[rows[i]]
    for j in range(4):
        acc = 0.0
        for i in range(n):
            acc += kt[i, j] * innov[i]
        x[j] += acc
    # a posteriori covariance, Joseph form: (I - K H) P (I - K H)^T + K R K^T
    ikh = np.eye(4)
    for i in range(n):
        for j in range(4):
            ikh[j, rows[i]] -= kt[i, j]
    tmp = np.empty((4, 4))
    _matmul4(ikh, p, tmp)
    ikh_t = ikh.T.copy()
    _matmul4(tmp, ikh_t, p)
    for a in range(4):
        for b in range(4):
            acc = 0.0
            for i in range(n):
                acc += kt[i, a] * r_diag[i] * kt[i, b]
            p[a, b] += acc
    finite = True
    for a in range(4):
        if not np.isfinite(x[a]):
            finite = False
        for b in range(a, 4):
            v = 0.5 * (p[a, b] + p[b, a])
            p[a, b] = v
            p[b, a] = v
            if not np.isfinite(v):
                finite = False
    return finite
