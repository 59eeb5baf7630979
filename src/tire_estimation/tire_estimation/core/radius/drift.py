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


class DriftTest:
    """The mean-innovation test over the last ``window`` accepted fixes.

    Args:
        gate: the chi-square (2 dof) quantile the statistic is compared with.
        window: number of accepted fixes in the mean.
    """

    def __init__(self, gate: float, window: int = DRIFT_WINDOW_FIXES) -> None:
        self.gate = float(gate)
        self.window = int(window)
        self._info: deque[F64] = deque(maxlen=self.window)
        self._weighted: deque[F64] = deque(maxlen=self.window)

    def clear(self) -> None:
        """Forget the fixes (after a re-initialization or a widening of the cloud)."""
        self._info.clear()
        self._weighted.clear()

    def push(self, innovation_m: F64, innovation_cov_m2: F64) -> F64 | None:
        """Add an accepted fix's innovation (2,) and its covariance (2, 2); return the mean
        innovation (2,) when the window is full and the test fires, else None."""
        s_inv = np.linalg.inv(innovation_cov_m2)
        self._info.append(s_inv)
        self._weighted.append(s_inv @ innovation_m)
        if len(self._info) < self.window:
            return None
        info = np.sum(self._info, axis=0)
        total = np.sum(self._weighted, axis=0)
        mean = np.linalg.solve(info, total)
        if not float(total @ mean) > self.gate:
            return None
        return mean


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
