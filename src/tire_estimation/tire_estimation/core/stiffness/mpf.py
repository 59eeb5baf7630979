"""Noise-adaptive marginalized particle filter with dependent noise and IMU bias.

Algorithm 1 of Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on
noise-adaptive particle filtering", IEEE TCST 2018 (eq. 19-20, 27, 29-30, 35-36, 39-41).

Per particle ``i`` (all arrays vectorized over ``N`` particles):

* state ``x`` (N, 3) = [vX, vY at the CG, yaw rate] (sampled),
* NiW statistics of the stiffness deviation ``w`` = [dCx, dCy_f, dCy_r] (eq. 8), d = 3
  (``core.niw``),
* IMU bias ``b`` (N, 3) = [b_ax, b_ay, b_r] with covariance ``P`` (N, 3, 3) (Kalman, eq. 29-30).

Step order at IMU sample ``k`` (after :meth:`StiffnessMpf.predict` to time k, which applies (9),
(20) and (29)): weights (36) -> normalize, N_eff, resample (lines 6-10) -> sample ``w_k`` from
the conditional predictive (39)-(41) -> NiW update (19) -> bias update (30) -> estimates (27,
42) -> store the state derivative for the prediction (9) of the next step.

Documented deviations from the printed paper: (i) eq. (40) is implemented as the conditional of
the joint Student-t of Approximation 1 per eq. (41) (dof ``nu~ + n_e``, gain ``L11 d^T L22^-1``),
the printed (40) mixes transposes and dofs; (ii) eq. (30) uses ``P - K S K^T`` (the printed
``K S^-1 K^T`` is dimensionally a typo); (iii) a small optional random walk ("jitter") on the
states keeps particle diversity when Sigma becomes small; (iv) the measurement noise ``R`` is
augmented by the wheel-speed noise that the slip (eq. 3) carries into ``y`` (the wheel speeds
are inputs ``u``); (v) the bias update (30) treats the total noise as the Student-t of
Approximation 1 (a residual far outside ``S`` barely moves the bias) and, while the stiffness
is learned, runs only while the particles' yaw rate plus bias agrees with the gyro
(:func:`yaw_rate_nis`, exponential mean below ``bias_gate_sigma^2``; the gyro row of ``d`` is
zero, so otherwise the per-particle bias filters absorb every yaw-rate model error, after which
the gyro no longer constrains the yaw rate and the filter diverges); it does not run within
``bias_hold_s`` of the initialization (the initial state and stiffness transient is not bias);
(vi) without longitudinal excitation the Cx part of the statistics is frozen
(:func:`freeze_component`); (vii) with a measured speed and no wheel speeds the slip (eq. 3),
hence the longitudinal tyre force, is unknown: by default (``measured_speed_model`` =
``kinematic``) the measured ax drives vX (eq. 1a as kinematics, ``dvX/dt = ax + vY r``) and the
speed replaces ax as measurement row 0 (``stiffness_model.kinematic_speed_row``); the ax bias
is then not estimated; (viii) optional saturating lateral tyre ``Fy = C alpha_s tanh(alpha /
alpha_s)`` (``friction_coefficient``, still affine in ``C``), by default with the peak at the
friction limit, ``alpha_s = mu Fz / C`` at each particle's stiffness mean (``saturation_peak``),
and with the tanh or, for a tyre whose curve is known, Pacejka's Magic Formula shape scaled to the
same stiffness and peak (``tyre_shape``);
(ix) optional, against the collapse of the particles onto a jointly scaled stiffness pair at
activation: the NiW mean and ``gamma`` updated with the measurement's information share of the
draw of ``w`` (``niw_update``, :func:`niw_mean_gains`), and a Liu & West (2001) shrinkage kernel
on the means after resampling (``rejuvenation_bandwidth``, :func:`rejuvenate_means`); (x) the
bias update (30) adds ``(tau / Ts) P`` to its noise (``bias_average_s`` = tau), which caps its
gain at ``Ts / (tau + Ts)``: right after the initialization (``P`` = ``P_0``) eq. (30) as printed
takes the particle's own start-up transient as bias within a few steps, after which the
yaw-rate gate of (v) keeps it; with the cap the bias is an average over about tau; (xi) by
default (``inactive_statistics`` = ``held``) the statistics of all particles are replaced by
their weighted moment match (:func:`niw.collapse`) when a learning phase ends, so that weighting
and resampling for the lateral state do not move the stiffness estimate while nothing is learned
(the paper runs Algorithm 1 only while the stiffness is observable, Sec. V); (xii) optional
(``propagation_draw_share`` h < 1, default 1 = eq. 9 as printed): the state is driven by ``loc
+ h (w_k - loc)`` instead of the draw ``w_k`` (:func:`propagated_draw`), ``loc`` its
conditional mean (41); the NiW update (19) still takes the draw. Experimental: it speeds up the
learning of the common stiffness scale on snow but takes away the state diversity that lets the
gyro correct the lateral state (docs/results.md section 6); (xiii) optional
(``inactive_propagation`` = ``mean``, default ``draw`` = eq. 9 as printed): while the stiffness
is not learned, eq. (9) takes each particle's NiW mean ``mu`` instead of the draw ``w_k``. The
stiffness is then a held parameter, not a fresh sample of the predictive ``(1 + gamma) Sigma``
at every step whose conditional mean explains each ay residual by a stiffness change.
Experimental (docs/results.md section 6).

Speed: :meth:`StiffnessMpf.predict` and :meth:`StiffnessMpf.update` run the per-particle algebra
after the linearization in the compiled kernels of :mod:`.stiffness_kernels` (three passes over
the particles per IMU step, the same random stream); the vectorized NumPy functions below
(:func:`likelihood_params`, :func:`conditional_predictive`, :func:`sample_student_t`,
:func:`bias_update`, ...) are the reference they are tested against, and run the filter when
``StiffnessMpf.compiled`` is False (and with ``state_proposal`` = ``measured``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw, resampling
from tire_estimation.core.stiffness import kernels as stiffness_kernels
from tire_estimation.core.stiffness import mat3
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.model import (
    Linearized,
    SingleTrackParams,
    kinematic_speed_row,
    linearize,
    saturation_slip_at,
    wheel_speed_gain,
)
from tire_estimation.core.stiffness.proposal import (
    marginal_maha_logdet,
    measured_state_proposal,
)

F64 = NDArray[np.float64]
#: Dimension of w (eq. 8) and of the measurement (n_e, eq. 12).
NW = 3
NE = 3


def bias_predict(p_bias: F64, q_cov: F64) -> None:
    """Kalman prediction of the random-walk bias (eq. 29), in place; ``p_bias`` (N, 3, 3)."""
    # eq. (29) b_{k+1|k} = b_{k|k}, P_{k+1} = P_k + Q
    p_bias += q_cov


def bias_update(
    b: F64,
    p_bias: F64,
    resid: F64,
    extra_cov: F64,
    r_cov: F64,
    dof: F64 | float | None = None,
) -> None:
    """Kalman measurement update of the bias (eq. 30), in place, vectorized over particles.

    Args:
        b: predicted bias b_{k|k-1}, (N, 3).
        p_bias: its covariance P_{k|k-1}, (N, 3, 3).
        resid: y - h - d mu_{k|k} - b_{k|k-1}, (N, 3).
        extra_cov: d Sigma_{k|k} d^T, (N, 3, 3).
        r_cov: measurement-noise covariance R, (3, 3) or (N, 3, 3).
        dof: degrees of freedom nu~ of the Student-t total noise (Approximation 1), scalar or
            (N,); ``None`` is the Gaussian update as printed. With ``dof`` the noise covariance
            ``R + d Sigma d^T`` of a particle is scaled by ``(nu~ + m) / (nu~ + n_e)``, ``m`` its
            squared Mahalanobis residual: the precision weight of a Student-t noise given the
            residual (one expectation step of the scale-mixture form), so that a residual far
            outside ``S`` (state or model error) does not move the bias.
    """
    p_s = mat3.soa(p_bias)
    noise_aos = r_cov + extra_cov
    if noise_aos.shape != p_bias.shape:
        noise_aos = np.broadcast_to(noise_aos, p_bias.shape)
    noise = mat3.soa(noise_aos)
    resid_s = mat3.soa(resid)
    # eq. (30) S = P + R + d Sigma d^T
    s = p_s + noise
    if dof is not None:
        s_inv, _ = mat3.inv_sym(s)
        maha = np.sum(resid_s * mat3.mv(s_inv, resid_s), axis=0)
        nu = np.asarray(dof, dtype=float)
        # Student-t noise (eq. 35) as a scale mixture: E[precision scale | resid] =
        # (nu + n_e) / (nu + m); the noise covariance is divided by it
        scale = (nu + NE) / (nu + maha)
        s = p_s + noise / scale
    s_inv, _ = mat3.inv_sym(s)
    # eq. (30) K = P S^-1
    k = mat3.mm(p_s, s_inv)
    # eq. (30) b_{k|k} = b_{k|k-1} + K (y - h - d mu - b_{k|k-1})
    b += mat3.aos(mat3.mv(k, resid_s))
    # eq. (30) P_{k|k} = P - K S K^T  (= P - K P)
    p_bias[...] = mat3.aos(mat3.sym(p_s - mat3.mm(k, p_s)))


@dataclass(frozen=True)
class LikelihoodParams:
    """Student-t of Approximation 1 for the total measurement noise e_bar (eq. 35-36).

    Attributes:
        loc: mu_e = d mu_{k|k-1}, (N, 3).
        shape: Lambda~_e = (1+gamma)/nu~ d Lambda d^T + (nu~-2)/nu~ (R + P), (N, 3, 3).
        w_shape: Lambda_11 = (1+gamma)/nu~ Lambda, the shape of the predictive of w, (N, 3, 3).
        dof: nu~ = nu_{k|k-1} - d + 1, scalar or (N,).
        shape_inv: Lambda~_e^-1, (N, 3, 3).
        logdet: log det Lambda~_e, (N,).
    """

    loc: F64
    shape: F64
    w_shape: F64
    dof: F64
    shape_inv: F64
    logdet: F64

    def take(self, idx: NDArray[np.intp]) -> LikelihoodParams:
        """The parameters of the particles ``idx`` (resampling)."""
        return LikelihoodParams(
            loc=self.loc[idx],
            shape=self.shape[idx],
            w_shape=self.w_shape[idx],
            dof=self.dof[idx] if np.ndim(self.dof) else self.dof,
            shape_inv=self.shape_inv[idx],
            logdet=self.logdet[idx],
        )


def likelihood_params(stats: niw.NiwStats, d: F64, r_cov: F64, p_bias: F64) -> LikelihoodParams:
    """Parameters of eq. (35) for every particle (see :class:`LikelihoodParams`).

    ``d`` (N, 3, 3), ``r_cov`` (3, 3) or (N, 3, 3), ``p_bias`` (N, 3, 3).
    """
    # eq. (21) nu~ = nu - d + 1 and Lambda_11 = (1 + gamma) Lambda / nu~
    dof = niw.predictive_dof(stats.dof, stats.d)
    w_shape = niw.predictive_shape(stats)
    # eq. (35) mu_e = d mu_{k|k-1}
    loc = np.einsum("nij,nj->ni", d, stats.mean)
    d_s = mat3.soa(d)
    # eq. (35) Lambda_e = (1+gamma)/nu~ d Lambda d^T + (nu~ - 2)/nu~ (R + P)
    rp = r_cov + p_bias
    if rp.shape != d.shape:
        rp = np.broadcast_to(rp, d.shape)
    shape = mat3.mm_bt(mat3.mm(d_s, mat3.soa(w_shape)), d_s) + (dof - 2.0) / dof * mat3.soa(rp)
    shape_inv, det = mat3.inv_sym(shape)
    return LikelihoodParams(
        loc=loc,
        shape=mat3.aos(shape),
        w_shape=w_shape,
        dof=dof,
        shape_inv=mat3.aos(shape_inv),
        logdet=np.log(det),
    )


def _maha(z: F64, inv: F64) -> F64:
    """``z_n^T inv_n z_n`` for (N, 3) and (N, 3, 3) -> (N,)."""
    return np.sum(z * np.einsum("nij,nj->ni", inv, z), axis=-1)


def log_likelihood(e_bar: F64, lp: LikelihoodParams) -> F64:
    """Log of St(e_bar; mu_e, Lambda_e, nu~) (eq. 35-36), (N, 3) -> (N,)."""
    # eq. (36) q_k ∝ q_{k-1} St(y; h + b + d mu, Lambda*, nu~)
    return niw.student_t_log_density(_maha(e_bar - lp.loc, lp.shape_inv), lp.logdet, lp.dof, NE)


def yaw_rate_nis(e_bar: F64, lp: LikelihoodParams, weights: F64) -> float:
    """Weighted mean normalized squared yaw-rate innovation of the predictive (35), 1.

    ``z_i = (e_bar_i - mu_e,i)_r / sqrt(var_i)`` with the Student-t variance ``var = Lambda~_e,rr
    nu~ / (nu~ - 2)`` (= ``R_rr + P_rr``: the gyro row of ``d`` is zero), averaged with the
    particle weights before this step's update. About 1 when the particles' predicted yaw rate
    plus bias matches the gyro; much larger when the model is wrong for every particle.
    """
    nu = np.asarray(lp.dof, dtype=float)
    var = lp.shape[:, 2, 2] * nu / (nu - 2.0)
    z2 = (e_bar[:, 2] - lp.loc[:, 2]) ** 2 / var
    return float(weights @ z2)


@dataclass(frozen=True)
class ConditionalPredictive:
    """Student-t of w_k given e_bar_k (eq. 39-41).

    Attributes:
        loc: mu* (N, 3).
        shape: Lambda* (N, 3, 3).
        dof: nu* scalar or (N,).
    """

    loc: F64
    shape: F64
    dof: F64


def conditional_predictive(
    stats: niw.NiwStats,
    d: F64,
    e_bar: F64,
    lp: LikelihoodParams,
    maha: F64 | None = None,
    n_meas: int = NE,
) -> ConditionalPredictive:
    """Conditional Student-t of ``w`` given the measurement (Theorem 1 via eq. 41).

    ``maha`` (N,): ``z^T Lambda~_e^-1 z`` with ``z = e_bar - mu_e`` when the caller has it
    already (the likelihood of eq. 36 needs the same); computed here otherwise. ``n_meas`` < 3
    conditions on the rows that carry ``d w`` only (``maha`` then of those rows; a row with no
    ``d w``, gyro or measured speed, does not move the gain: ``Lambda~_e`` is block diagonal).
    """
    # eq. (40) z = e_bar - mu_e
    z = e_bar - lp.loc
    l11 = mat3.soa(lp.w_shape)
    # eq. (41) Lambda_21 = d Lambda_11 (joint of w and e_bar = d w + e); Lambda_12 = Lambda_21^T
    l21 = mat3.mm(mat3.soa(d), l11)
    # gain Lambda_12 Lambda_22^-1 = Lambda_21^T Lambda_22^-1
    gain = np.einsum("kin,kln->iln", l21, mat3.soa(lp.shape_inv))
    if maha is None:
        maha = _maha(z, lp.shape_inv)
    nu = np.asarray(lp.dof, dtype=float)
    # eq. (41) nu_{1|2} = nu + d_2
    dof = nu + n_meas
    # eq. (41) mu_{1|2} = mu_1 + Lambda_12 Lambda_22^-1 (x_2 - mu_2)
    loc = stats.mean + mat3.aos(mat3.mv(gain, mat3.soa(z)))
    # eq. (41) Lambda_{1|2} = (nu + z^T L22^-1 z)/(nu + d_2) (L11 - L12 L22^-1 L12^T)
    shape = (nu + maha) / dof * mat3.sym(l11 - mat3.mm(gain, l21))
    return ConditionalPredictive(loc=loc, shape=mat3.aos(shape), dof=np.asarray(dof))


def sample_student_t(cp: ConditionalPredictive, rng: np.random.Generator) -> F64:
    """One draw per particle from St(loc, shape, dof) (eq. 39), (N, 3)."""
    n, dim = cp.loc.shape
    z = rng.standard_normal((n, dim))
    dof = np.asarray(cp.dof, dtype=float)
    # chi2(nu) = 2 Gamma(nu / 2); one shared nu takes NumPy's faster scalar-shape path (the
    # same stream as an array of equal shapes)
    half = 0.5 * dof
    chi2 = 2.0 * (
        rng.standard_gamma(float(half), size=n)
        if half.ndim == 0 or np.all(half == half.flat[0])
        else rng.standard_gamma(half)
    )
    shape = mat3.soa(cp.shape)
    # a relative 1e-9 ridge keeps the factorization of a (numerically) singular shape finite
    shape += (1e-9 * (shape[0, 0] + shape[1, 1] + shape[2, 2])) * np.eye(dim)[:, :, None]
    chol = mat3.aos(mat3.cholesky(shape))
    return niw.student_t_from_draws(cp.loc, chol, cp.dof, z, chi2)


def information_fraction(w_shape: F64, d: F64, shape_inv: F64, components: F64) -> F64:
    """Share ``beta`` of the predictive variance of ``w`` that one measurement explains, (N,).

    ``B = Lambda_11 d^T Lambda~_e^-1 d`` (the gain of eq. 41 times ``d``; ``w_shape`` =
    ``Lambda_11`` and ``shape_inv`` = ``Lambda~_e^-1`` of :class:`LikelihoodParams`, ``d`` (N, 3,
    3)): the conditional shape of ``w`` is ``(I - B) Lambda_11`` (eq. 41 without the Student-t
    factor), so the eigenvalues of ``B`` in [0, 1) are the variance shares the measurement
    removes. ``beta_i`` is the mean of the diagonal of ``B_i`` over ``components`` (3,) (1 for a
    learned component, 0 otherwise): ``tr`` of the removed share in the metric of ``Lambda``,
    per learned component.
    """
    b = np.einsum("nij,nkj,nkl,nlm->nim", w_shape, d, shape_inv, d)
    return np.einsum("nii,i->n", b, components) / float(np.sum(components))


def niw_mean_gains(gamma: float, beta: float, mode: str) -> tuple[float, float, float]:
    """Gains of the NiW mean update and the new ``gamma`` (``niw_update``; not in the paper).

    The mean moves by ``g_loc (loc - mu) + g_w (w - loc)``, ``loc`` the conditional mean of the
    draw ``w`` (eq. 41), ``Lambda`` and ``nu`` as eq. (19). Returns ``(g_loc, g_w, gamma_new)``.

    Derivation (Gaussian, ``S = E[Sigma]``, ``g = gamma``): with ``mu ~ N(m, g S)`` and ``w ~
    N(mu, S)`` the predictive of ``w`` is ``(1 + g) S`` and its conditional given the
    measurement ``P_w = (1 - beta)(1 + g) S`` (:func:`information_fraction`, trace-averaged).
    The exact posterior of ``mu`` given the measurement (``w`` integrated out) has the mean
    ``m + g / (1 + g) (loc - m)`` and the variance ``[g / (1 + g) + g^2 (1 - beta) / (1 + g)]
    S`` (Kalman update of ``mu``; the gain of ``mu`` is ``g / (1 + g)`` times that of ``w``).

    * ``sampled`` (eq. 19, Remark 3): ``g_loc = g_w = g / (1 + g)``, ``gamma_new = g / (1 +
      g)``: exact given the draw; across the particles the draws add the spread ``(g / (1 +
      g))^2 P_w`` to the means, which makes up the total. At activation (``beta`` about 0, ``g``
      = 100) each mean jumps onto its own prior draw and ``gamma`` falls to 1.
    * ``tempered``: the draw counts as the fraction ``alpha = beta / (1 + g (1 - beta))`` of an
      observation (NiW update with ``w ~ N(mu, Sigma / alpha)``: ``kappa += alpha``): the
      effective observation that gives the measurement's information ``beta`` about ``w``
      has the noise ``R_w`` with ``S / (S + R_w) = alpha``. ``g_loc = g_w = alpha g / (1 + alpha
      g) = g beta / (1 + g)``, ``gamma_new = g / (1 + alpha g)`` (= the exact variance above).
    * ``rao_blackwellized``: the exact mean (``g_loc = g / (1 + g)``) plus the share ``beta``
      of the draw's deviation (``g_w = beta g / (1 + g)``: the state is propagated with ``w``,
      and a draw the measurement does not inform carries nothing about ``mu``); ``gamma_new =
      g / (1 + g) + (1 - beta^2) g^2 (1 - beta) / (1 + g)``, so that within (``gamma_new S``)
      plus between the particles (``g_w^2 P_w``) is the exact variance (law of total variance).

    Both are eq. (19) at ``beta = 1``.
    """
    k = gamma / (1.0 + gamma)
    if mode == "sampled":
        return k, k, k
    if mode == "tempered":
        return k * beta, k * beta, gamma * (1.0 + gamma * (1.0 - beta)) / (1.0 + gamma)
    if mode == "rao_blackwellized":
        return k, k * beta, k + (1.0 - beta * beta) * gamma * k * (1.0 - beta)
    raise ValueError(f"unknown niw_update {mode!r}")


def propagated_draw(w: F64, loc: F64, share: float, lower: F64, upper: F64) -> F64:
    """The stiffness deviation that drives the state in eq. (9), (N, 3) (deviation xii).

    ``loc + h (w - loc)`` with ``h`` = ``share``, ``w`` the draw (39) and ``loc`` its conditional
    mean (41), projected to the bounds (Sec. V); ``h`` = 1 returns ``w`` (eq. 9 as printed).
    """
    if share >= 1.0:
        return w
    return np.clip(loc + share * (w - loc), lower, upper)


def rejuvenate_means(
    mean: F64,
    bandwidth: float,
    components: NDArray[np.intp],
    lower: F64,
    upper: F64,
    rng: np.random.Generator,
) -> None:
    """Liu & West (2001) kernel shrinkage of equally weighted NiW means, in place.

    ``mu_i <- a mu_i + (1 - a) mu_bar + h L z_i`` for the ``components`` of ``mean`` (N, 3),
    ``a = sqrt(1 - h^2)``, ``mu_bar`` and ``V = L L^T`` the mean and covariance of the means,
    ``z_i ~ N(0, I)``: the kernel keeps ``mu_bar`` and ``V`` (``a^2 V + h^2 V = V``) and gives
    the copies of a resampled particle distinct means. Projected to ``lower`` / ``upper``
    (Sec. V).
    """
    h = float(bandwidth)
    a = math.sqrt(1.0 - h * h)
    m = mean[:, components]
    m_bar = m.mean(axis=0)
    dev = m - m_bar
    v = dev.T @ dev / m.shape[0]
    # a relative 1e-9 ridge keeps the factor of a (numerically) singular V finite
    v += 1e-9 * np.trace(v) * np.eye(len(components)) + 1e-300 * np.eye(len(components))
    chol = np.linalg.cholesky(v)
    z = rng.standard_normal((m.shape[0], len(components)))
    new = a * m + (1.0 - a) * m_bar + h * (z @ chol.T)
    mean[:, components] = np.clip(new, lower[components], upper[components])


def freeze_component(stats: niw.NiwStats, before: niw.NiwStats, j: int) -> None:
    """Undo this step's NiW prediction (20) and update (19) for component ``j``, in place.

    Used for Cx without longitudinal excitation (Sec. II-B: the Gramian is singular for zero
    wheel slip): the mean of ``w_j`` and its expected variance ``E[Sigma_jj] = Lambda_jj /
    (nu - d - 1)`` (eq. 27b) stay as in ``before``; its covariances with the other components
    are set to zero, which keeps ``Lambda`` positive definite. ``gamma`` and ``nu`` are shared.
    """
    d = stats.d
    nu_new = np.asarray(stats.dof, dtype=float) - d - 1.0
    nu_old = np.asarray(before.dof, dtype=float) - d - 1.0
    ratio = nu_new / nu_old
    # eq. (27b) E[Sigma_jj] = Lambda_jj / (nu - 4) unchanged: Lambda_jj scales with nu - 4
    stats.mean[:, j] = before.mean[:, j]
    stats.scale[:, j, :] = 0.0
    stats.scale[:, :, j] = 0.0
    stats.scale[:, j, j] = before.scale[:, j, j] * ratio


@dataclass(frozen=True)
class MpfEstimate:
    """Weighted estimates of Algorithm 1 (eq. 27, 42).

    Attributes:
        stiffness: C_n + mu_hat (eq. 7, 27a), (3,).
        stiffness_std: sqrt(diag(Sigma_hat)) of eq. (27b), (3,).
        mean_std: std of the posterior of the mean mu, (3,).
        state: weighted mean [vX, vY, r] (eq. 42), (3,).
        state_cov: weighted covariance of the state, (3, 3).
        bias: weighted mean bias [b_ax, b_ay, b_r], (3,).
        n_eff: effective sample size before the last resampling decision.
    """

    stiffness: F64
    stiffness_std: F64
    mean_std: F64
    state: F64
    state_cov: F64
    bias: F64
    n_eff: float


class StiffnessMpf:
    """Algorithm 1, vectorized over particles.

    Args:
        config: tuning (see :class:`StiffnessEstimatorConfig`).
        params: single-track parameters (nominal stiffness, geometry).
        rng: random generator for every draw.
    """

    #: run the per-particle algebra in the compiled kernels of :mod:`.stiffness_kernels`
    #: (False: the NumPy reference functions of this module; same filter, same random stream)
    compiled: bool = True

    def __init__(
        self,
        config: StiffnessEstimatorConfig,
        params: SingleTrackParams,
        rng: np.random.Generator,
    ) -> None:
        self.config = config
        self.params = params
        self.rng = rng
        self.n = config.n_particles
        c = config
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower = c.min_stiffness_fraction * self.nominal - self.nominal
        self.upper = c.max_stiffness_fraction * self.nominal - self.nominal
        # float arrays: integer config values (0 from YAML / ROS) must not make them int
        self.r_cov = np.diag(
            np.array(
                [c.accel_noise_std_m_s2**2, c.accel_noise_std_m_s2**2, c.gyro_noise_std_rad_s**2],
                dtype=float,
            )
        )
        self.q_rate = np.diag(
            np.array(
                [
                    c.accel_bias_walk_m_s2_sqrt_s**2,
                    c.accel_bias_walk_m_s2_sqrt_s**2,
                    c.gyro_bias_walk_rad_s_sqrt_s**2,
                ],
                dtype=float,
            )
        )
        self.jitter = np.array(
            [
                c.state_jitter_vx_m_s_sqrt_s,
                c.state_jitter_vy_m_s_sqrt_s,
                c.state_jitter_yaw_rate_rad_s_sqrt_s,
            ]
        )
        #: state_proposal = measured (core/stiffness/proposal.py): the random walk of the
        #: yaw rate and, with a measured speed in the kinematic model, of vX is drawn in
        #: update() given the gyro / speed; ``_drawn_in_update`` marks those states
        self.measured_proposal = c.state_proposal == "measured"
        self._drawn_in_update = np.array([False, False, self.measured_proposal])
        self._resample = getattr(resampling, c.resampler)
        self.initialized = False
        self.x = np.zeros((self.n, 3))
        self.rate = np.zeros((self.n, 3))
        self.b = np.zeros((self.n, 3))
        self.p_bias = np.zeros((self.n, 3, 3))
        self.log_w = np.full(self.n, -np.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.stats = self.prior_stats()
        #: prior gamma_0: the cap of gamma with ``niw_update`` other than ``sampled`` (forgetting
        #: must not make the mean less certain than the prior)
        self._gamma0 = float(self.stats.gamma)
        #: ``niw_update``: weighted share of the predictive variance of w explained by the last
        #: learning step's measurement (:func:`information_fraction`), 1
        self.information_share = 0.0
        self.n_eff = float(self.n)
        self.resample_count = 0
        #: sum over updates of log p(y_k | y_1:k-1) (nats) and the number of terms: the log
        #: marginal likelihood of the measurements under this configuration (model selection
        #: without ground truth)
        self.log_evidence = 0.0
        self.evidence_steps = 0
        self.yaw_rate_nis = 0.0
        self.yaw_rate_nis_mean = 0.0
        self.bias_updated = False
        #: time since :meth:`initialize`, s (the bias hold, ``bias_hold_s``)
        self.time_since_init = 0.0
        self._dt_s = 0.0
        self._step_dt_s = 0.0
        self._before_learning: niw.NiwStats | None = None
        #: inactive_statistics = held: whether the last update learned, and which components
        self._learned_last_step = False
        self._last_learned_components = np.arange(NW)
        # compiled path: ancestors without resampling, "no freeze", constant of eq. (35)
        self._identity = np.arange(self.n, dtype=np.intp)
        self._no_freeze = np.empty(0)
        self._log_const: tuple[float, float] = (np.nan, np.nan)

    def prior_stats(self) -> niw.NiwStats:
        """Prior NiW statistics: mean at the initial guess, E[Sigma] and gamma from config."""
        c = self.config
        mean0 = (c.initial_stiffness_factor - 1.0) * self.nominal
        noise_var = (c.stiffness_noise_std_fraction * self.nominal) ** 2
        scale0 = np.diag(noise_var) * (c.prior_dof - NW - 1.0)
        gamma0 = (c.initial_stiffness_std_fraction / c.stiffness_noise_std_fraction) ** 2
        return niw.init_stats(self.n, mean0, gamma0, c.prior_dof, scale0)

    def initialize(self, x0: F64, x0_std: F64, bias0: F64 | None = None) -> None:
        """Algorithm 1 'Initialize': x ~ N(x0, diag(x0_std^2)), b ~ N(bias0, P0), q = 1/N."""
        c = self.config
        self.x = x0[None, :] + self.rng.standard_normal((self.n, 3)) * x0_std[None, :]
        self.rate = np.zeros((self.n, 3))
        self.b = np.tile(np.zeros(3) if bias0 is None else bias0, (self.n, 1))
        p0 = np.diag(
            np.array(
                [c.accel_bias_std_m_s2**2, c.accel_bias_std_m_s2**2, c.gyro_bias_std_rad_s**2],
                dtype=float,
            )
        )
        self.p_bias = np.tile(p0, (self.n, 1, 1))
        self.log_w = np.full(self.n, -np.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.initialized = True
        # the gate of the bias update starts closed: the yaw rate must first prove consistent
        self.yaw_rate_nis_mean = 4.0 * self.config.bias_gate_sigma**2
        self.time_since_init = 0.0

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        """Time update to the next IMU sample: eq. (9) state, (20) NiW, (29) bias.

        ``learn`` applies (20); ``learn_cx`` False (default ``learn``) keeps the statistics
        before (20) for the Cx freeze of the following :meth:`update`.
        """
        # jitter (iii) of the states whose random walk update() does not draw
        jitter = np.where(self._drawn_in_update, 0.0, self.jitter)
        if self.compiled:
            # eq. (9) with the stored rate, jitter (iii), vX >= 0 and eq. (29) P += Q Ts
            stiffness_kernels.predict_states(
                self.x, self.rate, self.p_bias, self.q_rate * dt_s, dt_s, jitter, self.rng
            )
        else:
            # eq. (9) x_{k+1} = f + g w_k with the stored rate = rate_n + a w_k
            self.x += dt_s * self.rate
            if np.any(jitter > 0.0):
                self.x += self.rng.standard_normal((self.n, 3)) * (jitter * np.sqrt(dt_s))
            self.x[:, 0] = np.maximum(self.x[:, 0], 0.0)
        self._before_learning = None
        if learn:
            if learn_cx is False:
                self._before_learning = self.stats.copy()
            # eq. (20) gamma/lambda, mu, lambda nu, lambda Lambda
            niw.time_update(self.stats, self.config.forgetting)
        if not self.compiled:
            # eq. (29) P_{k+1} = P_k + Q
            bias_predict(self.p_bias, self.q_rate * dt_s)
        self._dt_s = dt_s
        self.time_since_init += dt_s

    def bias_gate_open(self, learn: bool) -> bool:
        """Whether the bias update (30) runs at this step (deviation v).

        Not within ``bias_hold_s`` of :meth:`initialize`; after that always on straight driving
        (``learn`` False) and, while the stiffness is learned, when the exponential mean of the
        yaw-rate NIS is at most ``bias_gate_sigma^2``.
        """
        if self.time_since_init < self.config.bias_hold_s:
            return False
        return (not learn) or self.yaw_rate_nis_mean <= self.config.bias_gate_sigma**2

    def update(
        self,
        y: F64,
        delta_rad: float,
        wheel_speed_m_s: tuple[float, float],
        learn: bool,
        vx_m_s: float | None = None,
        learn_cx: bool | None = None,
    ) -> None:
        """Measurement part of Algorithm 1 at one IMU sample ``y`` (3,) = [ax, ay, r].

        ``learn`` enables the NiW update (19) (activation, Sec. V); ``learn_cx`` (default
        ``learn``) False keeps the Cx part of the statistics as it was before this step's (20)
        and (19) (no longitudinal excitation, see :func:`freeze_component`). ``vx_m_s``
        (optional) is a measured speed (no wheel speeds): with ``measured_speed_model`` =
        ``input`` it replaces the particles' vX; with ``kinematic`` the measured ax drives vX and
        the speed is the measurement row 0 (:func:`kinematic_speed_row`).
        """
        # IMU period of this step (the bias update's gain cap, bias_average_s)
        self._step_dt_s = self._dt_s
        self._hold_statistics(learn, bool(learn) and learn_cx is False)
        kinematic = vx_m_s is not None and self.config.measured_speed_model == "kinematic"
        if vx_m_s is not None and not kinematic:
            self.x[:, 0] = vx_m_s
        freeze_cx = learn and learn_cx is False
        before = self._before_learning
        if freeze_cx and before is None:
            before = self.stats.copy()
        self._before_learning = None
        # state_proposal = measured: draw the random walk of the measured states given their
        # measurement (stiffness_proposal.measured_state_proposal): (row, y, offset, P, R)
        log_w_measured = None
        rows = (0, 1, 2)
        gyro_nis = 0.0
        if self.measured_proposal:
            self._drawn_in_update[0] = kinematic
            measured = [(2, float(y[2]), self.b[:, 2], self.p_bias[:, 2, 2], self.r_cov[2, 2])]
            if kinematic:
                assert vx_m_s is not None
                speed_var = self.config.speed_noise_std_m_s**2
                measured.append((0, float(vx_m_s), 0.0, 0.0, speed_var))
            log_w_measured = np.zeros(self.n)
            for j, y_j, b_j, p_j, r_j in measured:
                prop = measured_state_proposal(
                    self.x[:, j], y_j, b_j, p_j, float(r_j), self.jitter[j] ** 2 * self._dt_s,
                    self.rng,
                )  # fmt: skip
                self.x[:, j] = prop.state
                log_w_measured += prop.log_weight
                if j == 2:
                    gyro_nis = float(self.weights @ prop.nis)
            rows = tuple(i for i in range(NE) if i not in {m[0] for m in measured})
        sat = self._saturation_slips()
        if kinematic:
            assert vx_m_s is not None
            # slip 0 (wheel speed = each particle's vX): the longitudinal force is unknown
            vx_p = self.x[:, 0]
            lin = kinematic_speed_row(
                linearize(self.x, delta_rad, (vx_p, vx_p), self.params, sat),
                self.x,
                y[0],
                self.params,
            )
            y = np.array([vx_m_s, y[1], y[2]])
            # the ax bias is not a measurement offset of the speed row: not estimated
            self.b[:, 0] = 0.0
            self.p_bias[:, 0, :] = 0.0
            self.p_bias[:, :, 0] = 0.0
            r_cov = np.tile(self.r_cov, (self.n, 1, 1))
            r_cov[:, 0, 0] = self.config.speed_noise_std_m_s**2
        else:
            lin = linearize(self.x, delta_rad, wheel_speed_m_s, self.params, sat)
            r_cov = self.measurement_cov(delta_rad, wheel_speed_m_s)
        if (
            self.compiled
            and log_w_measured is None
            and np.ndim(self.stats.dof) == 0
            and np.ndim(self.stats.gamma) == 0
        ):
            # the steps below in stiffness_kernels (same filter, same random stream)
            self._update_compiled(y, lin, r_cov, learn, before if freeze_cx else None)
            return
        # e_bar = y - h - b_{k|k-1} (eq. 12)
        e_bar = y[None, :] - lin.h - self.b
        lp = likelihood_params(self.stats, lin.d, r_cov, self.p_bias)
        self.yaw_rate_nis = (
            yaw_rate_nis(e_bar, lp, self.weights) if log_w_measured is None else gyro_nis
        )
        a = min(1.0, self._dt_s / self.config.bias_gate_window_s)
        self.yaw_rate_nis_mean += a * (self.yaw_rate_nis - self.yaw_rate_nis_mean)
        self._dt_s = 0.0
        # Algorithm 1 line 3: eq. (36)
        # (log_likelihood(e_bar, lp); the Mahalanobis term is kept for eq. 41 below)
        n_meas = len(rows)
        if log_w_measured is None:
            maha = _maha(e_bar - lp.loc, lp.shape_inv)
            self.log_w += niw.student_t_log_density(maha, lp.logdet, lp.dof, NE)
        else:
            # measured proposal: q_k = q_{k-1} prod_j N(nu_j; 0, S_j) St(other rows)
            maha, logdet = marginal_maha_logdet(e_bar - lp.loc, lp.shape, rows)
            self.log_w += log_w_measured + niw.student_t_log_density(maha, logdet, lp.dof, n_meas)
        # line 6-7: normalize, N_eff; the normalizer of the normalized previous weights times
        # the likelihoods is the predictive density p(y_k | y_1:k-1) (model evidence increment)
        self.weights, log_pred = resampling.normalize_log_weights(self.log_w)
        if np.isfinite(log_pred):
            self.log_evidence += log_pred
            self.evidence_steps += 1
        self.n_eff = resampling.ess(self.weights)
        if not np.all(np.isfinite(self.weights)):
            self.weights = np.full(self.n, 1.0 / self.n)
        beta = 0.0
        if learn and self.config.niw_update != "sampled":
            # niw_update: the share of the predictive variance of w this measurement explains,
            # weighted with the normalized weights before resampling
            comps = self._learned_components(freeze_cx)
            beta = float(
                self.weights @ information_fraction(lp.w_shape, lin.d, lp.shape_inv, comps)
            )
        # line 8-10: resample and copy the statistics
        resampled = self.n_eff <= self.config.resample_threshold * self.n
        if resampled:
            idx = self._resample(self.weights, self.rng)
            self._take(idx)
            if before is not None:
                # the statistics the Cx freeze restores follow their particles
                before.take(idx)
            lin = Linearized(rate=lin.rate[idx], a=lin.a[idx], h=lin.h[idx], d=lin.d[idx])
            e_bar = e_bar[idx]
            r_cov = r_cov[idx]
            lp = lp.take(idx)
            maha = maha[idx]
            self.weights = np.full(self.n, 1.0 / self.n)
            self.resample_count += 1
        self.log_w = resampling.log_of_weights(self.weights)
        # line 17: sample w_k from the conditional predictive (39)-(41)
        cp = conditional_predictive(self.stats, lin.d, e_bar, lp, maha, n_meas)
        w = sample_student_t(cp, self.rng)
        # Sec. V parameter projection to physical bounds
        w = np.clip(w, self.lower, self.upper)
        if learn:
            if self.config.niw_update == "sampled":
                # line 4: eq. (19) with w_bar = w_k (Remark 3)
                niw.measurement_update(self.stats, w)
            else:
                # eq. (19) for Lambda and nu, the mean and gamma by niw_mean_gains
                g_loc, g_w, g_new = niw_mean_gains(
                    float(self.stats.gamma), beta, self.config.niw_update
                )
                niw.measurement_update_split(
                    self.stats, w, cp.loc, g_loc, g_w, min(g_new, self._gamma0)
                )
                self.information_share = beta
            np.clip(self.stats.mean, self.lower, self.upper, out=self.stats.mean)
            if freeze_cx and before is not None:
                freeze_component(self.stats, before, 0)
            if resampled:
                self._rejuvenate(freeze_cx)
        # line 15: eq. (30) with mu_{k|k} and Sigma_{k|k} = Lambda / (nu - 4)
        sigma = self.stats.scale / np.reshape(
            np.asarray(self.stats.dof) - NW - 1.0, (-1, 1, 1) if np.ndim(self.stats.dof) else ()
        )
        d_s = mat3.soa(lin.d)
        extra = mat3.aos(mat3.mm_bt(mat3.mm(d_s, mat3.soa(sigma)), d_s))
        resid = e_bar - np.einsum("nij,nj->ni", lin.d, self.stats.mean)
        # eq. (30) on straight driving; while learning only when the particles' yaw rate plus
        # bias agrees with the gyro (else the bias filters absorb the yaw-rate model error)
        self.bias_updated = self.bias_gate_open(learn)
        if self.bias_updated:
            bias_update(self.b, self.p_bias, resid, extra, self._bias_noise(r_cov), lp.dof)
        # line 18 (first half): derivative for eq. (9), applied in predict(); deviation (xii):
        # the state is driven by loc + h (w - loc), h = propagation_draw_share; deviation
        # (xiii): without learning and inactive_propagation = mean by the held mean mu
        if self._drive_by_mean(learn):
            w_state = self.stats.mean
        else:
            w_state = propagated_draw(
                w, cp.loc, self.config.propagation_draw_share, self.lower, self.upper
            )
        self.rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w_state)

    def _drive_by_mean(self, learn: bool) -> bool:
        """Whether eq. (9) of the next step takes the NiW mean instead of the draw (xiii)."""
        return not learn and self.config.inactive_propagation == "mean"

    def _student_t_log_const(self, nu_t: float) -> float:
        """``lgamma((nu~+3)/2) - lgamma(nu~/2) - 3/2 log(nu~ pi)`` of eq. (35), cached on nu~."""
        if self._log_const[0] != nu_t:
            # the reference's own expression at maha = 0, logdet = 0 (same rounding)
            c = niw.student_t_log_density(np.zeros(1), np.zeros(1), nu_t, NE)
            self._log_const = (nu_t, float(c[0]))
        return self._log_const[1]

    def _update_compiled(
        self,
        y: F64,
        lin: Linearized,
        r_cov: F64,
        learn: bool,
        freeze_before: niw.NiwStats | None,
    ) -> None:
        """The measurement part of :meth:`update` in :mod:`.stiffness_kernels` (same steps).

        ``freeze_before``: the statistics whose Cx part is kept (:func:`freeze_component`), or
        ``None``. Shared ``gamma`` and ``nu`` only (``niw.init_stats(shared=True)``).
        """
        st = self.stats
        gamma, nu = float(st.gamma), float(st.dof)
        # eq. (21) nu~ = nu - d + 1
        log_const = self._student_t_log_const(nu - NW + 1.0)
        # Algorithm 1 line 3: eq. (35)-(36), normalize and N_eff (lines 6-7), yaw-rate NIS
        e_bar, z, shape_inv, _, maha, weights, nis, log_pred, n_eff = (
            stiffness_kernels.likelihood_weights(
                y, lin.h, self.b, lin.d, st.mean, st.scale, r_cov, self.p_bias, gamma, nu,
                log_const, self.weights, self.log_w,
            )
        )  # fmt: skip
        self.yaw_rate_nis = nis
        a = min(1.0, self._dt_s / self.config.bias_gate_window_s)
        self.yaw_rate_nis_mean += a * (self.yaw_rate_nis - self.yaw_rate_nis_mean)
        self._dt_s = 0.0
        # the predictive density p(y_k | y_1:k-1) (model evidence increment)
        self.weights = weights
        if np.isfinite(log_pred):
            self.log_evidence += log_pred
            self.evidence_steps += 1
        self.n_eff = n_eff
        # line 8-10: resample (the kernel below reads each particle's ancestor)
        idx = self._identity
        if self.n_eff <= self.config.resample_threshold * self.n:
            idx = self._resample(self.weights, self.rng)
            self.weights = np.full(self.n, 1.0 / self.n)
            self.resample_count += 1
        self.log_w = resampling.log_of_weights(self.weights)
        # eq. (30) on straight driving; while learning only when the particles' yaw rate plus
        # bias agrees with the gyro (else the bias filters absorb the yaw-rate model error)
        self.bias_updated = self.bias_gate_open(learn)
        mean0 = scale00 = self._no_freeze
        gains = self._no_freeze
        g_new = gamma / (1.0 + gamma)
        if learn and self.config.niw_update != "sampled":
            # the share of the predictive variance of w this measurement explains
            beta = stiffness_kernels.information_fraction(
                lin.d, st.scale, shape_inv, (1.0 + gamma) / (nu - NW + 1.0),
                self._learned_components(freeze_before is not None), weights,
            )  # fmt: skip
            g_loc, g_w, g_new = niw_mean_gains(gamma, beta, self.config.niw_update)
            g_new = min(g_new, self._gamma0)
            gains = np.array([g_loc, g_w])
            self.information_share = beta
        if learn and freeze_before is not None:
            # freeze_component: E[Sigma_00] = Lambda_00 / (nu - 4) (eq. 27b) unchanged
            ratio = ((np.asarray(st.dof, dtype=float) + 1.0) - NW - 1.0) / (
                np.asarray(freeze_before.dof, dtype=float) - NW - 1.0
            )
            mean0 = np.ascontiguousarray(freeze_before.mean[:, 0])
            scale00 = freeze_before.scale[:, 0, 0] * ratio
        # lines 17, 4, 15, 18: eq. (39)-(41) draw, projection, eq. (19), eq. (30), eq. (9) rate;
        # the kernel reads r_cov only in eq. (30): R plus the bias_average_s term, per ancestor
        r_bias = self._bias_noise(r_cov)
        x, b, p_bias, rate, mean, scale, _ = stiffness_kernels.posterior_step(
            idx, self.x, self.b, self.p_bias, st.mean, st.scale, gamma, nu, lin.d, lin.a,
            lin.rate, r_bias, e_bar, z, shape_inv, maha, self.lower, self.upper, learn, mean0,
            scale00, self.bias_updated, gains, self.rng, self.config.propagation_draw_share,
            self._drive_by_mean(learn),
        )  # fmt: skip
        self.x, self.b, self.p_bias, self.rate = x, b, p_bias, rate
        st.mean, st.scale = mean, scale
        if learn:
            if self.config.niw_update == "sampled":
                # eq. (19) shared scalars: gamma_{k|k} = gamma / (1 + gamma), nu_{k|k} = nu + 1
                c = 1.0 / (1.0 + st.gamma)
                st.gamma[...] = st.gamma * c
            else:
                # niw_mean_gains (capped at the prior gamma_0); nu as eq. (19)
                st.gamma[...] = g_new
            st.dof += 1.0
            if idx is not self._identity:
                self._rejuvenate(freeze_before is not None)

    def _hold_statistics(self, learn: bool, freeze_cx: bool) -> None:
        """``inactive_statistics`` = ``held``: at the first step without learning after a learning
        phase, every particle takes the weighted moment match of the statistics
        (:func:`niw.collapse`, the learned components set ``gamma``), so that the estimate (27)
        stays at its last learned value while the particles are weighted and resampled for the
        state only.
        """
        if self.config.inactive_statistics != "held":
            return
        if learn:
            self._last_learned_components = np.flatnonzero(self._learned_components(freeze_cx))
        elif self._learned_last_step:
            niw.collapse(self.stats, self.weights, self._last_learned_components)
        self._learned_last_step = learn

    def _bias_noise(self, r_cov: F64) -> F64:
        """Measurement noise of the bias update (eq. 30), (N, 3, 3).

        ``R`` (with the wheel-speed term), plus with ``bias_average_s`` = tau > 0 the term
        ``(tau / Ts) P`` (deviation x), which caps the Kalman gain at ``Ts / (tau + Ts)``:
        the bias follows the residuals as an average over about tau instead of taking a
        transient of the particle's trajectory within a few steps while ``P`` is near ``P_0``.
        """
        tau = self.config.bias_average_s
        if tau <= 0.0 or self._step_dt_s <= 0.0:
            return r_cov
        # deviation (x): R_b = R + (tau / Ts) P  ->  K = P (P + R_b)^-1 <= Ts / (tau + Ts)
        return r_cov + (tau / self._step_dt_s) * self.p_bias

    def _saturation_slips(self) -> tuple[F64, F64] | None:
        """Per-particle saturation slips with ``saturation_peak`` = ``friction``, else None.

        ``alpha_s = mu Fz / C`` at each particle's stiffness mean ``C_n + mu_i`` (eq. 7, 27a
        per particle) before this step's draw, so the step stays affine in ``w``.
        """
        p = self.params
        if self.config.saturation_peak != "friction" or (
            p.saturation_slip_front_rad <= 0.0 and p.saturation_slip_rear_rad <= 0.0
        ):
            return None
        c = self.nominal[None, :] + self.stats.mean
        return saturation_slip_at(p, c[:, 1], c[:, 2])

    def _learned_components(self, freeze_cx: bool) -> F64:
        """1 for each component of ``w`` learned in this step, 0 for a frozen Cx, (3,)."""
        return np.array([0.0 if freeze_cx else 1.0, 1.0, 1.0])

    def _rejuvenate(self, freeze_cx: bool) -> None:
        """:func:`rejuvenate_means` after a resampling while learning (if its bandwidth > 0)."""
        h = self.config.rejuvenation_bandwidth
        if h > 0.0:
            comps = np.flatnonzero(self._learned_components(freeze_cx))
            rejuvenate_means(self.stats.mean, h, comps, self.lower, self.upper, self.rng)

    def measurement_cov(self, delta_rad: float, wheel_speed_m_s: tuple[float, float]) -> F64:
        """Measurement-noise covariance of ``y`` per particle, (N, 3, 3).

        ``R`` of the IMU (eq. 12) plus the wheel-speed noise carried into ``y`` by the slip
        (eq. 2-3): ``s^2 G^T G`` with ``G`` from :func:`wheel_speed_gain` at each particle's
        mean Cx (nominal + mu, eq. 7) and ``s`` = ``wheel_speed_noise_std_m_s``.
        """
        s = self.config.wheel_speed_noise_std_m_s
        if s <= 0.0 or self.params.drive not in ("front", "rear", "all"):
            return np.tile(self.r_cov, (self.n, 1, 1))
        cx = self.nominal[0] + self.stats.mean[:, 0]
        g = wheel_speed_gain(self.x, delta_rad, wheel_speed_m_s, self.params, cx)
        # input noise through eq. (2)-(3): Cov = s^2 sum_axles g g^T
        outer = g[:, 0, :, None] * g[:, 0, None, :]
        for j in range(1, g.shape[1]):
            outer += g[:, j, :, None] * g[:, j, None, :]
        return self.r_cov + (s * s) * outer

    def _take(self, idx: NDArray[np.intp]) -> None:
        self.x = self.x[idx]
        self.b = self.b[idx]
        self.p_bias = self.p_bias[idx]
        self.rate = self.rate[idx]
        self.stats.take(idx)

    def estimate(self) -> MpfEstimate:
        """Estimates (27) of the stiffness and (42) of the state."""
        q = self.weights
        st = self.stats
        # eq. (27a) mu_hat = sum q_i mu_i
        mu = q @ st.mean
        dev = st.mean - mu
        nu = np.broadcast_to(np.asarray(st.dof, dtype=float), (self.n,))
        gam = np.broadcast_to(np.asarray(st.gamma, dtype=float), (self.n,))
        spread = np.einsum("n,ni,nj->ij", q, dev, dev)
        # eq. (27b) Sigma_hat = sum q_i (Lambda_i / (nu - 4) + dev dev^T)
        e_sigma = np.einsum("n,nij->ij", q / (nu - NW - 1.0), st.scale)
        sigma_hat = e_sigma + spread
        mean_cov = np.einsum("n,nij->ij", q * gam / (nu - NW - 1.0), st.scale) + spread
        # eq. (42) weighted mean of the state
        xm = q @ self.x
        dx = self.x - xm
        return MpfEstimate(
            stiffness=self.nominal + mu,
            stiffness_std=np.sqrt(np.maximum(np.diag(sigma_hat), 0.0)),
            mean_std=np.sqrt(np.maximum(np.diag(mean_cov), 0.0)),
            state=xm,
            state_cov=np.einsum("n,ni,nj->ij", q, dx, dx),
            bias=q @ self.b,
            n_eff=float(self.n_eff),
        )
