"""The fixes' stated accuracy checked against their innovations.

A receiver's ``position_covariance`` is what the receiver believes, not its error: a driver that
passes on a consumer receiver's accuracy estimate, or one derived from HDOP, can be off by a
factor of three in std either way. Taken as stated, a covariance whose std is 3.3 times too small
left the rear radii of ten simulated 10-min drives with positions only 0.15-12 mm off, at a NEES
of 11 to 15,000; one three times too large widens the reported std and the pose's error.

The check: every fix predicted with a pose (used, anchored or rejected as an outlier) gives its
innovation across the track (the direction of the pose's heading turned left), squared over its
predicted variance: chi-square with one degree of freedom when the covariance is right. Along
the track a wrong radius scale, a latency or a wheel-speed offset move the fixes as well; across
it they do not. These values are collected in windows of :data:`WINDOW_S` seconds and at least
:data:`WINDOW_MIN_FIXES` fixes; a window's median over the chi-square median (0.455) is the
factor ``q`` by which the fixes' variance is off (the median is not moved by the outliers an
understated covariance produces). When two windows in a row give ``q`` beyond :data:`LIMIT` on
the same side, every later fix covariance is multiplied by the geometric mean of the two (the
total scale bounded to ``1 / MAX_SCALE .. MAX_SCALE``), and the check goes on with the scaled
fixes. A window acts only while the stated covariance makes up at least :data:`MIN_SHARE` of
the predicted variance (the rest: the particle cloud's spread, a Gauss-Markov error of a fixed
size, ``radius.gnss_bias_std_m``): otherwise the innovations do not measure it. A filter that
has followed its fixes shows a ``q`` beyond the truth; the next windows show what is left, and
nothing within the band is changed. When the fixes are found less accurate than stated, what
was learned from them is not kept: the estimator restarts the radii and the pose
(``RadiusEstimator._scale_radii`` with a factor of 1).

On one simulated drive each, ``q`` stayed within 0.7-1.4 for the clean drives (with and without
the Doppler velocity) and within 0.8-2.5 with the unmodelled effects the residual analysis
names at the sizes of ``docs/results.md`` (a fix or velocity latency of 0.2 s, a wheel-speed
offset of 0.1 s, a speed- or load-dependent radius, a lateral antenna offset of 0.5 m): those
are left to the verdict. A stated covariance 3.3 times too small in std gave ``q`` of 24-64.
"""

from __future__ import annotations

import math
import statistics

import numpy as np

from tire_estimation.core.arrays import F64

#: a window's length, s
WINDOW_S = 30.0

#: fewest fixes in a window
WINDOW_MIN_FIXES = 50

#: a window's variance factor ``q`` beyond ``LIMIT`` or below ``1 / LIMIT`` counts
LIMIT = 3.0

#: the total scale of the fix covariance stays within ``1 / MAX_SCALE .. MAX_SCALE``
MAX_SCALE = 100.0

#: a window acts only when the stated covariance is at least this share of the innovation's
#: predicted variance (across the track, mean of the window)
MIN_SHARE = 0.5

#: median of a chi-square variable with 1 degree of freedom
CHI2_1_MEDIAN = 0.45493642311957283


def across_track(yaw_rad: float, innovation_m: F64, s_m2: F64, r_m2: F64) -> tuple[float, float]:
    """The innovation across the track (heading ``yaw_rad`` turned left), squared over its
    predicted variance from ``s_m2`` (2, 2), and the share of the stated covariance ``r_m2``
    (2, 2) in that variance; NaN for both when the variance is not positive."""
    across = np.array([-math.sin(yaw_rad), math.cos(yaw_rad)])
    # c^T S c, c^T nu, c^T R c
    s = float(across @ s_m2 @ across)
    if not s > 0.0:
        return math.nan, math.nan
    nu = float(across @ innovation_m)
    return nu * nu / s, float(across @ r_m2 @ across) / s


class FixCovarianceCheck:
    """Scales the fix covariance when its innovations show it off by a factor beyond
    :data:`LIMIT` in two windows in a row (module docstring)."""

    def __init__(self, enabled: bool = True) -> None:
        self.enabled = enabled
        #: the factor every fix covariance is multiplied by
        self.scale = 1.0
        #: the factors applied, in order
        self.changes: list[float] = []
        #: stamps of the changes, ns
        self.change_t_ns: list[int] = []
        #: the variance factor ``q`` of the last complete window (None before one)
        self.last_ratio: float | None = None
        self._nis: list[float] = []
        self._share: list[float] = []
        self._t0_ns: int | None = None
        self._pending: float | None = None

    def apply(self, r_m2: F64) -> F64:
        """The fix covariance ``r_m2`` (2, 2) with the scale applied."""
        return r_m2 if self.scale == 1.0 else r_m2 * self.scale

    def add(self, t_ns: int, nis: float, share: float = 1.0) -> bool:
        """One fix's innovation across the track, squared over its predicted variance (with the
        scaled covariance), and the share of the stated covariance in that variance; return
        True when the scale changed."""
        if not self.enabled or not math.isfinite(nis) or not math.isfinite(share):
            return False
        if self._t0_ns is None:
            self._t0_ns = t_ns
        self._nis.append(nis)
        self._share.append(share)
        if (t_ns - self._t0_ns) * 1e-9 < WINDOW_S or len(self._nis) < WINDOW_MIN_FIXES:
            return False
        q = statistics.median(self._nis) / CHI2_1_MEDIAN
        share = statistics.fmean(self._share)
        self._nis.clear()
        self._share.clear()
        self._t0_ns = None
        self.last_ratio = q
        if 1.0 / LIMIT <= q <= LIMIT or share < MIN_SHARE:
            self._pending = None
            return False
        prev, self._pending = self._pending, q
        if prev is None or (prev > 1.0) != (q > 1.0):
            return False
        factor = math.sqrt(prev * q)
        total = min(max(self.scale * factor, 1.0 / MAX_SCALE), MAX_SCALE)
        self._pending = None
        if total == self.scale:
            return False
        self.changes.append(total / self.scale)
        self.change_t_ns.append(t_ns)
        self.scale = total
        return True
