"""Drift test of the GNSS fix innovations: whether the pose prediction has drifted away from the
fixes while each fix still passes the outlier gate (part of the GNSS handling, :mod:`.gnss`).

A consistent filter's fix innovations ``i_k`` are white with the covariances ``S_k`` it
predicts, so their information-weighted mean over the last ``n`` accepted fixes,
``m = (sum S_k^-1)^-1 sum S_k^-1 i_k``, has the covariance ``(sum S_k^-1)^-1`` and
``T = m' (sum S_k^-1) m`` is chi-square with 2 degrees of freedom. A prediction that drifts
(a radius that changed faster than the filter's random walk lets it, turning the heading)
shows as a mean innovation that the single-fix gate does not see: each fix is within
``sqrt(gate)`` standard deviations of ``S``, the mean of ``n`` of them needs only
``sqrt(gate / n)``. ``T`` is compared with the same chi-square quantile as the outlier gate.

A filter whose noise model does not fit the fixes (a white GNSS error read as partly
Gauss-Markov: ``S`` too small, innovations correlated through the GNSS-error filters) spreads
the mean innovation more than ``S`` says, and ``T`` would pass the quantile in about one window
in a hundred. The test therefore also measures ``T`` against its own scatter: the mean of
``T / 2`` over the last ``K`` non-overlapping windows that did not fire (batch means) estimates
the factor ``c`` by which the mean innovation's covariance exceeds the predicted one, and with
``T_j ~ c chi2_2`` independent, ``T / c_hat`` is ``2 F(2, 2K)``. The test fires when ``T``
passes both the chi-square quantile and ``c_hat`` times the ``2 F(2, 2K)`` quantile of the same
tail probability: a drift is a mean innovation that is large against the fixes' past
scatter, not one that is merely large against ``S``.

When the test fires the particle cloud is too narrow for its error, and it is widened about its
mean (:meth:`~.mpf.RadiusMPF.inflate`) by the factor that makes the mean innovation a typical
deviation of the cloud (covariance matching: ``m' (alpha^2 C)^-1 m = 2`` with ``C`` the cloud's
covariance of the predicted antenna positions), so that the fixes and velocities re-select the
pose, heading and radii from a cloud that covers them; the learned radii are kept.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from tire_estimation.core.arrays import F64

#: accepted fixes whose mean innovation is tested: a systematic offset of
#: ``sqrt(gate / n)`` = 1.4 innovation standard deviations (at the default gate) is seen, where
#: a single fix needs 4.3
DRIFT_WINDOW_FIXES = 10

#: past non-overlapping windows whose statistics measure the filter's own scatter of the mean
#: innovation (batch means): the ``2 F(2, 2K)`` quantile is 21.6 at the default gate
#: probability for ``K = 30`` (18.4 for the chi-square quantile alone), 53 for ``K = 5``; the
#: test does not fire before the first window is complete
DRIFT_HISTORY_WINDOWS = 30


def f2_quantile(tail: float, dof: int) -> float:
    """Upper ``tail`` quantile of the F distribution with (2, ``dof``) degrees of freedom:
    ``P(F > f) = (1 + 2 f / dof)^(-dof / 2)``."""
    return 0.5 * dof * (tail ** (-2.0 / dof) - 1.0)


class DriftTest:
    """The mean-innovation test over the last ``window`` accepted fixes.

    Args:
        gate: the chi-square (2 dof) quantile the statistic is compared with.
        window: number of accepted fixes in the mean.
        history: number of past windows whose statistics measure its scatter.
    """

    def __init__(
        self, gate: float, window: int = DRIFT_WINDOW_FIXES, history: int = DRIFT_HISTORY_WINDOWS
    ) -> None:
        self.gate = float(gate)
        self.window = int(window)
        self.history = int(history)
        # 2 F(2, 2 K) quantiles of the gate's tail probability exp(-gate / 2) (chi-square,
        # 2 dof) for K = 1 .. history past windows
        tail = math.exp(-0.5 * self.gate)
        self._scatter_gates = [2.0 * f2_quantile(tail, 2 * k) for k in range(1, self.history + 1)]
        self._info: deque[F64] = deque(maxlen=self.window)
        self._weighted: deque[F64] = deque(maxlen=self.window)
        self._batches: deque[float] = deque(maxlen=self.history)
        self._since_batch = 0

    def clear(self) -> None:
        """Forget the fixes (after a re-initialization or a widening of the cloud); the past
        windows' scatter is kept."""
        self._info.clear()
        self._weighted.clear()
        self._since_batch = 0

    def threshold(self) -> float:
        """The statistic's threshold: the gate, and ``2 F(2, 2K)`` times the mean half statistic
        of the ``K`` past windows (inf before the first)."""
        k = len(self._batches)
        if k == 0:
            return math.inf
        scale = 0.5 * sum(self._batches) / k
        return max(self.gate, self._scatter_gates[k - 1] * scale)

    def push(self, innovation_m: F64, innovation_cov_m2: F64) -> F64 | None:
        """Add an accepted fix's innovation (2,) and its covariance (2, 2); return the mean
        innovation (2,) when the window is full and the test fires, else None."""
        s_inv = np.linalg.inv(innovation_cov_m2)
        self._info.append(s_inv)
        self._weighted.append(s_inv @ innovation_m)
        self._since_batch += 1
        if len(self._info) < self.window:
            return None
        info = np.sum(self._info, axis=0)
        total = np.sum(self._weighted, axis=0)
        mean = np.linalg.solve(info, total)
        stat = float(total @ mean)
        if stat > self.threshold():
            return mean
        if self._since_batch >= self.window:
            self._batches.append(stat)
            self._since_batch = 0
        return None


def inflation_factor(mean_m: F64, cloud_cov_m2: F64) -> float:
    """Factor ``alpha >= 1`` by which the cloud's spread is scaled so that the mean innovation
    ``mean_m`` (2,) is a typical deviation of the widened cloud: ``m' (alpha^2 C)^-1 m = 2``
    (covariance matching) with ``C`` (2, 2) the cloud's covariance of the predicted antenna
    positions; 1 when the cloud has no spread to scale."""
    c00, c01, c11 = float(cloud_cov_m2[0, 0]), float(cloud_cov_m2[0, 1]), float(cloud_cov_m2[1, 1])
    det = c00 * c11 - c01 * c01
    if not det > 0.0:
        return 1.0
    m0, m1 = float(mean_m[0]), float(mean_m[1])
    maha = (c11 * m0 * m0 - 2.0 * c01 * m0 * m1 + c00 * m1 * m1) / det
    return max(1.0, math.sqrt(maha / 2.0))


def widen_cloud(
    east_m: F64,
    north_m: F64,
    yaw_rad: F64,
    mu_m: F64,
    weights: F64,
    alpha: float,
    prior_mean_std_m: float,
    drift_m: F64 | None = None,
) -> float:
    """Widen a particle cloud about its weighted mean, in place: positions and headings (N,)
    ``x_i <- xbar + alpha (x_i - xbar)``, the NiW means ``mu_m`` (d, N) likewise by
    ``alpha_r <= alpha``; weights, NiW scales and the GNSS-error filters are not touched
    (multiplicative inflation keeps the correlations the cloud learned between pose and radii).
    ``alpha`` is capped so that the spread of the NiW means does not exceed
    ``prior_mean_std_m``, the prior std of the mean radius errors.

    ``drift_m`` (2,), the mean position innovation that made the cloud too narrow: the radii
    are widened only as far as they explain it. The cloud's regression of the radius errors on
    its east/north positions gives the radius change the offset implies, ``dmu = C_mu,p
    C_p,p^-1 drift_m`` (the Kalman shift, unchanged by a multiplicative inflation);
    ``alpha_r`` makes the largest ``|dmu_k| / std_k`` one standard deviation, so that an offset
    the radii do not explain (a slip the model lacks) leaves them as they are and one a changed
    radius explains (a pressure step turning the heading) lets the fixes re-select it. Without
    ``drift_m``, ``alpha_r = alpha``. Returns the factor applied to the pose (1: nothing done).
    """
    w = weights
    mbar = mu_m @ w
    dev = mu_m - mbar[:, None]
    var_r = (dev * dev) @ w
    spread = math.sqrt(float(np.max(var_r)))
    if spread > 0.0:
        alpha = min(alpha, max(1.0, prior_mean_std_m / spread))
    if not alpha > 1.0:
        return 1.0
    alpha_r = alpha
    if drift_m is not None:
        alpha_r = min(
            alpha, max(1.0, _implied_radius_ratio(east_m, north_m, w, dev, var_r, drift_m))
        )
    for a in (east_m, north_m):
        m = float(w @ a)
        a *= alpha
        a += (1.0 - alpha) * m
    # headings are not wrapped, but a cloud may straddle a wrap of its mean: deviations from one
    # particle's heading, wrapped
    ref = float(yaw_rad[0])
    rel = np.remainder(yaw_rad - ref + math.pi, 2.0 * math.pi) - math.pi
    m_rel = float(w @ rel)
    yaw_rad[:] = ref + m_rel + alpha * (rel - m_rel)
    mu_m[...] = mbar[:, None] + alpha_r * dev
    return alpha


def _implied_radius_ratio(
    east_m: F64, north_m: F64, w: F64, dev: F64, var_r: F64, drift_m: F64
) -> float:
    """``max_k |dmu_k| / std_k`` with ``dmu = C_mu,p C_p,p^-1 drift_m`` over the cloud (``dev``
    the NiW means' deviations (d, N), ``var_r`` their weighted variances); 0 when the positions
    or the radii have no spread."""
    pos = np.vstack([east_m - w @ east_m, north_m - w @ north_m])
    c_pp = (pos * w) @ pos.T
    ok = var_r > 0.0
    if not np.linalg.det(c_pp) > 0.0 or not np.any(ok):
        return 0.0
    # Kalman shift of the radius errors for a position offset: C_mu,p C_p,p^-1 drift
    implied = ((dev * w) @ pos.T) @ np.linalg.solve(c_pp, np.asarray(drift_m, dtype=float))
    return float(np.max(np.abs(implied[ok]) / np.sqrt(var_r[ok])))
