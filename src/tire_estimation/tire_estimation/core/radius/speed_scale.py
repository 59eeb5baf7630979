"""A gross error of the radii, seen in the receiver's speed, and the radii moved to it.

The MPF learns a radius error of the size its prior allows (``prior_radius_error_std_m``, 3
mm: 1 % of a car's radius) within seconds; one several times larger (a ``vehicle.yaml`` that
states the rim's nominal radius, new tyres of another size under radii restored from the last
drive) it creeps towards at the pace of the radius random walk, about 1.5 mm per minute, while
reporting a std of 0.1-0.2 mm: a 20-mm error (6.5 %) took 13 min on the simulator's car and
the GNSS velocities were all rejected as outliers meanwhile.

The receiver's Doppler speed tells the scale directly. On straight driving at a steady speed
the ratio of the antenna's horizontal speed to the rear wheels' (with the learned radii) is 1
up to the noise; its median over :data:`WINDOW` velocities is compared with 1. Beyond
:data:`GROSS_RATIO` (2 %; a tyre losing 20 % of its pressure moves the axle's mean by about
0.25 %) and the median's own noise, in two windows in a row, both rear radii are scaled by the
latest median: every particle's NiW mean
(and the AUG-KF's radii) moves by ``(r_n + mu) (median - 1)``, the learning then refines the
split. Counted and reported (``radii.speed_scale`` in ``metrics.json``, ``speed_scale.*`` on
``/diagnostics``, a ``RADII RESCALED`` line in the replay's summary).

A receiver that reports positions only (no Doppler velocity, or the velocity switched off) is
checked on the same terms through :class:`StraightRuns`: the distance between the fixes of a
straight run against the distance the rear wheels rolled over it.
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

import numpy as np

from tire_estimation.core.state_checks import MAX_RADIUS_ERROR_FRACTION

#: velocities whose median ratio is tested (one window after the other, not sliding)
WINDOW = 50

#: |median - 1| beyond which a window counts as a gross error: 2 % (six prior stds; the MPF
#: learns a 3 % error by itself, on the simulator's car within a minute); two windows in a row
#: on the same side rescale the radii
GROSS_RATIO = 0.02

#: ... and beyond this many standard errors of the median (the ratio is noisy at low speed:
#: 1.7 % per velocity at 3 m/s)
NOISE_MULTIPLE = 6.0

#: a ratio is taken at this speed and above, m/s, this straight (|yaw rate|, rad/s)
MIN_SPEED_M_S = 3.0
MAX_YAW_RATE_RAD_S = 0.05


#: straight runs whose median ratio is tested
RUN_WINDOW = 10

#: a run spans this many times the fixes' reported std of wheel distance (so that one run's
#: ratio is good to 1-2 %: a line fitted to n fixes over a length L has a slope error of
#: std sqrt(12 / n) / L; longer runs are rarer), within these bounds, m
RUN_LENGTH_PER_STD = 70.0
MIN_RUN_M = 30.0
MAX_RUN_M = 100.0

#: a run is taken at this wheel speed and above, m/s (its length sets its precision, not the
#: speed)
MIN_RUN_SPEED_M_S = 1.0

#: time constant of the low-pass of the yaw rate that tells straight driving, s
YAW_SMOOTHING_S = 0.5

#: a run whose heading (the wheels' yaw rate integrated) spans more than this, or whose two
#: halves of fixes point more than this apart, is not straight, rad. Within it the fitted
#: slope falls short of the path by at most dpsi^2 / 40 on an arc (the least-squares slope of
#: u = s - k^2 s^3 / 6 over a length L is 1 - k^2 L^2 / 40), 0.23 %, and by a^2 / 4 for a
#: weave of heading amplitude a = 0.15 rad, 0.56 %: well inside GROSS_RATIO
MAX_BEND_RAD = 0.3

#: ... nor one whose speed varies by more than this share of its mean (a latency of the fixes
#: against the wheel speeds would move the fitted slope by latency * dv / L)
MAX_SPEED_SPREAD = 0.3


class StraightRuns:
    """The distance between GNSS fixes over the rear wheels' along straight runs.

    The wheels' rolled angle is integrated between the fixes (:meth:`roll`, per wheel sample);
    a run starts at a fix and ends at the fix where the wheels have rolled the run's length, or
    at the first fix after the driving left the bounds (turning, slow, a gap). Its fixes are
    fitted with a line against the rolled angle: ``enu = p0 + g * angle``; ``|g|`` is the
    rolling radius the run measured (m per radian), independent of what the filter has learned
    meanwhile.
    """

    def __init__(self) -> None:
        self._yaw_lp = 0.0
        self._angle_rad = 0.0
        self._heading_rad = self._heading_min = self._heading_max = 0.0
        self._speed_min = math.inf
        self._speed_max = 0.0
        self._broken = True
        #: (rolled angle rad, east m, north m) of the current run's fixes
        self._points: list[tuple[float, float, float]] = []
        #: runs that ended long enough but bent or uneven in speed (not used)
        self.rejected = 0
        #: the heading change the wheel speeds' yaw rate gives since the start (no fix
        #: corrects it), rad: the turn regressor of the residual analysis
        self.wheel_yaw_rad = 0.0

    def roll(
        self, dt_s: float, omega_rad_s: float, yaw_rate_rad_s: float, speed_m_s: float
    ) -> None:
        """One wheel-speed step: the rear wheels' mean speed (rad/s), the yaw rate and the
        speed (any sign: a reversing run counts the same)."""
        speed = abs(speed_m_s)
        self.wheel_yaw_rad += yaw_rate_rad_s * dt_s
        # the yaw rate low-passed over YAW_SMOOTHING_S: one wheel sample's speed quantization
        # reads as a yaw rate of several 0.01 rad/s
        self._yaw_lp += (yaw_rate_rad_s - self._yaw_lp) * min(1.0, dt_s / YAW_SMOOTHING_S)
        if speed < MIN_RUN_SPEED_M_S or abs(self._yaw_lp) > MAX_YAW_RATE_RAD_S:
            self._broken = True
            return
        self._angle_rad += abs(omega_rad_s) * dt_s
        self._heading_rad += self._yaw_lp * dt_s
        if self._heading_rad < self._heading_min:
            self._heading_min = self._heading_rad
        elif self._heading_rad > self._heading_max:
            self._heading_max = self._heading_rad
        if speed < self._speed_min:
            self._speed_min = speed
        if speed > self._speed_max:
            self._speed_max = speed

    def gap(self) -> None:
        """The wheel speeds or the pose were interrupted: the run ends."""
        self._broken = True

    def fix(self, east_m: float, north_m: float, std_m: float, radius_m: float) -> float | None:
        """A fix (ENU, m) with its reported horizontal std; ``radius_m`` the learned mean rear
        radius (it sets the run's length). Returns the rolling radius a run that ends here
        measured (the fixes' distance per radian the wheels rolled, m), else None."""
        ratio = None
        length_m = self._angle_rad * radius_m
        target_m = min(MAX_RUN_M, max(MIN_RUN_M, RUN_LENGTH_PER_STD * std_m))
        if self._broken or length_m >= target_m:
            if not self._broken:
                self._points.append((self._angle_rad, east_m, north_m))
            if len(self._points) >= 3 and self._points[-1][0] * radius_m >= MIN_RUN_M:
                ratio = self._fit()
            self._start()
            self._broken = False
        self._points.append((self._angle_rad, east_m, north_m))
        return ratio

    def _start(self) -> None:
        self._angle_rad = 0.0
        self._heading_rad = self._heading_min = self._heading_max = 0.0
        self._speed_min = math.inf
        self._speed_max = 0.0
        self._points = []

    def _fit(self) -> float | None:
        pts = np.asarray(self._points)
        speed_mean = 0.5 * (self._speed_min + self._speed_max)
        if self._speed_max - self._speed_min > MAX_SPEED_SPREAD * speed_mean:
            self.rejected += 1
            return None
        x = pts[:, 0]
        half = len(x) // 2
        if half < 2 or self._heading_max - self._heading_min > MAX_BEND_RAD:
            self.rejected += 1
            return None
        # least squares of [1, x] against east and north: the slopes g are distance per radian
        g = _slopes(x, pts[:, 1:])
        g1, g2 = _slopes(x[: half + 1], pts[: half + 1, 1:]), _slopes(x[half:], pts[half:, 1:])
        bend = abs(math.remainder(math.atan2(g2[1], g2[0]) - math.atan2(g1[1], g1[0]), math.tau))
        if bend > MAX_BEND_RAD:
            self.rejected += 1
            return None
        return math.hypot(g[0], g[1])


def _slopes(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Least-squares slopes of the columns of ``y`` (n, 2) against ``x`` (n,)."""
    xc = x - x.mean()
    return (xc @ (y - y.mean(axis=0))) / float(xc @ xc)


class _Window:
    """Values whose median is tested, one full window after the other."""

    def __init__(self, size: int) -> None:
        #: ratios (the Doppler speed's, 1) or radii (the straight runs', m)
        self.values: deque[float] = deque(maxlen=size)
        #: the previous window's median when it was beyond the bound, else None
        self.previous: float | None = None

    def clear(self) -> None:
        self.values.clear()
        self.previous = None


class SpeedScaleCheck:
    """The median GNSS-over-wheel distance ratio and the rescalings it asked for: from the
    Doppler speed (:meth:`add`) and from straight runs between fixes (:meth:`add_fix`)."""

    def __init__(self, nominal_radius_m: float) -> None:
        #: whether a gross error is acted on (studies switch it off to show what it does)
        self.enabled = True
        #: a rescale may take the radii at most MAX_RADIUS_ERROR_FRACTION from this, m
        self._limits_m = (
            nominal_radius_m * (1.0 - MAX_RADIUS_ERROR_FRACTION),
            nominal_radius_m * (1.0 + MAX_RADIUS_ERROR_FRACTION),
        )
        #: scale factors shown but beyond that bound (not applied): a unit or a diameter
        self.refused: list[float] = []
        self._windows = {"velocity": _Window(WINDOW), "fixes": _Window(RUN_WINDOW)}
        #: the straight runs between fixes (the estimator rolls them on each wheel sample)
        self.runs = StraightRuns()
        #: the scale factors applied so far (1.05: the radii grew by 5 %), when, and from what
        #: ("velocity" or "fixes")
        self.rescales: list[float] = []
        self.rescale_t_ns: list[int] = []
        self.rescale_sources: list[str] = []
        #: the median ratio of the latest full window of each source (1 until one is full)
        self.median_ratio = {"velocity": 1.0, "fixes": 1.0}

    def add(
        self,
        t_ns: int,
        gnss_speed_m_s: float,
        wheel_speed_m_s: float,
        yaw_rate_rad_s: float,
        radius_m: float,
    ) -> float:
        """One steady velocity stamped ``t_ns`` (the caller has gated acceleration): the
        antenna's horizontal speed, the rear wheels' with the learned radii and the yaw rate of
        the wheel-speed difference with the nominal radii (a wrong learned split must not hide
        the straight driving); ``radius_m`` the learned mean rear radius. Returns the factor to
        scale the rear radii by now, or 1."""
        if (
            not self.enabled
            or wheel_speed_m_s < MIN_SPEED_M_S
            or abs(yaw_rate_rad_s) > MAX_YAW_RATE_RAD_S
            or not math.isfinite(gnss_speed_m_s)
        ):
            return 1.0
        return self._test("velocity", t_ns, gnss_speed_m_s / wheel_speed_m_s, 1.0, radius_m)

    def add_fix(
        self, t_ns: int, east_m: float, north_m: float, std_m: float, radius_m: float
    ) -> float:
        """One fix (ENU, m; its reported horizontal std) and the learned mean rear radius:
        returns the factor to scale the rear radii by now, or 1."""
        run_radius_m = self.runs.fix(east_m, north_m, std_m, radius_m)
        if run_radius_m is None or not self.enabled:
            return 1.0
        # the runs' radii, not their ratios to the learned one, are kept: the learning moves
        # the radius while a window fills (minutes, where straight runs are rare)
        return self._test("fixes", t_ns, run_radius_m, radius_m, radius_m)

    def _test(
        self, source: str, t_ns: int, value: float, reference: float, radius_m: float
    ) -> float:
        """``value`` (a ratio, or a run's radius) into ``source``'s window; a full window's
        median over ``reference`` is the ratio tested; a rescale that would take the learned
        radius ``radius_m`` beyond :data:`MAX_RADIUS_ERROR_FRACTION` of nominal is refused."""
        window = self._windows[source]
        window.values.append(value)
        if len(window.values) < (window.values.maxlen or 0):
            return 1.0
        values = list(window.values)
        window.values.clear()
        med_value = median(values)
        self.median_ratio[source] = med = med_value / reference
        # the median's standard error from the window's own spread (1.4826 MAD estimates the
        # std; the median of n has about 1.25 std / sqrt(n))
        mad = median(abs(x - med_value) for x in values) / reference
        noise = 1.25 * 1.4826 * mad / math.sqrt(len(values))
        gross = abs(med - 1.0) > max(GROSS_RATIO, NOISE_MULTIPLE * noise)
        previous, window.previous = window.previous, (med if gross else None)
        if not gross or previous is None or (previous - 1.0) * (med - 1.0) <= 0.0:
            return 1.0
        # two windows in a row beyond the bound, on the same side: the latest is the scale
        if not self._limits_m[0] <= radius_m * med <= self._limits_m[1]:
            self.refused.append(med)
            self.restart()
            return 1.0
        self.rescales.append(med)
        self.rescale_t_ns.append(t_ns)
        self.rescale_sources.append(source)
        self.restart()
        return med

    def restart(self) -> None:
        """Forget the windows and the current run (the radii were reset or replaced)."""
        for window in self._windows.values():
            window.clear()
        self.runs.gap()

    def summary(self) -> dict[str, object]:
        """For ``metrics.json``: the rescalings and the latest median ratios."""
        return {
            "rescales": list(self.rescales),
            "rescale_t_ns": list(self.rescale_t_ns),
            "rescale_sources": list(self.rescale_sources),
            "refused": list(self.refused),
            "median_ratio": dict(self.median_ratio),
        }
