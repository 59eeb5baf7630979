"""Particle resampling schemes and the effective sample size.

Every scheme maps normalized weights ``(N,)`` to ancestor indices ``(N,)`` (sorted) such that the
expected number of copies of particle ``i`` is ``N * w_i`` (unbiased). All draws use the
``np.random.Generator`` passed in. References: Douc & Cappe (2005), "Comparison of resampling
schemes for particle filtering"; Chopin & Papaspiliopoulos, "An Introduction to Sequential Monte
Carlo" (the ``particles`` package).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64

IDX = NDArray[np.intp]


def ess(weights: F64) -> float:
    """Effective sample size ``1 / sum w_i^2`` of normalized weights (N,)."""
    return float(1.0 / np.dot(weights, weights))


def normalize_log_weights(log_w: F64) -> tuple[F64, float]:
    """Normalized weights from log weights (N,) and ``log(sum(exp(log_w)))``.

    Non-finite log weights get weight zero; if none is finite, the weights become uniform.
    """
    finite = np.isfinite(log_w)
    if not finite.any():
        n = log_w.shape[0]
        return np.full(n, 1.0 / n), -np.inf
    m = np.max(log_w[finite])
    w = np.where(finite, np.exp(log_w - m), 0.0)
    s = w.sum()
    return w / s, float(m + np.log(s))


def log_of_weights(weights: F64) -> F64:
    """``log(weights)`` (N,) with ``-inf`` for a weight that underflowed to zero, without the
    divide-by-zero warning: :func:`normalize_log_weights` gives such a particle weight zero.
    """
    with np.errstate(divide="ignore"):
        return np.log(weights)


def _inverse_cdf(weights: F64, u: F64) -> IDX:
    """Indices ``j`` with ``cumsum(w)[j-1] <= u < cumsum(w)[j]`` for sorted uniforms ``u``."""
    cdf = np.cumsum(weights)
    cdf[-1] = 1.0
    idx = np.searchsorted(cdf, u, side="right")
    return np.minimum(idx, weights.shape[0] - 1).astype(np.intp)


def systematic(weights: F64, rng: np.random.Generator) -> IDX:
    """Systematic resampling: one uniform, ``u_i = (i + U) / N`` (lowest variance in practice)."""
    n = weights.shape[0]
    u = (np.arange(n) + rng.random()) / n
    return _inverse_cdf(weights, u)


def stratified(weights: F64, rng: np.random.Generator) -> IDX:
    """Stratified resampling: ``u_i = (i + U_i) / N`` with independent ``U_i``."""
    n = weights.shape[0]
    u = (np.arange(n) + rng.random(n)) / n
    return _inverse_cdf(weights, u)


def multinomial(weights: F64, rng: np.random.Generator) -> IDX:
    """Multinomial resampling: ``N`` i.i.d. draws from the weights (sorted uniforms)."""
    n = weights.shape[0]
    u = np.sort(rng.random(n))
    return _inverse_cdf(weights, u)


def residual(weights: F64, rng: np.random.Generator) -> IDX:
    """Residual resampling: ``floor(N w_i)`` copies, then multinomial on the residuals."""
    n = weights.shape[0]
    nw = n * weights
    counts = np.floor(nw).astype(np.intp)
    n_rest = n - int(counts.sum())
    if n_rest > 0:
        res = nw - counts
        res /= res.sum()
        u = np.sort(rng.random(n_rest))
        counts += np.bincount(_inverse_cdf(res, u), minlength=n)
    return np.repeat(np.arange(n, dtype=np.intp), counts)


RESAMPLERS: dict[str, Callable[[F64, np.random.Generator], IDX]] = {
    "systematic": systematic,
    "stratified": stratified,
    "multinomial": multinomial,
    "residual": residual,
}
