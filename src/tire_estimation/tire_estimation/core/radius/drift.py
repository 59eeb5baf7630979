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
