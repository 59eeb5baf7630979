"""Compiled IMU step of the stiffness MPF (Numba, ``cache=True``): two calls per IMU sample.

Algorithm 1 of Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on
noise-adaptive particle filtering", IEEE TCST 2018, with ``state_proposal`` = ``prior``:

* :func:`predict` -- eq. (9) ``x_{k+1} = x_k + Ts (rate_n + a w_k)``, the state jitter
  (deviation iii of ``core.stiffness.mpf``), ``vX >= 0``, eq. (29) ``P += Q Ts`` and, while the
  stiffness is learned, the NiW prediction (20) (``Lambda *= lambda``, ``gamma /= lambda``,
  ``nu *= lambda``), keeping ``Lambda_00`` before it for the Cx freeze (deviation vi);
* :func:`update` -- the model at each particle (eq. 1-12: ``model.linearize``,
  ``model.kinematic_speed_row``, ``model.measurement_cov``), ``e_bar = y - h - b`` and the
  Student-t of Approximation 1 (eq. 35): ``mu_e = d mu``, ``Lambda~_e = (1+gamma)/nu~ d Lambda
  d^T + (nu~-2)/nu~ (R + P)`` with its inverse and determinant by cofactors, the weights (36)
  and the weighted yaw-rate NIS of the bias gate (deviation v); the normalization, ``N_eff``
  and the predictive density (lines 6-7), the information share ``beta`` of ``niw_update`` =
  ``rao_blackwellized``, systematic resampling (lines 8-10); then for each particle, from its
  ancestor: the conditional Student-t of ``w`` (eq. 39-41), one draw, the projection to the
  bounds (Sec. V), the NiW update (eq. 19, Remark 3, or the split mean update), the Cx freeze,
  the Student-t-weighted bias update (eq. 30, deviations ii, v and x) and the state derivative
  (eq. 9) for the next step;
* :func:`estimate` -- the weighted estimates (27) and (42) in one pass.

The per-particle algebra reads the same triangles of symmetric matrices as the NumPy functions
of ``core.stiffness.model`` and ``core.stiffness.student_t`` and keeps their order of
operations, up to divisions by constants taken as products with their reciprocals; the zero row
of ``d`` (the gyro row carries no ``d w``, eq. 12) is skipped (its products are exact zeros).
The NumPy reference filter of the tests (tests/core/stiffness/reference_mpf.py,
test_kernels.py) equals it to rounding.

Layout: :func:`update` packs the particles into a scratch in blocks of :data:`LANES` (each
field of a block contiguous), so that its arithmetic passes (the model and the likelihood, the
conditional draw and the NiW update, the bias update) loop over the lanes of one array at
offsets known to the compiler and run in SIMD registers, 8 particles at a time; the random
draws, the logarithms of the weights, the resampling and the copies in and out run particle by
particle. A loop over particles that reads and writes several arrays is not vectorized (the
compiler cannot rule out that they overlap), nor is one whose body holds another loop.

Random numbers: each call that draws takes four raw words of the caller's
``np.random.Generator`` (``bit_generator.random_raw(4)``, the words of
:func:`~tire_estimation.core.kernel_random.kernel_state`) and draws with
:mod:`~tire_estimation.core.kernel_random`: in :func:`predict` three normals per particle (the
jitter, if any); in :func:`update` one uniform (if it resamples), then per particle three
normals and one ``Gamma(nu_{1|2} / 2)``.

The loops are compiled, not Python loops over particles: the guide's rule "vectorize over
particles" is about the cost per particle (about 0.1 µs here, the NumPy reference about 1 µs).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from tire_estimation.core import kernel_random as kr
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.kernel_passes import (
    C_CURV_E,
    C_SHAPE_C,
    C_TYRE,
    F_A,
    F_AF,
    F_AR,
    F_B,
    F_CHI2,
    F_D,
    F_DET,
    F_E,
    F_FL00,
    F_FM0,
    F_INV,
    F_L,
    F_MAHA,
    F_MU,
    F_N,
    F_P,
    F_R,
    F_RATE,
    F_RC,
    F_VX,
    F_VY,
    F_Z,
    FIELDS,
    IDX,
    LANES,
    NIW_RAO_BLACKWELLIZED,
    NIW_SAMPLED,
    TYRE_LINEAR,
    U64,
    at,
    information_share,
    inv_sym,
    maximum,
    model_constants,
    noise_cov,
    particle_model,
    posterior,
    scalars,
    scratch_size,
    seeded,
    slip_function,
    systematic,
)

__all__ = [
    "NIW_RAO_BLACKWELLIZED",
    "NIW_SAMPLED",
    "estimate",
    "model_constants",
    "predict",
    "scratch_size",
    "update",
]


@numba.njit(cache=True, error_model="numpy")
def predict(
    x: F64,
    rate: F64,
    p_bias: F64,
    q_rate: F64,
    dt_s: float,
    jitter: F64,
    words: U64,
    scale: F64,
    gamma: F64,
    dof: F64,
    learn: bool,
    forgetting: float,
    scale00_before: F64,
) -> None:
    """Time update to the next IMU sample, in place.

    ``x += dt rate`` (eq. 9, ``rate = rate_n + a w_k`` stored by :func:`update`), then ``x +=
    N(0, diag(jitter^2) dt)`` when any ``jitter`` (3,) > 0 (three normals per particle from
    ``words``), ``vX >= 0``, ``P += q_rate dt`` (eq. 29, ``q_rate`` (3, 3) = ``Q`` per second).
    ``learn``: eq. (20) with the factor ``forgetting`` on the NiW statistics, ``scale`` (N, 3,
    3) and the shared 0-d ``gamma`` and ``dof``; a non-empty ``scale00_before`` (N,) receives
    ``Lambda_00`` before it (the Cx freeze, deviation vi).
    """
    n = x.shape[0]
    if jitter[0] > 0.0 or jitter[1] > 0.0 or jitter[2] > 0.0:
        st = seeded(words)
        sd0 = jitter[0] * math.sqrt(dt_s)
        sd1 = jitter[1] * math.sqrt(dt_s)
        sd2 = jitter[2] * math.sqrt(dt_s)
        for i in range(n):
            # eq. (9) x_{k+1} = x_k + Ts (rate_n + a w_k); deviation (iii) random walk
            z0, st = kr.normal(st)
            z1, st = kr.normal(st)
            z2, st = kr.normal(st)
            x[i, 0] = (x[i, 0] + dt_s * rate[i, 0]) + z0 * sd0
            x[i, 1] = (x[i, 1] + dt_s * rate[i, 1]) + z1 * sd1
            x[i, 2] = (x[i, 2] + dt_s * rate[i, 2]) + z2 * sd2
    else:
        for i in range(n):
            for k in range(3):
                x[i, k] += dt_s * rate[i, k]
    q = (
        q_rate[0, 0] * dt_s, q_rate[0, 1] * dt_s, q_rate[0, 2] * dt_s,
        q_rate[1, 0] * dt_s, q_rate[1, 1] * dt_s, q_rate[1, 2] * dt_s,
        q_rate[2, 0] * dt_s, q_rate[2, 1] * dt_s, q_rate[2, 2] * dt_s,
    )  # fmt: skip
    for i in range(n):
        # vX >= 0 (np.maximum: a NaN stays NaN)
        if x[i, 0] < 0.0:
            x[i, 0] = 0.0
        # eq. (29) P_{k+1} = P_k + Q Ts
        for k in range(3):
            for j in range(3):
                p_bias[i, k, j] += q[3 * k + j]
    if learn:
        save = scale00_before.shape[0] > 0
        for i in range(n):
            if save:
                scale00_before[i] = scale[i, 0, 0]
            # eq. (20) lambda Lambda
            for k in range(3):
                for j in range(3):
                    scale[i, k, j] *= forgetting
        # eq. (20) gamma / lambda, lambda nu
        gamma[()] = gamma[()] / forgetting
        dof[()] = dof[()] * forgetting


@numba.njit(cache=True, error_model="numpy")
def update(
    x: F64,
    b: F64,
    p_bias: F64,
    rate: F64,
    mean: F64,
    scale: F64,
    gamma: F64,
    dof: F64,
    weights: F64,
    log_w: F64,
    work: F64,
    work2: F64,
    idx: IDX,
    c: F64,
    y: F64,
    cd: float,
    sd: float,
    delta: float,
    wf: float,
    wr: float,
    vx_meas: float,
    learn: bool,
    freeze_ratio: float,
    scale00_before: F64,
    niw_mode: int,
    gamma_cap: float,
    nis_mean: float,
    nis_rate: float,
    nis_max: float,
    bias_fac: float,
    resample_threshold: float,
    words: U64,
) -> tuple[float, float, bool, float, bool, float, float]:
    """Measurement part of Algorithm 1 at one IMU sample, in place (see the module doc).

    Args:
        x, b, p_bias, rate: states (N, 3), IMU bias (N, 3), its covariance (N, 3, 3), the state
            derivative (N, 3) for the next :func:`predict`.
        mean, scale, gamma, dof: NiW statistics ``mu`` (N, 3), ``Lambda`` (N, 3, 3) after eq.
            (20) and the shared 0-d ``gamma``, ``nu``.
        weights, log_w: normalized weights (N,) and their logs, before -> after this step.
        work, work2, idx: scratch (:func:`scratch_size`,) twice and (N,) (the ancestors).
        c: :func:`model_constants`.
        y: IMU measurement [ax, ay, r], (3,).
        cd, sd, delta: cos and sin of the road-wheel angle, the angle, rad.
        wf, wr: (front, rear) axle mean ``R_w omega``, m/s.
        vx_meas: a measured speed (deviation vii), or NaN (wheel speeds).
        learn: the NiW update (19) runs (activation, Sec. V).
        freeze_ratio: > 0 keeps Cx as before this step (deviation vi): ``Lambda_00`` becomes
            ``scale00_before`` (N,) of the ancestor times this ratio of ``nu - 4``.
        niw_mode, gamma_cap: ``niw_update`` (:data:`NIW_SAMPLED` or
            :data:`NIW_RAO_BLACKWELLIZED`) and the cap of ``gamma`` of the latter.
        nis_mean, nis_rate, nis_max: the exponential mean of the yaw-rate NIS, the weight of
            this step's NIS in it and the level at most which the bias update (30) runs while
            learning (deviation v).
        bias_fac: ``tau / Ts`` of deviation (x) (0: eq. 30 as printed).
        resample_threshold: resample when ``N_eff`` is at most this share of ``N``.
        words: four raw words of the caller's generator.

    Returns:
        ``(log_pred, n_eff, resampled, beta, bias_on, nis, nis_mean)``: ``log p(y_k |
        y_1:k-1)`` (``-inf`` if no log weight is finite), ``N_eff`` before resampling, whether it
        resampled, the information share of ``rao_blackwellized`` (0 otherwise), whether eq.
        (30) ran, the weighted yaw-rate NIS and its new exponential mean.
    """
    n = x.shape[0]
    n_blocks = -(-n // LANES)
    kinematic = vx_meas == vx_meas
    k = scalars(c)
    tyre = c[C_TYRE]
    # eq. (21) nu~ = nu - d + 1; Lambda_11 = (1 + gamma) / nu~ Lambda
    g0 = gamma[()]
    nu = dof[()]
    nu_t = nu - 3.0 + 1.0
    w_fac = (1.0 + g0) / nu_t
    rp_fac = (nu_t - 2.0) / nu_t
    inv_nu_t = 1.0 / nu_t
    # the constant of the log density of eq. (35)
    log_const = (
        math.lgamma(0.5 * (nu_t + 3.0)) - math.lgamma(0.5 * nu_t) - 1.5 * math.log(nu_t * math.pi)
    )
    y0 = vx_meas if kinematic else y[0]
    y1, y2, ax = y[1], y[2], y[0]
    lf, lr, min_speed = k[0], k[1], k[6]
    wk = work
    # pack the particles into the block layout (the padding lanes repeat particle 0)
    for i in range(n_blocks * LANES):
        s = i if i < n else 0
        o = at(i)
        if kinematic:
            # the ax bias is not a measurement offset of the speed row: not estimated
            b[s, 0] = 0.0
            for m in range(3):
                p_bias[s, 0, m] = 0.0
                p_bias[s, m, 0] = 0.0
        wk[o + F_VX * LANES] = x[s, 0]
        wk[o + F_VY * LANES] = x[s, 1]
        wk[o + F_R * LANES] = x[s, 2]
        for m in range(3):
            wk[o + (F_B + m) * LANES] = b[s, m]
            wk[o + (F_MU + m) * LANES] = mean[s, m]
        for m, (r_, c_) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
            wk[o + (F_P + m) * LANES] = p_bias[s, r_, c_]
            wk[o + (F_L + m) * LANES] = scale[s, r_, c_]
    # eq. (4) slip angles
    for blk in range(n_blocks):
        base = blk * (FIELDS * LANES)
        for ln in range(LANES):
            o = base + ln
            vx, vy, r = wk[o + F_VX * LANES], wk[o + F_VY * LANES], wk[o + F_R * LANES]
            inv_vx = 1.0 / maximum(vx, min_speed)
            wk[o + F_AF * LANES] = delta - (vy + lf * r) * inv_vx
            wk[o + F_AR * LANES] = (lr * r - vy) * inv_vx
    if tyre != TYRE_LINEAR:
        # the saturating tyre phi(alpha) with alpha_s = mu Fz / C at C = C_n + mu
        # (model.saturation_slip_at, lateral_slip_function)
        cyf, cyr, shape_c, curv_e = k[8], k[9], c[C_SHAPE_C], c[C_CURV_E]
        for i in range(n):
            o = at(i)
            mu1, mu2 = wk[o + (F_MU + 1) * LANES], wk[o + (F_MU + 2) * LANES]
            sat_f = k[19] * cyf / maximum(cyf + mu1, 0.01 * cyf)
            sat_r = k[20] * cyr / maximum(cyr + mu2, 0.01 * cyr)
            af, ar = wk[o + F_AF * LANES], wk[o + F_AR * LANES]
            wk[o + F_AF * LANES] = slip_function(af, sat_f, tyre, shape_c, curv_e)
            wk[o + F_AR * LANES] = slip_function(ar, sat_r, tyre, shape_c, curv_e)
    # eq. (1)-(12), eq. (35): the model, R, e_bar, mu_e and Lambda~_e with its inverse
    for blk in range(n_blocks):
        base = blk * (FIELDS * LANES)
        for ln in range(LANES):
            o = base + ln
            vx, vy, r = wk[o + F_VX * LANES], wk[o + F_VY * LANES], wk[o + F_R * LANES]
            mu0 = wk[o + F_MU * LANES]
            mu1 = wk[o + (F_MU + 1) * LANES]
            mu2 = wk[o + (F_MU + 2) * LANES]
            a, rate_n, h, d = particle_model(
                k, vx, vy, r, wk[o + F_AF * LANES], wk[o + F_AR * LANES], cd, sd, wf, wr,
                kinematic, ax,
            )  # fmt: skip
            r00, r01, r11, r22 = noise_cov(k, vx, cd, sd, wf, wr, kinematic, k[7] + mu0)
            # eq. (12) e_bar = y - h - b_{k|k-1}
            e0 = y0 - h[0] - wk[o + F_B * LANES]
            e1 = y1 - h[1] - wk[o + (F_B + 1) * LANES]
            e2 = y2 - h[2] - wk[o + (F_B + 2) * LANES]
            # eq. (35) mu_e = d mu_{k|k-1}; z = e_bar - mu_e (row 2 of d is zero)
            z0 = e0 - (d[0] * mu0 + d[1] * mu1 + d[2] * mu2)
            z1 = e1 - (d[3] * mu0 + d[4] * mu1 + d[5] * mu2)
            # eq. (35) Lambda~_e = (1+gamma)/nu~ d Lambda d^T + (nu~ - 2)/nu~ (R + P)
            l00 = w_fac * wk[o + F_L * LANES]
            l01 = w_fac * wk[o + (F_L + 1) * LANES]
            l02 = w_fac * wk[o + (F_L + 2) * LANES]
            l11 = w_fac * wk[o + (F_L + 3) * LANES]
            l12 = w_fac * wk[o + (F_L + 4) * LANES]
            l22 = w_fac * wk[o + (F_L + 5) * LANES]
            dl00 = d[0] * l00 + d[1] * l01 + d[2] * l02
            dl01 = d[0] * l01 + d[1] * l11 + d[2] * l12
            dl02 = d[0] * l02 + d[1] * l12 + d[2] * l22
            dl10 = d[3] * l00 + d[4] * l01 + d[5] * l02
            dl11 = d[3] * l01 + d[4] * l11 + d[5] * l12
            dl12 = d[3] * l02 + d[4] * l12 + d[5] * l22
            p00, p01 = wk[o + F_P * LANES], wk[o + (F_P + 1) * LANES]
            p02, p11 = wk[o + (F_P + 2) * LANES], wk[o + (F_P + 3) * LANES]
            p12, p22 = wk[o + (F_P + 4) * LANES], wk[o + (F_P + 5) * LANES]
            s00 = (dl00 * d[0] + dl01 * d[1] + dl02 * d[2]) + rp_fac * (r00 + p00)
            s01 = (dl00 * d[3] + dl01 * d[4] + dl02 * d[5]) + rp_fac * (r01 + p01)
            s11 = (dl10 * d[3] + dl11 * d[4] + dl12 * d[5]) + rp_fac * (r11 + p11)
            s02 = 0.0 + rp_fac * (0.0 + p02)
            s12 = 0.0 + rp_fac * (0.0 + p12)
            s22 = 0.0 + rp_fac * (r22 + p22)
            inv = inv_sym(s00, s01, s02, s11, s12, s22)
            q0 = inv[0] * z0 + inv[1] * z1 + inv[2] * e2
            q1 = inv[1] * z0 + inv[3] * z1 + inv[4] * e2
            q2 = inv[2] * z0 + inv[4] * z1 + inv[5] * e2
            wk[o + F_MAHA * LANES] = z0 * q0 + z1 * q1 + e2 * q2
            wk[o + F_DET * LANES] = inv[6]
            wk[o + (F_D + 0) * LANES] = d[0]
            wk[o + (F_D + 1) * LANES] = d[1]
            wk[o + (F_D + 2) * LANES] = d[2]
            wk[o + (F_D + 3) * LANES] = d[3]
            wk[o + (F_D + 4) * LANES] = d[4]
            wk[o + (F_D + 5) * LANES] = d[5]
            wk[o + (F_INV + 0) * LANES] = inv[0]
            wk[o + (F_INV + 1) * LANES] = inv[1]
            wk[o + (F_INV + 2) * LANES] = inv[2]
            wk[o + (F_INV + 3) * LANES] = inv[3]
            wk[o + (F_INV + 4) * LANES] = inv[4]
            wk[o + (F_INV + 5) * LANES] = inv[5]
            wk[o + (F_A + 0) * LANES] = a[0]
            wk[o + (F_A + 1) * LANES] = a[1]
            wk[o + (F_A + 2) * LANES] = a[2]
            wk[o + (F_A + 3) * LANES] = a[3]
            wk[o + (F_A + 4) * LANES] = a[4]
            wk[o + (F_A + 5) * LANES] = a[5]
            wk[o + (F_A + 6) * LANES] = a[6]
            wk[o + (F_A + 7) * LANES] = a[7]
            wk[o + (F_A + 8) * LANES] = a[8]
            wk[o + (F_RATE + 0) * LANES] = rate_n[0]
            wk[o + (F_RATE + 1) * LANES] = rate_n[1]
            wk[o + (F_RATE + 2) * LANES] = rate_n[2]
            wk[o + F_E * LANES] = e0
            wk[o + (F_E + 1) * LANES] = e1
            wk[o + (F_E + 2) * LANES] = e2
            wk[o + F_Z * LANES] = z0
            wk[o + (F_Z + 1) * LANES] = z1
            wk[o + F_RC * LANES] = r00
            wk[o + (F_RC + 1) * LANES] = r01
            wk[o + (F_RC + 2) * LANES] = r11
            wk[o + (F_RC + 3) * LANES] = r22
    # eq. (36) q_k ∝ q_{k-1} St(e_bar; mu_e, Lambda~_e, nu~) (log density of eq. 35) and the
    # yaw-rate NIS of the bias gate (Student-t variance Lambda~_e,rr nu~ / (nu~ - 2) = R + P)
    nis = 0.0
    any_finite = False
    m_max = -np.inf
    for i in range(n):
        o = at(i)
        e2 = wk[o + (F_E + 2) * LANES]
        var = wk[o + (F_RC + 3) * LANES] + wk[o + (F_P + 5) * LANES]
        nis += weights[i] * (e2 * e2 / var)
        lw = log_w[i] + (
            log_const
            - 0.5 * math.log(wk[o + F_DET * LANES])
            - 0.5 * (nu_t + 3.0) * math.log1p(wk[o + F_MAHA * LANES] * inv_nu_t)
        )
        log_w[i] = lw
        if np.isfinite(lw):
            any_finite = True
            m_max = max(m_max, lw)
    # deviation (v): exponential mean of the yaw-rate NIS, the gate of the bias update (30)
    nis_mean += nis_rate * (nis - nis_mean)
    bias_on = (not learn) or nis_mean <= nis_max
    # Algorithm 1 lines 6-7: normalize (non-finite log weights get weight 0), N_eff
    if not any_finite:
        log_pred = -np.inf
        for i in range(n):
            weights[i] = 1.0 / n
        n_eff = float(n)
    else:
        s_w = 0.0
        for i in range(n):
            weights[i] = math.exp(log_w[i] - m_max) if np.isfinite(log_w[i]) else 0.0
            s_w += weights[i]
        sq = 0.0
        inv_s = 1.0 / s_w
        for i in range(n):
            weights[i] *= inv_s
            sq += weights[i] * weights[i]
        log_pred = m_max + math.log(s_w)
        n_eff = 1.0 / sq
    # niw_update: the NiW mean gains (student_t.niw_mean_gains)
    c_niw = 1.0 / (1.0 + g0)
    k_niw = g0 * c_niw
    g_loc = k_niw
    g_w = k_niw
    g_new = k_niw
    beta = 0.0
    if learn and niw_mode == NIW_RAO_BLACKWELLIZED:
        beta = information_share(wk, n, w_fac, freeze_ratio > 0.0, weights)
        g_loc = g0 / (1.0 + g0)
        g_w = g_loc * beta
        g_new = min(g_loc + (1.0 - beta * beta) * g0 * g_loc * (1.0 - beta), gamma_cap)
    st = seeded(words)
    # lines 8-10: systematic resampling (resampling.systematic), weights reset; the ancestors'
    # fields are copied to the second scratch
    resampled = n_eff <= resample_threshold * n
    src = wk
    if resampled:
        u0, st = kr.uniform(st)
        systematic(weights, u0, idx)
        log_u = math.log(1.0 / n)
        for i in range(n):
            weights[i] = 1.0 / n
            log_w[i] = log_u
        src = work2
        for i in range(n_blocks * LANES):
            o, oj = at(i), at(idx[i] if i < n else idx[0])
            for f in range(F_N):
                src[o + f * LANES] = wk[oj + f * LANES]
    else:
        # log of the normalized weights (a non-finite one: weight 0)
        for i in range(n):
            idx[i] = i
            log_w[i] = log_w[i] - log_pred if np.isfinite(log_w[i]) else -np.inf
    # line 17 draws: three normals and chi2(nu_{1|2}) = 2 Gamma(nu_{1|2} / 2) per particle;
    # the Cx freeze's mean and Lambda_00 of the ancestor
    dof_c = nu_t + 3.0
    for i in range(n_blocks * LANES):
        o = at(i)
        if i < n:
            for m in range(3):
                src[o + (F_N + m) * LANES], st = kr.normal(st)
            g, st = kr.gamma(st, 0.5 * dof_c)
            src[o + F_CHI2 * LANES] = 2.0 * g
            src[o + F_FM0 * LANES] = mean[idx[i], 0]
            src[o + F_FL00 * LANES] = (
                scale00_before[idx[i]] * freeze_ratio if freeze_ratio > 0.0 else 0.0
            )
        else:
            for m in range(3):
                src[o + (F_N + m) * LANES] = 0.0
            src[o + F_CHI2 * LANES] = dof_c
            src[o + F_FM0 * LANES] = 0.0
            src[o + F_FL00 * LANES] = 0.0
    kr.store(words, st)
    posterior(
        src, n_blocks, w_fac, nu_t, dof_c, learn, freeze_ratio > 0.0, niw_mode, c_niw, g_loc,
        g_w, g_new, c, nu + 1.0 if learn else nu, bias_on, bias_fac,
    )  # fmt: skip
    # unpack the particles
    for i in range(n):
        o = at(i)
        if resampled:
            x[i, 0], x[i, 1], x[i, 2] = (
                src[o + F_VX * LANES],
                src[o + F_VY * LANES],
                src[o + F_R * LANES],
            )
        for m in range(3):
            b[i, m] = src[o + (F_B + m) * LANES]
            mean[i, m] = src[o + (F_MU + m) * LANES]
            rate[i, m] = src[o + (F_RATE + m) * LANES]
        for m, (r_, c_) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
            pv = src[o + (F_P + m) * LANES]
            lv = src[o + (F_L + m) * LANES]
            p_bias[i, r_, c_] = pv
            p_bias[i, c_, r_] = pv
            scale[i, r_, c_] = lv
            scale[i, c_, r_] = lv
    if learn:
        # eq. (19) shared scalars: gamma_{k|k} (capped with rao_blackwellized), nu_{k|k} = nu + 1
        gamma[()] = g0 * c_niw if niw_mode == NIW_SAMPLED else g_new
        dof[()] = nu + 1.0
    return log_pred, n_eff, resampled, beta, bias_on, nis, nis_mean


@numba.njit(cache=True, error_model="numpy")
def estimate(
    weights: F64,
    mean: F64,
    scale: F64,
    x: F64,
    b: F64,
    gamma: float,
    nu: float,
    nominal: F64,
    out: F64,
) -> None:
    """Weighted estimates of eq. (27) and (42) into ``out`` (24,): the stiffness ``C_n +
    mu_hat`` (3, eq. 7, 27a), the square root of the diagonal of ``Sigma_hat`` (3, eq. 27b) and
    of the covariance of the mean (3), the state mean (3, eq. 42), its covariance (9,
    row-major), the mean bias (3)."""
    n = weights.shape[0]
    mu = np.zeros(3)
    for k in range(24):
        out[k] = 0.0
    for i in range(n):
        q = weights[i]
        for k in range(3):
            mu[k] += q * mean[i, k]
            out[9 + k] += q * x[i, k]
            out[21 + k] += q * b[i, k]
    # E[Sigma_i] = Lambda_i / (nu - d - 1); the mean's covariance gamma E[Sigma_i]
    f_sigma = 1.0 / (nu - 3.0 - 1.0)
    for i in range(n):
        q = weights[i]
        for k in range(3):
            dev = mean[i, k] - mu[k]
            spread = q * dev * dev
            e_sigma = q * f_sigma * scale[i, k, k]
            out[3 + k] += e_sigma + spread
            out[6 + k] += gamma * e_sigma + spread
            dx = x[i, k] - out[9 + k]
            for m in range(3):
                out[12 + 3 * k + m] += q * dx * (x[i, m] - out[9 + m])
    for k in range(3):
        out[k] = nominal[k] + mu[k]
        out[3 + k] = math.sqrt(max(out[3 + k], 0.0))
        out[6 + k] = math.sqrt(max(out[6 + k], 0.0))
