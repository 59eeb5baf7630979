"""Outputs of the radius estimator: the current estimate and the persisted learned state
(part of :class:`~.estimator.RadiusEstimator`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_estimation.core import niw
from tire_estimation.core import state_checks as checks
from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.inputs import finite_or_zero, sanitize
from tire_estimation.core.radius.mpf import PRIOR_RADIUS_NOISE_STD_M
from tire_estimation.core.wheels import FRONT_WHEELS, REAR_WHEELS
from tire_estimation.errors import InputError

if TYPE_CHECKING:
    from tire_estimation.core.radius.aug_kf import AugKf
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.drive_slip import DriveSlip
    from tire_estimation.core.radius.mpf import MpfEstimate, RadiusMPF
    from tire_estimation.core.radius.road_grade import RoadGradeFit
    from tire_estimation.core.radius.speed_scale import SpeedScaleCheck
    from tire_estimation.core.radius.wheel_timing import WheelSpeedTiming
    from tire_estimation.core.vehicle import VehicleParams


STATE_DICT_VERSION = 1


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
            distance, checked against the IMU's; positive uphill), rad; 0 until a window of
            fixes is available.
        road_grade_source: where ``road_grade_rad`` came from at the latest fix: ``altitude``
            (the GNSS altitude, confirmed by the IMU unless ``road_grade_source: altitude``),
            ``imu`` (the IMU's specific force: the altitude disagreed) or ``none``.
        road_grade_imu_offset_rad: the IMU grade's offset (accelerometer bias and mounting
            pitch) found against the GNSS altitude and taken out, rad; 0 until found beyond
            what the check allows for (``core/radius/road_grade.py``).
        road_grade_counts: fixes (with a full grade window) per source, the keys of
            ``road_grade.GRADE_SOURCES``.
        rear_brake_decel_m_s2: braking deceleration ``b = max(0, -f_x - a_0)``: the one of the
            latest wheel-speed sample when the rear brake slip is on, else computed at the pose
            time for the residual signature, m/s^2.
        wheel_speed_lag_s: the wheel speeds' lag brought back before the prediction (half their
            median sample period, ``core/radius/wheel_timing.py``), s; 0 until it is known.
        wheel_speed_tooth_pitch_rad: the tooth pitch of an edge-timed ABS unit, read off the
            values it holds at low speed, rad; there the lag brought back is a tooth period
            ``pitch / |omega|``; 0 until found (none is found when no value is held).
        drive_slip: what the traction-slip correction of driven rear wheels did
            (``core/radius/drive_slip.py``, :meth:`DriveSlip.summary`); empty when the rear
            wheels are not driven.
        radius_rescales: the factors the rear radii were scaled by when the GNSS showed a gross
            scale error (``core/radius/speed_scale.py``), in order.
        radius_rescale_sources: what showed each: ``velocity`` (the Doppler speed) or
            ``fixes`` (the distance between the fixes of straight runs).
        radius_rescales_refused: scale factors the GNSS showed but beyond what a radius can be
            off (``MAX_RADIUS_ERROR_FRACTION`` of nominal): not applied.
        fix_covariance_scale: the factor every fix covariance is multiplied by, as the fixes'
            innovations have shown it (``core/radius/fix_scale.py``); 1 when never changed.
        fix_covariance_changes: the factors applied to it, in order.
        model_change_t_ns: the stamp of the latest change the estimator made to its own model
            from what the data showed (the rear radii rescaled, the fix covariance scaled), ns;
            None when it made none. The innovations before it were judged by a model no longer
            in use: the residual verdict leaves them out.
        wheel_yaw_rad: the heading change of the rear wheel speeds' yaw rate (eq. 6b with the
            learned radii; the gyro's while the rear axle is locked) integrated since the
            start, no fix correcting it, rad.
        rear_radius_error_cov_m2: (2, 2) posterior covariance of the rear radius errors
            (wheel_rl, wheel_rr; the diagonal is ``radius_error_std_m`` squared), m^2; None
            when not given.
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
    rear_radius_error_cov_m2: F64 | None = None
    road_grade_source: str = "none"
    road_grade_counts: Mapping[str, int] = field(default_factory=dict)
    road_grade_imu_offset_rad: float = 0.0
    wheel_speed_lag_s: float = 0.0
    wheel_speed_tooth_pitch_rad: float = 0.0
    drive_slip: Mapping[str, Any] = field(default_factory=dict)
    radius_rescales: tuple[float, ...] = ()
    radius_rescale_sources: tuple[str, ...] = ()
    radius_rescales_refused: tuple[float, ...] = ()
    fix_covariance_scale: float = 1.0
    fix_covariance_changes: tuple[float, ...] = ()
    model_change_t_ns: int | None = None
    wheel_yaw_rad: float = 0.0


#: wheel samples kept to align a GNSS velocity with the wheel speeds (2.56 s at 100 Hz)
SPEED_HISTORY = 256

#: at most this many GNSS altitudes are kept for the grade fit (100 s at 10 Hz)
GRADE_MAX_POINTS = 1000


class Reporting:
    """The output part of :class:`~.estimator.RadiusEstimator`."""

    config: RadiusEstimatorConfig
    vehicle: VehicleParams
    rng: np.random.Generator
    mpf: RadiusMPF
    kf: AugKf | None
    grade: RoadGradeFit
    timing: WheelSpeedTiming
    drive_slip: DriveSlip
    speed_scale: SpeedScaleCheck
    brake_decel_m_s2: float
    _cache: MpfEstimate
    _front: niw.NiwStats
    _active: bool
    _reason: str
    _pose_ok: bool
    _prev_ws: F64 | None
    _t_pose_ns: int | None

    def _radii(self) -> tuple[MpfEstimate, tuple[str, ...], F64, F64, F64, tuple[bool, ...]]:
        """The MPF estimate and, per wheel covered, the radius errors, their std, the noise std
        and whether each is updated now (before :func:`sanitize`)."""
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
        if self.drive_slip.enabled:
            # the slip model of driven rear wheels: its uncertainty, common to both
            std = np.sqrt(std**2 + self.drive_slip.radius_variance_m2())
        active = (self._active, self._active)
        if self.config.wheels == "all":
            fe = niw.mmse(self._front, np.ones(1))
            wheels = FRONT_WHEELS + REAR_WHEELS
            mean = np.concatenate([fe.mean, mean])
            fstd = np.sqrt(np.maximum(np.diag(fe.mean_cov), 0.0) + np.mean(std**2))
            std = np.concatenate([fstd, std])
            noise = np.concatenate([np.sqrt(np.maximum(np.diag(fe.noise_cov), 0.0)), noise])
            active = (self._active,) * 4
        return est, wheels, mean, std, noise, active

    def radius_errors(self) -> tuple[tuple[str, ...], list[float], list[float], list[bool]]:
        """``wheels``, ``radius_error_m``, ``radius_error_std_m`` and ``active`` of
        :meth:`estimate` (the same values, as lists), without the rest of it."""
        _, wheels, mean, std, _, active = self._radii()
        return (
            tuple(wheels),
            sanitize(mean).tolist(),
            sanitize(std, 1.0).tolist(),
            [bool(a) for a in active],
        )

    def estimate(self) -> RadiusEstimate:
        """Current estimate (always finite). Reading it changes nothing in the filter (the MPF's
        queued predictions are not processed for it: :meth:`RadiusMPF.peek`)."""
        est, wheels, mean, std, noise, active = self._radii()
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
            radius_error_m=sanitize(mean),
            radius_error_std_m=sanitize(std, 1.0),
            radius_noise_std_m=sanitize(noise, 1.0),
            active=tuple(bool(a) for a in active),
            pose=sanitize(pose),
            pose_cov=sanitize(pose_cov, 1e6),
            speed_m_s=finite_or_zero(v),
            yaw_rate_rad_s=finite_or_zero(yr),
            n_eff=finite_or_zero(est.n_eff),
            resample_count=est.resample_count,
            state=state,
            state_reason=self._reason,
            baseline=baseline,
            road_grade_rad=self.grade.grade_rad,
            rear_brake_decel_m_s2=(
                self.brake_decel_m_s2
                if self.config.rear_brake_slip_s2_per_m
                else self.braking_decel_at(int(self._t_pose_ns or 0))
            ),
            rear_radius_error_cov_m2=sanitize(
                est.radius.mean_cov + self.drive_slip.radius_variance_m2(), 1.0
            ),
            road_grade_source=self.grade.source,
            road_grade_counts=dict(self.grade.counts),
            road_grade_imu_offset_rad=math.asin(self.grade.imu_offset),
            wheel_speed_lag_s=self.timing.lag_s,
            wheel_speed_tooth_pitch_rad=self.timing.tooth_pitch_rad,
            drive_slip=self.drive_slip.summary() if self.drive_slip.enabled else {},
            wheel_yaw_rad=self.speed_scale.runs.wheel_yaw_rad,
            radius_rescales=tuple(self.speed_scale.rescales),
            radius_rescale_sources=tuple(self.speed_scale.rescale_sources),
            radius_rescales_refused=tuple(self.speed_scale.refused),
            fix_covariance_scale=self.fix_scale.scale,
            fix_covariance_changes=tuple(self.fix_scale.changes),
            model_change_t_ns=max(
                [*self.speed_scale.rescale_t_ns, *self.fix_scale.change_t_ns], default=None
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
        """Restore :meth:`state_dict` output; raises InputError (kind ``state``) naming the
        value when it does not belong to this vehicle or is not plausible: every mean within
        :func:`~tire_estimation.core.state_checks.radius_error_limit_m` of the nominal radius,
        every covariance positive definite with standard deviations up to that limit (or the
        configured prior std, when larger), the dof finite within (3, 1e9]. Nothing changes
        unless the whole state is valid."""
        checks.require_keys(
            "state", "radius state", d, ("version", "vehicle", "rear"), ("front", "aug_kf")
        )
        checks.choice("state", "radius state version", d["version"], STATE_DICT_VERSION)
        if d["vehicle"] != self.vehicle.name:
            raise InputError("state", f"state of vehicle {checks.shown(d['vehicle'])}")
        nominal = self.vehicle.nominal_tire_radius_m
        limit = checks.radius_error_limit_m(nominal)
        stds = (
            checks.MIN_STD_FRACTION * nominal,
            max(limit, self.config.prior_radius_error_std_m, PRIOR_RADIUS_NOISE_STD_M),
        )
        mean, mean_cov, noise_cov, dof = _axle_moments("rear", d["rear"], REAR_WHEELS, limit, stds)
        front = None
        if "front" in d and self.config.wheels == "all":
            front = _axle_moments("front", d["front"], FRONT_WHEELS, limit, stds)
        aug = None
        if "aug_kf" in d:
            a = checks.require_keys("state", "aug_kf", d["aug_kf"], ("mean_m", "cov_m2"))
            aug = (
                checks.vector("state", "aug_kf.mean_m", a["mean_m"], 2, limit),
                checks.covariance("state", "aug_kf.cov_m2", a["cov_m2"], 2, *stds),
            )
        n = self.mpf.n
        # half of the uncertainty of the mean in gamma, half as spread of the particle means
        stats = niw.stats_from_moments(n, mean, 0.5 * mean_cov, noise_cov, dof)
        if not all(
            np.all(np.isfinite(a)) for a in (stats.mean, stats.scale, stats.gamma, stats.dof)
        ):
            raise InputError("state", "non-finite rear statistics")
        # spread the particle means over the restored uncertainty of the mean
        chol = np.linalg.cholesky(0.5 * mean_cov)
        z = self.rng.standard_normal((n, 2))
        z -= z.mean(axis=0)
        stats.mean += z @ chol.T
        self.mpf.set_stats(stats)
        self.speed_scale.restart()
        if front is not None:
            self._front = niw.stats_from_moments(1, *front)
        if self.kf is not None and aug is not None:
            self.kf.x[3:5] = aug[0]
            self.kf.p[3:5, 3:5] = aug[1]
        self._set_cache(self.mpf.estimate())


def _axle_moments(
    axle: str,
    data: Any,
    wheels: tuple[str, ...],
    limit_m: float,
    stds_m: tuple[float, float],
) -> tuple[F64, F64, F64, float]:
    """The checked mean, mean covariance, noise covariance and dof of one axle's saved
    statistics."""
    a = checks.require_keys(
        "state", axle, data, ("mean_m", "mean_cov_m2", "noise_cov_m2", "dof"), ("wheels",)
    )
    if "wheels" in a:
        checks.choice("state", f"{axle}.wheels", a["wheels"], list(wheels))
    return (
        checks.vector("state", f"{axle}.mean_m", a["mean_m"], 2, limit_m),
        checks.covariance("state", f"{axle}.mean_cov_m2", a["mean_cov_m2"], 2, *stds_m),
        checks.covariance("state", f"{axle}.noise_cov_m2", a["noise_cov_m2"], 2, *stds_m),
        checks.dof("state", f"{axle}.dof", a["dof"], 2),
    )
