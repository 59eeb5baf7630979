"""Online road grade, the input of the ``road_grade`` effect (:mod:`.effects`): the
least-squares slope of the GNSS altitude over the wheel-travelled (slope) distance, checked
against the grade that the IMU's specific force gives over the same distance.

A consumer receiver's altitude can wander by tens of metres within minutes, which a fit over
100 m reads as a steep hill. The accelerometer sees the grade too: along the road,

    specific force: f_x = dv/dt + g sin(theta)

(v the speed along the slope, theta the grade, positive uphill). Multiplied by ``v`` and
integrated over time it is an altitude: ``integral f_x v dt - v^2 / 2 = g z + const``, since
``g sin(theta) v dt = g dz``. The least-squares slope of that IMU altitude over the same
fixes' travelled distances is the IMU grade, free of the altitude error but offset by the
accelerometer's bias and mounting pitch. That offset is constant, and the altitude has none
over long distances: the slope of the IMU altitude minus the GNSS altitude over the distance
since the IMU stream became continuous is the offset. The check allows for an offset of the
size of :data:`IMU_GRADE_STD_RAD`; one beyond :data:`OFFSET_MIN_RAD` (an IMU pitched on its
mount by 2 degrees reads 3.5 %) is taken out of the IMU grade once its standard error (twice
the residual scatter plus :data:`ALTITUDE_WANDER_M`, over the span) is at most
:data:`OFFSET_MAX_SE` (an altitude that drifts steadily over kilometres is read as an offset
of the IMU). The altitude grade is used where a chi-square test finds the two consistent;
elsewhere the grade is the IMU's (``road_grade_source: checked``, the default) or the
altitude's alone (``altitude``). The IMU's rather than none: its offset ``b`` costs ``b^2 / 2``
of the distance where the road is flat (1.2e-4 at one std, 0.04 mm on a 0.3 m tyre), no grade
costs ``theta^2 / 2`` on a slope (1.8e-3 at 6 %).
"""

from __future__ import annotations

import math
from collections import deque

from scipy.special import chdtri

#: at most this many GNSS altitudes are kept for the grade fit (100 s at 10 Hz)
GRADE_MAX_POINTS = 1000

#: travelled distance over which the grade is fitted, m: long against the altitude noise of a
#: fix (a 1 m altitude error over 100 m is 1 %), short against the length of a slope
ROAD_GRADE_WINDOW_M = 100.0

#: travelled distance the IMU altitude needs before its grade is used, m: its slope is not
#: limited by noise (vibration averages out in the integral) but by the offset, so a quarter
#: of the altitude's window suffices (the IMU altitude starts after the first wheel-speed
#: interval, a fix later than the altitude's)
IMU_GRADE_MIN_SPAN_M = 0.25 * ROAD_GRADE_WINDOW_M

#: standard gravity, m/s^2
G_M_S2 = 9.80665

#: std of the IMU grade's offset, rad: 0.15 m/s^2 of specific force along x over g. It is the
#: root sum square of a consumer MEMS accelerometer's bias after turn-on (0.1 m/s^2, the
#: simulator's ``accel_bias_initial_std_m_s2``; 0.05-0.1 m/s^2 is typical of automotive
#: parts), a mounting pitch of 0.5 degree (g sin(0.5 deg) = 0.086 m/s^2) and the body's pitch
#: on its suspension under the window's mean acceleration (about 0.05 m/s^2): sqrt(0.1^2 +
#: 0.086^2 + 0.05^2) = 0.14, rounded up
IMU_GRADE_STD_RAD = 0.15 / G_M_S2

#: shortest span of the IMU grade's offset fit, m
OFFSET_MIN_SPAN_M = 500.0

#: the GNSS altitude's slow error that the scatter about a line may not show (a wander as
#: long as the span), m
ALTITUDE_WANDER_M = 5.0

#: largest standard error of an offset estimate used, rad: a third of
#: :data:`IMU_GRADE_STD_RAD` (with the simulator's 1.5-m altitude error, about 2 km of travel)
OFFSET_MAX_SE = IMU_GRADE_STD_RAD / 3.0

#: an offset is taken out of the IMU grade from this size on, rad: twice the one the check
#: allows for (3 % of grade, 0.3 m/s^2 of specific force, a mounting pitch of 1.75 degrees)
OFFSET_MIN_RAD = 2.0 * IMU_GRADE_STD_RAD

#: the offset is bounded to this, rad (a 5-degree mounting pitch and a bias of 0.15 m/s^2)
OFFSET_MAX_RAD = 0.1

#: a point of the offset's line every this much travel, m (4000 points: 20 km)
OFFSET_STEP_M = 5.0

#: chi-square (1 dof) probability of the altitude-against-IMU test: the altitude grade is
#: rejected when ``(theta_alt - theta_imu)^2 / (var_alt + var_imu)`` exceeds its quantile
GRADE_CHECK_PROBABILITY = 0.99

#: the sources of the grade, as counted per fix in :attr:`RoadGradeFit.counts`
GRADE_SOURCES = ("altitude", "imu", "none")

#: how the grade is chosen (``RadiusEstimatorConfig.road_grade_source``): ``checked`` = the
#: altitude grade where the IMU grade confirms it, the IMU grade where it does not, none
#: without a fresh IMU; ``altitude`` = the altitude grade alone
GRADE_SOURCE_MODES = ("checked", "altitude")


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
        self._n_s = self._n_z = self._n_ss = self._n_sz = self._n_zz = 0.0
        self._updates = 0
        for s, z in self.pts:
            self._add(s, z, 1.0)

    def _add(self, s: float, z: float, sign: float) -> None:
        ds, dz = s - self._o[0], z - self._o[1]
        self._n_s += sign * ds
        self._n_z += sign * dz
        self._n_ss += sign * ds * ds
        self._n_sz += sign * ds * dz
        self._n_zz += sign * dz * dz

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

    def clear(self) -> None:
        """Forget every point."""
        self.pts.clear()
        self._rebuild()

    def span(self) -> float:
        """Distance between the first and the last point (0 when fewer than two)."""
        return self.pts[-1][0] - self.pts[0][0] if len(self.pts) > 1 else 0.0

    def _scatter(self) -> tuple[float, float]:
        """Residual variance about the line (n - 2 dof) and ``sum (s - s_mean)^2``; NaN for
        both if degenerate."""
        n = len(self.pts)
        if n < 3:
            return math.nan, math.nan
        sxx = self._n_ss - self._n_s * self._n_s / n
        sxz = self._n_sz - self._n_s * self._n_z / n
        szz = self._n_zz - self._n_z * self._n_z / n
        if sxx <= 0.0:
            return math.nan, math.nan
        return max(szz - sxz * sxz / sxx, 0.0) / (n - 2), sxx

    def slope_var(self) -> float:
        """Variance of :meth:`slope` from the points' own scatter about the line,
        ``s^2 / sum (s - s_mean)^2`` with ``s^2`` the residual variance (n - 2 dof); NaN if
        degenerate. Errors correlated over the window (a wandering altitude) do not show in
        it."""
        var, sxx = self._scatter()
        return var / sxx

    def scatter_std(self) -> float:
        """Std of the points about their line (n - 2 dof); NaN if degenerate."""
        return math.sqrt(self._scatter()[0])

    def slope(self) -> float:
        """``sum (s - s_mean)(z - z_mean) / sum (s - s_mean)^2`` (NaN if degenerate)."""
        n = len(self.pts)
        sxx = self._n_ss - self._n_s * self._n_s / n
        sxz = self._n_sz - self._n_s * self._n_z / n
        return sxz / sxx if sxx > 0.0 else math.nan


class RoadGradeFit:
    """Wheel-travelled distance, the altitude and IMU grades fitted over it and the grade used.

    Args:
        mode: one of :data:`GRADE_SOURCE_MODES`.
    """

    def __init__(self, mode: str = "checked") -> None:
        self.mode = mode
        #: slope distance rolled by the rear wheels, m
        self.distance_m = 0.0
        self._fit = SlidingLine(GRADE_MAX_POINTS)
        #: IMU altitude ``(integral f_x v dt - v^2 / 2) / g`` at the fixes' distances
        self._imu_fit = SlidingLine(GRADE_MAX_POINTS)
        #: ``integral f_x v dt`` since the IMU stream became continuous, m^2/s^2
        self._work_m2_s2 = 0.0
        #: rolling speed of the latest wheel sample, m/s
        self._speed_m_s = 0.0
        self._imu_continuous = False
        #: grade used by the correction (positive uphill), rad; 0 until a window is available
        self.grade_rad = 0.0
        #: where :attr:`grade_rad` came from at the latest fix (one of :data:`GRADE_SOURCES`)
        self.source = "none"
        #: fixes (with a full window) per source of the grade
        self.counts = dict.fromkeys(GRADE_SOURCES, 0)
        #: the latest altitude and IMU grades (NaN when not available), rad, and their
        #: normalized squared difference
        self.altitude_grade_rad = math.nan
        self.imu_grade_rad = math.nan
        self.check_nis = math.nan
        self._gate = float(chdtri(1, 1.0 - GRADE_CHECK_PROBABILITY))
        #: (IMU altitude - GNSS altitude) at the fixes' distances, for the IMU grade's offset
        self._offset_fit = SlidingLine(4000)
        #: the IMU grade's offset (accelerometer bias and mounting pitch; sin of the grade),
        #: taken out of the IMU grade; 0 until estimated beyond OFFSET_MIN_RAD
        self.imu_offset = 0.0
        self._offset_se = OFFSET_MAX_SE

    def roll(
        self,
        dt_s: float,
        rolled_m_s: float,
        fx_m_s2: float | None = None,
        forward_m_s: float | None = None,
    ) -> None:
        """Add ``dt_s`` at the rolling speed ``rolled_m_s`` (>= 0) to the distance;
        ``fx_m_s2`` is the IMU's longitudinal specific force over the step (None: no fresh IMU,
        which restarts the IMU grade) and ``forward_m_s`` the signed speed along ``base_link``
        x (negative in reverse; None: ``rolled_m_s``)."""
        self.distance_m += dt_s * rolled_m_s
        v = rolled_m_s if forward_m_s is None else forward_m_s
        self._speed_m_s = v
        if fx_m_s2 is None:
            self.restart_imu()
            return
        self._imu_continuous = True
        # specific force times the signed speed: f_x v = d(v^2 / 2)/dt + g dz/dt (in reverse
        # both v and the nose-up grade's sign flip, dz/dt = v sin(theta) keeps its meaning)
        self._work_m2_s2 += fx_m_s2 * v * dt_s

    def restart_imu(self) -> None:
        """Restart the IMU grade (no fresh IMU, or a wheel-speed gap that the integral of
        ``f_x v`` cannot span)."""
        if self._imu_continuous:
            self._imu_continuous = False
            self._imu_fit.clear()
            self._offset_fit.clear()
            self._work_m2_s2 = 0.0

    def fix(self, up_m: float) -> None:
        """Update the grade with a GNSS altitude: least-squares slopes of the altitude and of
        the IMU altitude over the wheel-travelled distance in the last
        :data:`ROAD_GRADE_WINDOW_M`, and the choice between them."""
        window = ROAD_GRADE_WINDOW_M
        s = self.distance_m
        fit, imu = self._fit, self._imu_fit
        fit.append(s, up_m)
        if self._imu_continuous:
            # IMU altitude: g z = integral f_x v dt - v^2 / 2 (+ const)
            imu.append(s, z_imu := (self._work_m2_s2 - 0.5 * self._speed_m_s**2) / G_M_S2)
            self._track_offset(s, z_imu - up_m)
        for line in (fit, imu):
            while line.pts and line.pts[0][0] < s - window:
                line.popleft()
        if len(fit.pts) < 5 or fit.span() < 0.5 * window:
            return  # keep the last estimate (standstill, start)
        # sin(theta) = dz / ds along the slope distance s (least-squares slope)
        sin_alt = fit.slope()
        if not math.isfinite(sin_alt):
            return
        self.altitude_grade_rad = math.asin(min(0.5, max(-0.5, sin_alt)))
        self.imu_grade_rad = self.check_nis = math.nan
        if len(imu.pts) >= 5 and imu.span() >= IMU_GRADE_MIN_SPAN_M:
            sin_imu = imu.slope() - self.imu_offset
            if math.isfinite(sin_imu):
                self.imu_grade_rad = math.asin(min(0.5, max(-0.5, sin_imu)))
                var = fit.slope_var() + imu.slope_var() + IMU_GRADE_STD_RAD**2
                self.check_nis = (sin_alt - sin_imu) ** 2 / var
        if self.mode == "altitude":
            source = "altitude"
        elif not math.isfinite(self.check_nis):
            source = "none"  # no IMU grade to check the altitude against
        elif self.check_nis <= self._gate:
            source = "altitude"
        else:
            source = "imu"
        self.source = source
        self.counts[source] += 1
        if source == "altitude":
            self.grade_rad = self.altitude_grade_rad
        elif source == "imu":
            self.grade_rad = self.imu_grade_rad
        else:
            self.grade_rad = 0.0

    def _track_offset(self, s: float, dz_m: float) -> None:
        """A point of the IMU altitude minus the GNSS altitude; the offset (their slope over the
        distance) taken when its standard error is below :data:`OFFSET_MAX_SE` and below that
        of the offset in use (0 while it is below :data:`OFFSET_MIN_RAD`)."""
        line = self._offset_fit
        if line.pts and s - line.pts[-1][0] < OFFSET_STEP_M:
            return
        line.append(s, dz_m)
        span = line.span()
        if span < OFFSET_MIN_SPAN_M or len(line.pts) < 10:
            return
        # the scatter is mostly the altitude's slow wander: twice it (plus a wander it may
        # not show) over the span bounds the slope's error better than the white-noise formula
        se = (2.0 * line.scatter_std() + ALTITUDE_WANDER_M) / span
        slope = line.slope()
        if se < self._offset_se and math.isfinite(slope):
            self._offset_se = se
            slope = min(OFFSET_MAX_RAD, max(-OFFSET_MAX_RAD, slope))
            self.imu_offset = slope if abs(slope) >= OFFSET_MIN_RAD else 0.0
