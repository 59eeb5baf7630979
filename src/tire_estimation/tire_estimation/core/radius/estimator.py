"""Front-end of the tyre-radius estimation: input validation, gates, GNSS handling, estimates.

The ROS node and the bag replay drive the same :class:`RadiusEstimator`. Bad input never raises
out of the ``on_*`` methods: the sample is dropped and counted in :attr:`RadiusEstimator.stats`
as ``<stream>:<kind>`` (``wheel_speeds:nan``, ``gnss_fix:bad_covariance``, ``gnss_fix:outlier``,
...); a fix without altitude is used and counted as ``gnss_fix:no_altitude``.

Beyond the paper (``wheels='all'``): the front radii are estimated from the front wheel speeds
and the rear-based speed and yaw rate (kinematic front-wheel rolling speed with Ackermann steer
angles, :meth:`RadiusMotionModel.front_wheel_geometry`). For a driven front axle the rolling
speed is corrected by the slip ``s = F_x / C_x`` with ``F_x = m a_x`` (a slip-vs-acceleration
coefficient ``m / C_x`` from the vehicle description). The per-sample pseudo measurement
``delta_i = v_roll_i (1 + s) / omega_i - r`` feeds a single NiW (d = 2, forgetting factor as the
MPF) whose MMSE mean is the front radius error. The slip that balances the driving resistance
at constant speed (rolling resistance, drag) is not modelled and cannot be separated from the
radius: it biases the front radii of a driven axle by about ``r F_resist / C_x`` (see the tests).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.special import chdtri

from tire_estimation.core import niw
from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import drop_key, stamp_after
from tire_estimation.core.radius.aug_kf import (
    RADIUS_RANDOM_WALK_M_SQRT_S as AUG_KF_RADIUS_RANDOM_WALK_M_SQRT_S,
)
from tire_estimation.core.radius.aug_kf import AugKf
from tire_estimation.core.radius.axle_check import AxleCheck
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.drive_slip import DriveSlip
from tire_estimation.core.radius.effects import EFFECTS, delay_s
from tire_estimation.core.radius.fix_scale import FixCovarianceCheck
from tire_estimation.core.radius.gates import Gates
from tire_estimation.core.radius.gnss import (
    SPEED_HISTORY,
    GnssHandling,
    GnssUpdate,
    GnssVelocityUpdate,
    Init,
)
from tire_estimation.core.radius.inputs import finite, finite_or_zero, floats, parse_wheels
from tire_estimation.core.radius.model import FL, FR, RL, RR, RadiusMotionModel
from tire_estimation.core.radius.mpf import (
    KERNEL_SHRINKAGE,
    PRIOR_DOF,
    PRIOR_RADIUS_NOISE_STD_M,
    MpfEstimate,
    RadiusMPF,
)
from tire_estimation.core.radius.report import BaselineEstimate, RadiusEstimate, Reporting
from tire_estimation.core.radius.road_grade import RoadGradeFit
from tire_estimation.core.radius.speed_scale import SpeedScaleCheck
from tire_estimation.core.radius.wheel_timing import WheelSpeedTiming
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import InputError


@dataclass
class _Stream:
    last_t_ns: int | None = None


@dataclass(frozen=True)
class SensorSnapshot:
    """What the estimator's wheel and IMU inputs say at one instant, for the sensor-agreement
    record of the residual analysis (``evaluation.agreement``).

    Attributes:
        rear_rad_s: newest rear wheel speeds (rl, rr) after the configured corrections, rad/s.
        gyro_z_rad_s: yaw rate of a fresh IMU sample, rad/s (None: no fresh IMU).
        lateral_specific_force_m_s2: lateral specific force of a fresh IMU sample, m/s^2.
        brake_decel_m_s2: braking deceleration beyond the driving resistances, m/s^2.
        learning: the radii are being learned.
        rear_locked: the axle check finds the rear wheels cannot be told apart.
    """

    rear_rad_s: tuple[float, float]
    gyro_z_rad_s: float | None
    lateral_specific_force_m_s2: float | None
    brake_decel_m_s2: float
    learning: bool
    rear_locked: bool


if TYPE_CHECKING:
    from tire_estimation.core.geodesy import LocalTangentPlane


class RadiusEstimator(GnssHandling, Reporting, Gates):
    """Tyre-radius estimator front-end (MPF + optional AUG-KF baseline).

    The GNSS handling (:class:`~.gnss.GnssHandling`), the gates (:class:`~.gates.Gates`) and
    the outputs (:class:`~.report.Reporting`) are in their own modules.

    Args:
        config: estimator configuration.
        vehicle: vehicle description (nominal radius, track, wheelbase, antenna position).
        rng: the random generator of the particle filter.
    """

    def __init__(
        self, config: RadiusEstimatorConfig, vehicle: VehicleParams, rng: np.random.Generator
    ) -> None:
        self.config = config
        self.vehicle = vehicle
        self.rng = rng
        self.model = RadiusMotionModel.from_vehicle(vehicle)
        self._nominal_radius_m = self.model.nominal_radius_m
        self._track_width_m = self.model.track_width_m
        # antenna (x, y) in base_link: the vehicle description plus the calibrated correction
        ant = vehicle.gnss_antenna_position_m
        lever = [ant[0], ant[1]]
        for e in EFFECTS:
            if e.antenna_axis is not None:
                lever[e.antenna_axis] = lever[e.antenna_axis] + e.value(config)
        self.lever_arm_m = np.array(lever)
        # calibrated time alignment of the fixes and velocities against the pose, s
        self._fix_shift_s = delay_s(config, lambda e: e.fix_delay_sign)
        self._velocity_shift_s = delay_s(config, lambda e: e.velocity_delay_sign)
        # the wheel-speed corrections that are on, with their values: the rolling ones (before
        # the slope distance) and the horizontal projection (after it)
        on = [(e, e.value(config)) for e in EFFECTS if e.wheel_speeds and e.value(config)]
        self._rolling = [(e.wheel_speeds, v) for e, v in on if not e.after_slope_distance]
        self._horizontal = [(e.wheel_speeds, v) for e, v in on if e.after_slope_distance]
        # chi-square(2) quantile (= scipy.stats.chi2.ppf, without importing scipy.stats)
        self._gate = float(chdtri(2, 1.0 - config.gnss_gate_probability))
        c = config
        self.mpf = RadiusMPF(
            self.model,
            c.n_particles,
            np.zeros(2),
            c.prior_radius_error_std_m,
            PRIOR_RADIUS_NOISE_STD_M,
            PRIOR_DOF,
            c.forgetting_factor,
            c.position_process_noise_m_sqrt_s,
            c.yaw_process_noise_rad_sqrt_s,
            rng,
            mean_random_walk_m_sqrt_s=c.radius_random_walk_m_sqrt_s,
            kernel_shrinkage=KERNEL_SHRINKAGE,
            gnss_bias_std_m=c.gnss_bias_std_m,
            gnss_bias_time_constant_s=c.gnss_bias_time_constant_s,
            gnss_bias_fraction=c.gnss_bias_fraction,
        )
        self.kf: AugKf | None = None
        if c.run_aug_kf:
            self.kf = AugKf(
                self.model,
                np.zeros(2),
                c.prior_radius_error_std_m,
                PRIOR_RADIUS_NOISE_STD_M,
                AUG_KF_RADIUS_RANDOM_WALK_M_SQRT_S,
                c.position_process_noise_m_sqrt_s,
                c.yaw_process_noise_rad_sqrt_s,
                gnss_bias_std_m=c.gnss_bias_std_m,
                gnss_bias_time_constant_s=c.gnss_bias_time_constant_s,
                gnss_bias_fraction=c.gnss_bias_fraction,
            )
        self.stats: dict[str, int] = {}
        #: whether each axle's two wheels can be told apart (gyro against wheel speeds)
        self.axles = AxleCheck(vehicle)
        #: wheel-speed samples whose rear heading change came from the gyro (locked rear axle)
        self.gyro_heading_samples = 0
        self.reset()

    def reset(self) -> None:
        """Forget everything: radii, pose, origin, counters of the gates (not ``stats``)."""
        self.mpf.reset_radii()
        if self.kf is not None:
            self.kf.reset_radii()
        self._front = self._front_prior()
        self._restart_inputs()

    def _restart_inputs(self) -> None:
        """Forget the pose, the origin and what the input checks took from the samples so far
        (not the radii): all of it after :meth:`reset`, and after a wheel's sign is corrected."""
        self._ltp: Any = None
        self._streams = {
            k: _Stream() for k in ("wheel", "steering", "imu", "gnss", "gnss_velocity")
        }
        #: (stamp, rl, rr wheel speed) of the recent wheel samples, for the GNSS velocity
        self._speed_hist: deque[tuple[int, float, float]] = deque(maxlen=SPEED_HISTORY)
        #: GNSS velocities that re-weighted the particles
        self.velocity_updates = 0
        #: GNSS velocities not used because the wheels accelerated (``gnss_velocity_max_accel``)
        self.velocity_skipped_accel = 0
        #: the half-period lag of the wheel speeds, compensated before the prediction
        self.timing = WheelSpeedTiming()
        #: the traction slip of driven rear wheels, removed before the prediction
        self.drive_slip = DriveSlip(self.vehicle)
        #: the GNSS speed against the wheels' with the learned radii: gross scale errors
        self.speed_scale = SpeedScaleCheck(self.vehicle.nominal_tire_radius_m)
        #: the fixes' stated covariance against their innovations
        self.fix_scale = FixCovarianceCheck()
        self._prev_ws: F64 | None = None
        self._prev_rear: tuple[float, float] = (0.0, 0.0)
        self._t_pose_ns: int | None = None
        self._pose_ok = False
        self._init = Init()
        self.init_distance_ratios = []
        self._steer: tuple[int, float] | None = None
        self._imu: tuple[int, Any, Any] | None = None
        self._ax_lp = 0.0
        self._gyro_bias_rad_s = 0.0
        self._t_gyro_bias_ns: int | None = None
        self._prev_v: float | None = None
        self._active = False
        self._reason = "waiting for wheel speeds"
        self._rejections = 0
        self._t_last_fix_ns: int | None = None
        self._t_prev_received_ns: int | None = None
        #: index of the rear wheel whose signal is lost (None: both live)
        self._lost_wheel: int | None = None
        self._fix_period_s: float | None = None
        #: altitude of the last fix that reported one, m (used for a fix without altitude)
        self._last_alt_m = 0.0
        self.last_fix_enu = None
        self._active_time_s = 0.0
        #: road grade: wheel-travelled (slope) distance and the grade fitted over it
        self.grade = RoadGradeFit(self.config.road_grade_source)
        #: braking deceleration of the latest sample (rear brake slip on), m/s^2
        self.brake_decel_m_s2 = 0.0
        self._set_cache(self.mpf.estimate())

    @property
    def initialized(self) -> bool:
        """True once the pose is initialized (the estimate's state is not ``initializing``)."""
        return self._pose_ok

    @property
    def signal_lost_wheel(self) -> str | None:
        """The rear wheel whose signal was lost at the latest wheel-speed sample (the pose's
        heading then comes from the gyro), or None."""
        return None if self._lost_wheel is None else WHEELS[self._lost_wheel]

    @property
    def datum(self) -> LocalTangentPlane | None:
        """The ENU frame of the pose (``map``): its origin is the first GNSS fix (None before
        it, and again after :meth:`reset`)."""
        return self._ltp

    def speed_m_s(self) -> float:
        """The estimate's ``speed_m_s`` without computing the rest of :meth:`estimate`."""
        ws = self._prev_ws if self._prev_ws is not None else np.zeros(4)
        # eq. (6a) with the learned mean radius errors
        return finite_or_zero(self._speed_yaw_rate(ws)[0])

    @property
    def velocity_shift_s(self) -> float:
        """A GNSS velocity stamped ``t`` is compared with the wheels at ``t`` + this, s (the
        configured velocity latency and wheel-speed time offset)."""
        return self._velocity_shift_s

    @property
    def fix_shift_s(self) -> float:
        """A GNSS fix stamped ``t`` is compared with the pose at ``t`` + this, s (the configured
        fix latency and wheel-speed time offset)."""
        return self._fix_shift_s

    @property
    def learning(self) -> bool:
        """The radii are being learned (the newest wheel-speed step passed the gates)."""
        return self._active

    def sensor_snapshot(self, t_ns: int) -> SensorSnapshot | None:
        """The corrected rear wheel speeds and a fresh IMU at ``t_ns`` (None before the first
        wheel-speed sample)."""
        if self._prev_ws is None:
            return None
        imu = self._imu if self._imu_fresh(t_ns) else None
        return SensorSnapshot(
            self._prev_rear,
            None if imu is None else float(imu[1][2]),
            None if imu is None else float(imu[2][1]),
            self.braking_decel_at(t_ns),
            self._active,
            self.axles.locked("rear"),
        )

    @property
    def active_time_s(self) -> float:
        """Time the radii have been learned since the start (or the last reset), s."""
        return self._active_time_s

    def _set_cache(self, est: MpfEstimate) -> None:
        """Remember the MPF estimate (valid until the filter state changes)."""
        self._cache = est
        self._cache_version = self.mpf.version
        self._radius_mean = (float(est.radius.mean[0]), float(est.radius.mean[1]))

    def _front_prior(self) -> niw.NiwStats:
        d = 2
        # gamma_0 of eq. (22b) and the scale of eq. (22c), as in the MPF's prior
        gamma0 = (self.config.prior_radius_error_std_m / PRIOR_RADIUS_NOISE_STD_M) ** 2
        scale0 = np.eye(d) * PRIOR_RADIUS_NOISE_STD_M**2 * (PRIOR_DOF - d - 1.0)
        return niw.init_stats(1, np.zeros(d), gamma0, PRIOR_DOF, scale0)

    def _drop(self, stream: str, kind: str) -> None:
        key = drop_key(stream, kind)
        self.stats[key] = self.stats.get(key, 0) + 1

    def _check_order(self, stream: str, t_ns: int) -> None:
        stamp_after(stream, t_ns, self._streams[stream].last_t_ns)

    # ------------------------------------------------------------------ inputs
    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle (rad, positive left); used by eq. (31a) at low speed."""
        stream = self._streams["steering"]
        last = stream.last_t_ns
        if (
            type(t_ns) is int
            and (last is None or t_ns > last)
            and type(angle_rad) is float
            and -1.2 <= angle_rad <= 1.2  # False for NaN
        ):
            # fast path: a valid, ordered sample (the checks below, without the calls)
            stream.last_t_ns = t_ns
            self._steer = (t_ns, angle_rad)
            return
        try:
            self._check_order("steering", t_ns)
            finite("steering", float(angle_rad))
            if abs(angle_rad) > 1.2:
                raise InputError("out_of_range", f"steering angle {angle_rad} rad")
        except (InputError, TypeError, ValueError) as exc:
            self._drop("steering", exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        stream.last_t_ns = int(t_ns)
        self._steer = (int(t_ns), float(angle_rad))

    def on_imu(
        self, t_ns: int, angular_velocity_rad_s: Any, linear_acceleration_m_s2: Any
    ) -> None:
        """IMU sample in ``base_link`` axes (acceleration gates, load transfer, brake slip)."""
        stream = self._streams["imu"]
        last = stream.last_t_ns
        if (
            type(t_ns) is int
            and (last is None or t_ns > last)
            and type(angular_velocity_rad_s) is np.ndarray
            and type(linear_acceleration_m_s2) is np.ndarray
            and angular_velocity_rad_s.shape == (3,)
            and linear_acceleration_m_s2.shape == (3,)
            and angular_velocity_rad_s.dtype == np.float64
            and linear_acceleration_m_s2.dtype == np.float64
        ):
            # fast path: ordered float64 vectors of 3 (finiteness checked on the sum)
            gyro = angular_velocity_rad_s.tolist()
            acc = linear_acceleration_m_s2.tolist()
            total = sum(gyro) + sum(acc)
            if total - total == 0.0:
                stream.last_t_ns = t_ns
                if self.axles.gyro_reversed:
                    gyro[2] = -gyro[2]  # found turning against the GNSS course (axle_check.py)
                self._imu = (t_ns, gyro, acc)
                self.axles.on_imu(gyro, acc)
                return
        try:
            self._check_order("imu", t_ns)
            gyro = floats(angular_velocity_rad_s)
            acc = floats(linear_acceleration_m_s2)
            if len(gyro) != 3 or len(acc) != 3:
                raise InputError("wrong_length", "imu vectors must have 3 components")
            finite("imu", *gyro, *acc)
        except (InputError, TypeError, ValueError) as exc:
            self._drop("imu", exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        stream.last_t_ns = int(t_ns)
        if self.axles.gyro_reversed:
            gyro[2] = -gyro[2]
        self._imu = (int(t_ns), gyro, acc)
        self.axles.on_imu(gyro, acc)

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr) in rad/s; drives the prediction of the filters."""
        stream = self._streams["wheel"]
        last = stream.last_t_ns
        ws: Any = None
        vals: list[float] | None = None
        if (
            type(t_ns) is int
            and (last is None or t_ns > last)
            and type(wheel_speed_rad_s) is np.ndarray
            and wheel_speed_rad_s.shape == (4,)
            and wheel_speed_rad_s.dtype == np.float64
        ):
            # fast path: ordered, finite (a sum is finite when every term is) float64 vector of
            # 4 within +-1000 rad/s; anything else takes the checks below
            vals = wheel_speed_rad_s.tolist()
            total = sum(vals)
            if total - total == 0.0 and min(vals) >= -1000.0 and max(vals) <= 1000.0:
                ws = np.array(vals)
            else:
                vals = None
        if ws is None:
            try:
                self._check_order("wheel", t_ns)
                ws = parse_wheels(wheel_speed_rad_s)
            except (InputError, TypeError, ValueError) as exc:
                kind = exc.kind if isinstance(exc, InputError) else "bad_value"
                self._drop("wheel_speeds", kind)
                return
            t_ns = int(t_ns)
        axles = self.axles
        signs = axles.signs
        if not signs.settled and signs.add(t_ns, ws.tolist() if vals is None else vals):
            # a wheel found reversed (wheel_signs.py): the pose starts again with this sample
            self._restart_inputs()
            stream, last = self._streams["wheel"], None
        if axles.rewires_wheels:
            # wheels reversed, an axle's sides exchanged (wheel_signs.py, axle_check.py)
            ws = axles.rewire_wheels(ws)
            vals = None if vals is None else ws.tolist()
        checked = ws
        if self.axles.on_wheel_speeds(t_ns, ws if vals is None else vals):
            self.reset()  # front and rear names exchanged (axle_order.py): learn again
            return
        self._lost_wheel = None
        front_measured = True
        if vals is None and math.isnan(sum(ws.tolist())):
            front_measured = not (math.isnan(ws[FL]) or math.isnan(ws[FR]))
            ws = self._fill_front(ws)
        for k in (RL, RR):
            # a rear wheel not reported (NaN) is lost whatever the speed
            if self.axles.signal_lost(k) or math.isnan(ws[k]):
                self._lost_wheel = k
                self._drop("wheel_speeds", f"signal_lost_{WHEELS[k].removeprefix('wheel_')}")
        if self._lost_wheel is not None:
            # the pose moves on with the live rear wheel and the gyro; nothing is learned
            ws = self._rear_from_live_wheel(t_ns, ws, self._lost_wheel)
        elif self.axles.locked("rear"):
            # the rear wheels cannot be told apart (eq. 6b gives no heading change): the
            # heading change from the gyro, the axle's common radius from the mean speed
            ws = self._rear_heading_from_gyro(t_ns, ws)
        elif self._imu is not None:
            self._track_gyro_bias(t_ns, ws)
        ws = self.timing.compensate(t_ns, ws, self.config.max_gap_s)
        if self.drive_slip.enabled or self.drive_slip.learnable:
            ws = self.drive_slip.correct(
                t_ns, ws, self.grade.grade_rad, self.config.max_gap_s, front_measured
            )
        for correct, value in self._rolling:
            ws = correct(self, value, t_ns, ws)
        if ws is checked and vals is not None:
            w3, w4 = vals[RL], vals[RL + 1]  # the same values, without the slice
        else:
            w3, w4 = ws[RL:].tolist()
        if last is not None and (t_ns - last) * 1e-9 <= self.config.max_gap_s:
            # slope distance rolled by the rear wheels (nominal radius) for the grade fit
            r_half = 0.5 * self.model.nominal_radius_m
            imu = self._imu
            fx = float(imu[2][0]) if imu is not None and self._imu_fresh(t_ns) else None
            # signed forward speed for the IMU altitude (f_x v holds in reverse too)
            self.grade.roll(
                (t_ns - last) * 1e-9, r_half * (abs(w3) + abs(w4)), fx, r_half * (w3 + w4)
            )
        elif last is not None:
            self.grade.restart_imu()  # the integral of f_x v cannot span a wheel-speed gap
        if self._horizontal:
            for correct, value in self._horizontal:
                ws = correct(self, value, t_ns, ws)
            w3, w4 = ws[RL:].tolist()
        stream.last_t_ns = t_ns
        if self.config.gnss_velocity_enabled:
            self._speed_hist.append((t_ns, w3, w4))
        prev = self._prev_ws
        prev_rear = self._prev_rear
        self._prev_ws = ws
        self._prev_rear = (w3, w4)
        if last is None or prev is None:
            self._t_pose_ns = t_ns
            return
        dt = (t_ns - last) * 1e-9
        if dt > self.config.max_gap_s:
            self._drop("wheel_speeds", "gap")
            self.speed_scale.runs.gap()
            self._reinit_pose("wheel-speed gap")
            self._t_pose_ns = t_ns
            self._prev_v = None
            return
        # the straight runs between fixes (speed_scale.py), turning told by eq. (6) with the
        # learned radii (with the nominal ones a left-right radius difference of 1.3 mm, 0.4 %,
        # reads as 0.05 rad/s at 20 m/s)
        speed, yaw_rate = self._rear_speed_yaw_rate(w3, w4)
        self.speed_scale.runs.roll(dt, 0.5 * (w3 + w4), yaw_rate, speed)
        self._step(dt, t_ns, prev, prev_rear, w3, w4)

    def _fill_front(self, ws: F64) -> F64:
        """A front wheel not reported (NaN) takes its side's rear wheel's speed (the rear model
        does not read it; the front pseudo measurement and the corrections get a finite value)
        and is counted (``wheel_speeds:missing_fl``); a NaN rear wheel stays for the signal
        check."""
        out = ws.copy()
        for front, rear, other in ((FL, RL, RR), (FR, RR, RL)):
            if math.isnan(out[front]):
                self._drop("wheel_speeds", f"missing_{WHEELS[front].removeprefix('wheel_')}")
                out[front] = out[rear] if not math.isnan(out[rear]) else out[other]
        return out

    def _step(
        self,
        dt: float,
        t_ns: int,
        ws: F64,
        rear: tuple[float, float],
        w3_new: float,
        w4_new: float,
    ) -> None:
        """Propagate over ``dt`` with the speeds ``ws`` (4,) of the interval start, ``rear`` its
        rear wheels as floats (eq. 3, zero-order hold); the gates use the newest sample's rear
        wheel speeds ``w3_new``, ``w4_new``."""
        active, reason, ax, _ay, steer = self._gates(t_ns, dt, w3_new, w4_new)
        if active and self.fix_overdue(t_ns):
            active, reason = False, "no GNSS fix"
        if active and self._lost_wheel is not None:
            active, reason = False, f"{WHEELS[self._lost_wheel]} signal lost"
        steer_for_front = steer if steer is not None else (self._steer[1] if self._steer else 0.0)
        if not self._pose_ok:
            # dead-reckon in the body frame of the anchor fix (two-fix heading initialization)
            if self._init.anchor is not None:
                mu = self._cache.radius.mean
                v, yr = self.model.speed_yaw_rate(ws, mu)
                b = self._init.body
                b[0] += dt * float(v) * math.cos(b[2])
                b[1] += dt * float(v) * math.sin(b[2])
                b[2] += dt * float(yr)
            self._active = False
            self._reason = "waiting for GNSS"
            self._t_pose_ns = t_ns
            return
        # eq. (31a), the heading from the steer angle, only while the radii are not learned:
        # while they are, the heading change comes from the rear wheel-speed difference
        # (eq. 6b), which is what makes the left-right radius difference observable
        heading_steer = None if active else steer
        self.mpf.predict_rear(dt, rear[0], rear[1], active, heading_steer)
        if self.kf is not None:
            self.kf.predict(dt, ws, learn=active, steer_angle_rad=heading_steer)
        self._t_pose_ns = t_ns
        self._active = active
        self._reason = reason
        if active:
            self._active_time_s += dt
            if self.config.wheels == "all":
                self._front_update(ws, ax, steer_for_front)

    def _front_update(self, ws: F64, ax: float, steer: float) -> None:
        """Front radius pseudo measurement and NiW update (beyond the paper)."""
        mu = self._cache.radius.mean
        v, yr = self.model.speed_yaw_rate(ws, mu)
        a, b = self.model.front_wheel_geometry(steer)
        v_roll = a * float(v) + b * float(yr)
        veh = self.vehicle
        if veh.drive == "front":
            slip = veh.mass_kg * ax / veh.longitudinal_stiffness_front_n
        elif veh.drive == "all":
            slip = 0.5 * veh.mass_kg * ax / veh.longitudinal_stiffness_front_n
        else:
            slip = 0.0
        omega = ws[[FL, FR]]
        if np.any(np.abs(omega) < 1.0):
            return
        delta = v_roll * (1.0 + slip) / omega - self.model.nominal_radius_m
        niw.time_update(self._front, self.config.forgetting_factor)
        niw.measurement_update(self._front, delta[None, :])

    def _scale_radii(self, factor: float, why: str = "radii rescaled") -> None:
        """A gross scale error in the GNSS speed (:mod:`.speed_scale`; fixes less accurate than
        stated, :mod:`.fix_scale`, with ``factor`` 1): the radii learn again from the prior,
        centred on the common radius times ``factor`` (the front ones likewise), and the pose is
        initialized again from the next two fixes."""
        self.mpf.scale_radii(factor)
        if self.kf is not None:
            self.kf.scale_radii(factor)
        r_n = self.model.nominal_radius_m
        front = (r_n + float(self._front.mean.mean())) * factor - r_n
        self._front = self._front_prior()
        self._front.mean[...] = front
        self._set_cache(self.mpf.estimate())
        # the pose ran on the wrong scale, its fixes rejected: a heading error left in it
        # would be taken up by the restarted split (16 mm within a second on the simulator)
        self._reinit_pose(why)


__all__ = [
    "WHEELS",
    "BaselineEstimate",
    "GnssUpdate",
    "GnssVelocityUpdate",
    "RadiusEstimate",
    "RadiusEstimator",
]
