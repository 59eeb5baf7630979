"""Student-t algebra of Algorithm 1 (Berntorp & Di Cairano, IEEE TCST 2018), vectorized.

The likelihood of Approximation 1 (eq. 35-36), the conditional predictive of the stiffness
noise (eq. 39-41) and one draw from it, the Student-t-weighted bias Kalman update (eq. 30), the
NiW mean gains of ``niw_update`` and the Cx freeze, as NumPy functions over ``N`` particles.
:class:`~tire_estimation.core.stiffness.mpf.StiffnessMpf` runs them with ``state_proposal`` =
``measured`` (the rows drawn given their measurement are weighed apart); every other step runs
in the compiled kernels of :mod:`.kernels`, which keep their order of operations and are tested
against them (tests/core/stiffness/test_kernels.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness import mat3

#: Dimension of w (eq. 8) and of the measurement (n_e, eq. 12).
NW = 3
NE = 3


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


def mahalanobis(z: F64, inv: F64) -> F64:
    """``z_n^T inv_n z_n`` for (N, 3) and (N, 3, 3) -> (N,)."""
    return np.sum(z * np.einsum("nij,nj->ni", inv, z), axis=-1)


def log_likelihood(e_bar: F64, lp: LikelihoodParams) -> F64:
    """Log of St(e_bar; mu_e, Lambda_e, nu~) (eq. 35-36), (N, 3) -> (N,)."""
    # eq. (36) q_k ∝ q_{k-1} St(y; h + b + d mu, Lambda*, nu~)
    m = mahalanobis(e_bar - lp.loc, lp.shape_inv)
    return niw.student_t_log_density(m, lp.logdet, lp.dof, NE)


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
        maha = mahalanobis(z, lp.shape_inv)
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
    return student_t_draw(cp, z, chi2)


def student_t_draw(cp: ConditionalPredictive, z: F64, chi2: F64) -> F64:
    """The draws of St(loc, shape, dof) (eq. 39) from normals ``z`` (N, 3) and ``chi2`` (N,)
    chi-square variates with ``dof`` degrees of freedom, (N, 3)."""
    dim = cp.loc.shape[1]
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
    * ``rao_blackwellized``: the exact mean (``g_loc = g / (1 + g)``) plus the share ``beta``
      of the draw's deviation (``g_w = beta g / (1 + g)``: the state is propagated with ``w``,
      and a draw the measurement does not inform carries nothing about ``mu``); ``gamma_new =
      g / (1 + g) + (1 - beta^2) g^2 (1 - beta) / (1 + g)``, so that within (``gamma_new S``)
      plus between the particles (``g_w^2 P_w``) is the exact variance (law of total variance).

    ``rao_blackwellized`` is eq. (19) at ``beta = 1``.
    """
    k = gamma / (1.0 + gamma)
    if mode == "sampled":
        return k, k, k
    if mode == "rao_blackwellized":
        return k, k * beta, k + (1.0 - beta * beta) * gamma * k * (1.0 - beta)
    raise ValueError(f"unknown niw_update {mode!r}")


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
