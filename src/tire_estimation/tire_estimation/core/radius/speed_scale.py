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
"""

from __future__ import annotations

import math
from collections import deque
from statistics import median

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


class SpeedScaleCheck:
    """The median GNSS-over-wheel speed ratio and the rescalings it asked for."""

    def __init__(self) -> None:
        #: whether a gross error is acted on (studies switch it off to show what it does)
        self.enabled = True
        self._ratios: deque[float] = deque(maxlen=WINDOW)
        #: the scale factors applied so far (1.05: the radii grew by 5 %), and when
        self.rescales: list[float] = []
        self.rescale_t_ns: list[int] = []
        #: the median ratio of the latest full window (1 until one is full)
        self.median_ratio = 1.0
        #: the previous window's median when it was beyond the bound, else None
        self._previous: float | None = None

    def add(
        self, t_ns: int, gnss_speed_m_s: float, wheel_speed_m_s: float, yaw_rate_rad_s: float
    ) -> float:
        """One steady velocity stamped ``t_ns`` (the caller has gated acceleration): the
        antenna's horizontal speed, the rear wheels' with the learned radii and the yaw rate of
        the wheel-speed difference with the nominal radii (a wrong learned split must not hide
        the straight driving). Returns the factor to scale the rear radii by now, or 1."""
        if (
            not self.enabled
            or wheel_speed_m_s < MIN_SPEED_M_S
            or abs(yaw_rate_rad_s) > MAX_YAW_RATE_RAD_S
            or not math.isfinite(gnss_speed_m_s)
        ):
            return 1.0
        self._ratios.append(gnss_speed_m_s / wheel_speed_m_s)
        if len(self._ratios) < WINDOW:
            return 1.0
        ratios = list(self._ratios)
        self._ratios.clear()
        self.median_ratio = med = median(ratios)
        # the median's standard error from the window's own spread (1.4826 MAD estimates the
        # std; the median of n has about 1.25 std / sqrt(n))
        mad = median(abs(x - med) for x in ratios)
        noise = 1.25 * 1.4826 * mad / math.sqrt(len(ratios))
        gross = abs(med - 1.0) > max(GROSS_RATIO, NOISE_MULTIPLE * noise)
        previous, self._previous = self._previous, (med if gross else None)
        if not gross or previous is None or (previous - 1.0) * (med - 1.0) <= 0.0:
            return 1.0
        # two windows in a row beyond the bound, on the same side: the latest is the scale
        self._previous = None
        self.rescales.append(med)
        self.rescale_t_ns.append(t_ns)
        return med

    def restart(self) -> None:
        """Forget the window (the radii were reset or replaced)."""
        self._ratios.clear()
        self._previous = None

    def summary(self) -> dict[str, object]:
        """For ``metrics.json``: the rescalings and the latest median ratio."""
        return {
            "rescales": list(self.rescales),
            "rescale_t_ns": list(self.rescale_t_ns),
            "median_ratio": self.median_ratio,
        }
