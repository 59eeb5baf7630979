"""Per-particle passes of the stiffness MPF's compiled IMU step (Numba, ``cache=True``).

The pieces that :mod:`.kernels` (Algorithm 1 of Berntorp & Di Cairano, IEEE TCST 2018) runs
for each particle: the small-matrix algebra (row-major 9-tuples and upper triangles, kept in
registers), the single-track model at one particle (eq. 1-12), the block layout of the scratch
of ``kernels.update`` (:data:`LANES` particles per block, each field of a block contiguous, so
that a loop over the lanes of one array runs in SIMD registers), the conditional draw with the
NiW update (:func:`posterior`, eq. 19, 39-41), the bias update (:func:`bias_update`, eq. 30),
the information share of ``niw_update`` = ``rao_blackwellized`` and systematic resampling.
Every loop over the lanes is the innermost loop and reads and writes only the scratch: the
compiler vectorizes neither a loop whose body holds another loop nor one over several arrays.
Numba's cache of the kernels is keyed on the text of ``kernels.py`` alone (touching it is not
enough): after a change here, remove its ``kernels.*.nbi`` / ``.nbc`` files in ``__pycache__``
so that they compile again.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import kernel_random as kr
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness import mat3
from tire_estimation.core.stiffness.model import MIN_SPEED_M_S, SingleTrackParams

IDX = NDArray[np.intp]
U64 = NDArray[np.uint64]
#: a 3x3 matrix as a row-major 9-tuple (kept in registers by the compiler), a 3-vector as a 3-tuple
M3 = tuple[float, float, float, float, float, float, float, float, float]
V3 = tuple[float, float, float]

#: :func:`model_constants`: positions in the constants vector of :func:`update`
(
    C_MASS, C_IZ, C_LF, C_LR, C_PX, C_PY, C_CX, C_CYF, C_CYR, C_ROLL, C_DRAG, C_SATF, C_SATR,
    C_SHAPE_C, C_CURV_E, C_FRONT, C_REAR, C_TYRE, C_R0, C_R1, C_R2, C_WS_STD, C_SPEED_VAR,
    C_MIN_SPEED, C_INV_MASS, C_INV_IZ, C_LO, C_HI,
) = (*range(26), 26, 29)  # fmt: skip
N_CONSTANTS = 32
#: ``tyre`` codes of the constants vector: linear (eq. 2), tanh, Magic Formula
TYRE_LINEAR, TYRE_TANH, TYRE_MAGIC = 0.0, 1.0, 2.0
#: ``niw_mode`` of :func:`update`
NIW_SAMPLED, NIW_RAO_BLACKWELLIZED = 0, 1

_JIT = {"cache": True, "error_model": "numpy", "inline": "always"}


@numba.njit(**_JIT)
def mm(a: M3, b: M3) -> M3:
    """``a @ b``."""
    return (
        a[0] * b[0] + a[1] * b[3] + a[2] * b[6],
        a[0] * b[1] + a[1] * b[4] + a[2] * b[7],
        a[0] * b[2] + a[1] * b[5] + a[2] * b[8],
        a[3] * b[0] + a[4] * b[3] + a[5] * b[6],
        a[3] * b[1] + a[4] * b[4] + a[5] * b[7],
        a[3] * b[2] + a[4] * b[5] + a[5] * b[8],
        a[6] * b[0] + a[7] * b[3] + a[8] * b[6],
        a[6] * b[1] + a[7] * b[4] + a[8] * b[7],
        a[6] * b[2] + a[7] * b[5] + a[8] * b[8],
    )


@numba.njit(**_JIT)
def mv(a: M3, v: V3) -> V3:
    """``a @ v``."""
    return (
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
        a[6] * v[0] + a[7] * v[1] + a[8] * v[2],
    )


@numba.njit(**_JIT)
def quad(a: M3, v: V3) -> float:
    """``v^T a v`` (as ``student_t.mahalanobis``: ``sum_k v_k (a v)_k``)."""
    av = mv(a, v)
    return v[0] * av[0] + v[1] * av[1] + v[2] * av[2]


#: ``mat3.sym_cofactors`` compiled (the same expressions in the same order)
_sym_cofactors = numba.njit(**_JIT)(mat3.sym_cofactors)


@numba.njit(**_JIT)
def inv_sym(a00: float, a01: float, a02: float, a11: float, a12: float, a22: float) -> M3:
    """Inverse of a symmetric 3x3 from its upper triangle, by cofactors (``mat3.inv_sym``), and
    its determinant (last element of the result)."""
    c00, c01, c02, c11, c12, c22, det = _sym_cofactors(a00, a01, a02, a11, a12, a22)
    # a^-1 = C^T / det
    inv_det = 1.0 / det
    return (
        c00 * inv_det, c01 * inv_det, c02 * inv_det, c11 * inv_det, c12 * inv_det,
        c22 * inv_det, det, 0.0, 0.0,
    )  # fmt: skip


@numba.njit(**_JIT)
def clip(v: float, lo: float, hi: float) -> float:
    """``np.clip`` of a scalar (a NaN stays NaN)."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


@numba.njit(**_JIT)
def maximum(a: float, b: float) -> float:
    """``np.maximum`` of two scalars (a NaN wins)."""
    if a >= b or a != a:
        return a
    return b


@numba.njit(**_JIT)
def seeded(words: U64) -> kr.State:
    """The xoshiro256++ state of four raw words (``kernel_state``: the all-zero state is 1)."""
    st = kr.load(words)
    if st[0] == 0 and st[1] == 0 and st[2] == 0 and st[3] == 0:
        st = (np.uint64(1), st[1], st[2], st[3])
    return st


@numba.njit(**_JIT)
def slip_function(alpha: float, sat: float, tyre: float, shape_c: float, curv_e: float) -> float:
    """``model.lateral_slip_function`` of one slip angle: ``alpha`` (eq. 2) for the linear tyre
    or ``sat`` <= 0, else the tanh or the Magic Formula with the saturation slip ``sat``."""
    if tyre == TYRE_LINEAR or sat <= 0.0:
        return alpha
    if tyre == TYRE_MAGIC:
        u = alpha / (shape_c * sat)
        return sat * math.sin(shape_c * math.atan(u - curv_e * (u - math.atan(u))))
    return sat * math.tanh(alpha / sat)


@numba.njit(**_JIT)
def wheel_slip(vx: float, rw: float, min_speed: float) -> float:
    """``model.wheel_slip``: ``(R w - vX) / max(vX, R w, MIN_SPEED_M_S)`` (eq. 3)."""
    return (rw - vx) / maximum(maximum(vx, rw), min_speed)


@numba.njit(**_JIT)
def slip_gain(vx: float, rw: float, min_speed: float) -> float:
    """``d lambda / d(R w)`` of ``model.wheel_speed_gain`` (eq. 3)."""
    den = maximum(maximum(vx, rw), min_speed)
    if rw > maximum(vx, min_speed):
        return vx / (den * den)
    return 1.0 / den


#: the block layout of the per-particle scratch of :func:`update`: particle ``i`` has field ``f``
#: at ``(i // LANES) * (FIELDS * LANES) + f * LANES + i % LANES``, so that a loop over the
#: ``LANES`` particles of a block reads and writes one array at offsets the compiler knows and
#: runs in SIMD registers (a loop over particles that touches several arrays does not: the
#: compiler cannot rule out that they overlap)
LANES = 8
# packed inputs: state, bias, P (upper triangle), mu, Lambda (upper triangle)
F_VX, F_VY, F_R, F_B, F_P, F_MU, F_L = 0, 1, 2, 3, 6, 12, 15
# model and likelihood: slip angles (then phi), d rows 0-1, a, rate_n, e_bar, z rows 0-1,
# Lambda~_e^-1 (upper), z^T Lambda~_e^-1 z, det Lambda~_e, R (00, 01, 11, 22)
F_AF, F_AR, F_D, F_A, F_RATE, F_E, F_Z, F_INV, F_MAHA, F_DET, F_RC = (
    21, 22, 23, 29, 38, 41, 44, 46, 52, 53, 54,
)  # fmt: skip
# posterior inputs: three normals, the chi-square variate, the kept Cx mean and Lambda_00
F_N, F_CHI2, F_FM0, F_FL00 = 58, 61, 62, 63
# posterior output: the drawn w
F_W = 64
FIELDS = 67


def scratch_size(n: int) -> int:
    """Length of the scratch arrays of :func:`update` for ``n`` particles."""
    return -(-n // LANES) * LANES * FIELDS


@numba.njit(**_JIT)
def at(i: int) -> int:
    """Offset of particle ``i``'s field 0 in the block layout (field ``f``: + ``f * LANES``)."""
    return (i // LANES) * (FIELDS * LANES) + i % LANES


@numba.njit(**_JIT)
def load3(wk: F64, o: int, f: int) -> V3:
    """Fields ``f`` to ``f + 2`` of the particle at offset ``o`` of the block layout."""
    return wk[o + f * LANES], wk[o + (f + 1) * LANES], wk[o + (f + 2) * LANES]


@numba.njit(**_JIT)
def load6(wk: F64, o: int, f: int) -> tuple[float, float, float, float, float, float]:
    """Fields ``f`` to ``f + 5`` of the particle at offset ``o`` (an upper triangle, two rows)."""
    a, b, c = load3(wk, o, f)
    d, e, g = load3(wk, o, f + 3)
    return a, b, c, d, e, g


@numba.njit(**_JIT)
def store3(wk: F64, o: int, f: int, v: V3) -> None:
    """``v`` into fields ``f`` to ``f + 2`` of the particle at offset ``o``."""
    wk[o + f * LANES] = v[0]
    wk[o + (f + 1) * LANES] = v[1]
    wk[o + (f + 2) * LANES] = v[2]


@numba.njit(**_JIT)
def scalars(c: F64) -> tuple[float, ...]:
    """The model constants as scalars (kept in registers in the loops)."""
    return (
        c[C_LF], c[C_LR], c[C_PX], c[C_PY], c[C_INV_MASS], c[C_INV_IZ], c[C_MIN_SPEED],
        c[C_CX], c[C_CYF], c[C_CYR], c[C_ROLL], c[C_DRAG], c[C_FRONT], c[C_REAR], c[C_R0],
        c[C_R1], c[C_R2], c[C_WS_STD], c[C_SPEED_VAR], c[C_SATF], c[C_SATR],
    )  # fmt: skip


@numba.njit(**_JIT)
def particle_model(
    k: tuple[float, ...], vx: float, vy: float, r: float, alpha_f: float, alpha_r: float,
    cd: float, sd: float, wf: float, wr: float, kinematic: bool, ax: float,
) -> tuple[M3, V3, V3, M3]:  # fmt: skip
    """Eq. (1)-(12) at one particle with the (effective) slip angles ``alpha_f``, ``alpha_r``:
    ``a`` (force regressor), ``rate_n``, ``h`` and ``d`` (row 2 zero) of ``model.linearize``
    (``model.kinematic_speed_row`` when ``kinematic``: the measured ``ax`` drives vX, row 0 is
    the speed). ``k``: :func:`scalars`."""
    lf, lr, px, py, inv_m, inv_iz, min_speed = k[0], k[1], k[2], k[3], k[4], k[5], k[6]
    cx, cyf, cyr, roll, drag, front, rear = k[7], k[8], k[9], k[10], k[11], k[12], k[13]
    # eq. (3) wheel slips of the driven axles (the measured speed: none)
    lam_f = wheel_slip(vx, wf, min_speed) if front > 0.0 and not kinematic else 0.0
    lam_r = wheel_slip(vx, wr, min_speed) if rear > 0.0 and not kinematic else 0.0
    # eq. (1) with eq. (2): [ax, ay, dr] = A C + a0 (model.force_regressor); the factors of the
    # slips do not change over the particles
    sd_m, cd_m = sd * inv_m, cd * inv_m
    lsd_iz, lcd_iz = lf * sd * inv_iz, lf * cd * inv_iz
    a = (
        (lam_f * cd + lam_r) * inv_m, -alpha_f * sd_m, 0.0,
        lam_f * sd_m, alpha_f * cd_m, alpha_r * inv_m,
        lam_f * lsd_iz, alpha_f * lcd_iz, alpha_r * (-lr * inv_iz),
    )  # fmt: skip
    # eq. (7) accelerations with C = C_n (and the known resistances)
    acc0 = a[0] * cx + a[1] * cyf + a[2] * cyr
    acc1 = a[3] * cx + a[4] * cyf + a[5] * cyr
    acc2 = a[6] * cx + a[7] * cyf + a[8] * cyr
    acc0 = acc0 + -(roll + drag * vx * abs(vx)) * inv_m if roll != 0.0 or drag != 0.0 else acc0
    # eq. (9)-(10) state derivative with the coupling [vY r, -vX r, 0]
    rate = (acc0 + vy * r, acc1 - vx * r, acc2)
    # rigid body at the IMU: a_p = a_cg + dr z x p - r^2 p; eq. (12) y_r = r
    r2 = r * r
    h = (acc0 - py * acc2 - px * r2, acc1 + px * acc2 - py * r2, r)
    d = (
        a[0] - py * a[6], a[1] - py * a[7], a[2] - py * a[8],
        a[3] + px * a[6], a[4] + px * a[7], a[5] + px * a[8],
        0.0, 0.0, 0.0,
    )  # fmt: skip
    if kinematic:
        # dvX/dt = ax_cg + vY r, ax_cg = ax_imu + p_y dr + p_x r^2; measurement y_0 = vX
        rate = (ax + px * r * r + py * acc2 + vy * r, rate[1], rate[2])
        a = (py * a[6], py * a[7], py * a[8], a[3], a[4], a[5], a[6], a[7], a[8])
        h = (vx, h[1], h[2])
        d = (0.0, 0.0, 0.0, d[3], d[4], d[5], 0.0, 0.0, 0.0)
    return a, rate, h, d


@numba.njit(**_JIT)
def noise_cov(
    k: tuple[float, ...], vx: float, cd: float, sd: float, wf: float, wr: float,
    kinematic: bool, cx: float,
) -> tuple[float, float, float, float]:  # fmt: skip
    """``R`` of eq. (12) at one particle, entries (00, 01, 11, 22) (``model.measurement_cov``:
    the wheel-speed noise carried into ``y`` by the slip, at the longitudinal stiffness ``cx``;
    with the measured speed the speed noise in row 0)."""
    lf, px, py, inv_m, inv_iz, min_speed = k[0], k[2], k[3], k[4], k[5], k[6]
    front, rear, r0, r1, r2, s, speed_var = k[12], k[13], k[14], k[15], k[16], k[17], k[18]
    # eq. (1) column of Fxf at the IMU: lever @ [cos d / m, sin d / m, lf sin d / I]
    col2 = lf * sd * inv_iz
    f = cx * slip_gain(vx, wf, min_speed)
    gf0 = f * (cd * inv_m - py * col2)
    gf1 = f * (sd * inv_m + px * col2)
    # eq. (1) column of Fxr: [1 / m, 0, 0]
    f = cx * slip_gain(vx, wr, min_speed)
    gr0 = f * inv_m
    gr1 = f * 0.0
    if front > 0.0 and rear > 0.0:
        o00, o01, o11 = gf0 * gf0 + gr0 * gr0, gf0 * gf1 + gr0 * gr1, gf1 * gf1 + gr1 * gr1
    elif front > 0.0:
        o00, o01, o11 = gf0 * gf0, gf0 * gf1, gf1 * gf1
    else:
        o00, o01, o11 = gr0 * gr0, gr0 * gr1, gr1 * gr1
    ss = s * s
    if kinematic:
        return speed_var, 0.0, r1, r2
    if s <= 0.0 or (front <= 0.0 and rear <= 0.0):
        return r0, 0.0, r1, r2
    return r0 + ss * o00, 0.0 + ss * o01, r1 + ss * o11, r2 + ss * 0.0


@numba.njit(**_JIT)
def posterior(
    wk: F64, n_blocks: int, w_fac: float, nu_t: float, dof_c: float, learn: bool, freeze: bool,
    niw_mode: int, c_niw: float, g_loc: float, g_w: float, g_new: float, c: F64,
    nu_post: float, bias_on: bool, bias_fac: float,
) -> None:  # fmt: skip
    """Algorithm 1 lines 4, 15, 17-18 on the block-layout scratch ``wk`` of the resampled
    particles, in place: the conditional Student-t of ``w`` (eq. 39-41), the draw from the
    fields ``F_N``, ``F_CHI2``, the projection (Sec. V), the NiW update (19) (``learn``), the Cx
    freeze (deviation vi), the bias update (30) (``bias_on``) and ``rate = rate_n + a w``."""
    lo0, lo1, lo2 = c[C_LO], c[C_LO + 1], c[C_LO + 2]
    hi0, hi1, hi2 = c[C_HI], c[C_HI + 1], c[C_HI + 2]
    inv_dof_c = 1.0 / dof_c
    # eq. (27b) Sigma_{k|k} = Lambda / (nu - d - 1)
    inv_nu_s = 1.0 / (nu_post - 3.0 - 1.0)
    rao = niw_mode == NIW_RAO_BLACKWELLIZED
    for blk in range(n_blocks):
        base = blk * (FIELDS * LANES)
        for ln in range(LANES):
            o = base + ln
            d = load6(wk, o, F_D)
            mu = load3(wk, o, F_MU)
            lu = load6(wk, o, F_L)
            # Lambda_11 = (1 + gamma) / nu~ Lambda (symmetric)
            l11 = (
                w_fac * lu[0], w_fac * lu[1], w_fac * lu[2], w_fac * lu[1], w_fac * lu[3],
                w_fac * lu[4], w_fac * lu[2], w_fac * lu[4], w_fac * lu[5],
            )  # fmt: skip
            # eq. (41) Lambda_21 = d Lambda_11 (rows 0-1; row 2 of d is zero)
            l21 = (
                d[0] * l11[0] + d[1] * l11[3] + d[2] * l11[6],
                d[0] * l11[1] + d[1] * l11[4] + d[2] * l11[7],
                d[0] * l11[2] + d[1] * l11[5] + d[2] * l11[8],
                d[3] * l11[0] + d[4] * l11[3] + d[5] * l11[6],
                d[3] * l11[1] + d[4] * l11[4] + d[5] * l11[7],
                d[3] * l11[2] + d[4] * l11[5] + d[5] * l11[8],
            )
            i00, i01, i02, i11, i12, _ = load6(wk, o, F_INV)
            # gain Lambda_12 Lambda_22^-1 = Lambda_21^T Lambda~_e^-1 (3, 3)
            gain = (
                l21[0] * i00 + l21[3] * i01, l21[0] * i01 + l21[3] * i11,
                l21[0] * i02 + l21[3] * i12, l21[1] * i00 + l21[4] * i01,
                l21[1] * i01 + l21[4] * i11, l21[1] * i02 + l21[4] * i12,
                l21[2] * i00 + l21[5] * i01, l21[2] * i01 + l21[5] * i11,
                l21[2] * i02 + l21[5] * i12,
            )  # fmt: skip
            # eq. (41) mu_{1|2} = mu_1 + Lambda_12 Lambda_22^-1 (e_bar - mu_e)
            z0, z1, z2 = wk[o + F_Z * LANES], wk[o + (F_Z + 1) * LANES], wk[o + (F_E + 2) * LANES]
            loc = (
                mu[0] + (gain[0] * z0 + gain[1] * z1 + gain[2] * z2),
                mu[1] + (gain[3] * z0 + gain[4] * z1 + gain[5] * z2),
                mu[2] + (gain[6] * z0 + gain[7] * z1 + gain[8] * z2),
            )
            # eq. (41) Lambda_{1|2} = (nu~ + z^T L22^-1 z)/(nu~ + n_e) (L11 - L12 L22^-1 L21),
            # symmetrized; only the lower triangle is factored below
            f = (nu_t + wk[o + F_MAHA * LANES]) * inv_dof_c
            gl00 = gain[0] * l21[0] + gain[1] * l21[3]
            gl01 = gain[0] * l21[1] + gain[1] * l21[4]
            gl02 = gain[0] * l21[2] + gain[1] * l21[5]
            gl10 = gain[3] * l21[0] + gain[4] * l21[3]
            gl11 = gain[3] * l21[1] + gain[4] * l21[4]
            gl12 = gain[3] * l21[2] + gain[4] * l21[5]
            gl20 = gain[6] * l21[0] + gain[7] * l21[3]
            gl21 = gain[6] * l21[1] + gain[7] * l21[4]
            gl22 = gain[6] * l21[2] + gain[7] * l21[5]
            c00 = f * (0.5 * ((l11[0] - gl00) + (l11[0] - gl00)))
            c10 = f * (0.5 * ((l11[3] - gl10) + (l11[1] - gl01)))
            c11 = f * (0.5 * ((l11[4] - gl11) + (l11[4] - gl11)))
            c20 = f * (0.5 * ((l11[6] - gl20) + (l11[2] - gl02)))
            c21 = f * (0.5 * ((l11[7] - gl21) + (l11[5] - gl12)))
            c22 = f * (0.5 * ((l11[8] - gl22) + (l11[8] - gl22)))
            # eq. (39) w ~ St(mu_{1|2}, Lambda_{1|2}, nu_{1|2}): a relative 1e-9 ridge keeps the
            # factor of a (numerically) singular shape finite; closed-form lower Cholesky factor
            ridge = 1e-9 * (c00 + c11 + c22)
            ch00 = math.sqrt(c00 + ridge)
            inv_ch00 = 1.0 / ch00
            ch10 = c10 * inv_ch00
            ch20 = c20 * inv_ch00
            ch11 = math.sqrt((c11 + ridge) - ch10 * ch10)
            ch21 = (c21 - ch20 * ch10) / ch11
            ch22 = math.sqrt((c22 + ridge) - ch20 * ch20 - ch21 * ch21)
            n0, n1, n2 = load3(wk, o, F_N)
            tf = math.sqrt(dof_c / wk[o + F_CHI2 * LANES])
            # w = mu_{1|2} + chol z sqrt(nu_{1|2} / chi2); Sec. V projection to physical bounds
            w0 = clip(loc[0] + (ch00 * n0) * tf, lo0, hi0)
            w1 = clip(loc[1] + (ch10 * n0 + ch11 * n1) * tf, lo1, hi1)
            w2 = clip(loc[2] + (ch20 * n0 + ch21 * n1 + ch22 * n2) * tf, lo2, hi2)
            store3(wk, o, F_W, (w0, w1, w2))
            # eq. (19) with w_bar = w_k (Remark 3): Lambda += c (w - mu)(w - mu)^T; the mean
            # mu += gamma_{k|k} (w - mu), or the split update mu += g_loc (loc - mu) + g_w (w -
            # loc); projected to the bounds
            dw0, dw1, dw2 = w0 - mu[0], w1 - mu[1], w2 - mu[2]
            if rao:
                m0 = mu[0] + (g_loc * (loc[0] - mu[0]) + g_w * (w0 - loc[0]))
                m1 = mu[1] + (g_loc * (loc[1] - mu[1]) + g_w * (w1 - loc[1]))
                m2 = mu[2] + (g_loc * (loc[2] - mu[2]) + g_w * (w2 - loc[2]))
            else:
                m0 = mu[0] + g_new * dw0
                m1 = mu[1] + g_new * dw1
                m2 = mu[2] + g_new * dw2
            fm0, fl00 = wk[o + F_FM0 * LANES], wk[o + F_FL00 * LANES]
            if learn:
                lu = (
                    lu[0] + c_niw * (dw0 * dw0), lu[1] + c_niw * (dw0 * dw1),
                    lu[2] + c_niw * (dw0 * dw2), lu[3] + c_niw * (dw1 * dw1),
                    lu[4] + c_niw * (dw1 * dw2), lu[5] + c_niw * (dw2 * dw2),
                )  # fmt: skip
                mu = (clip(m0, lo0, hi0), clip(m1, lo1, hi1), clip(m2, lo2, hi2))
                if freeze:
                    # deviation (vi): Cx mean and E[Sigma_00] (eq. 27b) as before this step, of
                    # the ancestor (eq. 20 keeps the mean)
                    mu = (fm0, mu[1], mu[2])
                    lu = (fl00, 0.0, 0.0, lu[3], lu[4], lu[5])
            # (stored unconditionally: one path for the SIMD lanes)
            store3(wk, o, F_MU, mu)
            store3(wk, o, F_L, (lu[0], lu[1], lu[2]))
            store3(wk, o, F_L + 3, (lu[3], lu[4], lu[5]))
            # line 18 (first half): derivative for eq. (9), rate = rate_n + a w_k
            # (no inner loops here: the loop over the lanes must be the innermost one)
            wk[o + (F_RATE + 0) * LANES] = wk[o + (F_RATE + 0) * LANES] + (
                wk[o + (F_A + 0) * LANES] * w0
                + wk[o + (F_A + 1) * LANES] * w1
                + wk[o + (F_A + 2) * LANES] * w2
            )
            wk[o + (F_RATE + 1) * LANES] = wk[o + (F_RATE + 1) * LANES] + (
                wk[o + (F_A + 3) * LANES] * w0
                + wk[o + (F_A + 4) * LANES] * w1
                + wk[o + (F_A + 5) * LANES] * w2
            )
            wk[o + (F_RATE + 2) * LANES] = wk[o + (F_RATE + 2) * LANES] + (
                wk[o + (F_A + 6) * LANES] * w0
                + wk[o + (F_A + 7) * LANES] * w1
                + wk[o + (F_A + 8) * LANES] * w2
            )
    if bias_on:
        for blk in range(n_blocks):
            base = blk * (FIELDS * LANES)
            for ln in range(LANES):
                bias_update(wk, base + ln, inv_nu_s, nu_t, bias_fac)


@numba.njit(**_JIT)
def bias_update(wk: F64, o: int, inv_nu_s: float, nu_t: float, bias_fac: float) -> None:
    """Line 15: eq. (30) for the particle at offset ``o`` of the block-layout scratch, with
    ``mu_{k|k}`` and ``Lambda_{k|k}`` (``student_t.bias_update`` with the Student-t total
    noise, deviations ii, v and x), in place."""
    d = load6(wk, o, F_D)
    mu = load3(wk, o, F_MU)
    lu = load6(wk, o, F_L)
    pu = load6(wk, o, F_P)
    pj = (pu[0], pu[1], pu[2], pu[1], pu[3], pu[4], pu[2], pu[4], pu[5])
    # eq. (30) with mu_{k|k} and Sigma_{k|k} = Lambda / (nu - 4): extra = d Sigma d^T
    sg = (
        lu[0] * inv_nu_s, lu[1] * inv_nu_s, lu[2] * inv_nu_s,
        lu[1] * inv_nu_s, lu[3] * inv_nu_s, lu[4] * inv_nu_s,
        lu[2] * inv_nu_s, lu[4] * inv_nu_s, lu[5] * inv_nu_s,
    )  # fmt: skip
    ds00 = d[0] * sg[0] + d[1] * sg[3] + d[2] * sg[6]
    ds01 = d[0] * sg[1] + d[1] * sg[4] + d[2] * sg[7]
    ds02 = d[0] * sg[2] + d[1] * sg[5] + d[2] * sg[8]
    ds10 = d[3] * sg[0] + d[4] * sg[3] + d[5] * sg[6]
    ds11 = d[3] * sg[1] + d[4] * sg[4] + d[5] * sg[7]
    ds12 = d[3] * sg[2] + d[4] * sg[5] + d[5] * sg[8]
    e00 = ds00 * d[0] + ds01 * d[1] + ds02 * d[2]
    e01 = ds00 * d[3] + ds01 * d[4] + ds02 * d[5]
    e11 = ds10 * d[3] + ds11 * d[4] + ds12 * d[5]
    # resid = y - h - d mu_{k|k} - b_{k|k-1}
    resid = (
        wk[o + F_E * LANES] - (d[0] * mu[0] + d[1] * mu[1] + d[2] * mu[2]),
        wk[o + (F_E + 1) * LANES] - (d[3] * mu[0] + d[4] * mu[1] + d[5] * mu[2]),
        wk[o + (F_E + 2) * LANES] - 0.0,
    )
    # noise = R + (tau / Ts) P (deviation x) + d Sigma d^T (upper triangle)
    n00 = (wk[o + F_RC * LANES] + bias_fac * pj[0]) + e00
    n01 = (wk[o + (F_RC + 1) * LANES] + bias_fac * pj[1]) + e01
    n02 = (0.0 + bias_fac * pj[2]) + 0.0
    n11 = (wk[o + (F_RC + 2) * LANES] + bias_fac * pj[4]) + e11
    n12 = (0.0 + bias_fac * pj[5]) + 0.0
    n22 = (wk[o + (F_RC + 3) * LANES] + bias_fac * pj[8]) + 0.0
    # eq. (30) S = P + R + d Sigma d^T
    si = inv_sym(pj[0] + n00, pj[1] + n01, pj[2] + n02, pj[4] + n11, pj[5] + n12, pj[8] + n22)
    s_inv = (si[0], si[1], si[2], si[1], si[3], si[4], si[2], si[4], si[5])
    mb = quad(s_inv, resid)
    # deviation (v): Student-t total noise (eq. 35) as a scale mixture, E[precision scale |
    # resid] = (nu~ + n_e) / (nu~ + m); the noise covariance is divided by it
    inv_sc = (nu_t + mb) / (nu_t + 3.0)
    si = inv_sym(
        pj[0] + n00 * inv_sc, pj[1] + n01 * inv_sc, pj[2] + n02 * inv_sc,
        pj[4] + n11 * inv_sc, pj[5] + n12 * inv_sc, pj[8] + n22 * inv_sc,
    )  # fmt: skip
    s_inv = (si[0], si[1], si[2], si[1], si[3], si[4], si[2], si[4], si[5])
    # eq. (30) K = P S^-1
    kg = mm(pj, s_inv)
    # eq. (30) b_{k|k} = b_{k|k-1} + K (y - h - d mu - b_{k|k-1})
    kr_ = mv(kg, resid)
    wk[o + (F_B + 0) * LANES] = wk[o + (F_B + 0) * LANES] + kr_[0]
    wk[o + (F_B + 1) * LANES] = wk[o + (F_B + 1) * LANES] + kr_[1]
    wk[o + (F_B + 2) * LANES] = wk[o + (F_B + 2) * LANES] + kr_[2]
    # eq. (30) P_{k|k} = P - K S K^T  (= P - K P), symmetrized
    kp = mm(kg, pj)
    wk[o + (F_P + 0) * LANES] = 0.5 * ((pj[0] - kp[0]) + (pj[0] - kp[0]))
    wk[o + (F_P + 1) * LANES] = 0.5 * ((pj[1] - kp[1]) + (pj[3] - kp[3]))
    wk[o + (F_P + 2) * LANES] = 0.5 * ((pj[2] - kp[2]) + (pj[6] - kp[6]))
    wk[o + (F_P + 3) * LANES] = 0.5 * ((pj[4] - kp[4]) + (pj[4] - kp[4]))
    wk[o + (F_P + 4) * LANES] = 0.5 * ((pj[5] - kp[5]) + (pj[7] - kp[7]))
    wk[o + (F_P + 5) * LANES] = 0.5 * ((pj[8] - kp[8]) + (pj[8] - kp[8]))


@numba.njit(**_JIT)
def information_share(wk: F64, n: int, w_fac: float, freeze_cx: bool, weights: F64) -> float:
    """Weighted mean over particles of ``student_t.information_fraction``: ``B_i = Lambda_11
    d^T Lambda~_e^-1 d``, ``beta_i`` the mean of ``diag(B_i)`` over the learned components (Cx
    not while it is frozen)."""
    c0 = 0.0 if freeze_cx else 1.0
    n_c = c0 + 1.0 + 1.0
    total = 0.0
    for i in range(n):
        o = at(i)
        d6 = load6(wk, o, F_D)
        d = (*d6, 0.0, 0.0, 0.0)
        dt = (d[0], d[3], 0.0, d[1], d[4], 0.0, d[2], d[5], 0.0)
        v0, v1, v2, v3, v4, v5 = load6(wk, o, F_INV)
        inv = (v0, v1, v2, v1, v3, v4, v2, v4, v5)
        u = load6(wk, o, F_L)
        l11 = (
            w_fac * u[0], w_fac * u[1], w_fac * u[2], w_fac * u[1], w_fac * u[3],
            w_fac * u[4], w_fac * u[2], w_fac * u[4], w_fac * u[5],
        )  # fmt: skip
        bm = mm(mm(mm(l11, dt), inv), d)
        tr = c0 * bm[0] + 1.0 * bm[4] + 1.0 * bm[8]
        total += weights[i] * (tr / n_c)
    return total


@numba.njit(**_JIT)
def systematic(weights: F64, u0: float, idx: IDX) -> None:
    """``resampling.systematic`` with the uniform ``u0``: ``idx[i]`` the first ``j`` with
    ``cumsum(weights)[j] > (i + u0) / N`` (the last sum taken as 1)."""
    n = weights.shape[0]
    j = 0
    cum = weights[0] if n > 1 else 1.0
    for i in range(n):
        u = (i + u0) / n
        while j < n - 1 and cum <= u:
            j += 1
            cum = cum + weights[j] if j < n - 1 else 1.0
        idx[i] = j


def model_constants(
    p: SingleTrackParams,
    r_diag: F64,
    wheel_speed_std_m_s: float,
    speed_var: float,
    lower: F64,
    upper: F64,
) -> F64:
    """The constants vector of :func:`update` (``C_*`` positions): the single-track parameters
    ``p``, ``R``'s diagonal (3,), the wheel-speed noise carried into ``y`` (m/s), the measured
    speed's variance and the projection bounds of ``w`` (3,) each."""
    c = np.zeros(N_CONSTANTS)
    tyre = TYRE_LINEAR
    if p.saturation_slip_front_rad > 0.0 or p.saturation_slip_rear_rad > 0.0:
        tyre = TYRE_MAGIC if p.tyre_shape == "magic_formula" else TYRE_TANH
    c[[C_MASS, C_IZ, C_LF, C_LR, C_PX, C_PY]] = (
        p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m, p.lr_m, p.imu_x_m, p.imu_y_m,
    )  # fmt: skip
    c[[C_CX, C_CYF, C_CYR]] = p.nominal
    c[[C_ROLL, C_DRAG, C_SATF, C_SATR]] = (
        p.rolling_resistance_n, p.drag_n_s2_m2, p.saturation_slip_front_rad,
        p.saturation_slip_rear_rad,
    )  # fmt: skip
    c[[C_SHAPE_C, C_CURV_E, C_TYRE]] = (p.magic_formula_shape_c, p.magic_formula_curvature_e, tyre)
    c[C_FRONT] = 1.0 if p.drive in ("front", "all") else 0.0
    c[C_REAR] = 1.0 if p.drive in ("rear", "all") else 0.0
    c[[C_R0, C_R1, C_R2]] = r_diag
    c[[C_WS_STD, C_SPEED_VAR, C_MIN_SPEED]] = (wheel_speed_std_m_s, speed_var, MIN_SPEED_M_S)
    c[[C_INV_MASS, C_INV_IZ]] = (1.0 / p.mass_kg, 1.0 / p.yaw_inertia_kg_m2)
    c[C_LO : C_LO + 3] = lower
    c[C_HI : C_HI + 3] = upper
    return c
