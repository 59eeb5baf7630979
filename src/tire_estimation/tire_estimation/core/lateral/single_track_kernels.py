"""Compiled (Numba, ``cache=True``) single-track discretization and linear lateral KF step.

The linear single-track model of :mod:`.single_track` (eq. 23-28 of Tuononen 2009:
``continuous_matrices``), its exact discretization over a step (the matrix exponential of the
augmented system, a Taylor series of order 10 with scaling and squaring) with the steer angle
held or linear between its samples, and the predict and update of
:class:`~.linear_kf.LinearLateralKF`, on scalars and small scratch arrays, in the order of
operations of the NumPy reference (tests/core/lateral/reference_single_track.py; the two agree to
rounding, about 1e-15 relative). One call per IMU sample instead of some sixty NumPy calls on
2x2 and 4x4 arrays.

Constants of the model (:func:`model_constants`): ``[m, Iz, lf, lr, Cf, Cr]``; of the filter
(:func:`kf_constants`): those, then the process-noise densities of vy and r and the measurement
variances of ay and r.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from tire_estimation.core.arrays import F64

#: Taylor order of the matrix exponential
EXPM_ORDER = 10
#: the scaled matrix's row-sum norm is brought to at most this before the Taylor series
EXPM_NORM = 0.25
#: length of :func:`kf_constants`
N_KF_CONSTANTS = 10


def model_constants(
    mass_kg: float,
    yaw_inertia_kg_m2: float,
    lf_m: float,
    lr_m: float,
    cf_n_rad: float,
    cr_n_rad: float,
) -> F64:
    """``[m, Iz, lf, lr, Cf, Cr]`` as the kernels take them, (6,)."""
    return np.array([mass_kg, yaw_inertia_kg_m2, lf_m, lr_m, cf_n_rad, cr_n_rad], dtype=float)


def kf_constants(model: F64, q_vy: float, q_r: float, r_ay: float, r_r: float) -> F64:
    """The model constants, the process-noise densities (vy, r) and the measurement variances
    (ay, r) of the linear KF, (10,)."""
    return np.concatenate([np.asarray(model, dtype=float), [q_vy, q_r, r_ay, r_r]])


@numba.njit(cache=True)
def _matmul4(a: F64, b: F64, out: F64) -> None:
    """``out`` = ``a @ b`` of 4x4 ``a`` and ``b`` (``out`` neither of them), summed in index
    order."""
    for i in range(4):
        for j in range(4):
            out[i, j] = (
                a[i, 0] * b[0, j] + a[i, 1] * b[1, j] + a[i, 2] * b[2, j] + a[i, 3] * b[3, j]
            )


@numba.njit(cache=True)
def _expm4(m: F64, out: F64) -> None:
    """``out`` = expm(m) of a 4x4 ``m``: scaling to a row-sum norm of at most
    :data:`EXPM_NORM`, a Taylor series of order :data:`EXPM_ORDER`, squaring (accurate to about
    1e-12 at the filters' step sizes; scipy.linalg.expm costs milliseconds per call)."""
    norm = 0.0
    for i in range(4):
        s = abs(m[i, 0]) + abs(m[i, 1]) + abs(m[i, 2]) + abs(m[i, 3])
        norm = max(norm, s)
    squarings = 0
    if norm > EXPM_NORM:
        squarings = max(0, math.ceil(math.log2(norm / EXPM_NORM)))
    scale = 2.0**squarings
    a = np.empty((4, 4))
    term = np.zeros((4, 4))
    tmp = np.empty((4, 4))
    for i in range(4):
        for j in range(4):
            a[i, j] = m[i, j] / scale
        term[i, i] = 1.0
    for i in range(4):
        for j in range(4):
            out[i, j] = term[i, j]
    for k in range(1, EXPM_ORDER + 1):
        _matmul4(term, a, tmp)
        for i in range(4):
            for j in range(4):
                term[i, j] = tmp[i, j] / k
                out[i, j] = out[i, j] + term[i, j]
    for _ in range(squarings):
        _matmul4(out, out, tmp)
        for i in range(4):
            for j in range(4):
                out[i, j] = tmp[i, j]


@numba.njit(cache=True)
def continuous_matrices(
    model: F64, vx_m_s: float
) -> tuple[float, float, float, float, float, float]:
    """``(A00, A01, A10, A11, B0, B1)`` of ``single_track.continuous_matrices``."""
    m, iz, lf, lr, cf, cr = model[0], model[1], model[2], model[3], model[4], model[5]
    v = vx_m_s
    # eq. (23) with (25)-(28): dvy = (Cf af + Cr ar) / m - vx r
    # eq. (24) with (25)-(28): dr = (lf Cf af - lr Cr ar) / Iz
    a00 = -(cf + cr) / (m * v)
    a01 = -v - (cf * lf - cr * lr) / (m * v)
    a10 = -(cf * lf - cr * lr) / (iz * v)
    a11 = -(cf * lf * lf + cr * lr * lr) / (iz * v)
    return a00, a01, a10, a11, cf / m, cf * lf / iz


@numba.njit(cache=True)
def _held_exponential(model: F64, vx_m_s: float, dt_s: float, ramp_dt_s: float, out: F64) -> None:
    """First two rows of expm(M T), ``M`` = [[A, B, 0], [0, 0, 1], [0, 0, 0]] at ``vx_m_s``
    with the ramp entry ``ramp_dt_s`` (``dt_s``: a steer angle linear between its samples; 0:
    held), into ``out`` (2, k) (its first k columns)."""
    a00, a01, a10, a11, b0, b1 = continuous_matrices(model, vx_m_s)
    aug = np.zeros((4, 4))
    aug[0, 0] = a00 * dt_s
    aug[0, 1] = a01 * dt_s
    aug[1, 0] = a10 * dt_s
    aug[1, 1] = a11 * dt_s
    aug[0, 2] = b0 * dt_s
    aug[1, 2] = b1 * dt_s
    aug[2, 3] = ramp_dt_s
    e = np.empty((4, 4))
    _expm4(aug, e)
    for i in range(2):
        for j in range(out.shape[1]):
            out[i, j] = e[i, j]


@numba.njit(cache=True)
def first_order_hold(model: F64, vx_m_s: float, dt_s: float, out: F64) -> None:
    """``out`` (2, 4) = ``[Ad | B0 | B1]``, the exact discretization over ``dt_s`` at ``vx_m_s``
    for a steer angle linear between its samples (first-order hold):
    x(T) = Ad x(0) + B0 delta0 + B1 (delta1 - delta0) / T."""
    # d/dt [x, delta, w] = [[A, B, 0], [0, 0, 1], [0, 0, 0]] [x, delta, w]
    _held_exponential(model, vx_m_s, dt_s, dt_s, out)


@numba.njit(cache=True)
def zero_order_hold(model: F64, vx_m_s: float, dt_s: float, out: F64) -> None:
    """``out`` (2, 3) = ``[Ad | Bd]``: expm([[A, B], [0, 0]] T) with the steer angle held (as
    ``SingleTrackModel.step`` without a start angle; the 3x3 exponential embedded in a 4x4 with
    a zero last row and column, which leaves its first three rows and columns unchanged)."""
    _held_exponential(model, vx_m_s, dt_s, 0.0, out)


@numba.njit(cache=True)
def kf_step(
    x: F64,
    p: F64,
    consts: F64,
    dt_s: float,
    vx_m_s: float,
    delta0_rad: float,
    delta1_rad: float,
    ay_m_s2: float,
    r_meas_rad_s: float,
) -> None:
    """One predict + update of ``LinearLateralKF`` in place on ``x`` (2,) and ``p`` (2, 2)."""
    # ---- predict: single-track eq. (23)-(28), first-order hold on delta
    fb = np.empty((2, 4))
    first_order_hold(consts, vx_m_s, dt_s, fb)
    f00, f01, f10, f11 = fb[0, 0], fb[0, 1], fb[1, 0], fb[1, 1]
    slope = (delta1_rad - delta0_rad) / dt_s
    x0, x1 = x[0], x[1]
    x0n = (f00 * x0 + f01 * x1) + fb[0, 2] * delta0_rad + fb[0, 3] * slope
    x1n = (f10 * x0 + f11 * x1) + fb[1, 2] * delta0_rad + fb[1, 3] * slope
    # P' = F P F^T + Q T
    p00, p01, p10, p11 = p[0, 0], p[0, 1], p[1, 0], p[1, 1]
    fp00 = f00 * p00 + f01 * p10
    fp01 = f00 * p01 + f01 * p11
    fp10 = f10 * p00 + f11 * p10
    fp11 = f10 * p01 + f11 * p11
    p00 = (fp00 * f00 + fp01 * f01) + consts[6] * dt_s
    p01 = fp00 * f10 + fp01 * f11
    p10 = fp10 * f00 + fp11 * f01
    p11 = (fp10 * f10 + fp11 * f11) + consts[7] * dt_s
    # ---- update: y = [ay, r], ay = (Ff + Fr) / m with eq. (25)-(28)
    m, lf, lr, cf, cr = consts[0], consts[2], consts[3], consts[4], consts[5]
    c00 = -(cf + cr) / (m * vx_m_s)
    c01 = (cr * lr - cf * lf) / (m * vx_m_s)
    d0 = cf / m
    r_ay, r_r = consts[8], consts[9]
    innov0 = ay_m_s2 - ((c00 * x0n + c01 * x1n) + d0 * delta1_rad)
    innov1 = r_meas_rad_s - x1n
    # C P
    cp00 = c00 * p00 + c01 * p10
    cp01 = c00 * p01 + c01 * p11
    cp10 = p10
    cp11 = p11
    # S = C P C^T + R
    s00 = (cp00 * c00 + cp01 * c01) + r_ay
    s01 = cp01
    s10 = cp10 * c00 + cp11 * c01
    s11 = cp11 + r_r
    # K^T = S^-1 (C P)
    det = s00 * s11 - s01 * s10
    m00 = (s11 * cp00 - s01 * cp10) / det
    m01 = (s11 * cp01 - s01 * cp11) / det
    m10 = (s00 * cp10 - s10 * cp00) / det
    m11 = (s00 * cp11 - s10 * cp01) / det
    k00, k01, k10, k11 = m00, m10, m01, m11
    x[0] = x0n + (k00 * innov0 + k01 * innov1)
    x[1] = x1n + (k10 * innov0 + k11 * innov1)
    # Joseph form: (I - K C) P (I - K C)^T + K R K^T
    i00 = 1.0 - k00 * c00
    i01 = -(k00 * c01 + k01)
    i10 = -(k10 * c00)
    i11 = 1.0 - (k10 * c01 + k11)
    ip00 = i00 * p00 + i01 * p10
    ip01 = i00 * p01 + i01 * p11
    ip10 = i10 * p00 + i11 * p10
    ip11 = i10 * p01 + i11 * p11
    p[0, 0] = (ip00 * i00 + ip01 * i01) + (k00 * r_ay * k00 + k01 * r_r * k01)
    p[0, 1] = (ip00 * i10 + ip01 * i11) + (k00 * r_ay * k10 + k01 * r_r * k11)
    p[1, 0] = (ip10 * i00 + ip11 * i01) + (k10 * r_ay * k00 + k11 * r_r * k01)
    p[1, 1] = (ip10 * i10 + ip11 * i11) + (k10 * r_ay * k10 + k11 * r_r * k11)


__all__ = [
    "EXPM_ORDER",
    "N_KF_CONSTANTS",
    "continuous_matrices",
    "first_order_hold",
    "kf_constants",
    "kf_step",
    "model_constants",
    "zero_order_hold",
]
