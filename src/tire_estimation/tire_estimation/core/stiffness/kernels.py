"""Compiled per-particle kernels of the stiffness MPF's IMU step (Numba, ``cache=True``).

Algorithm 1 of Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on
noise-adaptive particle filtering", IEEE TCST 2018, after the model has been linearized
(``stiffness_model.linearize``, eq. 9-12, stays NumPy) is three passes over the particles:

* :func:`predict_states` -- eq. (9) ``x_{k+1} = x_k + Ts (rate_n + a w_k)`` plus the optional
  state jitter (deviation iii of ``core.stiffness.mpf``) and eq. (29) ``P += Q Ts``;
* :func:`likelihood_weights` -- ``e_bar = y - h - b`` (eq. 12), the Student-t of
  Approximation 1 (eq. 35): ``mu_e = d mu``, ``Lambda~_e = (1+gamma)/nu~ d Lambda d^T +
  (nu~-2)/nu~ (R + P)``, its inverse and determinant by cofactors, the weights (36), their
  normalization, the predictive density ``p(y_k | y_1:k-1)``, ``N_eff`` and the weighted yaw-rate
  NIS of the bias gate;
* :func:`posterior_step` -- for each particle ``i`` with ancestor ``idx[i]`` (resampling,
  Algorithm 1 lines 8-10, is done by ``core.resampling`` in between): the conditional Student-t
  of ``w`` (eq. 39-41), one draw from it, the projection to the bounds (Sec. V), the NiW update
  (eq. 19, Remark 3), the optional Cx freeze (deviation vi), the Student-t-weighted bias Kalman
  update (eq. 30, deviations ii and v) and the state derivative (eq. 9) for the next step.

Where the NumPy functions (``student_t.likelihood_params``, ``conditional_predictive``,
``sample_student_t``, ``bias_update``, ``niw.measurement_update``, ``freeze_component``) reads
one triangle of a symmetric matrix (the cofactor inverse the upper, the Cholesky factor the
lower), the kernels read the same one, and they keep its order of operations, so the results
equal the NumPy reference filter of the tests to rounding (tests/core/stiffness/reference_mpf.py,
test_kernels.py). Small matrices are
row-major 9-tuples (registers, no allocation per particle). The particle arrays keep the
filter's layout (``(N, 3)``, ``(N, 3, 3)``); ``gamma`` and ``nu`` of the NiW statistics are
shared scalars (``niw.init_stats(shared=True)``, as in the MPF).

Random numbers come from the caller's ``np.random.Generator`` in the reference's order (state
jitter normals ``(N, 3)`` in :func:`predict_states`; in :func:`posterior_step` the normals
``(N, 3)`` then the ``N`` gamma variates with one shared shape), so a seeded filter draws the
same numbers as the NumPy path.

Cost (2-core shared machine, N = 500 / 2000): :func:`predict_states` 29 / 85 µs,
:func:`likelihood_weights` 43 / 157 µs, :func:`posterior_step` 128 / 457 µs (a dozen 3x3
products, three cofactor inverses, one Cholesky factor, about 25 divisions, three normals and
one gamma variate per particle), i.e. about 0.3 µs per particle in all, plus about 10 µs per call
that takes the Generator (Numba unboxes it through ctypes). The NumPy reference needs about
150 NumPy calls and 1 µs per particle for the same steps.

The ``for i in range(n)`` loops below are compiled by Numba, not Python loops over particles:
the guide's rule "vectorize over particles" is about the cost per particle, which here is
about 0.3 µs against 1 µs for the vectorized NumPy reference (as in ``core/radius_kernels``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness import mat3

IDX = NDArray[np.intp]
#: a 3x3 matrix as a row-major 9-tuple (kept in registers by the compiler), a 3-vector as a 3-tuple
M3 = tuple[float, float, float, float, float, float, float, float, float]
V3 = tuple[float, float, float]


_JIT = {"cache": True, "error_model": "numpy", "inline": "always"}


@numba.njit(**_JIT)
def _ld(a: F64, f: float = 1.0) -> M3:
    """``f a`` of a (3, 3) array as a 9-tuple (``f`` multiplies each element, as ``f * a``)."""
    return (
        f * a[0, 0], f * a[0, 1], f * a[0, 2],
        f * a[1, 0], f * a[1, 1], f * a[1, 2],
        f * a[2, 0], f * a[2, 1], f * a[2, 2],
    )  # fmt: skip


@numba.njit(**_JIT)
def _st(out: F64, a: M3) -> None:
    """Store the 9-tuple ``a`` into the (3, 3) array ``out``."""
    for k in range(3):
        for m in range(3):
            out[k, m] = a[3 * k + m]


@numba.njit(**_JIT)
def _mm(a: M3, b: M3) -> M3:
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
def _tr(a: M3) -> M3:
    """``a^T``."""
    return (a[0], a[3], a[6], a[1], a[4], a[7], a[2], a[5], a[8])


@numba.njit(**_JIT)
def _mtm(a: M3, b: M3) -> M3:
    """``a^T @ b`` (the products and sums of ``_mm`` on the transpose: the same rounding)."""
    return _mm(_tr(a), b)


@numba.njit(**_JIT)
def _mmt_upper(a: M3, b: M3) -> M3:
    """Upper triangle of ``a @ b^T``, mirrored (for products that are symmetric)."""
    c00 = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    c01 = a[0] * b[3] + a[1] * b[4] + a[2] * b[5]
    c02 = a[0] * b[6] + a[1] * b[7] + a[2] * b[8]
    c11 = a[3] * b[3] + a[4] * b[4] + a[5] * b[5]
    c12 = a[3] * b[6] + a[4] * b[7] + a[5] * b[8]
    c22 = a[6] * b[6] + a[7] * b[7] + a[8] * b[8]
    return (c00, c01, c02, c01, c11, c12, c02, c12, c22)


@numba.njit(**_JIT)
def _mv(a: M3, v: V3) -> V3:
    """``a @ v``."""
    return (
        a[0] * v[0] + a[1] * v[1] + a[2] * v[2],
        a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
        a[6] * v[0] + a[7] * v[1] + a[8] * v[2],
    )


@numba.njit(**_JIT)
def _quad(a: M3, v: V3) -> float:
    """``v^T a v`` (as ``student_t.mahalanobis``: ``sum_k v_k (a v)_k``)."""
    av = _mv(a, v)
    return v[0] * av[0] + v[1] * av[1] + v[2] * av[2]


#: ``mat3.sym_cofactors`` compiled (the same expressions in the same order)
_sym_cofactors = numba.njit(**_JIT)(mat3.sym_cofactors)


@numba.njit(**_JIT)
def _inv_sym(a: M3) -> tuple[M3, float]:
    """Inverse and determinant of a symmetric 3x3 by cofactors (``mat3.inv_sym``).

    Reads only the upper triangle of ``a``.
    """
    c00, c01, c02, c11, c12, c22, det = _sym_cofactors(a[0], a[1], a[2], a[4], a[5], a[8])
    # a^-1 = C^T / det
    inv_det = 1.0 / det
    i01 = c01 * inv_det
    i02 = c02 * inv_det
    i12 = c12 * inv_det
    return (c00 * inv_det, i01, i02, i01, c11 * inv_det, i12, i02, i12, c22 * inv_det), det


@numba.njit(**_JIT)
def _clip(v: float, lo: float, hi: float) -> float:
    """``np.clip`` of a scalar (a NaN stays NaN)."""
    if v < lo:
        return lo
    if v > hi:
        return hi
    return v


@numba.njit(cache=True, error_model="numpy")
def predict_states(
    x: F64, rate: F64, p_bias: F64, q_dt: F64, dt_s: float, jitter: F64, rng: np.random.Generator
) -> None:
    """Time update of the sampled states and the bias covariance, in place.

    ``x += dt rate`` (eq. 9, ``rate = rate_n + a w_k`` stored by :func:`posterior_step`), then
    ``x += N(0, diag(jitter^2) dt)`` when any ``jitter`` (3,) > 0 (normals ``(N, 3)`` drawn in C
    order), ``vX >= 0``, and ``P += q_dt`` (eq. 29, ``q_dt`` (3, 3) = ``Q Ts``).
    """
    n = x.shape[0]
    # eq. (9) x_{k+1} = f + g w_k = x_k + Ts (rate_n + a w_k)
    for i in range(n):
        for k in range(3):
            x[i, k] += dt_s * rate[i, k]
    if jitter[0] > 0.0 or jitter[1] > 0.0 or jitter[2] > 0.0:
        sd0 = jitter[0] * math.sqrt(dt_s)
        sd1 = jitter[1] * math.sqrt(dt_s)
        sd2 = jitter[2] * math.sqrt(dt_s)
        for i in range(n):
            # deviation (iii): random walk on the states for particle diversity
            x[i, 0] += rng.standard_normal() * sd0
            x[i, 1] += rng.standard_normal() * sd1
            x[i, 2] += rng.standard_normal() * sd2
    for i in range(n):
        # vX >= 0 (np.maximum: a NaN stays NaN)
        if x[i, 0] < 0.0:
            x[i, 0] = 0.0
        # eq. (29) P_{k+1} = P_k + Q Ts
        for k in range(3):
            for j in range(3):
                p_bias[i, k, j] += q_dt[k, j]


@numba.njit(cache=True, error_model="numpy")
def likelihood_weights(
    y: F64,
    h: F64,
    b: F64,
    d: F64,
    mean: F64,
    scale: F64,
    r_cov: F64,
    p_bias: F64,
    gamma: float,
    nu: float,
    log_const: float,
    weights: F64,
    log_w: F64,
) -> tuple[F64, F64, F64, F64, F64, F64, float, float, float]:
    """Weights of eq. (36) and what the conditional predictive (40-41) reuses, one pass.

    Args:
        y: IMU measurement (3,).
        h: measurement mean with nominal stiffness, (N, 3); ``d`` its gain of ``w``, (N, 3, 3).
        b: predicted bias, (N, 3); ``p_bias`` its covariance, (N, 3, 3).
        mean, scale: NiW statistics ``mu`` (N, 3) and ``Lambda`` (N, 3, 3) after eq. (20).
        r_cov: measurement-noise covariance ``R``, (N, 3, 3).
        gamma, nu: shared NiW ``gamma`` and ``nu`` after eq. (20).
        log_const: ``lgamma((nu~+3)/2) - lgamma(nu~/2) - 3/2 log(nu~ pi)`` of eq. (35).
        weights: normalized weights before this step (the yaw-rate NIS average), (N,).
        log_w: log weights, (N,); the log likelihood (36) is added in place.

    Returns:
        ``(e_bar, z, shape_inv, logdet, maha, w_new, nis, log_pred, n_eff)``: ``e_bar = y - h -
        b`` (N, 3); ``z = e_bar - d mu`` (N, 3); ``Lambda~_e^-1`` (N, 3, 3); ``log det
        Lambda~_e`` (N,); ``z^T Lambda~_e^-1 z`` (N,); the normalized weights (N,) (uniform if
        no log weight is finite); the weighted mean normalized squared yaw-rate innovation;
        ``log sum exp(log_w)`` (``-inf`` if none is finite); ``N_eff = 1 / sum w^2``.
    """
    n = h.shape[0]
    # eq. (21) nu~ = nu - d + 1; Lambda_11 = (1 + gamma) / nu~ Lambda
    nu_t = nu - 3.0 + 1.0
    w_fac = (1.0 + gamma) / nu_t
    rp_fac = (nu_t - 2.0) / nu_t
    e_bar = np.empty((n, 3))
    z = np.empty((n, 3))
    shape_inv = np.empty((n, 3, 3))
    logdet = np.empty(n)
    maha = np.empty(n)
    nis = 0.0
    any_finite = False
    m_max = -np.inf
    for i in range(n):
        di = _ld(d[i])
        # eq. (12) e_bar = y - h - b_{k|k-1}
        e = (y[0] - h[i, 0] - b[i, 0], y[1] - h[i, 1] - b[i, 1], y[2] - h[i, 2] - b[i, 2])
        # eq. (35) mu_e = d mu_{k|k-1}; z = e_bar - mu_e
        loc = _mv(di, (mean[i, 0], mean[i, 1], mean[i, 2]))
        zi = (e[0] - loc[0], e[1] - loc[1], e[2] - loc[2])
        # eq. (35) Lambda~_e = (1+gamma)/nu~ d Lambda d^T + (nu~ - 2)/nu~ (R + P)
        dwd = _mmt_upper(_mm(di, _ld(scale[i], w_fac)), di)
        rp = _ld(r_cov[i])
        pb = _ld(p_bias[i])
        shape = (
            dwd[0] + rp_fac * (rp[0] + pb[0]), dwd[1] + rp_fac * (rp[1] + pb[1]),
            dwd[2] + rp_fac * (rp[2] + pb[2]), 0.0, dwd[4] + rp_fac * (rp[4] + pb[4]),
            dwd[5] + rp_fac * (rp[5] + pb[5]), 0.0, 0.0, dwd[8] + rp_fac * (rp[8] + pb[8]),
        )  # fmt: skip
        inv, det = _inv_sym(shape)
        m = _quad(inv, zi)
        ld = math.log(det)
        for k in range(3):
            e_bar[i, k] = e[k]
            z[i, k] = zi[k]
        _st(shape_inv[i], inv)
        logdet[i] = ld
        maha[i] = m
        # yaw-rate NIS (bias gate): Student-t variance Lambda~_e,rr nu~ / (nu~ - 2)
        var = shape[8] * nu_t / (nu_t - 2.0)
        nis += weights[i] * (zi[2] * zi[2] / var)
        # eq. (36) q_k ∝ q_{k-1} St(e_bar; mu_e, Lambda~_e, nu~) (log density of eq. 35)
        log_w[i] += log_const - 0.5 * ld - 0.5 * (nu_t + 3.0) * math.log1p(m / nu_t)
        if np.isfinite(log_w[i]):
            any_finite = True
            m_max = max(m_max, log_w[i])
    # Algorithm 1 lines 6-7: normalize (non-finite log weights get weight 0), N_eff
    w_new = np.empty(n)
    if not any_finite:
        w_new[:] = 1.0 / n
        return e_bar, z, shape_inv, logdet, maha, w_new, nis, -np.inf, float(n)
    s = 0.0
    for i in range(n):
        w_new[i] = math.exp(log_w[i] - m_max) if np.isfinite(log_w[i]) else 0.0
        s += w_new[i]
    sq = 0.0
    for i in range(n):
        w_new[i] /= s
        sq += w_new[i] * w_new[i]
    return e_bar, z, shape_inv, logdet, maha, w_new, nis, m_max + math.log(s), 1.0 / sq


@numba.njit(cache=True, error_model="numpy")
def information_fraction(
    d: F64, scale: F64, shape_inv: F64, w_fac: float, components: F64, weights: F64
) -> float:
    """Weighted mean over particles of ``student_t.information_fraction``, one pass.

    ``B_i = Lambda_11 d^T Lambda~_e^-1 d`` with ``Lambda_11 = w_fac Lambda`` (eq. 21, ``w_fac =
    (1 + gamma) / nu~``), ``shape_inv`` from :func:`likelihood_weights`; ``beta_i`` the mean of
    ``diag(B_i)`` over ``components`` (3,) (1 learned, 0 not); returns ``sum_i weights_i
    beta_i``.
    """
    n = d.shape[0]
    n_c = components[0] + components[1] + components[2]
    total = 0.0
    for i in range(n):
        di = _ld(d[i])
        bm = _mm(_mm(_mm(_ld(scale[i], w_fac), _tr(di)), _ld(shape_inv[i])), di)
        tr = components[0] * bm[0] + components[1] * bm[4] + components[2] * bm[8]
        total += weights[i] * (tr / n_c)
    return total


@numba.njit(cache=True, error_model="numpy")
def posterior_step(
    idx: IDX,
    x: F64,
    b: F64,
    p_bias: F64,
    mean: F64,
    scale: F64,
    gamma: float,
    nu: float,
    d: F64,
    a: F64,
    rate_n: F64,
    r_cov: F64,
    e_bar: F64,
    z: F64,
    shape_inv: F64,
    maha: F64,
    lower: F64,
    upper: F64,
    learn: bool,
    freeze_mean0: F64,
    freeze_scale00: F64,
    bias_on: bool,
    mean_gains: F64,
    rng: np.random.Generator,
) -> tuple[F64, F64, F64, F64, F64, F64, F64]:
    """Algorithm 1 lines 4, 15, 17-18 for the particles ``idx`` (ancestors after resampling).

    Particle ``i`` of the result continues old particle ``idx[i]`` (the identity without
    resampling); the inputs are the arrays before resampling (``e_bar``, ``z``, ``shape_inv``,
    ``maha`` from :func:`likelihood_weights`; ``d``, ``a``, ``rate_n`` from the linearization;
    ``r_cov`` (N, 3, 3)), ``gamma`` and ``nu`` the shared NiW values after eq. (20).

    ``learn`` applies the NiW update (19) (the caller updates the shared ``gamma``, ``nu``);
    ``freeze_mean0`` / ``freeze_scale00`` (N,) non-empty keep the Cx part as
    ``student_t.freeze_component`` (particle ``i`` with ancestor ``j`` gets the mean
    ``freeze_mean0[j]`` and variance ``freeze_scale00[j]``, already scaled by the ratio of
    ``nu - 4``); ``bias_on`` runs the bias
    update (30). ``mean_gains`` (2,) non-empty ``(g_loc, g_w)`` replaces the mean update of eq.
    (19) by ``mu += g_loc (loc - mu) + g_w (w - loc)`` (``loc`` the conditional mean of eq. 41;
    ``student_t.niw_mean_gains``); empty is eq. (19).

    Returns new arrays ``(x, b, p_bias, rate, mean, scale, w)``: ``rate = rate_n + a w`` for
    eq. (9) of the next step, ``w`` (N, 3) the sampled stiffness deviation after projection.
    """
    n = idx.shape[0]
    # eq. (21) nu~ = nu - d + 1; Lambda_11 = (1 + gamma) / nu~ Lambda
    nu_t = nu - 3.0 + 1.0
    w_fac = (1.0 + gamma) / nu_t
    # eq. (41) nu_{1|2} = nu~ + n_e
    dof_c = nu_t + 3.0
    # draws in the reference's order: all normals (N, 3), then N chi2 = 2 Gamma(nu_{1|2} / 2)
    zs = np.empty((n, 3))
    for i in range(n):
        for k in range(3):
            zs[i, k] = rng.standard_normal()
    chi2 = np.empty(n)
    for i in range(n):
        chi2[i] = 2.0 * rng.standard_gamma(0.5 * dof_c)
    # eq. (19) NiW update: c = 1 / (1 + gamma), gamma_{k|k} = gamma c, nu_{k|k} = nu + 1
    c_niw = 1.0 / (1.0 + gamma)
    g_new = gamma * c_niw
    nu_post = nu + 1.0 if learn else nu
    # eq. (27b) Sigma_{k|k} = Lambda / (nu - d - 1)
    nu_s = nu_post - 3.0 - 1.0
    freeze = freeze_mean0.shape[0] > 0
    split = mean_gains.shape[0] > 0
    g_loc = mean_gains[0] if split else 0.0
    g_w = mean_gains[1] if split else 0.0
    x_o = np.empty((n, 3))
    b_o = np.empty((n, 3))
    p_o = np.empty((n, 3, 3))
    rate_o = np.empty((n, 3))
    mean_o = np.empty((n, 3))
    scale_o = np.empty((n, 3, 3))
    w_o = np.empty((n, 3))
    for i in range(n):
        j = idx[i]
        dj = _ld(d[j])
        zj = (z[j, 0], z[j, 1], z[j, 2])
        mu = (mean[j, 0], mean[j, 1], mean[j, 2])
        lam = _ld(scale[j])
        l11 = _ld(scale[j], w_fac)
        # eq. (41) Lambda_21 = d Lambda_11 (joint of w and e_bar = d w + e)
        l21 = _mm(dj, l11)
        # gain Lambda_12 Lambda_22^-1 = Lambda_21^T Lambda~_e^-1
        gain = _mtm(l21, _ld(shape_inv[j]))
        # eq. (41) mu_{1|2} = mu_1 + Lambda_12 Lambda_22^-1 (e_bar - mu_e)
        gz = _mv(gain, zj)
        loc = (mu[0] + gz[0], mu[1] + gz[1], mu[2] + gz[2])
        # eq. (41) Lambda_{1|2} = (nu~ + z^T L22^-1 z)/(nu~ + n_e) (L11 - L12 L22^-1 L21),
        # symmetrized; only the lower triangle is factored below
        f = (nu_t + maha[j]) / dof_c
        gl = _mm(gain, l21)
        c00 = f * (0.5 * ((l11[0] - gl[0]) + (l11[0] - gl[0])))
        c10 = f * (0.5 * ((l11[3] - gl[3]) + (l11[1] - gl[1])))
        c11 = f * (0.5 * ((l11[4] - gl[4]) + (l11[4] - gl[4])))
        c20 = f * (0.5 * ((l11[6] - gl[6]) + (l11[2] - gl[2])))
        c21 = f * (0.5 * ((l11[7] - gl[7]) + (l11[5] - gl[5])))
        c22 = f * (0.5 * ((l11[8] - gl[8]) + (l11[8] - gl[8])))
        # eq. (39) w ~ St(mu_{1|2}, Lambda_{1|2}, nu_{1|2}): a relative 1e-9 ridge keeps the
        # factor of a (numerically) singular shape finite; closed-form lower Cholesky factor
        ridge = 1e-9 * (c00 + c11 + c22)
        l00 = math.sqrt(c00 + ridge)
        l10 = c10 / l00
        l20 = c20 / l00
        l11v = math.sqrt((c11 + ridge) - l10 * l10)
        l21v = (c21 - l20 * l10) / l11v
        l22 = math.sqrt((c22 + ridge) - l20 * l20 - l21v * l21v)
        z0, z1, z2 = zs[i, 0], zs[i, 1], zs[i, 2]
        st = math.sqrt(dof_c / chi2[i])
        # w = mu_{1|2} + chol z sqrt(nu_{1|2} / chi2); Sec. V projection to physical bounds
        w0 = _clip(loc[0] + (l00 * z0 + 0.0 * z1 + 0.0 * z2) * st, lower[0], upper[0])
        w1 = _clip(loc[1] + (l10 * z0 + l11v * z1 + 0.0 * z2) * st, lower[1], upper[1])
        w2 = _clip(loc[2] + (l20 * z0 + l21v * z1 + l22 * z2) * st, lower[2], upper[2])
        w = (w0, w1, w2)
        if learn:
            # eq. (19) with w_bar = w_k (Remark 3): Lambda += c (w - mu)(w - mu)^T,
            # mu += gamma_{k|k} (w - mu), projected to the bounds
            dw = (w0 - mu[0], w1 - mu[1], w2 - mu[2])
            lam = (
                lam[0] + c_niw * (dw[0] * dw[0]), lam[1] + c_niw * (dw[0] * dw[1]),
                lam[2] + c_niw * (dw[0] * dw[2]), lam[3] + c_niw * (dw[1] * dw[0]),
                lam[4] + c_niw * (dw[1] * dw[1]), lam[5] + c_niw * (dw[1] * dw[2]),
                lam[6] + c_niw * (dw[2] * dw[0]), lam[7] + c_niw * (dw[2] * dw[1]),
                lam[8] + c_niw * (dw[2] * dw[2]),
            )  # fmt: skip
            if split:
                # niw_update rao_blackwellized: mu += g_loc (loc - mu) + g_w (w - loc)
                mu = (
                    _clip(mu[0] + (g_loc * (loc[0] - mu[0]) + g_w * (w0 - loc[0])), lower[0],
                          upper[0]),
                    _clip(mu[1] + (g_loc * (loc[1] - mu[1]) + g_w * (w1 - loc[1])), lower[1],
                          upper[1]),
                    _clip(mu[2] + (g_loc * (loc[2] - mu[2]) + g_w * (w2 - loc[2])), lower[2],
                          upper[2]),
                )  # fmt: skip
            else:
                mu = (
                    _clip(mu[0] + g_new * dw[0], lower[0], upper[0]),
                    _clip(mu[1] + g_new * dw[1], lower[1], upper[1]),
                    _clip(mu[2] + g_new * dw[2], lower[2], upper[2]),
                )
            if freeze:
                # deviation (vi): Cx mean and E[Sigma_00] (eq. 27b) as before this step, of the
                # particle's ancestor j (the statistics before resampling)
                mu = (freeze_mean0[j], mu[1], mu[2])
                lam = (freeze_scale00[j], 0.0, 0.0, 0.0, lam[4], lam[5], 0.0, lam[7], lam[8])
        pj = _ld(p_bias[j])
        if bias_on:
            # line 15: eq. (30) with mu_{k|k} and Sigma_{k|k}: extra = d Sigma d^T
            sigma = (
                lam[0] / nu_s, lam[1] / nu_s, lam[2] / nu_s,
                lam[3] / nu_s, lam[4] / nu_s, lam[5] / nu_s,
                lam[6] / nu_s, lam[7] / nu_s, lam[8] / nu_s,
            )  # fmt: skip
            extra = _mmt_upper(_mm(dj, sigma), dj)
            # resid = y - h - d mu_{k|k} - b_{k|k-1}
            dmu = _mv(dj, mu)
            resid = (e_bar[j, 0] - dmu[0], e_bar[j, 1] - dmu[1], e_bar[j, 2] - dmu[2])
            rj = _ld(r_cov[j])
            noise = (
                rj[0] + extra[0], rj[1] + extra[1], rj[2] + extra[2],
                rj[3] + extra[3], rj[4] + extra[4], rj[5] + extra[5],
                rj[6] + extra[6], rj[7] + extra[7], rj[8] + extra[8],
            )  # fmt: skip
            # eq. (30) S = P + R + d Sigma d^T
            s_inv, _ = _inv_sym(
                (
                    pj[0] + noise[0], pj[1] + noise[1], pj[2] + noise[2],
                    0.0, pj[4] + noise[4], pj[5] + noise[5],
                    0.0, 0.0, pj[8] + noise[8],
                )
            )  # fmt: skip
            mb = _quad(s_inv, resid)
            # deviation (v): Student-t total noise (eq. 35) as a scale mixture, E[precision
            # scale | resid] = (nu~ + n_e) / (nu~ + m); the noise covariance is divided by it
            sc = (nu_t + 3.0) / (nu_t + mb)
            s_inv, _ = _inv_sym(
                (
                    pj[0] + noise[0] / sc, pj[1] + noise[1] / sc, pj[2] + noise[2] / sc,
                    0.0, pj[4] + noise[4] / sc, pj[5] + noise[5] / sc,
                    0.0, 0.0, pj[8] + noise[8] / sc,
                )
            )  # fmt: skip
            # eq. (30) K = P S^-1
            kg = _mm(pj, s_inv)
            # eq. (30) b_{k|k} = b_{k|k-1} + K (y - h - d mu - b_{k|k-1})
            kr = _mv(kg, resid)
            for k in range(3):
                b_o[i, k] = b[j, k] + kr[k]
            # eq. (30) P_{k|k} = P - K S K^T  (= P - K P), symmetrized
            kp = _mm(kg, pj)
            for k in range(3):
                for m in range(3):
                    p_o[i, k, m] = 0.5 * (
                        (pj[3 * k + m] - kp[3 * k + m]) + (pj[3 * m + k] - kp[3 * m + k])
                    )
        else:
            for k in range(3):
                b_o[i, k] = b[j, k]
            _st(p_o[i], pj)
        # line 18 (first half): derivative for eq. (9), rate = rate_n + a w_k
        aw = _mv(_ld(a[j]), w)
        for k in range(3):
            x_o[i, k] = x[j, k]
            rate_o[i, k] = rate_n[j, k] + aw[k]
            mean_o[i, k] = mu[k]
            w_o[i, k] = w[k]
        _st(scale_o[i], lam)
    return x_o, b_o, p_o, rate_o, mean_o, scale_o, w_o
