"""GNSS handling of the radius estimator: fixes (validation, outlier gate, re-initialization,
two-fix pose initialization) and Doppler velocities (alignment with the wheel speeds by
interpolation, acceleration gate); part of :class:`~.estimator.RadiusEstimator`."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import checked_covariance
from tire_estimation.core.radius.fix_scale import across_track
from tire_estimation.core.radius.inputs import finite, is_int
from tire_estimation.core.radius.wheel_timing import speeds_at
from tire_estimation.core.samples import MAX_ABS_ALTITUDE_M
from tire_estimation.errors import InputError

if TYPE_CHECKING:
    from tire_estimation.core.radius.aug_kf import AugKf
    from tire_estimation.core.radius.axle_check import AxleCheck
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.fix_scale import FixCovarianceCheck
    from tire_estimation.core.radius.model import RadiusMotionModel
    from tire_estimation.core.radius.mpf import MpfEstimate, RadiusMPF
    from tire_estimation.core.radius.road_grade import RoadGradeFit
    from tire_estimation.core.radius.speed_scale import SpeedScaleCheck


#: after this many consecutive rejected fixes the pose is re-initialized from GNSS (a genuine
#: relocation: at the default gate probability five chance rejections in a row have a
#: probability of 1e-20)
GNSS_MAX_REJECTIONS = 5

#: a fix arriving more than this after the last accepted one re-initializes the pose, s: after
#: half a minute of dead reckoning the pose is taken afresh from two fixes rather than trusted
GNSS_MAX_GAP_S = 30.0

#: learning pauses when no fix has been accepted for this many fix periods (the period taken
#: from the fixes' own spacing): without fixes nothing weighs the radius errors the particles
#: draw, and the NiW statistics would count those draws as data
GNSS_LEARN_TIMEOUT_PERIODS = 5.0

#: ... and at least this long, s (a fix or two missed at 10 Hz does not pause learning)
GNSS_LEARN_TIMEOUT_MIN_S = 1.0

#: fix spacings above this are outages, not the receiver's period, s
GNSS_PERIOD_MAX_S = 5.0

#: the acceleration gate of a GNSS velocity reads the wheel speeds up to this long before its
#: stamp, s: longer than a tooth takes to pass above 1 m/s, so that the gate and the compared
#: speeds share no sensor error
GATE_LEAD_S = 0.1

#: std of each horizontal velocity component used when a GNSS velocity has no covariance, m/s
#: (the Doppler accuracy of a consumer receiver)
GNSS_VELOCITY_DEFAULT_STD_M_S = 0.1

#: std of the lateral velocity of ``base_link`` that the kinematic model sets to zero (rear-axle
#: sideslip), added across the heading, m/s
GNSS_VELOCITY_LATERAL_STD_M_S = 0.2

#: uncertainty of the compensated GNSS velocity latency, s: the speed's variance grows by
#: ``(a std)^2`` at the acceleration ``a`` of the wheel speeds
GNSS_VELOCITY_LATENCY_STD_S = 0.1

#: wheel samples kept to align a GNSS velocity with the wheel speeds (2.56 s at 100 Hz)
SPEED_HISTORY = 256


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


@dataclass
class Init:
    """Two-fix initialization of the pose: anchor fix and body-frame odometry since then."""

    anchor: F64 | None = None
    body: F64 = field(default_factory=lambda: np.zeros(3))


class GnssHandling:
    """The GNSS part of :class:`~.estimator.RadiusEstimator`."""

    config: RadiusEstimatorConfig
    model: RadiusMotionModel
    mpf: RadiusMPF
    kf: AugKf | None
    grade: RoadGradeFit
    lever_arm_m: F64
    velocity_updates: int
    velocity_skipped_accel: int
    #: wheel-odometry distance over the fixes' distance of each two-fix initialization that
    #: failed its consistency check (outside 0.5-2): a wheel-speed unit or nominal radius off
    init_distance_ratios: list[float]
    _gate: float
    _fix_shift_s: float
    _velocity_shift_s: float
    #: stamp and (east, north) of the newest fix in the ``map`` frame, m (None before one)
    last_fix_enu: tuple[int, F64] | None
    _ltp: Any
    _streams: dict[str, Any]
    _speed_hist: deque[tuple[int, float, float]]
    _prev_ws: F64 | None
    _t_pose_ns: int | None
    _pose_ok: bool
    _init: Init
    _active: bool
    _reason: str
    _rejections: int
    _t_last_fix_ns: int | None
    _t_prev_received_ns: int | None
    _fix_period_s: float | None
    _last_alt_m: float
    _cache_version: int
    speed_scale: SpeedScaleCheck
    fix_scale: FixCovarianceCheck
    _cache: MpfEstimate
    axles: AxleCheck

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
        """GNSS antenna fix (WGS-84) with an optional ENU covariance (3, 3). A fix without
        altitude (NaN) is used horizontally and counted as ``gnss_fix:no_altitude``; a bad
        covariance drops it (``gnss_fix:bad_covariance``)."""
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
            finite("gnss", lat, lon)
            has_alt = math.isfinite(alt)
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 360.0) or (
                has_alt and abs(alt) > MAX_ABS_ALTITUDE_M
            ):
                raise InputError("out_of_range", f"gnss fix out of range: {lat}, {lon}, {alt}")
            r = self._gnss_cov(position_covariance_m2)
        except (InputError, TypeError, ValueError) as exc:
            kind = exc.kind if isinstance(exc, InputError) else "bad_value"
            self._drop("gnss_fix", kind)
            return GnssUpdate(int(t_ns) if is_int(t_ns) else 0, zeros2, eye2, 0.0, False, kind)
        t_ns = int(t_ns)
        self._streams["gnss"].last_t_ns = t_ns
        if has_alt:
            self._last_alt_m = alt
        else:
            # no altitude (NaN, the ROS convention): the horizontal position is used at the
            # last reported altitude (the frame's origin: the ellipsoid when none was ever
            # reported; a height error h moves east/north by h d / R at a distance d from the
            # origin, 0.16 m for 100 m at 10 km) and the road-grade fit skips the fix
            self._drop("gnss_fix", "no_altitude")
            alt = self._last_alt_m
        try:
            if self._ltp is None:
                from tire_estimation.core.geodesy import LocalTangentPlane

                self._ltp = LocalTangentPlane(lat, lon, alt)
            e, n, u = self._ltp.to_enu(lat, lon, alt)
            y = np.array([float(e), float(n)])
            finite("gnss", *y)
        except Exception:
            self._drop("gnss_fix", "bad_value")
            return GnssUpdate(t_ns, zeros2, eye2, 0.0, False, "bad_value")
        if has_alt:
            self.grade.fix(float(u))
        self.last_fix_enu = (t_ns, y)
        return self.on_gnss_enu(t_ns, y, r)

    def _gnss_cov(self, cov: Any, default_std: float | None = None) -> F64:
        """(2, 2) horizontal block of a (3, 3) or (2, 2) covariance
        (:func:`~tire_estimation.core.input_checks.checked_covariance`); all zero or None: the
        default std (``gnss_default_std_m`` unless given)."""
        sd = self.config.gnss_default_std_m if default_std is None else default_std
        c = checked_covariance(cov, "gnss covariance")
        if c is None:
            return np.eye(2) * sd**2  # "covariance unknown"
        return np.ascontiguousarray(c[:2, :2])

    def _learned_rear_radius_m(self) -> float:
        """The learned mean rear rolling radius, m (nominal plus the mean of the two errors)."""
        return self._nominal_radius_m + 0.5 * sum(self._radius_mean)

    def _track_fix_period(self, t_ns: int) -> None:
        """The receiver's fix period: exponential mean (weight 0.1) of the spacing of the fixes
        received, outages (above :data:`GNSS_PERIOD_MAX_S`) left out."""
        prev = self._t_prev_received_ns
        self._t_prev_received_ns = t_ns
        if prev is None:
            return
        dt = (t_ns - prev) * 1e-9
        if 0.0 < dt <= GNSS_PERIOD_MAX_S:
            p = self._fix_period_s
            self._fix_period_s = dt if p is None else p + 0.1 * (dt - p)

    def fix_overdue(self, t_ns: int) -> bool:
        """Whether no fix has been accepted for :data:`GNSS_LEARN_TIMEOUT_PERIODS` fix periods
        (at least :data:`GNSS_LEARN_TIMEOUT_MIN_S`) before ``t_ns``: learning pauses."""
        last = self._t_last_fix_ns
        if last is None:
            return False
        period = self._fix_period_s or 0.0
        timeout = max(GNSS_LEARN_TIMEOUT_MIN_S, GNSS_LEARN_TIMEOUT_PERIODS * period)
        return (t_ns - last) * 1e-9 > timeout

    def on_gnss_enu(self, t_ns: int, y_m: F64, r_m2: F64) -> GnssUpdate:
        """GNSS update with a fix already in the local ENU frame (east, north) and its (2, 2)
        covariance. Called by :meth:`on_gnss_fix`; usable directly by tests and simulations."""
        zeros2 = np.zeros(2)
        self._track_fix_period(t_ns)
        # the stated covariance as the innovations have shown it (fix_scale.py)
        r_m2 = self.fix_scale.apply(r_m2)
        east_m, north_m, std_m = float(y_m[0]), float(y_m[1]), math.sqrt(0.5 * np.trace(r_m2))
        # the receiver's motion, against which the wheels' signs are told (wheel_signs.py)
        self.axles.signs.on_fix(t_ns, east_m, north_m, std_m)
        # a gross scale error in the distance between the fixes of straight runs
        factor = self.speed_scale.add_fix(
            t_ns, east_m, north_m, std_m, self._learned_rear_radius_m()
        )
        if factor != 1.0:
            # the radii restart and the pose waits for two fixes, this one the first
            self._scale_radii(factor)
            return self._initialize(t_ns, y_m, r_m2)
        self.mpf.observe_fix_cov(r_m2)
        if self.kf is not None:
            self.kf.observe_fix_cov(r_m2)
        if (
            self._pose_ok
            and self._t_last_fix_ns is not None
            and (t_ns - self._t_last_fix_ns) * 1e-9 > GNSS_MAX_GAP_S
        ):
            self._drop("gnss_fix", "gap")
            self._reinit_pose("GNSS gap")
        if not self._pose_ok:
            return self._initialize(t_ns, y_m, r_m2)
        ext = 0.0 if self._t_pose_ns is None else (t_ns - self._t_pose_ns) * 1e-9
        if abs(ext) > 0.5:
            self._drop("gnss_fix", "stale")
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, False, "stale (no wheel speeds)")
        # calibrated time alignment (default 0): the fix describes the antenna at
        # t - gnss_latency_s, the pose describes base_link at t_pose - wheel_speed_time_offset_s
        ext += self._fix_shift_s
        pred = self.mpf.predict_fix(y_m, r_m2, self.lever_arm_m, ext)
        # the innovation across the track (fix_scale.py): along it a wrong radius scale, a
        # latency or a wheel-speed offset move the fixes as well
        nis_across, share = across_track(
            float(self._cache.pose[2]), pred.innovation_m, pred.innovation_cov_m2, r_m2
        )
        if self.fix_scale.add(t_ns, nis_across, share) and self.fix_scale.changes[-1] > 1.0:
            # what was learned from fixes trusted beyond their accuracy (a split of 20 mm within
            # 20 s on a simulated drive) is not kept: the radii and the pose start again
            self._scale_radii(1.0, "fixes less accurate than stated")
            return self._initialize(t_ns, y_m, r_m2 * self.fix_scale.changes[-1])
        if not math.isfinite(pred.nis) or pred.nis > self._gate:
            self._drop("gnss_fix", "outlier")
            self._rejections += 1
            if self._rejections >= GNSS_MAX_REJECTIONS:
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
        stamp = int(t_ns) if is_int(t_ns) else 0
        try:
            self._check_order("gnss_velocity", t_ns)
            v = np.asarray(velocity_enu_m_s, dtype=float).ravel()
            if v.size not in (2, 3):
                raise InputError("wrong_length", f"gnss velocity must have 3 values, got {v.size}")
            finite("gnss_velocity", *v.tolist())
            if float(np.hypot(v[0], v[1])) > 150.0:
                raise InputError("out_of_range", f"gnss velocity above 150 m/s: {v.tolist()}")
            r = self._gnss_cov(velocity_covariance_m2_s2, GNSS_VELOCITY_DEFAULT_STD_M_S)
        except (InputError, TypeError, ValueError) as exc:
            kind = exc.kind if isinstance(exc, InputError) else "bad_value"
            self._drop("gnss_velocity", kind)
            return GnssVelocityUpdate(stamp, zeros2, eye2, 0.0, False, kind)
        t_ns = int(t_ns)
        self._streams["gnss_velocity"].last_t_ns = t_ns
        # the course's turning against the gyro's (a reversed gyro, exchanged wheel sides)
        self.axles.on_course(t_ns, float(v[0]), float(v[1]))
        self.axles.signs.on_velocity(t_ns, float(v[0]), float(v[1]))
        if not c.gnss_velocity_enabled:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "disabled")
        if not self._pose_ok or self._prev_ws is None or len(self._speed_hist) < 2:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "initializing")
        if self._t_pose_ns is None or abs(t_ns - self._t_pose_ns) * 1e-9 > 0.5:
            self._drop("gnss_velocity", "stale")
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "stale (no wheel speeds)")
        if not self._active:
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, f"paused ({self._reason})")
        # the velocity describes the wheels' time t - latency + offset: rear wheel speeds there
        # (a line through the samples of the 0.2 s before it, wheel_timing.speeds_at)
        target = t_ns + round(self._velocity_shift_s * 1e9)
        # the newest samples back to the first one at or before 0.3 s before the earlier of
        # target and stamp (the fits and interpolations below read nothing older; the whole
        # history when it is shorter)
        lo_ns = min(target, t_ns) - 300_000_000
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
        (w3, w4), fit_var = speeds_at(x, rel, np.column_stack([w3s, w4s]))
        w3, w4 = float(w3), float(w4)
        sums = w3s + w4s
        r_half = 0.5 * self.model.nominal_radius_m

        def accel_before(x_s: float, sum_now: float) -> float:
            """Wheel acceleration over the 0.2 s before ``x_s`` (held at the history's ends)."""
            span = min(0.2, x_s - float(rel[0]))
            k0 = float(np.interp(x_s - 0.2, rel, sums))
            return (sum_now - k0) * r_half / span if span > 0 else 0.0

        # at the target: an error of the latency by std s adds (a s)^2 to the speed's variance
        accel = accel_before(x, w3 + w4)
        # the gate reads the acceleration over 0.2 s of wheel speeds before the velocity's
        # stamp, not its compensated time: which velocities are used is then a property of the
        # data, the same for every latency or time offset a residual profile re-runs with (else
        # the joint likelihood of those re-runs would sum over different sets of velocities);
        # the 0.2 s end GATE_LEAD_S before the stamp, so that the gate shares no sample error
        # with the speeds compared (gating on their own error keeps the velocities whose wheel
        # speeds read low while accelerating: a radius too large)
        x_g = (t_ns - int(ts[-1])) * 1e-9 - GATE_LEAD_S
        gate_accel = accel_before(x_g, float(np.interp(x_g, rel, sums)))
        if abs(gate_accel) > c.gnss_velocity_max_accel_m_s2:
            # an unknown latency tau biases the speed by tau a while accelerating: not used
            self.velocity_skipped_accel += 1
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "accelerating")
        # ... and the line's own error: var(v) = (a s)^2 + (r_n / 2)^2 var(w3 + w4)
        along_var = (accel * GNSS_VELOCITY_LATENCY_STD_S) ** 2 + r_half**2 * fit_var
        wheel_speed, yaw_rate = self._rear_speed_yaw_rate(w3, w4)
        # eq. (4b), the yaw rate with the nominal radii: a gross error of the learned split
        # would read as turning
        m = self.model
        yaw_nominal = (w4 - w3) * m.nominal_radius_m / m.track_width_m
        speed = float(np.hypot(v[0], v[1]))
        learned_m = self._learned_rear_radius_m()
        factor = self.speed_scale.add(t_ns, speed, wheel_speed, yaw_nominal, learned_m)
        if factor != 1.0:
            # the radii restart and the pose waits for two fixes: this velocity is not used
            self._scale_radii(factor)
            return GnssVelocityUpdate(t_ns, zeros2, r, 0.0, False, "radii rescaled")
        # the heading at the velocity's time: the pose is at t_pose, the velocity describes
        # the target time (rotation by the yaw rate over the difference)
        dpsi = -yaw_rate * (self._t_pose_ns - target) * 1e-9
        upd = self.mpf.update_velocity(
            v[:2], r, self.lever_arm_m, yaw_rate, GNSS_VELOCITY_LATERAL_STD_M_S, (w3, w4),
            along_var_m2_s2=along_var, gate_nis=self._gate, heading_offset_rad=dpsi,
        )  # fmt: skip
        if not upd.accepted:
            self._drop("gnss_velocity", "outlier")
            return GnssVelocityUpdate(
                t_ns, upd.innovation_m_s, upd.innovation_cov_m2_s2, upd.nis, False, "outlier"
            )
        self.velocity_updates += 1
        if self.kf is not None:
            kupd, hj = self.kf.velocity_innovation(
                v[:2], r, self.lever_arm_m, GNSS_VELOCITY_LATERAL_STD_M_S, (w3, w4), along_var,
                heading_offset_rad=dpsi,
            )  # fmt: skip
            if kupd.nis <= self._gate * 4.0:
                self.kf.update(kupd, hj, learn=True)
        self._set_cache(self.mpf.estimate())
        return GnssVelocityUpdate(
            t_ns, upd.innovation_m_s, upd.innovation_cov_m2_s2, upd.nis, True, "updated"
        )

    def _reinit_pose(self, why: str) -> None:
        self._pose_ok = False
        self._init = Init()
        self._reason = f"waiting for GNSS ({why})"

    def _initialize(self, t_ns: int, y_m: F64, r_m2: F64) -> GnssUpdate:
        """Two-fix pose initialization: heading from the GNSS displacement vs the odometry."""
        zeros2 = np.zeros(2)
        self._t_last_fix_ns = t_ns
        if self._init.anchor is None or self._prev_ws is None:
            self._init = Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, True, "initializing (anchor fix)")
        d_enu = y_m - self._init.anchor
        dist = float(np.hypot(*d_enu))
        b = self._init.body
        d_body = float(np.hypot(b[0], b[1]))
        if dist < self.config.init_min_distance_m:
            if d_body > 3.0 * self.config.init_min_distance_m:
                self._init = Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, True, "initializing (moving)")
        if not 0.5 * dist < d_body < 2.0 * dist:
            if len(self.init_distance_ratios) < 1000:
                self.init_distance_ratios.append(d_body / dist)
            self._init = Init(anchor=np.array(y_m, dtype=float))
            return GnssUpdate(t_ns, zeros2, r_m2, 0.0, False, "initializing (inconsistent)")
        yaw0 = math.atan2(d_enu[1], d_enu[0]) - math.atan2(b[1], b[0])
        yaw = yaw0 + b[2]
        sd = math.sqrt(float(np.trace(r_m2)) / 2.0)
        yaw_std = 2.0 * sd / dist + 0.01
        # invert the measurement model of predict_fix (eq. 13 with lever arm and the calibrated
        # time alignment): antenna = base_link + R(yaw) (lever + [ext v, 0])
        ext = 0.0 if self._t_pose_ns is None else (t_ns - self._t_pose_ns) * 1e-9
        ext += self._fix_shift_s
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
