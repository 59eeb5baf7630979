"""Can the two wheels of an axle be told apart? A check on the wheel speeds against the gyro.

The radius estimator owns one (:attr:`RadiusEstimator.axles`): while the rear axle is locked it
takes the heading change from the gyro instead of the rear wheels.

The radius model reads the heading change from the difference of the rear wheel speeds (eq. 6b:
``r = ((r0 + d4) w4 - (r0 + d3) w3) / l_T``), so a split of the two radii is learned from turns.
In a turn with yaw rate ``r`` the right wheel of an axle turns faster than the left by about
``x = r l_T / r0`` rad/s. When the two report the same speed through the turns (a locked axle
or spool, one sensor's signal copied to both sides, a dead sensor held at the other's value),
the split is unobservable: only the axle's common radius is.

At ``min_speed_m_s`` or more the check fits the measured difference ``y = w_right - w_left`` to
``y = slope x + c_k w`` by least squares, where ``w`` is the axle's mean wheel speed and
``c_k w`` the difference a left-right radius split makes. The split term ``c_k`` has its own
value in every block of ``block_s`` seconds, so a split that changes (a tyre losing pressure
changes it by about ``d/r0``, far more than a turn's ``x``) misfits one block only; ``slope``
is pooled over the blocks with exponential forgetting (``memory_s``). ``slope`` is about 1 on a
free axle and about 0 on a locked one (wheel-speed noise does not bias it). A verdict needs the
turns to carry information: the sum over the blocks of ``x_perp^2 dt`` (``x`` without its part
along ``w`` within its block) at least that of ``min_turning_s`` seconds at
``min_yaw_rate_rad_s``.

A slope of about -1 is a sign convention, not a lock: the axle's left and right speeds arrive
exchanged, or the gyro's yaw rate is reversed (an IMU frame other than REP-103's z up, e.g.
NED). The receiver's course tells which: its rate of change is regressed on the gyro's yaw rate
(:meth:`AxleCheck.on_course`), and two of the three yaw sources outvote the third. A gyro that
turns against the course and an axle is reversed (its yaw rate is negated from then on,
:attr:`AxleCheck.gyro_reversed`); an axle that turns against the (corrected) gyro and the course
has its two speeds exchanged (:attr:`AxleCheck.swapped`); a course against the gyro and both
axles is a velocity not in ENU, reported and not acted on. Each is decided once and reported;
the estimator applies them to its inputs, with the wheels whose speed arrives with its sign
reversed (:attr:`AxleCheck.signs`, ``wheel_signs.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.axle_order import AxleOrder
from tire_estimation.core.radius.wheel_signs import WheelSigns
from tire_estimation.core.validation import (
    Checked,
    Positive,
    in_range,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import WHEELS

#: axle name -> (left, right) index in the wheel-speed vector (fl, fr, rl, rr)
AXLES = {"front": (0, 1), "rear": (2, 3)}

#: longest sample interval one wheel-speed sample stands for, s (a gap counts as this)
_MAX_DT_S = 0.1

#: a wheel's signal is lost while its speed is below this share of the mean of the other three
#: (a tyre turns within a few tens of percent of the others, even in a tight turn)
LOST_SPEED_SHARE = 0.2

#: a lost signal is back after reading within ``1 +- LOST_SPEED_SHARE`` of the others this
#: long, s
LOST_AFTER_S = 0.5

#: the GNSS course's rate is taken between two velocities at this speed or more, m/s (0.05 m/s
#: of Doppler noise is 0.017 rad of course at 3 m/s), at most this far apart, s
COURSE_MIN_SPEED_M_S = 3.0
COURSE_MAX_DT_S = 0.5

#: the gyro's sign is decided on this many times the turning an axle's verdict needs (30 s at
#: 0.05 rad/s): the course also turns with the sideslip and lags by half a velocity period
#: (the slope settles near 0.9 on a lane change; after 3 s of it, 0.5)
COURSE_INFO_FACTOR = 10.0


@dataclass(frozen=True)
class AxleCheckConfig(Checked):
    """Thresholds of :class:`AxleCheck`.

    Attributes:
        min_yaw_rate_rad_s: a sample counts as turning from this gyro yaw rate, rad/s; also
            the yaw rate of the information needed for a verdict. Default 0.05 (a 400 m
            radius at 20 m/s).
        min_speed_m_s: samples below this speed are left out, m/s. Default 2.
        block_s: length of the blocks with their own split term, s. Default 20.
        memory_s: time constant of the forgetting over the blocks, s. Default 60.
        min_turning_s: the information needed for a verdict, in seconds of turning at
            ``min_yaw_rate_rad_s``. Default 3.
        locked_slope: the split is unobservable while the fitted slope is below this, 1.
            Default 0.5 (midway between a free and a locked axle).
    """

    min_yaw_rate_rad_s: Positive = 0.05
    min_speed_m_s: Positive = 2.0
    block_s: Positive = 20.0
    memory_s: Positive = 60.0
    min_turning_s: Positive = 3.0
    locked_slope: Annotated[float, in_range(0.0, 1.0)] = 0.5


@dataclass(frozen=True)
class AxleStatus:
    """One axle's verdict.

    Attributes:
        axle: ``front`` or ``rear``.
        split_observable: True, False, or None (not enough turning samples yet, or no gyro).
        turning_samples: turning samples seen so far.
        slope: the fitted slope of the measured on the expected speed difference (1 free,
            0 locked); NaN before the turns carry information.
        reason: the verdict in words.
    """

    axle: str
    split_observable: bool | None
    turning_samples: int
    slope: float
    reason: str
    #: the axle's left and right speeds arrived exchanged and are swapped back
    swapped: bool = False


class _AxleFit:
    """Pooled slope of ``y = slope x + c_k w`` with one ``c_k`` per block, for one axle."""

    def __init__(self, block_s: float, memory_s: float) -> None:
        self._block_s = block_s
        self._decay = math.exp(-block_s / memory_s)
        # dt-weighted sums of x^2, x w, w^2, x y, w y of the open block
        self._sums = [0.0] * 5
        self._block_start_ns: int | None = None
        # forgotten sums over the closed blocks of x_perp^2 and x_perp y
        self.info = 0.0
        self.cross = 0.0

    @staticmethod
    def _perp(sums: list[float]) -> tuple[float, float]:
        """``(sum x_perp^2, sum x_perp y)`` of one block, its split term fitted."""
        sxx, sxw, sww, sxy, swy = sums
        if sww <= 0.0:
            return 0.0, 0.0
        # normal equations of y = slope x + c w with c eliminated: x_perp = x - (sxw / sww) w
        return sxx - sxw * sxw / sww, sxy - sxw * swy / sww

    def add(self, t_ns: int, dt_s: float, x: float, w: float, y: float) -> None:
        if self._block_start_ns is None:
            self._block_start_ns = t_ns
        elif (t_ns - self._block_start_ns) * 1e-9 >= self._block_s:
            info, cross = self._perp(self._sums)
            self.info = self._decay * self.info + info
            self.cross = self._decay * self.cross + cross
            self._sums = [0.0] * 5
            self._block_start_ns = t_ns
        s = self._sums
        s[0] += dt_s * x * x
        s[1] += dt_s * x * w
        s[2] += dt_s * w * w
        s[3] += dt_s * x * y
        s[4] += dt_s * w * y

    def totals(self) -> tuple[float, float]:
        """Information and cross term over the closed blocks and the open one."""
        info, cross = self._perp(self._sums)
        return self.info + info, self.cross + cross


class _SignalCheck:
    """Whether one wheel's speed signal is lost: it reads (near) zero while the other wheels
    turn (a dead sensor, a broken cable, a value the bus no longer refreshes)."""

    def __init__(self) -> None:
        self.lost = False
        self.lost_s = 0.0
        #: the wheel has had a speed (finite) at least once
        self.reported = False
        self._since_ns: int | None = None

    def add(self, t_ns: int, dt_s: float, share: float) -> None:
        """One sample: the wheel's speed as a share of the mean of the other three. A reading
        below :data:`LOST_SPEED_SHARE` loses the signal at once (one such sample turns the
        heading of eq. 6b by radians within a second); it is back after :data:`LOST_AFTER_S`
        of readings like the others'."""
        if share < LOST_SPEED_SHARE:
            self.lost, self._since_ns = True, None
        elif self.lost:
            if abs(share - 1.0) > LOST_SPEED_SHARE:
                self._since_ns = None
            elif self._since_ns is None:
                self._since_ns = t_ns
            elif (t_ns - self._since_ns) * 1e-9 >= LOST_AFTER_S:
                self.lost, self._since_ns = False, None
        if self.lost:
            self.lost_s += dt_s


class AxleCheck:
    """Fits, per axle, the wheel-speed difference to the one the gyro implies, and watches each
    wheel's signal (:meth:`signal_lost`)."""

    def __init__(self, vehicle: VehicleParams, config: AxleCheckConfig | None = None) -> None:
        self.config = config or AxleCheckConfig()
        c = self.config
        # w_right - w_left per unit yaw rate: l_T / r0, s (eq. 6b)
        self._gain_s = vehicle.track_width_m / vehicle.nominal_tire_radius_m
        self._radius_m = vehicle.nominal_tire_radius_m
        # information needed: min_turning_s seconds of x = min_yaw_rate l_T / r0
        self._min_info = c.min_turning_s * (c.min_yaw_rate_rad_s * self._gain_s) ** 2
        self._yaw_rate: float | None = None
        self._accel_x = 0.0
        self._last_t_ns: int | None = None
        self._fits = {axle: _AxleFit(c.block_s, c.memory_s) for axle in AXLES}
        # per axle (name, left index, right index, fit), for the per-sample loop
        self._axles = tuple((axle, i, j, self._fits[axle]) for axle, (i, j) in AXLES.items())
        self._min_speed_m_s = c.min_speed_m_s
        self._min_yaw_rate_rad_s = c.min_yaw_rate_rad_s
        self._turning = dict.fromkeys(AXLES, 0)
        # the slope of the last verdict, kept while the recent turns carry too little
        # information (a straight stretch does not undo what the turns showed)
        self._decided: dict[str, float] = {}
        self._signals = tuple(_SignalCheck() for _ in WHEELS)
        self._t_signal_ns: int | None = None
        #: the gyro's yaw rate turns against the GNSS course: the estimator negates it
        self.gyro_reversed = False
        #: per axle: its left and right speeds arrive exchanged; the estimator swaps them
        self.swapped = dict.fromkeys(AXLES, False)
        #: the wheels whose speed arrives with its sign reversed; the estimator negates them
        self.signs = WheelSigns(vehicle.nominal_tire_radius_m)
        #: whether the front and rear names arrive exchanged (the estimator exchanges them)
        self.order = AxleOrder(vehicle.wheelbase_m, vehicle.nominal_tire_radius_m)
        #: the gyro's sign against the GNSS course: None until the turns tell, then the slope
        self.gyro_course_slope: float | None = None
        # the course fit: last (t_ns, course rad), forgotten sums of gyro^2 dt and gyro rate dt
        self._course: tuple[int, float] | None = None
        self._course_sums = [0.0, 0.0]

    def signal_lost(self, index: int) -> bool:
        """Whether wheel ``index`` (fl, fr, rl, rr) reads (near) zero, or is not reported,
        while the others turn (back once it reads like them for :data:`LOST_AFTER_S`)."""
        return self._signals[index].lost

    def lost_signals(self) -> dict[str, float]:
        """Seconds each wheel's signal has been lost, for the reported wheels whose signal ever
        was (:meth:`unreported_wheels`: the others)."""
        return {
            n: c.lost_s
            for n, c in zip(WHEELS, self._signals, strict=True)
            if c.lost_s and c.reported
        }

    def unreported_wheels(self) -> tuple[str, ...]:
        """The wheels that never had a speed while others did (a vehicle that publishes only
        its rear wheels, a two-wheeled robot)."""
        if not any(c.reported for c in self._signals):
            return ()
        return tuple(n for n, c in zip(WHEELS, self._signals, strict=True) if not c.reported)

    def _watch_signals(self, t_ns: int, speeds: list[float]) -> None:
        """Each wheel against the mean of the other three, while those turn at speed."""
        last, self._t_signal_ns = self._t_signal_ns, t_ns
        if last is None or len(speeds) != len(WHEELS):
            return
        dt_s = min(max((t_ns - last) * 1e-9, 0.0), _MAX_DT_S)
        mags = [abs(v) for v in speeds]
        live = [v for v in mags if math.isfinite(v)]
        if len(live) < 2:
            return
        total = sum(live)
        for k, check in enumerate(self._signals):
            mag = mags[k]
            if not check.reported and math.isfinite(mag):
                check.reported = True
            # a wheel not reported (NaN) reads as no signal
            others = (total - mag) / (len(live) - 1) if math.isfinite(mag) else total / len(live)
            if others * self._radius_m >= self._min_speed_m_s:
                check.add(t_ns, dt_s, mag / others if math.isfinite(mag) else 0.0)

    def on_imu(self, gyro_rad_s: Any, accel_m_s2: Any = (0.0, 0.0, 0.0)) -> None:
        """The latest gyro yaw rate (z), rad/s (as the estimator uses it: negated once the gyro
        is found reversed), and specific force (x for :class:`AxleOrder`), m/s^2."""
        self._yaw_rate = float(gyro_rad_s[2])
        self._accel_x = float(accel_m_s2[0])

    @property
    def rewired(self) -> bool:
        """Whether any input is corrected (gyro negated, an axle swapped, a wheel negated)."""
        return self.gyro_reversed or self.rewires_wheels

    @property
    def rewires_wheels(self) -> bool:
        """Whether the wheel speeds are corrected (:meth:`rewire_wheels`)."""
        swapped = self.swapped["front"] or self.swapped["rear"]
        return self.signs.any_reversed or swapped or self.order.exchanged

    def rewire_wheels(self, wheel_speed_rad_s: F64) -> F64:
        """The wheel speeds (4,) with the reversed wheels negated, the axles exchanged back
        when their names arrive exchanged, and the exchanged sides swapped back (a new
        array)."""
        ws = self.signs.correct(wheel_speed_rad_s)
        if self.order.exchanged:
            ws = ws[[2, 3, 0, 1]]
        for axle, (i, j) in AXLES.items():
            if self.swapped[axle]:
                ws[i], ws[j] = ws[j], ws[i]
        return ws

    def on_course(self, t_ns: int, east_m_s: float, north_m_s: float) -> None:
        """A GNSS Doppler velocity (ENU, m/s). The course's rate between two velocities at
        speed, against the gyro's yaw rate, until the sign is decided; then, with the gyro
        confirmed, an axle whose wheel-speed difference turns against it is swapped."""
        last = self._course
        course = None
        if math.hypot(east_m_s, north_m_s) >= COURSE_MIN_SPEED_M_S:
            course = self._course = (t_ns, math.atan2(north_m_s, east_m_s))
        else:
            self._course = None
        r = self._yaw_rate
        if self.gyro_course_slope is None and last and course and r is not None:
            dt_s = (t_ns - last[0]) * 1e-9
            if 0.0 < dt_s <= COURSE_MAX_DT_S:
                # the course's rate of change (the antenna turns with the body), rad/s
                rate = math.remainder(course[1] - last[1], math.tau) / dt_s
                sums = self._course_sums
                sums[0] += r * r * dt_s
                sums[1] += r * rate * dt_s
                if sums[0] >= COURSE_INFO_FACTOR * self._min_info / self._gain_s**2:
                    self._decide_gyro(sums[1] / sums[0])
        self._rewire()

    def _decide_gyro(self, slope: float) -> None:
        """The gyro's yaw rate against the course's rate: about +1, or -1 when one of the two
        is reversed."""
        if abs(slope) >= 0.5:  # else more turns are needed (a lever arm or a lag blurs a few)
            self.gyro_course_slope = slope

    def _rewire(self) -> None:
        """Two of the three yaw sources (GNSS course, gyro, an axle's wheels) outvote the one
        that turns against them: a gyro against the course and an axle is negated; an axle
        against the (corrected) gyro and the course is swapped. A course against the gyro and
        both axles is the GNSS velocity's frame: nothing is changed (:meth:`course_suspect`)."""
        course = self.gyro_course_slope
        if course is None:
            return
        low = -self.config.locked_slope
        if course < 0.0 and not self.gyro_reversed:
            if any(self.slope(axle) < low for axle in AXLES):
                self.gyro_reversed = True
                for axle in AXLES:
                    self._restart(axle)
            return
        for axle in AXLES:
            if not self.swapped[axle] and self.slope(axle) < low:
                self.swapped[axle] = True
                self._restart(axle)

    @property
    def course_suspect(self) -> bool:
        """The GNSS course turns against the gyro while both axles turn with it: the receiver's
        velocity is not in ENU (e.g. north and east exchanged); nothing was rewired."""
        course = self.gyro_course_slope
        high = self.config.locked_slope
        return bool(
            course is not None
            and course < 0.0
            and not self.gyro_reversed
            and all(self.slope(axle) > high for axle in AXLES)
        )

    def _restart(self, axle: str) -> None:
        """The axle's fit starts again (its input was corrected)."""
        c = self.config
        self._fits[axle] = _AxleFit(c.block_s, c.memory_s)
        self._axles = tuple((a, i, j, self._fits[a]) for a, (i, j) in AXLES.items())
        self._turning[axle] = 0
        self._decided.pop(axle, None)

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> bool:
        """One wheel-speed sample (fl, fr, rl, rr), rad/s; NaN for a wheel not reported. True
        when it shows the front and rear names exchanged (:class:`AxleOrder`): from the next
        sample on they are exchanged back, and the estimator learns again."""
        if type(wheel_speed_rad_s) is not list:
            wheel_speed_rad_s = [float(v) for v in wheel_speed_rad_s]
        self._watch_signals(t_ns, wheel_speed_rad_s)
        last, self._last_t_ns = self._last_t_ns, t_ns
        r = self._yaw_rate
        if r is None or last is None:
            return False
        if not self.order.decided and self.order.add(t_ns, wheel_speed_rad_s, r, self._accel_x):
            # the side swaps follow their axles; both fits start again
            self.swapped = {"front": self.swapped["rear"], "rear": self.swapped["front"]}
            for axle in AXLES:
                self._restart(axle)
            return True
        dt_s = min(max((t_ns - last) * 1e-9, 0.0), _MAX_DT_S)
        x = r * self._gain_s
        turning = abs(r) >= self._min_yaw_rate_rad_s
        radius_m, min_speed_m_s, isfinite = self._radius_m, self._min_speed_m_s, math.isfinite
        for axle, i, j, fit in self._axles:
            wl, wr = wheel_speed_rad_s[i], wheel_speed_rad_s[j]
            if not (isfinite(wl) and isfinite(wr)):
                continue
            if self._signals[i].lost or self._signals[j].lost:
                continue  # a lost signal says nothing about the axle
            w = 0.5 * (wl + wr)
            if w * radius_m < min_speed_m_s:
                continue
            self._turning[axle] += turning
            fit.add(t_ns, dt_s, x, w, wr - wl)
        return False

    def slope(self, axle: str) -> float:
        """Least-squares slope of the measured on the expected difference (split fitted per
        block), or the slope of the last verdict while the recent turns carry too little
        information."""
        info, cross = self._fits[axle].totals()
        if info < self._min_info:
            return self._decided.get(axle, math.nan)
        slope = cross / info
        self._decided[axle] = slope
        return slope

    def _scale_off(self, axle: str) -> float | None:
        """The other axle's slope when it is below ``locked_slope`` too and within 30 % of
        ``axle``'s: both axles then see the same fraction of the difference the gyro implies,
        which a wheel-speed unit or nominal radius off by that factor makes, not a lock."""
        other = "front" if axle == "rear" else "rear"
        mine, theirs = self.slope(axle), self.slope(other)
        low = self.config.locked_slope
        if not (mine < low and theirs < low and mine > 0.0 and theirs > 0.0):
            return None
        return theirs if abs(theirs / mine - 1.0) <= 0.3 else None

    def _gyro_against_both(self, axle: str) -> bool:
        """Both axles' differences turn against the gyro: the gyro is the odd one out (its yaw
        rate most likely reversed), not two locked axles."""
        other = "front" if axle == "rear" else "rear"
        low = -self.config.locked_slope
        return bool(self.slope(axle) < low and self.slope(other) < low)

    def locked(self, axle: str) -> bool:
        """True when ``axle``'s split is unobservable (:meth:`status` says False)."""
        return (
            bool(self.slope(axle) < self.config.locked_slope)
            and self._scale_off(axle) is None
            and not self._gyro_against_both(axle)
        )

    def status(self, axle: str) -> AxleStatus:
        """The verdict on ``axle`` (``front`` or ``rear``)."""
        slope = self.slope(axle)
        n = self._turning[axle]
        swapped = self.swapped[axle]
        note = ""
        if swapped:
            note += "; its left and right speeds arrived exchanged and are swapped back"
        if self.gyro_reversed:
            note += (
                "; the gyro's yaw rate turns against the GNSS course and is negated (REP-103: "
                "z up, yaw positive to the left)"
            )
        elif self.course_suspect:
            note += (
                "; the GNSS course turns against the gyro and both axles: the receiver's "
                "velocity is likely not in ENU (east, north, up); nothing was changed"
            )
        if self._yaw_rate is None:
            return AxleStatus(axle, None, n, slope, "unknown: no gyro yaw rate" + note, swapped)
        if math.isnan(slope):
            return AxleStatus(
                axle, None, n, slope, f"unknown: too few turns ({n} samples)" + note, swapped
            )
        if self._scale_off(axle) is not None:
            return AxleStatus(
                axle,
                None,
                n,
                slope,
                f"unknown: both axles' wheel-speed differences are {slope:.2f} of what the gyro "
                "implies: the wheel speeds' unit (rad/s) or vehicle.yaml's nominal_tire_radius_m "
                "or track_width_m is off by that factor" + note,
                swapped,
            )
        if self._gyro_against_both(axle):
            return AxleStatus(
                axle,
                None,
                n,
                slope,
                f"unknown: both axles' wheel-speed differences turn against the gyro (slope "
                f"{slope:.2f}): the gyro's yaw rate is most likely reversed (REP-103: z up); "
                "no GNSS velocity has confirmed it yet" + note,
                swapped,
            )
        if self.locked(axle):
            why = (
                f"the difference turns against the gyro (slope {slope:.2f}): the axle's left "
                "and right speeds are exchanged, or the gyro's yaw rate is reversed; no GNSS "
                "velocity has told which yet"
                if slope < -self.config.locked_slope
                else f"both wheels turn alike in the turns (slope {slope:.2f} of the difference "
                "the gyro implies: a locked axle or spool, or one signal copied to both sides)"
            )
            return AxleStatus(
                axle,
                False,
                n,
                slope,
                f"unobservable: {why}; only the axle's common radius is observable" + note,
                swapped,
            )
        return AxleStatus(axle, True, n, slope, f"observable (slope {slope:.2f})" + note, swapped)
