"""Front-end of the tyre-radius estimation: input validation, gates, GNSS handling, estimates.

The ROS node and the bag replay drive the same :class:`RadiusEstimator`. Bad input never raises
out of the ``on_*`` methods: the sample is dropped and counted in :attr:`RadiusEstimator.stats`.

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
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

from tire_estimation.core import niw
from tire_estimation.core.input_checks import stamp_after
from tire_estimation.core.radius.aug_kf import AugKf
from tire_estimation.core.radius.axle_check import AxleCheck
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.model import FL, FR, RL, RR, RadiusMotionModel
from tire_estimation.core.radius.mpf import MpfEstimate, RadiusMPF
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import FRONT_WHEELS, REAR_WHEELS, WHEEL_INDEX, WHEELS
from tire_estimation.errors import InputError

F64 = NDArray[np.float64]

_SHORT = {"fl": 0, "fr": 1, "rl": 2, "rr": 3}
STATE_DICT_VERSION = 1


@dataclass(frozen=True)
class GnssUpdate:
    """Outcome of one GNSS fix.

    Attributes:
        t_ns: stamp of the fix.
        innovation_m: (east, north) measurement minus prediction, m (zeros when not computed).
        innovation_cov_m2: its covariance (2, 2), m^2.
        nis: normalized innovation squared (0 when not computed).
        accepted: the fix was used (measurement update, anchoring or initialization).
        reason: short explanation (``updated``, ``anchored (paused)``, ``outlier``, ...).
    """

    t_ns: int
    innovation_m: F64
    innovation_cov_m2: F64
    nis: float
    accepted: bool
    reason: str


@dataclass(frozen=True)
class GnssVelocityUpdate:
    """Outcome of one GNSS Doppler velocity (:meth:`RadiusEstimator.on_gnss_velocity`).

    Attributes:
        t_ns: stamp of the velocity.
        innovation_m_s: (east, north) measurement minus prediction, m/s (zeros when not
            computed).
        innovation_cov_m2_s2: its covariance (2, 2), m^2/s^2.
        nis: normalized innovation squared (0 when not computed).
        accepted: the velocity re-weighted the particles.
        reason: short explanation (``updated``, ``paused``, ``outlier``, ``disabled``,
            ``accelerating``, ...).
    """

    t_ns: int
    innovation_m_s: F64
    innovation_cov_m2_s2: F64
    nis: float
    accepted: bool
    reason: str


@dataclass(frozen=True)
class BaselineEstimate:
    """AUG-KF estimate (same meaning as in :class:`RadiusEstimate`)."""

    radius_error_m: F64
    radius_error_std_m: F64
    pose: F64
    pose_cov: F64


@dataclass(frozen=True)
class RadiusEstimate:
    """Current estimate.

    Attributes:
        t_ns: stamp of the latest wheel-speed sample used.
        wheels: wheel names covered, in the order of the arrays below.
        radius_error_m: MMSE radius error (effective minus nominal radius) per wheel, m.
        radius_error_std_m: posterior std of the radius error per wheel, m.
        radius_noise_std_m: sqrt of the diagonal of the MMSE NiW covariance (fast variation), m.
        active: per wheel, the estimate is being updated now (not paused).
        pose: ``[east_m, north_m, yaw_rad]`` of ``base_link`` in the local ENU frame.
        pose_cov: (3, 3) covariance of the pose.
        speed_m_s: estimated speed of ``base_link``.
        yaw_rate_rad_s: estimated yaw rate.
        n_eff: effective sample size of the MPF.
        resample_count: resamplings so far.
        state: ``initializing``, ``running`` or ``paused``.
        state_reason: why (e.g. ``low speed``, ``braking``, ``waiting for GNSS``).
        baseline: AUG-KF estimate when ``run_aug_kf`` (else None).
        road_grade_rad: online road-grade estimate (GNSS altitude over the wheel-travelled
            distance, positive uphill), rad; 0 until a window of fixes is available.
        rear_brake_decel_m_s2: braking deceleration ``b = max(0, -f_x - a_0)``: the one of the
            latest wheel-speed sample when the rear brake slip is on, else computed at the pose
            time for the residual signature, m/s^2.
    """

    t_ns: int
    wheels: tuple[str, ...]
    radius_error_m: F64
    radius_error_std_m: F64
    radius_noise_std_m: F64
    active: tuple[bool, ...]
    pose: F64
    pose_cov: F64
    speed_m_s: float
    yaw_rate_rad_s: float
    n_eff: float
    resample_count: int
    state: str
    state_reason: str
    baseline: BaselineEstimate | None = None
    road_grade_rad: float = 0.0
    rear_brake_decel_m_s2: float = 0.0


#: wheel samples kept to align a GNSS velocity with the wheel speeds (2.56 s at 100 Hz)
SPEED_HISTORY = 256

#: at most this many GNSS altitudes are kept for the grade fit (100 s at 10 Hz)
GRADE_MAX_POINTS = 1000


@dataclass
class _Stream:
    last_t_ns: int | None = None


@dataclass
class _Init:
    """Two-fix initialization of the pose: anchor fix and body-frame odometry since then."""

    anchor: F64 | None = None
    body: F64 = field(default_factory=lambda: np.zeros(3))


class _SlidingLine:
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


def _finite(kind: str, *values: float) -> None:
    # fast path: a sum is finite when every term is (a finite sum that overflows is checked
    # term by term below)
    total = sum(values)
    if total - total == 0.0:
        return
    for v in values:
        if not math.isfinite(v):
            raise InputError("nan", f"{kind}: non-finite value {v!r}")


def _floats(values: Any) -> list[float]:
    """A flat list of Python floats from a sequence or array (raises TypeError/ValueError)."""
    if isinstance(values, np.ndarray) and values.dtype == np.float64:
        return values.ravel().tolist()  # type: ignore[no-any-return]
    if isinstance(values, np.ndarray):
        return [float(v) for v in values.reshape(-1).tolist()]
    return [float(v) for v in np.asarray(values, dtype=float).reshape(-1).tolist()]


class RadiusEstimator:
    """Tyre-radius estimator front-end (MPF + optional AUG-KF baseline).

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
        self.lever_arm_m = np.array(
            [ant[0] + config.gnss_antenna_offset_x_m, ant[1] + config.gnss_antenna_offset_y_m]
        )
        #: ``k r_nominal`` of the speed-dependent radius (0: not modelled)
        self._speed_gain = (
            config.radius_speed_coefficient_m_per_m2_s2 * vehicle.nominal_tire_radius_m
        )
        #: ``c / r_nominal`` of the load-dependent radius (0: not modelled)
        self._load_gain = config.radius_load_coefficient_m_per_n / vehicle.nominal_tire_radius_m
        # quasi-static load transfer per unit specific force, N per m/s^2 (the simulator's
        # geometry): longitudinal m h / (2 L) per wheel, lateral m h / l_T split between the
        # axles like the static loads (front lr / L, rear lf / L)
        wb = vehicle.cg_to_front_axle_m + vehicle.cg_to_rear_axle_m
        lat = vehicle.mass_kg * vehicle.cg_height_m / vehicle.track_width_m
        self._load_long = vehicle.mass_kg * vehicle.cg_height_m / (2.0 * wb)
        self._load_lat_front = lat * vehicle.cg_to_rear_axle_m / wb
        self._load_lat_rear = lat * vehicle.cg_to_front_axle_m / wb
        # chi-square(2) quantile (= scipy.stats.chi2.ppf, without importing scipy.stats)
        self._gate = float(chdtri(2, 1.0 - config.gnss_gate_probability))
        c = config
        self.mpf = RadiusMPF(
            self.model,
            c.n_particles,
            np.full(2, c.prior_radius_error_m),
            c.prior_radius_error_std_m,
            c.prior_radius_noise_std_m,
            c.prior_dof,
            c.forgetting_factor,
            c.resampler,
            c.resample_threshold,
            c.position_process_noise_m_sqrt_s,
            c.yaw_process_noise_rad_sqrt_s,
            rng,
            mean_random_walk_m_sqrt_s=c.radius_random_walk_m_sqrt_s,
            kernel_shrinkage=c.kernel_shrinkage,
            gnss_bias_std_m=c.gnss_bias_std_m,
            gnss_bias_time_constant_s=c.gnss_bias_time_constant_s,
            gnss_bias_fraction=c.gnss_bias_fraction,
        )
        self.kf: AugKf | None = None
        if c.run_aug_kf:
            self.kf = AugKf(
                self.model,
                np.full(2, c.prior_radius_error_m),
                c.prior_radius_error_std_m,
                c.prior_radius_noise_std_m,
                c.aug_kf_radius_random_walk_m_sqrt_s,
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

    # ------------------------------------------------------------------ housekeeping
    def reset(self) -> None:
        """Forget everything: radii, pose, origin, counters of the gates (not ``stats``)."""
        self.mpf.reset_radii()
        if self.kf is not None:
            self.kf.reset_radii()
        self._front = self._front_prior()
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
        self._prev_ws: F64 | None = None
        self._prev_rear: tuple[float, float] = (0.0, 0.0)
        self._t_pose_ns: int | None = None
        self._pose_ok = False
        self._init = _Init()
        self._steer: tuple[int, float] | None = None
        self._imu: tuple[int, F64, F64] | None = None
        self._ax_lp = 0.0
        self._prev_v: float | None = None
        self._active = False
        self._reason = "waiting for wheel speeds"
        self._rejections = 0
        self._t_last_fix_ns: int | None = None
        self._active_time_s = 0.0
        self._upper: F64 | None = None
        # road grade: wheel-travelled (slope) distance and (distance, GNSS altitude) pairs
        self._distance_m = 0.0
        self._grade_fit = _SlidingLine(GRADE_MAX_POINTS)
        self._grade_rad = 0.0
        self._brake_decel = 0.0
        self._set_cache(self.mpf.estimate())

    @property
    def initialized(self) -> bool:
        """True once the pose is initialized (the estimate's state is not ``initializing``)."""
        return self._pose_ok

    def speed_m_s(self) -> float:
        """The estimate's ``speed_m_s`` without computing the rest of :meth:`estimate`."""
        ws = self._prev_ws if self._prev_ws is not None else np.zeros(4)
        # eq. (6a) with the learned mean radius errors
        return _finite_or_zero(self._speed_yaw_rate(ws)[0])

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
        c = self.config
        d = 2
        gamma0 = (c.prior_radius_error_std_m / c.prior_radius_noise_std_m) ** 2
        scale0 = np.eye(d) * c.prior_radius_noise_std_m**2 * (c.prior_dof - d - 1.0)
        return niw.init_stats(1, np.full(d, c.prior_radius_error_m), gamma0, c.prior_dof, scale0)

    def _drop(self, kind: str) -> None:
        self.stats[kind] = self.stats.get(kind, 0) + 1

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
            _finite("steering", float(angle_rad))
            if abs(angle_rad) > 1.2:
                raise InputError("out_of_range", f"steering angle {angle_rad} rad")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
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
                self._imu = (t_ns, gyro, acc)
                self.axles.on_imu(gyro)
                return
        try:
            self._check_order("imu", t_ns)
            gyro = _floats(angular_velocity_rad_s)
            acc = _floats(linear_acceleration_m_s2)
            if len(gyro) != 3 or len(acc) != 3:
                raise InputError("wrong_length", "imu vectors must have 3 components")
            _finite("imu", *gyro, *acc)
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        stream.last_t_ns = int(t_ns)
        self._imu = (int(t_ns), gyro, acc)
        self.axles.on_imu(gyro)

    def _parse_wheels(self, wheel_speed_rad_s: Any) -> F64:
        if isinstance(wheel_speed_rad_s, Mapping):
            vals = [math.nan] * 4
            for name, value in wheel_speed_rad_s.items():
                idx = WHEEL_INDEX.get(name, _SHORT.get(name))
                if idx is None:
                    raise InputError("unknown_wheel", f"unknown wheel name {name!r}")
                vals[idx] = float(value)
            if len(wheel_speed_rad_s) != 4:
                raise InputError("wrong_length", f"need 4 wheels, got {len(wheel_speed_rad_s)}")
        else:
            vals = _floats(wheel_speed_rad_s)
            if len(vals) != 4:
                raise InputError("wrong_length", f"need 4 wheel speeds, got {len(vals)}")
        _finite("wheel speeds", *vals)
        if max(vals) > 1000.0 or min(vals) < -1000.0:
            raise InputError("out_of_range", f"wheel speed above 1000 rad/s: {vals}")
        return np.array(vals)

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr) in rad/s; drives the prediction of the filters."""
        stream = self._streams["wheel"]
        last = stream.last_t_ns
        ws: Any = None
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
        if ws is None:
            try:
                self._check_order("wheel", t_ns)
                ws = self._parse_wheels(wheel_speed_rad_s)
            except (InputError, TypeError, ValueError) as exc:
                self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
                return
            t_ns = int(t_ns)
        self.axles.on_wheel_speeds(t_ns, ws)
        if self.config.locked_axle_gyro_heading and self.axles.locked("rear"):
            ws = self._rear_heading_from_gyro(t_ns, ws)
        if self._speed_gain:
            # speed-dependent radius r = r_n + delta + k v^2 (r_n nominal, delta the radius
            # error at standstill); with k v^2 ~ k omega^2 r_n^2:
            # v = omega (r_n + delta + k omega^2 r_n^2) ~ omega (1 + k r_n omega^2) (r_n + delta)
            # (neglected: about 3 k r_n omega^2 delta of radius, 0.04 mm for k = 4e-6,
            # omega = 100 rad/s, delta = 1 mm); with the scaled speeds every model downstream
            # (eq. 6, front wheels, gates) estimates delta
            ws = ws * (1.0 + self._speed_gain * ws * ws)
        if self._load_gain:
            ws = ws * self._load_scale(t_ns, ws)
        b = 0.0
        if self.config.rear_brake_slip_s2_per_m:
            self._brake_decel = b = self._braking_decel(t_ns)
        if b > 0.0:
            # braked rear wheel: omega r = v (1 + kappa) with the slip kappa = -k b
            # (k = (1 - front brake share) m / C_x,rear), so the ground speed is
            # v = omega r / (1 + kappa); kappa floored at -0.5 (a locking wheel is not modelled)
            kappa = max(-0.5, -self.config.rear_brake_slip_s2_per_m * b)
            ws = ws.copy()
            ws[RL:] /= 1.0 + kappa
        w3, w4 = ws[RL:].tolist()
        if last is not None and (t_ns - last) * 1e-9 <= self.config.max_gap_s:
            # slope distance rolled by the rear wheels (nominal radius) for the grade fit
            rolled = 0.5 * self.model.nominal_radius_m * (abs(w3) + abs(w4))
            self._distance_m += (t_ns - last) * 1e-9 * rolled
        if self.config.road_grade_correction_gain and self._grade_rad:
            # the wheels roll along the slope, the pose and GNSS are horizontal:
            # ds_horizontal = ds cos(theta); the common mode of each axle is reduced by
            # gain (1 - cos theta), the left-right difference (the yaw rate) is kept
            eps = self.config.road_grade_correction_gain * (1.0 - math.cos(self._grade_rad))
            mf = 0.5 * float(ws[FL] + ws[FR])
            mr = 0.5 * float(ws[RL] + ws[RR])
            ws = ws - eps * np.array([mf, mf, mr, mr])
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
            self._drop("gap")
            self._reinit_pose("wheel-speed gap")
            self._t_pose_ns = t_ns
            self._prev_v = None
            return
        self._step(dt, t_ns, prev, prev_rear, w3, w4)

    def _rear_heading_from_gyro(self, t_ns: int, ws: F64) -> F64:
        """A locked rear axle (both wheels turn alike): the rear wheel speeds are replaced by
        their mean -+ the half difference that eq. (6b) gives the gyro's yaw rate, so that the
        heading change comes from the gyro and the speed from the mean; only the common radius
        of the axle is then learned (the split the filter shows is not a measurement)."""
        imu = self._imu
        if imu is None or (t_ns - imu[0]) * 1e-9 > self.config.imu_timeout_s:
            return ws
        self.gyro_heading_samples += 1
        mean = 0.5 * float(ws[RL] + ws[RR])
        # eq. (6b) with equal radii: yaw_rate = r_n (w4 - w3) / l_T
        half = 0.5 * float(imu[1][2]) * self._track_width_m / self._nominal_radius_m
        out = ws.copy()
        out[RL], out[RR] = mean - half, mean + half
        return out

    def _load_scale(self, t_ns: int, ws: F64) -> F64:
        """Per-wheel speed factor ``1 + c dFz_i / r_nominal`` of the load-dependent radius."""
        c = self.config
        if self._imu is not None and (t_ns - self._imu[0]) * 1e-9 <= c.imu_timeout_s:
            # specific force in base_link (the load transfer is driven by the contact forces,
            # m f; the IMU's offset from the CG is neglected)
            fx, fy = float(self._imu[2][0]), float(self._imu[2][1])
        else:
            # the fallbacks of the gates (the yaw rate of the uncorrected wheel speeds)
            v, yr = self._speed_yaw_rate(ws)
            fx = self._ax_lp
            if self._steer is not None and (t_ns - self._steer[0]) * 1e-9 <= c.imu_timeout_s:
                fy = v * float(self.model.steering_yaw_rate(v, self._steer[1]))
            else:
                fy = v * yr
        # quasi-static load transfer (Gillespie, Fundamentals of Vehicle Dynamics, eq. 2-7 and
        # ch. 9, roll stiffness split like the static loads): dFz = -+ m f_x h / (2 L) on the
        # front / rear wheels, -+ m f_y h / l_T (lr / L front, lf / L rear) on left / right
        d_long = self._load_long * fx
        d_f = self._load_lat_front * fy
        d_r = self._load_lat_rear * fy
        dfz = np.array([-d_long - d_f, -d_long + d_f, d_long - d_r, d_long + d_r])
        # r_i = r_n + delta_i + c dFz_i  ->  v_i = omega_i (r_n + delta_i) (1 + c dFz_i / r_n)
        # (neglected: c dFz_i delta_i / r_n, 1e-9 m for c = -5e-7, 600 N, delta_i = 1 mm)
        return 1.0 + self._load_gain * dfz

    def _braking_decel(self, t_ns: int) -> float:
        """Braking deceleration ``b = max(0, -f_x - a_0)`` of the rear brake slip, m/s^2."""
        c = self.config
        if self._imu is not None and (t_ns - self._imu[0]) * 1e-9 <= c.imu_timeout_s:
            # longitudinal specific force: m f_x = sum of the tyre forces - resistances
            fx = float(self._imu[2][0])
        else:
            fx = self._ax_lp  # the fallback of the gates (as in the load transfer)
        # the brakes take what the driving resistances (a_0, body forces) do not explain
        return max(0.0, -fx - c.rear_brake_slip_onset_m_s2)

    def _grade_fix(self, up_m: float) -> None:
        """Update the road grade with a GNSS altitude: least-squares slope of the altitude
        over the wheel-travelled distance in the last ``road_grade_window_m``."""
        window = self.config.road_grade_window_m
        fit = self._grade_fit
        fit.append(self._distance_m, up_m)
        pts = fit.pts
        while pts and pts[0][0] < self._distance_m - window:
            fit.popleft()
        if len(pts) < 5 or pts[-1][0] - pts[0][0] < 0.5 * window:
            return  # keep the last estimate (standstill, start)
        # sin(theta) = dz / ds along the slope distance s (least-squares slope)
        sin_grade = fit.slope()
        if math.isfinite(sin_grade):
            self._grade_rad = math.asin(min(0.5, max(-0.5, sin_grade)))

    def _speed_yaw_rate(self, ws: F64) -> tuple[float, float]:
        """Eq. (6) with the learned mean rear radius errors, in Python floats."""
        return self._rear_speed_yaw_rate(float(ws[RL]), float(ws[RR]))

    def _rear_speed_yaw_rate(self, w3: float, w4: float) -> tuple[float, float]:
        """Eq. (6) from the rear wheel speeds (rad/s) with the learned mean radius errors."""
        d3, d4 = self._radius_mean
        r, lt = self._nominal_radius_m, self._track_width_m
        # eq. (6a) v = r (w3 + w4) / 2 + (w3 d3 + w4 d4) / 2
        v = 0.5 * (w3 * (r + d3) + w4 * (r + d4))
        # eq. (6b) yaw_rate = (w4 (r + d4) - w3 (r + d3)) / l_T
        return v, (w4 * (r + d4) - w3 * (r + d3)) / lt

    def _gates(
        self, t_ns: int, dt: float, w3: float, w4: float
    ) -> tuple[bool, str, float, float, float | None]:
        """Gates of the newest sample (rear wheel speeds ``w3``, ``w4``, rad/s): learn or pause
        and why, the accelerations used (m/s^2), the steer angle for eq. (31a) or None."""
        c = self.config
        # speed and yaw rate with the learned radii (eq. 6): the virtual yaw rate (eq. 4b) is
        # off by ~0.05 rad/s per mm of left-right radius difference (eq. 9b)
        v, yr = self._rear_speed_yaw_rate(w3, w4)
        if self._prev_v is not None and dt > 0:
            a = (v - self._prev_v) / dt
            k = dt / (c.accel_filter_time_constant_s + dt)
            self._ax_lp += k * (a - self._ax_lp)
        self._prev_v = v
        imu_ok = self._imu is not None and (t_ns - self._imu[0]) * 1e-9 <= c.imu_timeout_s
        steer_ok = self._steer is not None and (t_ns - self._steer[0]) * 1e-9 <= c.imu_timeout_s
        if imu_ok and self._imu is not None:
            ax, ay = self._imu[2][0], self._imu[2][1]
        elif steer_ok and self._steer is not None:
            # lateral acceleration from the steer angle (independent of the radius estimates,
            # which may still be wrong while the filter converges)
            ax, ay = self._ax_lp, v * float(self.model.steering_yaw_rate(v, self._steer[1]))
        else:
            ax, ay = self._ax_lp, v * yr
        steer = None
        if steer_ok and self._steer is not None and abs(v) < c.steering_heading_speed_m_s:
            steer = self._steer[1]
        if v < c.min_speed_m_s:
            return False, "low speed", ax, ay, steer
        if ax < -c.braking_decel_m_s2:
            return False, "braking", ax, ay, steer
        if abs(ax) > c.max_abs_ax_m_s2:
            return False, "longitudinal acceleration", ax, ay, steer
        if abs(ay) > c.max_abs_ay_m_s2:
            return False, "lateral acceleration", ax, ay, steer
        return True, "estimating", ax, ay, steer

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

    def _reinit_pose(self, why: str) -> None:
        self._pose_ok = False
        self._init = _Init()
        self._reason = f"waiting for GNSS ({why})"

    # ------------------------------------------------------------------ GNSS
    def _refresh_cache(self) -> None:
        """After a measurement: the learned radii the gates and the speed use are brought up to
        date (the MPF's queued predictions are processed)."""
        if self._cache_version != self.mpf.version:
            self._set_cache(self.mpf.estimate())

    def on_gnss_fix(
        self,
        t_ns: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float,
        position_covariance_m2: Any = None,
    ) -> GnssUpdate:
        """GNSS antenna fix (WGS-84) with an optional ENU covariance (3, 3)."""
        update = self._gnss_fix(t_ns, lat_deg, lon_deg, alt_m, position_covariance_m2)
        self._refresh_cache()
        return update

    def _gnss_fix(
        self,
        t_ns: int,
        lat_deg: float,
        lon_deg: float,
        alt_m: float,
        position_covariance_m2: Any,
    ) -> GnssUpdate:
        zeros2, eye2 = np.zeros(2), np.zeros((2, 2))
        try:
            self._check_order("gnss", t_ns)
            lat, lon, alt = float(lat_deg), float(lon_deg), float(alt_m)
            _finite("gnss", lat, lon, alt)
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0 and abs(alt) < 1e5):
                raise InputError("out_of_range", f"gnss fix out of range: {lat}, {lon}, {alt}")
            r = self._gnss_cov(position_covariance_m2)
        except (InputError, TypeError, ValueError) as exc:
            kind = exc.kind if isinstance(exc, InputError) else "bad_value"
            self._drop(kind)
            return GnssUpdate(int(t_ns) if _is_int(t_ns) else 0, zeros2, eye2, 0.0, False, kind)
        t_ns = int(t_ns)
        self._streams["gnss"].last_t_ns = t_ns
        try:
            if self._ltp is None:
                from tire_estimation.core.geodesy import LocalTangentPlane

                self._ltp = LocalTangentPlane(lat, lon, alt)
            e, n, u = self._ltp.to_enu(lat, lon, alt)
            y = np.array([float(e), float(n)])
            _finite("gnss", *y)
        except Exception:
            self._drop("bad_value")
            return GnssUpdate(t_ns, zeros2, eye2, 0.0, False, "bad_value")
        self._grade_fix(float(u))
        return self.on_gnss_enu(t_ns, y, r)

    def _gnss_cov(self, cov: Any, default_std: float | None = None) -> F64:
        """(2, 2) horizontal block of a (3, 3) or (2, 2) covariance; all zero or None: the
        default std (``gnss_default_std_m`` unless given)."""
        sd = self.config.gnss_default_std_m if default_std is None else default_std
        if cov is None:
            return np.eye(2) * sd**2
        c = np.asarray(cov, dtype=float)
        if c.size == 9:
            flat = c.ravel().tolist()
            c00, c01, c10, c11 = flat[0], flat[1], flat[3], flat[4]
        elif c.size == 4:
            c00, c01, c10, c11 = c.ravel().tolist()
        else:
            raise InputError("wrong_length", f"gnss covariance must be 3x3, got size {c.size}")
        if not all(math.isfinite(v) for v in (c00, c01, c10, c11)):
            raise InputError("nan", "gnss covariance not finite")
        c01 = 0.5 * (c01 + c10)
        if c00 == 0.0 and c01 == 0.0 and c11 == 0.0:
            return np.eye(2) * sd**2  # "covariance unknown"
        # a symmetric 2x2 matrix is positive definite iff c00 > 0 and det > 0
        if not (c00 > 0.0 and c00 * c11 - c01 * c01 > 0.0):
            raise InputError("bad_covariance", "gnss covariance not positive definite")
        return np.array([[c00, c01], [c01, c11]])

    def on_gnss_enu(self, t_ns: int, y_m: F64, r_m2: F64) -> GnssUpdate:
        """GNSS update with a fix already in the local ENU frame (east, north) and its (2, 2)
        covariance. Called by :meth:`on_gnss_fix`; usable directly by tests and simulations."""
        c = self.config
        zeros2 = np.zeros(2)
        self.mpf.observe_fix_cov(r_m2)
        if self.kf is not None:
            self.kf.observe_fix_cov(r_m2)
        if (
            self._pose_ok
            and self._t_last_fix_ns is not None
            and (t_ns - self._t_last_fix_ns) * 1e-9 > c.gnss_max_gap_s
        ):
            self._drop("gnss_gap")
            self._reinit_pose("GNSS gap")
        if not self._pose_ok:
            return self._initialize(t_ns, y_m, r_m2)
        ext = 0.0 if self._t_pose_ns is None else (t_ns - self._t_pose_ns) * 1e-9
        if abs(ext) > 0.5:
            self._drop("stale")
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, False, "stale (no wheel speeds)")
        # calibrated time alignment (default 0): the fix describes the antenna at
        # t - gnss_latency_s, the pose describes base_link at t_pose - wheel_speed_time_offset_s
        ext += c.wheel_speed_time_offset_s - c.gnss_latency_s
        pred = self.mpf.predict_fix(y_m, r_m2, self.lever_arm_m, ext)
        if not math.isfinite(pred.nis) or pred.nis > self._gate:
            self._drop("gnss_outlier")
            self._rejections += 1
            if self._rejections >= c.gnss_max_rejections:
                self._rejections = 0
                self._reinit_pose("repeated GNSS outliers")
                self._initialize(t_ns, y_m, r_m2)
                return GnssUpdate(
                    t_ns,
                    pred.innovation_m,
                    pred.innovation_cov_m2,
                    pred.nis,
                    False,
                    "outlier; pose re-initialization",
                )
            return GnssUpdate(
                t_ns, pred.innovation_m, pred.innovation_cov_m2, pred.nis, False, "outlier"
            )
        self._rejections = 0
        self._t_last_fix_ns = t_ns
        learn = self._active
        if learn:
            self.mpf.update(y_m, r_m2, pred)
            self._calibration()
            reason = "updated"
        else:
            self.mpf.anchor(y_m, r_m2, pred)
            reason = f"anchored ({self._reason})"
        if self.kf is not None:
            upd, hj = self.kf.innovation(y_m, r_m2, self.lever_arm_m, ext)
            if upd.nis <= self._gate * 4.0:
                self.kf.update(upd, hj, learn=learn)
        self._set_cache(self.mpf.estimate())
        return GnssUpdate(t_ns, pred.innovation_m, pred.innovation_cov_m2, pred.nis, True, reason)

    def on_gnss_velocity(
        self, t_ns: int, velocity_enu_m_s: Any, velocity_covariance_m2_s2: Any = None
    ) -> GnssVelocityUpdate:
        """GNSS Doppler velocity of the antenna (:meth:`_gnss_velocity`)."""
        update = self._gnss_velocity(t_ns, velocity_enu_m_s, velocity_covariance_m2_s2)
        self._refresh_cache()
        return update

    def _gnss_velocity(
        self, t_ns: int, velocity_enu_m_s: Any, velocity_covariance_m2_s2: Any
    ) -> GnssVelocityUpdate:
        """GNSS Doppler velocity of the antenna in ENU (3,) or (2,) m/s with an optional (3, 3)
        or (2, 2) covariance (beyond the paper; used with ``gnss_velocity_enabled``).

        Applied while the radii are being learned (like a fix's re-weighting); while paused,
        initializing or with ``gnss_velocity_enabled`` false it is validated and skipped. The
        velocity is taken to describe the antenna at ``t - gnss_velocity_latency_s`` and is
        compared with the rear wheel speeds of that time."""
        c = self.config
        zeros2, eye2 = np.zeros(2), np.zeros((2, 2))
        stamp = int(t_ns) if _is_int(t_ns) else 0
        try:
            self._check_order("gnss_velocity", t_ns)
            v = np.asarray(velocity_enu_m_s, dtype=float).ravel()
            if v.size not in (2, 3):
                raise InputError("wrong_length", f"gnss velocity must have 3 values, got {v.size}")
            _finite("gnss_velocity", *v.tolist())
            if float(np.hypot(v[0], v[1])) > 150.0:
                raise InputError("out_of_range", f"gnss velocity above 150 m/s: {v.tolist()}")
            r = self._gnss_cov(velocity_covariance_m2_s2, c.gnss_velocity_default_std_m_s)
        except (InputError, TypeError, ValueError) as exc:
            kind = exc.kind if isinstance(exc, InputError) else "bad_value"
            self._drop(f"gnss_velocity_{kind}")
            return GnssVelocityUpdate(stamp, zeros2, eye2, 0.0, False, kind)
        t_ns = int(t_ns)
        self._streams["gnss_velocity"].last_t_ns = t_ns
        if not c.gnss_velocity_enabled:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "disabled")
        if not self._pose_ok or self._prev_ws is None or len(self._speed_hist) < 2:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "initializing")
        if self._t_pose_ns is None or abs(t_ns - self._t_pose_ns) * 1e-9 > 0.5:
            self._drop("gnss_velocity_stale")
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "stale (no wheel speeds)")
        if not self._active:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, f"paused ({self._reason})")
        # the velocity describes the wheels' time t - latency + offset: rear wheel speeds there
        # (linear interpolation of the recent samples, held at the ends)
        target = t_ns + round((c.wheel_speed_time_offset_s - c.gnss_velocity_latency_s) * 1e9)
        # the newest samples back to the first one at or before 0.2 s before the earlier of
        # target and stamp (the interpolations below read nothing older; the whole history
        # when it is shorter)
        lo_ns = min(target, t_ns) - 200_000_000
        hist: list[tuple[int, float, float]] = []
        for h in reversed(self._speed_hist):
            hist.append(h)
            if h[0] <= lo_ns:
                break
        hist.reverse()
        n_h = len(hist)
        ts = np.fromiter((h[0] for h in hist), dtype=np.int64, count=n_h)
        rel = (ts - ts[-1]) * 1e-9
        x = (target - int(ts[-1])) * 1e-9
        w3s = np.fromiter((h[1] for h in hist), float, n_h)
        w4s = np.fromiter((h[2] for h in hist), float, n_h)
        w3 = float(np.interp(x, rel, w3s))
        w4 = float(np.interp(x, rel, w4s))
        sums = w3s + w4s
        r_half = 0.5 * self.model.nominal_radius_m

        def accel_before(x_s: float, sum_now: float) -> float:
            """Wheel acceleration over the 0.2 s before ``x_s`` (held at the history's ends)."""
            span = min(0.2, x_s - float(rel[0]))
            k0 = float(np.interp(x_s - 0.2, rel, sums))
            return (sum_now - k0) * r_half / span if span > 0 else 0.0

        # at the target: an error of the latency by std s adds (a s)^2 to the speed's variance
        accel = accel_before(x, w3 + w4)
        # the gate reads the acceleration over the 0.2 s before the velocity's stamp, not its
        # compensated time: which velocities are used is then a property of the data, the same
        # for every latency or time offset a residual profile re-runs with (else the joint
        # likelihood of those re-runs would sum over different sets of velocities)
        x_g = (t_ns - int(ts[-1])) * 1e-9
        gate_accel = accel_before(x_g, float(np.interp(x_g, rel, sums)))
        if abs(gate_accel) > c.gnss_velocity_max_accel_m_s2:
            # an unknown latency tau biases the speed by tau a while accelerating: not used
            self.velocity_skipped_accel += 1
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "accelerating")
        along_var = (accel * c.gnss_velocity_latency_std_s) ** 2
        _, yaw_rate = self._rear_speed_yaw_rate(w3, w4)
        # the heading at the velocity's time: the pose is at t_pose, the velocity describes
        # the target time (rotation by the yaw rate over the difference)
        dpsi = -yaw_rate * (self._t_pose_ns - target) * 1e-9
        upd = self.mpf.update_velocity(
            v[:2], r, self.lever_arm_m, yaw_rate, c.gnss_velocity_lateral_std_m_s, (w3, w4),
            along_var_m2_s2=along_var, gate_nis=self._gate, heading_offset_rad=dpsi,
        )  # fmt: skip
        if not upd.accepted:
            self._drop("gnss_velocity_outlier")
            return GnssVelocityUpdate(
                t_ns, upd.innovation_m_s, upd.innovation_cov_m2_s2, upd.nis, False, "outlier"
            )
        self.velocity_updates += 1
        if self.kf is not None:
            kupd, hj = self.kf.velocity_innovation(
                v[:2], r, self.lever_arm_m, c.gnss_velocity_lateral_std_m_s, (w3, w4), along_var,
                heading_offset_rad=dpsi,
            )  # fmt: skip
            if kupd.nis <= self._gate * 4.0:
                self.kf.update(kupd, hj, learn=True)
        self._calibration()
        self._set_cache(self.mpf.estimate())
        return GnssVelocityUpdate(
            t_ns, upd.innovation_m_s, upd.innovation_cov_m2_s2, upd.nis, True, "updated"
        )

    def _calibration(self) -> None:
        c = self.config
        if not c.non_increasing_after_calibration:
            return
        if self._upper is None and self._active_time_s >= c.calibration_time_s:
            self._upper = self.mpf.estimate().radius.mean + c.non_increasing_margin_m
        if self._upper is not None:
            self.mpf.clip_mean(self._upper)

    def _initialize(self, t_ns: int, y_m: F64, r_m2: F64) -> GnssUpdate:
        """Two-fix pose initialization: heading from the GNSS displacement vs the odometry."""
        zeros2 = np.zeros(2)
        self._t_last_fix_ns = t_ns
        if self._init.anchor is None or self._prev_ws is None:
            self._init = _Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, True, "initializing (anchor fix)")
        d_enu = y_m - self._init.anchor
        dist = float(np.hypot(*d_enu))
        b = self._init.body
        d_body = float(np.hypot(b[0], b[1]))
        if dist < self.config.init_min_distance_m:
            if d_body > 3.0 * self.config.init_min_distance_m:
                self._init = _Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, True, "initializing (moving)")
        if not 0.5 * dist < d_body < 2.0 * dist:
            self._init = _Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, False, "initializing (inconsistent)")
        yaw0 = math.atan2(d_enu[1], d_enu[0]) - math.atan2(b[1], b[0])
        yaw = yaw0 + b[2]
        sd = math.sqrt(float(np.trace(r_m2)) / 2.0)
        yaw_std = 2.0 * sd / dist + 0.01
        # invert the measurement model of predict_fix (eq. 13 with lever arm and the calibrated
        # time alignment): antenna = base_link + R(yaw) (lever + [ext v, 0])
        c = self.config
        ext = 0.0 if self._t_pose_ns is None else (t_ns - self._t_pose_ns) * 1e-9
        ext += c.wheel_speed_time_offset_s - c.gnss_latency_s
        lx = float(self.lever_arm_m[0]) + ext * self._speed_yaw_rate(self._prev_ws)[0]
        ly = float(self.lever_arm_m[1])
        cy, sy = math.cos(yaw), math.sin(yaw)
        pos = y_m - np.array([lx * cy - ly * sy, lx * sy + ly * cy])
        # the inversion depends on the heading: pos = y - R(yaw) l, so d pos / d yaw =
        # -R'(yaw) l = [lx sin + ly cos, -lx cos + ly sin]; each particle's position must
        # follow its own heading (with an independent heading the cloud's antenna positions
        # R(yaw_i) l scatter by |l| yaw_std, 7.5 m x 0.17 rad for a 0.3 s latency at 25 m/s)
        jac = np.eye(3)
        jac[0, 2] = lx * sy + ly * cy
        jac[1, 2] = -lx * cy + ly * sy
        cov0 = np.zeros((3, 3))
        cov0[:2, :2] = r_m2
        cov0[2, 2] = yaw_std**2
        # cov = J diag(R, yaw_var) J^T (first-order propagation through the inversion)
        cov = jac @ cov0 @ jac.T
        mean = np.array([pos[0], pos[1], math.atan2(math.sin(yaw), math.cos(yaw))])
        self.mpf.init_pose(mean, cov)
        if self.kf is not None:
            self.kf.init_pose(mean, cov)
        self._pose_ok = True
        self._rejections = 0
        self._set_cache(self.mpf.estimate())
        return GnssUpdate(t_ns, zeros2, r_m2, 0.0, True, "pose initialized")

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> RadiusEstimate:
        """Current estimate (always finite). Reading it changes nothing in the filter (the MPF's
        queued predictions are not processed for it: :meth:`RadiusMPF.peek`)."""
        # the estimate computed after the last fix is still valid if nothing changed since
        fresh = getattr(self, "_cache_version", -1) == self.mpf.version
        est = self._cache if fresh else self.mpf.peek()
        rad = est.radius
        wheels: tuple[str, ...] = REAR_WHEELS
        mean = rad.mean
        mc, nc = rad.mean_cov, rad.noise_cov
        std = np.array(
            [math.sqrt(max(float(mc[0, 0]), 0.0)), math.sqrt(max(float(mc[1, 1]), 0.0))]
        )
        noise = np.array(
            [math.sqrt(max(float(nc[0, 0]), 0.0)), math.sqrt(max(float(nc[1, 1]), 0.0))]
        )
        active = (self._active, self._active)
        if self.config.wheels == "all":
            fe = niw.mmse(self._front, np.ones(1))
            wheels = FRONT_WHEELS + REAR_WHEELS
            mean = np.concatenate([fe.mean, mean])
            fstd = np.sqrt(np.maximum(np.diag(fe.mean_cov), 0.0) + np.mean(std**2))
            std = np.concatenate([fstd, std])
            noise = np.concatenate([np.sqrt(np.maximum(np.diag(fe.noise_cov), 0.0)), noise])
            active = (self._active,) * 4
        ws = self._prev_ws if self._prev_ws is not None else np.zeros(4)
        # eq. (6) with the MMSE mean radius errors (the cache set above)
        v, yr = self._speed_yaw_rate(ws)
        if self._pose_ok:
            state = "running" if self._active else "paused"
            pose, pose_cov = est.pose, est.pose_cov
        else:
            state = "initializing"
            pose, pose_cov = np.zeros(3), np.diag([1e6, 1e6, math.pi**2])
        baseline = None
        if self.kf is not None:
            baseline = BaselineEstimate(
                radius_error_m=self.kf.x[3:5].copy(),
                radius_error_std_m=np.sqrt(np.maximum(np.diag(self.kf.p)[3:5], 0.0)),
                pose=self.kf.x[:3].copy(),
                pose_cov=self.kf.p[:3, :3].copy(),
            )
        out = RadiusEstimate(
            t_ns=int(self._t_pose_ns or 0),
            wheels=tuple(wheels),
            radius_error_m=_sanitize(mean),
            radius_error_std_m=_sanitize(std, 1.0),
            radius_noise_std_m=_sanitize(noise, 1.0),
            active=tuple(bool(a) for a in active),
            pose=_sanitize(pose),
            pose_cov=_sanitize(pose_cov, 1e6),
            speed_m_s=_finite_or_zero(v),
            yaw_rate_rad_s=_finite_or_zero(yr),
            n_eff=_finite_or_zero(est.n_eff),
            resample_count=est.resample_count,
            state=state,
            state_reason=self._reason,
            baseline=baseline,
            road_grade_rad=self._grade_rad,
            rear_brake_decel_m_s2=(
                self._brake_decel
                if self.config.rear_brake_slip_s2_per_m
                else self._braking_decel(int(self._t_pose_ns or 0))
            ),
        )
        return out

    def state_dict(self) -> dict[str, Any]:
        """Learned radius statistics (JSON-serializable): per estimated axle the NiW MMSE mean,
        mean covariance, noise covariance and dof, plus the vehicle name and wheel order."""
        rad = self.mpf.estimate().radius
        out: dict[str, Any] = {
            "version": STATE_DICT_VERSION,
            "vehicle": self.vehicle.name,
            "rear": {
                "wheels": list(REAR_WHEELS),
                "mean_m": rad.mean.tolist(),
                "mean_cov_m2": rad.mean_cov.tolist(),
                "noise_cov_m2": rad.noise_cov.tolist(),
                "dof": float(self.mpf.stats.dof),
            },
        }
        if self.config.wheels == "all":
            fe = niw.mmse(self._front, np.ones(1))
            out["front"] = {
                "wheels": list(FRONT_WHEELS),
                "mean_m": fe.mean.tolist(),
                "mean_cov_m2": fe.mean_cov.tolist(),
                "noise_cov_m2": fe.noise_cov.tolist(),
                "dof": float(fe.dof),
            }
        if self.kf is not None:
            out["aug_kf"] = {
                "mean_m": self.kf.x[3:5].tolist(),
                "cov_m2": self.kf.p[3:5, 3:5].tolist(),
            }
        return out

    def load_state_dict(self, d: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output; raises InputError (kind ``state``) when it does not
        belong to this vehicle or is malformed."""
        try:
            if d.get("vehicle") != self.vehicle.name:
                raise InputError("state", f"state of vehicle {d.get('vehicle')!r}")
            rear = d["rear"]
            n = self.mpf.n
            # half of the uncertainty of the mean in gamma, half as spread of the particle means
            stats = niw.stats_from_moments(
                n,
                np.asarray(rear["mean_m"], dtype=float).reshape(2),
                0.5 * np.asarray(rear["mean_cov_m2"], dtype=float).reshape(2, 2),
                np.asarray(rear["noise_cov_m2"], dtype=float).reshape(2, 2),
                float(rear["dof"]),
            )
            if (
                not all(
                    np.all(np.isfinite(a))
                    for a in (stats.mean, stats.scale, stats.gamma, stats.dof)
                )
                or float(rear["dof"]) <= 3.0
            ):
                raise InputError("state", "non-finite or invalid rear statistics")
            # spread the particle means over the restored uncertainty of the mean
            cov = np.asarray(rear["mean_cov_m2"], dtype=float).reshape(2, 2)
            chol = np.linalg.cholesky(0.25 * (cov + cov.T) + 1e-18 * np.eye(2))
            z = self.rng.standard_normal((n, 2))
            z -= z.mean(axis=0)
            stats.mean += z @ chol.T
            front = None
            if "front" in d and self.config.wheels == "all":
                f = d["front"]
                front = niw.stats_from_moments(
                    1,
                    np.asarray(f["mean_m"], dtype=float).reshape(2),
                    np.asarray(f["mean_cov_m2"], dtype=float).reshape(2, 2),
                    np.asarray(f["noise_cov_m2"], dtype=float).reshape(2, 2),
                    float(f["dof"]),
                )
        except InputError:
            raise
        except (KeyError, TypeError, ValueError, np.linalg.LinAlgError) as exc:
            raise InputError("state", f"malformed radius state: {exc}") from exc
        self.mpf.set_stats(stats)
        if front is not None:
            self._front = front
        if self.kf is not None and "aug_kf" in d:
            self.kf.x[3:5] = np.asarray(d["aug_kf"]["mean_m"], dtype=float).reshape(2)
            self.kf.p[3:5, 3:5] = np.asarray(d["aug_kf"]["cov_m2"], dtype=float).reshape(2, 2)
        self._set_cache(self.mpf.estimate())


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _finite_or_zero(x: Any) -> float:
    v = float(x)
    return v if math.isfinite(v) else 0.0


def _sanitize(a: Any, fill: float = 0.0) -> F64:
    out = np.array(a, dtype=float)
    # every element finite (the sum of Python floats of these few elements is cheaper than
    # NumPy's reductions; an overflowing sum is checked below)
    if math.isfinite(sum(out.ravel().tolist())):
        return out
    if np.isfinite(out).all():
        return out
    return np.nan_to_num(out, nan=fill, posinf=fill, neginf=-fill)


__all__ = [
    "WHEELS",
    "BaselineEstimate",
    "GnssUpdate",
    "RadiusEstimate",
    "RadiusEstimator",
]
