"""Compiled per-particle kernels of the radius MPF's prediction (Numba, ``cache=True``).

The queued wheel-speed samples of :class:`~tire_estimation.core.radius.mpf.RadiusMPF` are
processed here as one block: per particle, one draw of ``(mu, Sigma)`` from its NiW statistics
(Bartlett decomposition), the radius errors of every sample of the block, the NiW recursion
(eq. 23-24 of Lundquist et al., T-ITS 2014) and the pose propagation (eq. 3, 6, 7, 31a), in one
pass over the particles. Why one draw of ``(mu, Sigma)`` per block samples the law of Table I is
explained in :meth:`RadiusMPF._draw_block`.

Shapes: ``N`` particles, ``k`` samples in the block. The NiW statistics are particle-last:
``mu`` (2, N), ``scale`` (2, 2, N); ``gamma`` and ``nu`` are shared scalars. Random numbers:
each kernel that draws takes ``state`` (4,) ``uint64`` from
:func:`~tire_estimation.core.kernel_random.kernel_state` of the caller's ``np.random.Generator``
and draws with :mod:`~tire_estimation.core.kernel_random` (a seeded generator gives reproducible
results; about 3 ns per normal against 9.4 ns through the ``Generator`` inside Numba).

These loops are compiled, not Python loops: the guide's rule "vectorize over particles" is about
the cost per particle, which here is a few tens of nanoseconds per sample.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import kernel_random as kr
from tire_estimation.core.arrays import F64

U64 = NDArray[np.uint64]


@numba.njit(cache=True, error_model="numpy", inline="always")
def _bartlett(
    a: float, b: float, c: float, lam: float, nu: float, st: kr.State
) -> tuple[float, float, float, kr.State]:
    """Square root ``S = M^-T`` of one ``Sigma ~ iW(nu, lam [[a, b], [b, c]])``.

    Bartlett: ``W = M M^T ~ Wishart(nu, Lambda^-1)``, ``M = chol(Lambda^-1) A``, ``A`` lower
    triangular with ``A_11^2 ~ chi2(nu)``, ``A_22^2 ~ chi2(nu - 1)``, ``A_21 ~ N(0, 1)``;
    ``Sigma = W^-1 = M^-T M^-1``. Returns ``(1 / M_11, 1 / M_22, M_21)``, from which
    ``S z = [(z_0 - M_21 z_1 / M_22) / M_11, z_1 / M_22]``, and the advanced random state.
    """
    det = (a * c - b * b) * lam * lam
    # chol(Lambda^-1) for Lambda = lam [[a, b], [b, c]]:
    # l11 = sqrt(c' / det'), l21 = -b' / sqrt(c' det'), l22 = 1 / sqrt(c')
    sc = math.sqrt(lam * c)
    sdet = math.sqrt(det)
    # chi2(n) = 2 Gamma(n / 2)
    g11, st = kr.gamma(st, 0.5 * nu)
    g22, st = kr.gamma(st, 0.5 * (nu - 1.0))
    z, st = kr.normal(st)
    a11 = math.sqrt(2.0 * g11)
    a22 = math.sqrt(2.0 * g22)
    inv_m11 = sdet / (sc * a11)
    inv_m22 = sc / a22
    m21 = -(lam * b) * a11 / (sc * sdet) + z / sc
    return inv_m11, inv_m22, m21, st


@numba.njit(cache=True, error_model="numpy")
def block_gains(k: int, lam: float, gamma: float, nu: float) -> tuple[F64, F64, float, float]:
    """Shared scalar gains of ``k`` NiW steps: ``c_j = 1 / (1 + gamma_{j|j-1})`` (k,),
    ``g_j = gamma_{j|j}`` (k,), and the final ``gamma`` and ``nu``."""
    c = np.empty(k)
    g = np.empty(k)
    for j in range(k):
        # eq. (24a) gamma_{j|j-1} = gamma / lambda; eq. (23a) gamma_{j|j} = gp / (1 + gp)
        gp = gamma / lam
        c[j] = 1.0 / (1.0 + gp)
        gamma = gp * c[j]
        g[j] = gamma
        # eq. (24c) + (23c) nu = lambda nu + 1
        nu = lam * nu + 1.0
    return c, g, gamma, nu


@numba.njit(cache=True, error_model="numpy")
def draw_block(
    mu: F64, scale: F64, lam: float, gamma: float, nu: float, k: int, state: U64
) -> tuple[F64, F64]:
    """Radius errors ``(d_rl, d_rr)``, each ``(k, N)``, of the next ``k`` learning steps.

    The draws of :func:`propagate_block` in the same order (for tests and diagnostics).
    """
    n = mu.shape[1]
    d3 = np.empty((k, n))
    d4 = np.empty((k, n))
    st = kr.load(state)
    # eq. (24a), (24c): statistics predicted to the first step of the block
    sg = math.sqrt(gamma / lam)
    nu_p = lam * nu
    for i in range(n):
        inv_m11, inv_m22, m21, st = _bartlett(scale[0, 0, i], scale[0, 1, i], scale[1, 1, i],
                                              lam, nu_p, st)  # fmt: skip
        # mu ~ N(mean, gamma Sigma), w_j ~ N(mu, Sigma): w_j = mean + S (sqrt(gamma) z + z_j)
        z1, st = kr.normal(st)
        z2, st = kr.normal(st)
        z1 *= sg
        z2 *= sg
        for j in range(k):
            x0, st = kr.normal(st)
            x1, st = kr.normal(st)
            u0 = z1 + x0
            u1 = z2 + x1
            e4 = u1 * inv_m22
            d3[j, i] = mu[0, i] + (u0 - m21 * e4) * inv_m11
            d4[j, i] = mu[1, i] + e4
    kr.store(state, st)
    return d3, d4


@numba.njit(cache=True, error_model="numpy")
def niw_block_update(
    mu: F64, scale: F64, d3: F64, d4: F64, lam: float, gamma: float, nu: float
) -> tuple[float, float]:
    """Eq. (24) + (23) applied to the samples ``(d3, d4)`` ``(k, N)`` in order, in place.

    Returns the new shared ``(gamma, nu)``.
    """
    k, n = d3.shape
    c, g, gamma_k, nu_k = block_gains(k, lam, gamma, nu)
    m0 = mu[0]
    m1 = mu[1]
    s00 = scale[0, 0]
    s01 = scale[0, 1]
    s11 = scale[1, 1]
    for j in range(k):
        cj = c[j]
        gj = g[j]
        for i in range(n):
            e3 = d3[j, i] - m0[i]
            e4 = d4[j, i] - m1[i]
            # eq. (24d) + (23d) Lambda = lambda Lambda + e e^T / (1 + gamma_{j|j-1})
            ce3 = cj * e3
            s00[i] = lam * s00[i] + ce3 * e3
            s01[i] = lam * s01[i] + ce3 * e4
            s11[i] = lam * s11[i] + cj * e4 * e4
            # eq. (23b) mean += gamma_{j|j} e
            m0[i] += gj * e3
            m1[i] += gj * e4
    scale[1, 0, :] = s01
    return gamma_k, nu_k


@numba.njit(cache=True, error_model="numpy")
def propagate_pose(
    east: F64,
    north: F64,
    yaw: F64,
    speed: F64,
    d3: F64,
    d4: F64,
    dt_s: F64,
    w_rl_rad_s: F64,
    w_rr_rad_s: F64,
    steer_rad: F64,
    radius_m: float,
    track_m: float,
    wheelbase_m: float,
) -> None:
    """Pose propagation (eq. 3) over ``k`` samples with the radius errors ``d3``, ``d4``
    ((k, N), or (1, N) for the same errors in every sample), in place.

    ``dt_s``, ``w_rl_rad_s``, ``w_rr_rad_s``, ``steer_rad`` (k,): interval length, rear wheel
    speeds at its start, steer angle (NaN = use the wheel-speed yaw rate). ``speed`` gets the
    speed of the last sample.
    """
    n = east.shape[0]
    k = dt_s.shape[0]
    per_sample = d3.shape[0] > 1
    cp = np.cos(yaw)
    sp = np.sin(yaw)
    ds = np.zeros(n)
    dpsi = np.empty(n)
    for j in range(k):
        jj = j if per_sample else 0
        w3 = w_rl_rad_s[j]
        w4 = w_rr_rad_s[j]
        h = 0.5 * dt_s[j]
        # eq. (6a)/(7a) v = r (w3 + w4) / 2 + (w3 d3 + w4 d4) / 2; ds = v dt = a + b3 d3 + b4 d4
        a = h * radius_m * (w3 + w4)
        b3 = h * w3
        b4 = h * w4
        st = steer_rad[j]
        if math.isnan(st):
            # eq. (6b)/(7c) yaw rate = r (w4 - w3) / l_T + (w4 d4 - w3 d3) / l_T
            q = dt_s[j] / track_m
            ya = q * radius_m * (w4 - w3)
            y3 = -q * w3
            y4 = q * w4
            t = 0.0
        else:
            # eq. (31a) low-speed heading from the steer angle: yaw rate = v tan(delta) / l_b
            ya = y3 = y4 = 0.0
            t = math.tan(st) / wheelbase_m
        big = 0.0
        for i in range(n):
            x3 = d3[jj, i]
            x4 = d4[jj, i]
            dsi = a + b3 * x3 + b4 * x4
            dp = ya + y3 * x3 + y4 * x4 + t * dsi
            ds[i] = dsi
            dpsi[i] = dp
            # eq. (3a)-(3c), zero-order hold over the interval
            east[i] += dsi * cp[i]
            north[i] += dsi * sp[i]
            yaw[i] += dp
            # (cos, sin) of the new heading by rotating with the Taylor series of cos dp and
            # sin dp to dp^4 and dp^5: exact to 3e-11 for |dp| < 0.05 (checked below)
            d2 = dp * dp
            cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0))
            sd = dp * (1.0 - d2 * ((1.0 / 6.0) - d2 * (1.0 / 120.0)))
            c0 = cp[i]
            cp[i] = c0 * cd - sp[i] * sd
            sp[i] = sp[i] * cd + c0 * sd
        for i in range(n):
            big = max(big, abs(dpsi[i]))
        if big >= 0.05:
            # a large heading step (low speed with steering, or a long interval): exact values
            for i in range(n):
                cp[i] = math.cos(yaw[i])
                sp[i] = math.sin(yaw[i])
    dt_last = dt_s[k - 1]
    inv = 1.0 / dt_last if dt_last > 0.0 else 0.0
    for i in range(n):
        speed[i] = ds[i] * inv


@numba.njit(cache=True, error_model="numpy")
def propagate_block(
    east: F64,
    north: F64,
    yaw: F64,
    speed: F64,
    mu: F64,
    scale: F64,
    dt_s: F64,
    w_rl_rad_s: F64,
    w_rr_rad_s: F64,
    steer_rad: F64,
    learn: bool,
    lam: float,
    gamma: float,
    nu: float,
    radius_m: float,
    track_m: float,
    wheelbase_m: float,
    state: U64,
) -> tuple[float, float]:
    """Propagate every particle over the ``k`` samples of a block, in place.

    ``learn=True``: Table I lines 9-11 and 13: radius errors drawn with :func:`draw_block`, NiW
    update with :func:`niw_block_update`, pose with :func:`propagate_pose`; ``learn=False``: the
    pose with each particle's mean radius error, statistics untouched. Returns the new shared
    ``(gamma, nu)``. Array arguments as in :func:`propagate_pose`.
    """
    k = dt_s.shape[0]
    if learn:
        d3, d4 = draw_block(mu, scale, lam, gamma, nu, k, state)
        gamma, nu = niw_block_update(mu, scale, d3, d4, lam, gamma, nu)
    else:
        d3 = mu[0:1].copy()
        d4 = mu[1:2].copy()
    propagate_pose(east, north, yaw, speed, d3, d4, dt_s, w_rl_rad_s, w_rr_rad_s, steer_rad,
                   radius_m, track_m, wheelbase_m)  # fmt: skip
    return gamma, nu


@numba.njit(cache=True, error_model="numpy")
def fix_predict(
    east: F64,
    north: F64,
    yaw: F64,
    speed: F64,
    mu: F64,
    weights: F64,
    pos_std_m: float,
    yaw_std_rad: float,
    mean_std_m: float,
    lever_x_m: float,
    lever_y_m: float,
    extrapolate_s: float,
    state: U64,
    bias: F64,
    bias_phi: float,
    with_bias: bool,
) -> tuple[F64, F64, F64]:
    """Pose noise since the last fix, then the predicted antenna positions and their moments.

    ``*_std_*``: std of the additive random walk accumulated since the last fix (east/north,
    yaw, NiW means; all zero: none is drawn), applied in place. Returns ``h`` (2, N) (eq. 13
    with the lever arm and the extrapolation to the fix time), the weighted mean (2,) and the
    weighted covariance (2, 2) of ``h``. With ``with_bias`` each particle's Gauss-Markov GNSS
    error mean ``bias`` (2, N) is first propagated in place (``b = phi b``) and added to its
    ``h`` (the fix model ``y = h(x) + b + v`` of ``RadiusMPF._bias_predict``).
    """
    n = east.shape[0]
    h = np.empty((2, n))
    jitter = pos_std_m > 0.0 or yaw_std_rad > 0.0 or mean_std_m > 0.0
    st = kr.load(state)
    m0 = 0.0
    m1 = 0.0
    for i in range(n):
        if jitter:
            # additive pose random walk (roughening); the NiW mean walk is beyond the paper
            z0, st = kr.normal(st)
            z1, st = kr.normal(st)
            z2, st = kr.normal(st)
            east[i] += pos_std_m * z0
            north[i] += pos_std_m * z1
            yaw[i] += yaw_std_rad * z2
            if mean_std_m > 0.0:
                z3, st = kr.normal(st)
                z4, st = kr.normal(st)
                mu[0, i] += mean_std_m * z3
                mu[1, i] += mean_std_m * z4
        c = math.cos(yaw[i])
        s = math.sin(yaw[i])
        lx = lever_x_m + extrapolate_s * speed[i]
        # eq. (13) h(x) = [x, y] of the antenna: base_link + R(psi) lever arm
        h[0, i] = east[i] + lx * c - lever_y_m * s
        h[1, i] = north[i] + lx * s + lever_y_m * c
        if with_bias:
            # Gauss-Markov GNSS error: b = phi b (time update), then y = h(x) + b + v
            bias[0, i] *= bias_phi
            bias[1, i] *= bias_phi
            h[0, i] += bias[0, i]
            h[1, i] += bias[1, i]
        m0 += weights[i] * h[0, i]
        m1 += weights[i] * h[1, i]
    c00 = 0.0
    c01 = 0.0
    c11 = 0.0
    for i in range(n):
        d0 = h[0, i] - m0
        d1 = h[1, i] - m1
        c00 += weights[i] * d0 * d0
        c01 += weights[i] * d0 * d1
        c11 += weights[i] * d1 * d1
    kr.store(state, st)
    mean = np.array([m0, m1])
    cov = np.array([[c00, c01], [c01, c11]])
    return h, mean, cov


@numba.njit(cache=True, error_model="numpy")
def bias_correct(
    bias: F64, h: F64, y0_m: float, y1_m: float, k00: float, k01: float, k10: float, k11: float
) -> None:
    """Measurement update of every particle's Gauss-Markov GNSS error mean, in place:
    ``b_i += K (y - h_i)`` with the shared gain ``K`` (2, 2) and ``h_i`` the predicted fix
    including ``b_i`` (Kalman filter update of ``RadiusMPF._bias_update``)."""
    for i in range(bias.shape[1]):
        d0 = y0_m - h[0, i]
        d1 = y1_m - h[1, i]
        bias[0, i] += k00 * d0 + k01 * d1
        bias[1, i] += k10 * d0 + k11 * d1


@numba.njit(cache=True, error_model="numpy")
def fix_reweight(
    weights: F64, h: F64, y0_m: float, y1_m: float, r00: float, r01: float, r11: float
) -> tuple[float, float]:
    """Eq. (18) ``w_k = w_{k-1} p(y_k | x_k)`` with the Gaussian GNSS likelihood (eq. 13c),
    then normalization (Table I line 15), in place.

    ``r..``: the fix covariance ``R`` (2, 2). Returns ``log sum_i w_{k-1,i} p(y_k | x_i)`` and
    the effective sample size ``1 / sum w_i^2``. Non-finite log weights get weight zero; if none
    is finite the weights become uniform and the log-likelihood is ``-inf``.
    """
    n = weights.shape[0]
    det = r00 * r11 - r01 * r01
    const = -0.5 * (2.0 * math.log(2.0 * math.pi) + math.log(det))
    logw = np.empty(n)
    top = -np.inf
    for i in range(n):
        d0 = y0_m - h[0, i]
        d1 = y1_m - h[1, i]
        # Mahalanobis distance with the closed-form inverse of R (2x2)
        maha = (r11 * d0 * d0 - 2.0 * r01 * d0 * d1 + r00 * d1 * d1) / det
        lw = math.log(weights[i]) - 0.5 * maha + const
        logw[i] = lw
        if math.isfinite(lw) and lw > top:
            top = lw
    return _normalize_log_weights(weights, logw, top)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _normalize_log_weights(weights: F64, logw: F64, top: float) -> tuple[float, float]:
    """``weights <- exp(logw - top) / sum`` in place (``top`` the largest finite ``logw``;
    non-finite entries get weight zero, none finite: uniform weights and ``-inf``). Returns
    ``log sum exp(logw)`` and the effective sample size ``1 / sum w_i^2`` (Table I line 15)."""
    n = weights.shape[0]
    if not math.isfinite(top):
        for i in range(n):
            weights[i] = 1.0 / n
        return -np.inf, float(n)
    total = 0.0
    for i in range(n):
        lw = logw[i]
        w = math.exp(lw - top) if math.isfinite(lw) else 0.0
        weights[i] = w
        total += w
    sq = 0.0
    for i in range(n):
        weights[i] /= total
        sq += weights[i] * weights[i]
    return top + math.log(total), 1.0 / sq


@numba.njit(cache=True, error_model="numpy")
def velocity_predict(
    yaw: F64,
    heading_offset_rad: float,
    mu: F64,
    scale: F64,
    weights: F64,
    v_virt: float,
    w3: float,
    w4: float,
    k_sigma: float,
    along_var: float,
    yaw_rate: float,
    lx: float,
    ly: float,
    q: float,
    r00: float,
    r01: float,
    r11: float,
    y0: float,
    y1: float,
    maha: F64,
    logdet: F64,
) -> tuple[float, float, float, float, float]:
    """Each particle's GNSS Doppler velocity likelihood (see ``RadiusMPF.update_velocity``).

    Per particle ``i``: speed ``v_i = v_virt + (w3 mu_3 + w4 mu_4) / 2`` (eq. 6a at the NiW
    mean), its variance ``p_i = k_sigma [w3, w4] Lambda_i [w3, w4]' + along_var``, the antenna
    velocity ``h_i = R(psi_i + offset) [v_i - r l_y, r l_x]`` and
    ``S_i = R + q n_i n_i' + p_i t_i t_i'``; writes ``maha[i] = d' S_i^-1 d`` for ``d = y - h_i``
    and ``logdet[i] = log det S_i`` (NaN when not positive). Returns the weighted mean of ``h``
    (2) and the cloud's innovation covariance ``sum w (h - m)(h - m)' + sum w S_i`` as
    ``(m0, m1, s00, s01, s11)``; ``weights`` sum to 1.
    """
    n = yaw.shape[0]
    h0 = np.empty(n)
    h1 = np.empty(n)
    m0 = 0.0
    m1 = 0.0
    sa00 = 0.0
    sa01 = 0.0
    sa11 = 0.0
    vby = yaw_rate * lx
    for i in range(n):
        psi = yaw[i] + heading_offset_rad
        c = math.cos(psi)
        s = math.sin(psi)
        # eq. (6a) with the NiW means
        v = v_virt + 0.5 * (w3 * mu[0, i] + w4 * mu[1, i])
        # E[Sigma] = Lambda / (nu - d - 1) (Ozkan et al. eq. 32), in k_sigma
        quad = w3 * w3 * scale[0, 0, i] + 2.0 * w3 * w4 * scale[0, 1, i]
        quad += w4 * w4 * scale[1, 1, i]
        p = k_sigma * quad + along_var
        vbx = v - yaw_rate * ly
        a = c * vbx - s * vby
        b = s * vbx + c * vby
        h0[i] = a
        h1[i] = b
        a00 = r00 + q * s * s + p * c * c
        a01 = r01 - q * s * c + p * c * s
        a11 = r11 + q * c * c + p * s * s
        det = a00 * a11 - a01 * a01
        d0 = y0 - a
        d1 = y1 - b
        maha[i] = (a11 * d0 * d0 - 2.0 * a01 * d0 * d1 + a00 * d1 * d1) / det
        logdet[i] = math.log(det) if det > 0.0 else np.nan
        wi = weights[i]
        m0 += wi * a
        m1 += wi * b
        sa00 += wi * a00
        sa01 += wi * a01
        sa11 += wi * a11
    s00 = 0.0
    s01 = 0.0
    s11 = 0.0
    for i in range(n):
        e0 = h0[i] - m0
        e1 = h1[i] - m1
        wi = weights[i]
        s00 += wi * e0 * e0
        s01 += wi * e0 * e1
        s11 += wi * e1 * e1
    return m0, m1, s00 + sa00, s01 + sa01, s11 + sa11


@numba.njit(cache=True, error_model="numpy")
def loglik_reweight(weights: F64, maha: F64, logdet: F64) -> tuple[float, float]:
    """``w_i <- w_i N(y; h_i, S_i)`` from the Mahalanobis distances and ``log det S_i`` of a
    2-D measurement, then normalization, in place (as :func:`fix_reweight`). Returns ``log sum
    w_i N_i`` and the effective sample size; non-finite log weights get weight zero, and if none
    is finite the weights become uniform and the log-likelihood is ``-inf``."""
    n = weights.shape[0]
    log_2pi = math.log(2.0 * math.pi)
    logw = np.empty(n)
    top = -np.inf
    for i in range(n):
        lw = math.log(weights[i]) - 0.5 * (maha[i] + logdet[i]) - log_2pi
        logw[i] = lw
        if math.isfinite(lw) and lw > top:
            top = lw
    return _normalize_log_weights(weights, logw, top)


@numba.njit(cache=True, error_model="numpy")
def moments(
    east: F64, north: F64, yaw: F64, mu: F64, scale: F64, weights: F64
) -> tuple[F64, F64, F64, F64, F64]:
    """Weighted summaries for the MMSE estimates (eq. 30).

    Returns the pose mean ``[east, north, yaw]`` (3,) with the circular mean of the yaw
    (wrapped to (-pi, pi]) and its covariance (3, 3) (headings unwrapped around the circular
    mean), the weighted mean of the NiW means (2,), their weighted spread (2, 2), and the weighted
    mean of the NiW scales (2, 2).
    """
    n = east.shape[0]
    two_pi = 2.0 * math.pi
    inv_two_pi = 1.0 / two_pi
    # circular mean atan2(sum w sin(psi), sum w cos(psi)), taken relative to the first
    # particle's heading: psi_i = ref + d_i, so it is ref + atan2(sum w sin d, sum w cos d);
    # for |d| < 0.05 rad (the whole cloud, usually) cos d and sin d are their Taylor series to
    # d^6 / d^5 (truncation below 1e-15 / 2e-13), otherwise exact
    ref = yaw[0]
    sc = 0.0
    ss = 0.0
    for i in range(n):
        d = yaw[i] - ref
        d -= two_pi * math.floor(d * inv_two_pi + 0.5)
        if abs(d) < 0.05:
            d2 = d * d
            cd = 1.0 - d2 * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0)))
            sd = d * (1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0)))
        else:
            cd = math.cos(d)
            sd = math.sin(d)
        sc += weights[i] * cd
        ss += weights[i] * sd
    yaw_c = ref + math.atan2(ss, sc)
    x = np.zeros(3)
    m = np.zeros(2)
    lw = np.zeros((2, 2))
    unwrapped = np.empty(n)
    for i in range(n):
        w = weights[i]
        # heading unwrapped into [yaw_c - pi, yaw_c + pi) (floor is cheaper than a modulo)
        dy = yaw[i] - yaw_c
        u = dy - two_pi * math.floor(dy * inv_two_pi + 0.5) + yaw_c
        unwrapped[i] = u
        x[0] += w * east[i]
        x[1] += w * north[i]
        x[2] += w * u
        m[0] += w * mu[0, i]
        m[1] += w * mu[1, i]
        lw[0, 0] += w * scale[0, 0, i]
        lw[0, 1] += w * scale[0, 1, i]
        lw[1, 1] += w * scale[1, 1, i]
    lw[1, 0] = lw[0, 1]
    cov = np.zeros((3, 3))
    spread = np.zeros((2, 2))
    d = np.empty(3)
    for i in range(n):
        w = weights[i]
        d[0] = east[i] - x[0]
        d[1] = north[i] - x[1]
        d[2] = unwrapped[i] - x[2]
        for a in range(3):
            for b in range(a, 3):
                cov[a, b] += w * d[a] * d[b]
        e0 = mu[0, i] - m[0]
        e1 = mu[1, i] - m[1]
        spread[0, 0] += w * e0 * e0
        spread[0, 1] += w * e0 * e1
        spread[1, 1] += w * e1 * e1
    for a in range(3):
        for b in range(a):
            cov[a, b] = cov[b, a]
    spread[1, 0] = spread[0, 1]
    x[2] = math.atan2(math.sin(x[2]), math.cos(x[2]))
    return x, cov, m, spread, lw
