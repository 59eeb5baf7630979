"""Normal-inverse-Wishart (NiW) sufficient statistics, vectorized over particles.

Generic ``d``-dimensional implementation of Lundquist et al., "Tire radii estimation using a
marginalized particle filter", IEEE T-ITS 2014, Section III-B/C (eq. 22-30). It is used by the
tyre-radius MPF (``d = 2`` rear wheels) and is meant to be reused by other MPFs (e.g. ``d = 3``).

Hierarchical model (eq. 22), per particle ``i``::

    w | mu, Sigma ~ N(mu, Sigma)
    mu | Sigma    ~ N(mean, gamma * Sigma)
    Sigma         ~ iW(dof, scale),  density ~ |Sigma|^-(dof+d+1)/2 exp(-tr(scale Sigma^-1)/2)

Shapes (``N`` particles, dimension ``d``):

* ``mean``  ``(N, d)``   -- mu-hat, location of the mean,
* ``scale`` ``(N, d, d)`` -- Lambda, inverse-Wishart scale matrix (symmetric positive definite),
* ``gamma`` ``(N,)`` or scalar ``()`` -- gamma = 1 / kappa, relative uncertainty of the mean,
* ``dof``   ``(N,)`` or scalar ``()`` -- nu, inverse-Wishart degrees of freedom (> d - 1).

``gamma`` and ``dof`` evolve identically for every particle whenever all particles receive the same
sequence of updates (as in the MPF), so they may be stored as 0-d arrays that broadcast against
``(N,)``. Every function below accepts both. All updates are in place unless stated otherwise.

Closed-form 2x2 algebra is used for ``d == 2`` (Cholesky, determinant, inverse); the generic path
(``np.linalg``) is exact for any ``d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import gammaln

from tire_estimation.core.arrays import F64


@dataclass
class NiwStats:
    """Mutable NiW statistics of ``N`` particles (see module docstring for shapes)."""

    mean: F64
    gamma: F64
    dof: F64
    scale: F64

    @property
    def n(self) -> int:
        """Number of particles ``N``."""
        return int(self.mean.shape[0])

    @property
    def d(self) -> int:
        """Dimension ``d`` of the noise vector."""
        return int(self.mean.shape[1])

    def copy(self) -> NiwStats:
        """Deep copy."""
        return NiwStats(self.mean.copy(), self.gamma.copy(), self.dof.copy(), self.scale.copy())

    def take(self, idx: NDArray[np.intp]) -> None:
        """Resample in place: particle ``i`` becomes old particle ``idx[i]`` (``idx`` (N,))."""
        self.mean[...] = self.mean[idx]
        self.scale[...] = self.scale[idx]
        if self.gamma.ndim:
            self.gamma[...] = self.gamma[idx]
        if self.dof.ndim:
            self.dof[...] = self.dof[idx]


def init_stats(
    n: int,
    mean0: F64,
    gamma0: float,
    dof0: float,
    scale0: F64,
    shared: bool = True,
) -> NiwStats:
    """Identical prior statistics for ``n`` particles.

    Args:
        n: number of particles ``N``.
        mean0: prior location of the mean, ``(d,)``.
        gamma0: prior gamma (> 0); ``gamma0 * E[Sigma]`` is the prior covariance of ``mu``.
        dof0: prior degrees of freedom nu (> d + 1 so that ``E[Sigma]`` exists).
        scale0: prior scale Lambda, ``(d, d)``; ``E[Sigma] = scale0 / (dof0 - d - 1)``.
        shared: store ``gamma`` and ``dof`` as 0-d arrays (``True``) or ``(N,)`` arrays.
    """
    mean0 = np.asarray(mean0, dtype=float)
    d = mean0.shape[0]
    scale0 = np.asarray(scale0, dtype=float).reshape(d, d)
    shape = () if shared else (n,)
    return NiwStats(
        mean=np.tile(mean0, (n, 1)),
        gamma=np.full(shape, float(gamma0)),
        dof=np.full(shape, float(dof0)),
        scale=np.tile(scale0, (n, 1, 1)),
    )


def time_update(stats: NiwStats, forgetting: float) -> None:
    """Prediction of the statistics with forgetting factor ``0 < lambda <= 1`` (eq. 24), in place.

    The statistics then rely on roughly the last ``h = 1 / (1 - lambda)`` samples.
    """
    lam = float(forgetting)
    # eq. (24a) gamma_{k|k-1} = gamma_{k-1|k-1} / lambda
    stats.gamma /= lam
    # eq. (24b) mean_{k|k-1} = mean_{k-1|k-1}  (unchanged)
    # eq. (24c) nu_{k|k-1} = lambda nu_{k-1|k-1}
    stats.dof *= lam
    # eq. (24d) Lambda_{k|k-1} = lambda Lambda_{k-1|k-1}
    stats.scale *= lam


def measurement_update(stats: NiwStats, w: F64) -> None:
    """Conjugate update with one sample ``w`` ``(N, d)`` per particle (eq. 23), in place."""
    g_pred = stats.gamma
    diff = w - stats.mean
    c = 1.0 / (1.0 + g_pred)
    # eq. (23d) Lambda += (mean_pred - w)(mean_pred - w)^T / (1 + gamma_pred)
    stats.scale += (c[..., None, None] if np.ndim(c) else c) * (
        diff[:, :, None] * diff[:, None, :]
    )
    # eq. (23a) gamma_{k|k} = gamma_{k|k-1} / (1 + gamma_{k|k-1})
    g_new = g_pred * c
    # eq. (23b) mean_{k|k} = mean_{k|k-1} + gamma_{k|k} (w - mean_{k|k-1})
    stats.mean += (g_new[:, None] if np.ndim(g_new) else g_new) * diff
    stats.gamma[...] = g_new
    # eq. (23c) nu_{k|k} = nu_{k|k-1} + 1
    stats.dof += 1.0


def measurement_update_split(
    stats: NiwStats, w: F64, loc: F64, gain_loc: float, gain_w: float, gamma_new: float
) -> None:
    """Eq. (23) with a split update of the mean and a given ``gamma``, in place.

    ``Lambda`` and ``nu`` as :func:`measurement_update` with the sample ``w`` (N, d) (eq. 23c-d);
    the mean moves by ``gain_loc (loc - mean) + gain_w (w - loc)`` with ``loc`` (N, d) the
    conditional mean of ``w`` given this step's measurement, and ``gamma`` becomes the shared
    ``gamma_new``. ``gain_loc = gain_w = gamma / (1 + gamma)`` and ``gamma_new = gamma / (1 +
    gamma)`` is :func:`measurement_update` (up to rounding). Shared ``gamma`` only.
    """
    g_pred = stats.gamma
    diff = w - stats.mean
    c = 1.0 / (1.0 + g_pred)
    # eq. (23d) Lambda += (mean_pred - w)(mean_pred - w)^T / (1 + gamma_pred)
    stats.scale += c * (diff[:, :, None] * diff[:, None, :])
    stats.mean += gain_loc * (loc - stats.mean) + gain_w * (w - loc)
    stats.gamma[...] = gamma_new
    # eq. (23c) nu_{k|k} = nu_{k|k-1} + 1
    stats.dof += 1.0


def predictive_dof(dof: F64 | float, d: int) -> F64:
    """Degrees of freedom ``nu - d + 1`` of the Student-t predictive (eq. 27)."""
    return np.asarray(dof, dtype=float) - d + 1.0


def predictive_shape(stats: NiwStats) -> F64:
    """Shape matrix of the Student-t predictive, ``(1 + gamma) Lambda / (nu - d + 1)`` (N, d, d).

    Eq. (27) with the shape of Ozkan et al. eq. (21c); the covariance is eq. (28).
    """
    f = (1.0 + stats.gamma) / predictive_dof(stats.dof, stats.d)
    return (f[..., None, None] if np.ndim(f) else f) * stats.scale


def predictive_cov(stats: NiwStats) -> F64:
    """Covariance of the predictive, ``(1 + gamma) Lambda / (nu - d - 1)`` (eq. 28), (N, d, d)."""
    f = (1.0 + stats.gamma) / (np.asarray(stats.dof, dtype=float) - stats.d - 1.0)
    return (f[..., None, None] if np.ndim(f) else f) * stats.scale


def cholesky(a: F64) -> F64:
    """Lower Cholesky factors of SPD matrices ``(..., d, d)``; closed form for ``d <= 2``."""
    d = a.shape[-1]
    if d == 1:
        return np.sqrt(a)
    if d == 2:
        out = np.zeros_like(a)
        l11 = np.sqrt(a[..., 0, 0])
        l21 = a[..., 1, 0] / l11
        out[..., 0, 0] = l11
        out[..., 1, 0] = l21
        out[..., 1, 1] = np.sqrt(a[..., 1, 1] - l21 * l21)
        return out
    return np.linalg.cholesky(a)


def student_t_from_draws(loc: F64, chol: F64, dof: F64 | float, z: F64, chi2: F64) -> F64:
    """Exact multivariate Student-t samples from pre-drawn variates.

    ``x = loc + chol @ z * sqrt(dof / chi2)`` with ``z ~ N(0, I)`` (N, d) and ``chi2 ~
    chi-square(dof)`` (N,). ``loc`` (N, d), ``chol`` (N, d, d) lower factor of the shape matrix,
    ``dof`` (N,) or scalar. Returns (N, d).
    """
    s = np.sqrt(np.asarray(dof, dtype=float) / chi2)
    return loc + np.einsum("nij,nj->ni", chol, z) * s[:, None]


def sample_predictive(stats: NiwStats, rng: np.random.Generator) -> F64:
    """Draw one sample per particle from the Student-t predictive (eq. 27), (N, d)."""
    nu_t = predictive_dof(stats.dof, stats.d)
    z = rng.standard_normal((stats.n, stats.d))
    chi2 = 2.0 * rng.standard_gamma(np.broadcast_to(0.5 * nu_t, (stats.n,)))
    return student_t_from_draws(stats.mean, cholesky(predictive_shape(stats)), nu_t, z, chi2)


def student_t_logpdf(x: F64, loc: F64, shape: F64, dof: F64 | float) -> F64:
    """Log density of the Student-t ``St(loc, shape, dof)`` at ``x``, (N, d) -> (N,)."""
    d = x.shape[-1]
    diff = x - loc
    chol = cholesky(shape)
    sol = np.linalg.solve(chol, diff[..., None])[..., 0] if d > 1 else diff / chol[..., 0]
    maha = np.sum(sol * sol, axis=-1)
    logdet = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    return student_t_log_density(maha, logdet, dof, d)


def student_t_log_density(maha: F64, logdet: F64, dof: F64 | float, d: int) -> F64:
    """Log density of a ``d``-dimensional Student-t from its squared Mahalanobis distance.

    ``maha`` = ``(x - loc)^T shape^-1 (x - loc)`` and ``logdet`` = ``log det(shape)``, (N,);
    ``dof`` scalar or (N,). Returns (N,).
    """
    nu = np.asarray(dof, dtype=float)
    # log St = lgamma((nu+d)/2) - lgamma(nu/2) - d/2 log(nu pi) - 1/2 log|shape|
    #          - (nu+d)/2 log(1 + maha/nu)
    return (
        gammaln(0.5 * (nu + d))
        - gammaln(0.5 * nu)
        - 0.5 * d * np.log(nu * math.pi)
        - 0.5 * logdet
        - 0.5 * (nu + d) * np.log1p(maha / nu)
    )


def predictive_logpdf(stats: NiwStats, w: F64) -> F64:
    """Log density of ``w`` (N, d) under each particle's Student-t predictive (eq. 27), (N,)."""
    return student_t_logpdf(
        w, stats.mean, predictive_shape(stats), predictive_dof(stats.dof, stats.d)
    )


@dataclass(frozen=True)
class NiwEstimate:
    """Weighted MMSE summary of the NiW mixture (eq. 29-30).

    Attributes:
        mean: MMSE of the noise mean mu, ``sum_i w_i mean_i`` (eq. 30a), (d,).
        mean_cov: posterior covariance of mu: ``sum_i w_i (gamma_i E[Sigma_i] + (mean_i - mean)
            (mean_i - mean)^T)`` (law of total covariance), (d, d).
        noise_cov: MMSE of Sigma, ``sum_i w_i Lambda_i / (nu_i - d - 1)`` (Ozkan et al. eq. 32),
            (d, d).
        noise_cov_eq30b: eq. (30b) of the T-ITS paper as printed: ``sum_i w_i ((nu_i - d + 1) /
            (nu_i - d - 1) Lambda_i + (mean_i - mean)(mean_i - mean)^T)``, (d, d). Kept for
            traceability; it is not the posterior mean of Sigma.
        dof: weighted mean degrees of freedom, scalar.
    """

    mean: F64
    mean_cov: F64
    noise_cov: F64
    noise_cov_eq30b: F64
    dof: float


def mmse(stats: NiwStats, weights: F64) -> NiwEstimate:
    """MMSE estimates from normalized particle ``weights`` (N,) (eq. 30)."""
    d = stats.d
    w = weights
    # eq. (30a) mu_hat = sum_i w_i mu_i
    mean = w @ stats.mean
    dev = stats.mean - mean
    spread = np.einsum("n,ni,nj->ij", w, dev, dev)
    nu = np.broadcast_to(np.asarray(stats.dof, dtype=float), (stats.n,))
    gam = np.broadcast_to(np.asarray(stats.gamma, dtype=float), (stats.n,))
    # E[Sigma | stats_i] = Lambda_i / (nu_i - d - 1)  (Ozkan et al. eq. 32)
    e_sigma_w = w / (nu - d - 1.0)
    noise_cov = np.einsum("n,nij->ij", e_sigma_w, stats.scale)
    mean_cov = np.einsum("n,nij->ij", e_sigma_w * gam, stats.scale) + spread
    # eq. (30b) as printed in the T-ITS paper
    f30 = w * (nu - d + 1.0) / (nu - d - 1.0)
    cov30 = np.einsum("n,nij->ij", f30, stats.scale) + spread
    return NiwEstimate(
        mean=mean,
        mean_cov=0.5 * (mean_cov + mean_cov.T),
        noise_cov=0.5 * (noise_cov + noise_cov.T),
        noise_cov_eq30b=0.5 * (cov30 + cov30.T),
        dof=float(w @ nu),
    )


def collapse(stats: NiwStats, weights: F64, components: NDArray[np.intp] | None = None) -> None:
    """Replace the weighted mixture of the particles' statistics by one, shared by all, in place.

    Moment matching of the mixture ``sum_i q_i NiW_i`` (``weights`` ``q`` (N,), normalized):
    every particle gets the mean ``mean_bar = sum q_i mean_i`` (eq. 30a), the expected noise
    covariance ``S = sum q_i Lambda_i / (nu_i - d - 1)`` (``nu`` = ``sum q_i nu_i``, ``Lambda =
    S (nu - d - 1)``) and the ``gamma`` that keeps the covariance of the mean, ``C = sum q_i
    gamma_i Lambda_i / (nu_i - d - 1) + sum q_i (mean_i - mean_bar)(mean_i - mean_bar)^T`` (eq.
    30b without the predictive factor), on the diagonal on average: ``gamma = mean_j C_jj /
    S_jj`` over ``components`` (indices; default all). Not in the papers: used to hold the
    statistics while nothing is learned (weighting and resampling the particles then no longer
    move the estimate).
    """
    d = stats.d
    q = np.asarray(weights, dtype=float)
    est = mmse(stats, q)
    comps = np.arange(d) if components is None else np.asarray(components, dtype=np.intp)
    s_diag = np.maximum(np.diag(est.noise_cov)[comps], 1e-300)
    gamma = float(np.mean(np.diag(est.mean_cov)[comps] / s_diag))
    nu = est.dof
    stats.mean[...] = est.mean[None, :]
    # Lambda = S (nu - d - 1) keeps E[Sigma] = S (Ozkan et al. eq. 32)
    stats.scale[...] = (est.noise_cov * (nu - d - 1.0))[None, :, :]
    stats.gamma[...] = gamma
    stats.dof[...] = nu


def stats_from_moments(n: int, mean: F64, mean_cov: F64, noise_cov: F64, dof: float) -> NiwStats:
    """Statistics whose MMSE summary reproduces (approximately) the given moments.

    Inverse of :func:`mmse` for identical particles: ``scale = noise_cov (dof - d - 1)`` and
    ``gamma = tr(mean_cov) / tr(noise_cov)``. Used to restore persisted estimates.
    """
    mean = np.asarray(mean, dtype=float)
    d = mean.shape[0]
    noise_cov = np.asarray(noise_cov, dtype=float).reshape(d, d)
    mean_cov = np.asarray(mean_cov, dtype=float).reshape(d, d)
    gamma = float(np.trace(mean_cov) / max(np.trace(noise_cov), 1e-300))
    return init_stats(n, mean, gamma, dof, noise_cov * (dof - d - 1.0))
