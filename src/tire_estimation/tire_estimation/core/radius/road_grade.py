"""Online road grade: least-squares slope of the GNSS altitude over the wheel-travelled
(slope) distance, the input of the ``road_grade`` effect (:mod:`.effects`)."""

from __future__ import annotations

import math
from collections import deque

#: at most this many GNSS altitudes are kept for the grade fit (100 s at 10 Hz)
GRADE_MAX_POINTS = 1000

#: travelled distance over which the grade is fitted, m: long against the altitude noise of a
#: fix (a 1 m altitude error over 100 m is 1 %), short against the length of a slope
ROAD_GRADE_WINDOW_M = 100.0


class SlidingLine:
    """Least-squares slope of ``z`` over ``s`` for points entering at the right and leaving at
    the left, in O(1) per point: running sums about an origin (the oldest point at the last
    rebuild), rebuilt from the points every ``REBUILD`` appends to bound the rounding drift."""

    REBUILD = 512

    def __init__(self, max_points: int) -> None:
        self.pts: deque[tuple[float, float]] = deque()
        self.max_points = max_points
        self._rebuild()

    def _rebuild(self) -> None:
        s0, z0 = self.pts[0] if self.pts else (0.0, 0.0)
        self._o = (s0, z0)
        self._n_s = self._n_z = self._n_ss = self._n_sz = 0.0
        self._updates = 0
        for s, z in self.pts:
            self._add(s, z, 1.0)

    def _add(self, s: float, z: float, sign: float) -> None:
        ds, dz = s - self._o[0], z - self._o[1]
        self._n_s += sign * ds
        self._n_z += sign * dz
        self._n_ss += sign * ds * ds
        self._n_sz += sign * ds * dz

    def append(self, s: float, z: float) -> None:
        if len(self.pts) >= self.max_points:
            self.popleft()
        if not self.pts:
            self.pts.append((s, z))
            self._rebuild()  # the origin is this point
            return
        self.pts.append((s, z))
        self._add(s, z, 1.0)
        self._updates += 1
        if self._updates >= self.REBUILD:
            self._rebuild()

    def popleft(self) -> None:
        s, z = self.pts.popleft()
        self._add(s, z, -1.0)

    def slope(self) -> float:
        """``sum (s - s_mean)(z - z_mean) / sum (s - s_mean)^2`` (NaN if degenerate)."""
        n = len(self.pts)
        sxx = self._n_ss - self._n_s * self._n_s / n
        sxz = self._n_sz - self._n_s * self._n_z / n
        return sxz / sxx if sxx > 0.0 else math.nan


class RoadGradeFit:
    """Wheel-travelled distance and the grade fitted to the GNSS altitudes over it."""

    def __init__(self) -> None:
        #: slope distance rolled by the rear wheels, m
        self.distance_m = 0.0
        self._fit = SlidingLine(GRADE_MAX_POINTS)
        #: online grade (positive uphill), rad; 0 until a window of fixes is available
        self.grade_rad = 0.0

    def roll(self, dt_s: float, rolled_m_s: float) -> None:
        """Add ``dt_s`` at the rolling speed ``rolled_m_s`` to the distance."""
        self.distance_m += dt_s * rolled_m_s

    def fix(self, up_m: float) -> None:
        """Update the grade with a GNSS altitude: least-squares slope of the altitude over the
        wheel-travelled distance in the last :data:`ROAD_GRADE_WINDOW_M`."""
        window = ROAD_GRADE_WINDOW_M
        fit = self._fit
        fit.append(self.distance_m, up_m)
        pts = fit.pts
        while pts and pts[0][0] < self.distance_m - window:
            fit.popleft()
        if len(pts) < 5 or pts[-1][0] - pts[0][0] < 0.5 * window:
            return  # keep the last estimate (standstill, start)
        # sin(theta) = dz / ds along the slope distance s (least-squares slope)
        sin_grade = fit.slope()
        if math.isfinite(sin_grade):
            self.grade_rad = math.asin(min(0.5, max(-0.5, sin_grade)))
