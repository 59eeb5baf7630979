"""Traces of what the estimators did over a run: pipeline observers that record them.

The replay and the campaigns push samples into
:class:`~tire_estimation.core.pipeline.EstimationPipeline` (the node's pipeline) and attach
these recorders; :func:`run_radius` is the radius MPF alone over a sample sequence.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.input_checks import merged_counts
from tire_estimation.core.pipeline import (
    DeflationOutput,
    EstimationPipeline,
    Output,
    PipelineConfig,
)
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimator
from tire_estimation.core.samples import GnssFix, GnssVelocity, ImuSample, Sample, TireForces
from tire_estimation.core.stiffness.model import NAMES as STIFFNESS_NAMES
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation.agreement import COLUMNS as AGREEMENT_COLUMNS
from tire_estimation.evaluation.agreement import AgreementBins


@dataclass
class RadiusTrace:
    """What the estimator reported over a run, sampled after every GNSS fix.

    Shapes: ``t_ns`` (K,); per-wheel arrays (K, W) in the order of ``wheel_names``; ``pose``
    (K, 3) [east m, north m, yaw rad] in the estimator's local ENU frame; ``pose_var`` (K, 3).
    Innovations: ``innov_t_ns`` (J,), ``innov_m`` (J, 2) [east, north], ``innov_cov_m2``
    (J, 2, 2), ``nis`` (J,), ``accepted`` (J,). GNSS velocity innovations of the velocities the
    estimator computed one for (``gnss_velocity_enabled``, while learning): ``vel_t_ns`` (V,),
    ``vel_innov_m_s`` (V, 2), ``vel_innov_cov_m2_s2`` (V, 2, 2), ``vel_nis`` (V,),
    ``vel_accepted`` (V,). Sensor agreement (:mod:`~tire_estimation.evaluation.agreement`):
    ``agreement_rows`` (B, C), one per 1-s bin of GNSS velocities, with the vehicle and
    configuration values its analysis needs in ``agreement_params``.
    """

    #: list attributes that hold the latest state, not one row per sample: a replay that moves
    #: the rows to disk block by block keeps them in memory
    LATEST: ClassVar[tuple[str, ...]] = (
        "init_distance_ratios",
        "radius_rescales",
        "radius_rescale_sources",
        "radius_rescales_refused",
        "fix_covariance_changes",
    )

    wheel_names: tuple[str, ...] = ()
    t_ns: list[int] = field(default_factory=list)
    radius_error_m: list[NDArray[np.float64]] = field(default_factory=list)
    radius_error_std_m: list[NDArray[np.float64]] = field(default_factory=list)
    radius_noise_std_m: list[NDArray[np.float64]] = field(default_factory=list)
    active: list[NDArray[np.bool_]] = field(default_factory=list)
    pose: list[NDArray[np.float64]] = field(default_factory=list)
    pose_var: list[NDArray[np.float64]] = field(default_factory=list)
    speed_m_s: list[float] = field(default_factory=list)
    #: the heading change of the wheel speeds' yaw rate since the start (eq. 6b), rad
    wheel_yaw_rad: list[float] = field(default_factory=list)
    n_eff: list[float] = field(default_factory=list)
    state: list[str] = field(default_factory=list)
    reason: list[str] = field(default_factory=list)
    baseline_radius_error_m: list[NDArray[np.float64]] = field(default_factory=list)
    baseline_radius_error_std_m: list[NDArray[np.float64]] = field(default_factory=list)
    innov_t_ns: list[int] = field(default_factory=list)
    innov_m: list[NDArray[np.float64]] = field(default_factory=list)
    innov_cov_m2: list[NDArray[np.float64]] = field(default_factory=list)
    nis: list[float] = field(default_factory=list)
    accepted: list[bool] = field(default_factory=list)
    vel_t_ns: list[int] = field(default_factory=list)
    vel_innov_m_s: list[NDArray[np.float64]] = field(default_factory=list)
    vel_innov_cov_m2_s2: list[NDArray[np.float64]] = field(default_factory=list)
    vel_nis: list[float] = field(default_factory=list)
    vel_accepted: list[bool] = field(default_factory=list)
    gnss_enu_m: list[NDArray[np.float64]] = field(default_factory=list)
    road_grade_rad: list[float] = field(default_factory=list)
    #: fixes per source of the road grade (``road_grade.GRADE_SOURCES``), at the latest sample
    road_grade_counts: dict[str, int] = field(default_factory=dict)
    #: the IMU grade's offset taken out, at the latest sample, rad
    road_grade_imu_offset_rad: float = 0.0
    #: the wheel speeds' compensated lag at the latest sample, s
    wheel_speed_lag_s: float = 0.0
    wheel_speed_tooth_pitch_rad: float = 0.0
    #: the traction-slip correction of driven rear wheels, at the latest sample (empty: none)
    drive_slip: dict[str, Any] = field(default_factory=dict)
    #: the factors the rear radii were scaled by for a gross scale error, at the latest sample
    radius_rescales: list[float] = field(default_factory=list)
    #: what showed each: "velocity" or "fixes"
    radius_rescale_sources: list[str] = field(default_factory=list)
    #: scale factors shown but beyond a plausible radius error (not applied)
    radius_rescales_refused: list[float] = field(default_factory=list)
    #: the fix covariance's scale and the factors applied to it, at the latest sample
    fix_covariance_scale: float = 1.0
    fix_covariance_changes: list[float] = field(default_factory=list)
    #: the stamp of the estimator's latest change to its own model (None: none), ns
    model_change_t_ns: int | None = None
    rear_brake_decel_m_s2: list[float] = field(default_factory=list)
    agreement_rows: list[NDArray[np.float64]] = field(default_factory=list)
    agreement_params: dict[str, float] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)
    resample_count: int = 0
    origin_lla: tuple[float, float, float] | None = None
    #: GNSS velocity summary: velocities that re-weighted the particles (``updates``), those with
    #: an innovation (``innovations``, gated ones included), the mean NIS of the accepted ones
    #: (2 for a consistent model) and the compensated latency, s (None: velocity not used)
    gnss_velocity: dict[str, Any] | None = None
    #: the estimator's failed two-fix initializations (odometry / fix distance, each)
    init_distance_ratios: list[float] = field(default_factory=list)

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The lists stacked into arrays (empty arrays when nothing was recorded)."""
        w = len(self.wheel_names)

        def stack(values: list[Any], shape: tuple[int, ...]) -> NDArray[Any]:
            return np.asarray(values) if values else np.zeros((0, *shape))

        return {
            "t_ns": np.asarray(self.t_ns, dtype=np.int64),
            "radius_error_m": stack(self.radius_error_m, (w,)),
            "radius_error_std_m": stack(self.radius_error_std_m, (w,)),
            "radius_noise_std_m": stack(self.radius_noise_std_m, (w,)),
            "active": stack(self.active, (w,)),
            "pose": stack(self.pose, (3,)),
            "pose_var": stack(self.pose_var, (3,)),
            "speed_m_s": np.asarray(self.speed_m_s, dtype=float),
            "wheel_yaw_rad": np.asarray(self.wheel_yaw_rad, dtype=float),
            "n_eff": np.asarray(self.n_eff, dtype=float),
            "baseline_radius_error_m": stack(self.baseline_radius_error_m, (w,)),
            "baseline_radius_error_std_m": stack(self.baseline_radius_error_std_m, (w,)),
            "innov_t_ns": np.asarray(self.innov_t_ns, dtype=np.int64),
            "innov_m": stack(self.innov_m, (2,)),
            "innov_cov_m2": stack(self.innov_cov_m2, (2, 2)),
            "nis": np.asarray(self.nis, dtype=float),
            "accepted": np.asarray(self.accepted, dtype=bool),
            "vel_t_ns": np.asarray(self.vel_t_ns, dtype=np.int64),
            "vel_innov_m_s": stack(self.vel_innov_m_s, (2,)),
            "vel_innov_cov_m2_s2": stack(self.vel_innov_cov_m2_s2, (2, 2)),
            "vel_nis": np.asarray(self.vel_nis, dtype=float),
            "vel_accepted": np.asarray(self.vel_accepted, dtype=bool),
            "gnss_enu_m": stack(self.gnss_enu_m, (2,)),
            "road_grade_rad": np.asarray(self.road_grade_rad, dtype=float),
            "rear_brake_decel_m_s2": np.asarray(self.rear_brake_decel_m_s2, dtype=float),
            "agreement_rows": stack(self.agreement_rows, (len(AGREEMENT_COLUMNS),)),
        }


class RadiusRecorder:
    """Pipeline observer: the radius MPF's trace, recorded after every GNSS fix (after the
    fix's Doppler velocity when one has the fix's stamp)."""

    def __init__(self) -> None:
        self.trace = RadiusTrace()
        self._pending: tuple[int, Any] | None = None
        self._bins: AgreementBins | None = None
        self._datum: object | None = None

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Record the fix's innovation and the estimate; a velocity's innovation."""
        pending = self._pending
        kind = type(sample)
        if kind is GnssVelocity:
            if result is not None:
                _record_velocity(self.trace, result)
            if pipeline.radius is not None:
                self._agreement(pipeline.radius, sample)
            if pending is not None and pending[0] == sample.t_ns:
                self._flush(pipeline)
                return
        if pending is not None:
            self._flush(pipeline)
        if kind is GnssFix and pipeline.radius is not None:
            self._pending = (sample.t_ns, result)
            self._agreement_fix(pipeline.radius, sample)

    def _flush(self, pipeline: EstimationPipeline) -> None:
        assert self._pending is not None and pipeline.radius is not None
        t_ns, update = self._pending
        self._pending = None
        _record(self.trace, pipeline.radius, update, t_ns)

    def _agreement(self, estimator: RadiusEstimator, sample: GnssVelocity) -> None:
        """Bin a GNSS velocity with the estimator's wheel and IMU inputs of its time."""
        snap = estimator.sensor_snapshot(sample.t_ns)
        if snap is None or not estimator.config.gnss_velocity_enabled:
            return
        bins = self._bins
        if bins is None:
            model = estimator.model
            veh = estimator.vehicle
            bins = self._bins = AgreementBins(
                model.nominal_radius_m,
                model.track_width_m,
                self.trace.agreement_rows,
                lever_arm_x_m=float(estimator.lever_arm_m[0]),
                # k = m l_f / (L C_r) of the rear axle's steady-state slip angle
                sideslip_s2_per_m=veh.mass_kg
                * veh.cg_to_front_axle_m
                / (veh.wheelbase_m * veh.cornering_stiffness_rear_n_rad),
            )
            self.trace.agreement_params = {
                "nominal_radius_m": model.nominal_radius_m,
                "track_width_m": model.track_width_m,
                "mass_kg": veh.mass_kg,
                "cg_height_m": veh.cg_height_m,
                "cg_to_front_axle_m": veh.cg_to_front_axle_m,
                "wheelbase_m": veh.wheelbase_m,
                "velocity_shift_s": estimator.velocity_shift_s,
                "fix_shift_s": estimator.fix_shift_s,
                "lever_arm_y_m": float(estimator.lever_arm_m[1]),
            }
        bins.add(
            sample.t_ns, sample.velocity_enu_m_s, snap.rear_rad_s, snap.gyro_z_rad_s,
            snap.lateral_specific_force_m_s2, snap.brake_decel_m_s2, snap.learning,
            snap.rear_locked,
        )  # fmt: skip

    def _agreement_fix(self, estimator: RadiusEstimator, sample: GnssFix) -> None:
        """A fix in the estimator's ENU frame into the agreement record (once it has a
        velocity)."""
        datum = estimator.datum
        if self._bins is None or datum is None:
            return
        if datum is not self._datum:
            # a new ENU origin (the estimator was reset): the fixes jump, so the integration
            # of the velocity starts again
            self._datum = datum
            self._bins.new_segment()
        fix = estimator.last_fix_enu
        if fix is None or fix[0] != sample.t_ns:
            return  # the fix was dropped
        east, north = fix[1].tolist()
        self._bins.add_fix(sample.t_ns, (east, north), estimator.learning)

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """Outputs are not part of this trace."""

    def flush(self, pipeline: EstimationPipeline) -> None:
        """Record the fix still waiting for a velocity of its stamp and the open agreement bin
        (after the last sample)."""
        if self._pending is not None:
            self._flush(pipeline)
        if self._bins is not None:
            self._bins.flush()

    def finish(self, pipeline: EstimationPipeline) -> RadiusTrace:
        """The trace with the run's counters (call after the last sample)."""
        self.flush(pipeline)
        trace, estimator = self.trace, pipeline.radius
        if estimator is None:
            return trace
        # the clock guard's outliers and the radius estimator's drops, as <stream>:<kind>
        trace.dropped = merged_counts(pipeline.clock.drop_counts(), estimator.stats)
        trace.init_distance_ratios = list(estimator.init_distance_ratios)
        if estimator.config.gnss_velocity_enabled and pipeline.received["gnss_velocity"]:
            nis = np.asarray(trace.vel_nis, dtype=float)
            trace.gnss_velocity = {
                "updates": estimator.velocity_updates,
                "skipped_accelerating": estimator.velocity_skipped_accel,
                "innovations": int(nis.size),
                "mean_nis": float(nis[np.asarray(trace.vel_accepted, dtype=bool)].mean())
                if estimator.velocity_updates
                else None,
                "latency_s": estimator.config.gnss_velocity_latency_s,
            }
        ltp = getattr(estimator, "_ltp", None)
        if ltp is not None:
            trace.origin_lla = (ltp.origin_lat_deg, ltp.origin_lon_deg, ltp.origin_alt_m)
        return trace


def radius_pipeline(
    config: RadiusEstimatorConfig, vehicle: VehicleParams, recorder: RadiusRecorder
) -> EstimationPipeline:
    """The radius MPF alone (seed ``config.seed``) recorded by ``recorder``; no outputs: the
    trace is recorded from the samples (the same values, in about half the time)."""
    return EstimationPipeline(
        PipelineConfig(seed=config.seed, radius=config),
        vehicle,
        observers=[recorder],
        outputs=False,
    )


def run_radius(
    config: RadiusEstimatorConfig, vehicle: VehicleParams, samples: Iterable[Sample]
) -> RadiusTrace:
    """The radius MPF alone (seed ``config.seed``) over ``samples``: its trace."""
    recorder = RadiusRecorder()
    pipeline = radius_pipeline(config, vehicle, recorder)
    pipeline.push_ordered(samples)
    return recorder.finish(pipeline)


def _record_velocity(trace: RadiusTrace, upd: Any) -> None:
    """Keep a GNSS velocity's innovation when one was computed (``nis`` > 0: learning, not
    dropped or skipped), accepted or gated."""
    if upd.nis <= 0.0:
        return
    trace.vel_t_ns.append(upd.t_ns)
    trace.vel_innov_m_s.append(np.asarray(upd.innovation_m_s, dtype=float))
    trace.vel_innov_cov_m2_s2.append(np.asarray(upd.innovation_cov_m2_s2, dtype=float))
    trace.vel_nis.append(float(upd.nis))
    trace.vel_accepted.append(bool(upd.accepted))


def _record(trace: RadiusTrace, estimator: RadiusEstimator, upd: Any, t_ns: int) -> None:
    est = estimator.estimate()
    if not trace.wheel_names:
        trace.wheel_names = tuple(est.wheels)
    reason = str(getattr(upd, "reason", ""))
    # a fix that anchors or initializes the pose is compared with nothing (innovation 0); while
    # a rear wheel's signal is lost the heading is the gyro's, not the radius model's
    compared = not (
        reason.startswith("initializing")
        or reason == "pose initialized"
        or estimator.signal_lost_wheel is not None
    )
    if upd is not None and getattr(upd, "innovation_m", None) is not None and compared:
        trace.innov_t_ns.append(t_ns)
        trace.innov_m.append(np.asarray(upd.innovation_m, dtype=float)[:2])
        trace.innov_cov_m2.append(np.asarray(upd.innovation_cov_m2, dtype=float)[:2, :2])
        trace.nis.append(float(upd.nis))
        trace.accepted.append(bool(upd.accepted))
    if est.state == "initializing":
        return
    trace.t_ns.append(t_ns)
    trace.radius_error_m.append(np.asarray(est.radius_error_m, dtype=float))
    trace.radius_error_std_m.append(np.asarray(est.radius_error_std_m, dtype=float))
    trace.radius_noise_std_m.append(np.asarray(est.radius_noise_std_m, dtype=float))
    trace.active.append(np.asarray(est.active, dtype=bool))
    trace.pose.append(np.asarray(est.pose, dtype=float))
    trace.pose_var.append(np.diag(np.asarray(est.pose_cov, dtype=float)).copy())
    trace.speed_m_s.append(float(est.speed_m_s))
    trace.wheel_yaw_rad.append(float(est.wheel_yaw_rad))
    trace.road_grade_rad.append(float(getattr(est, "road_grade_rad", 0.0)))
    trace.road_grade_counts = dict(getattr(est, "road_grade_counts", {}))
    trace.road_grade_imu_offset_rad = float(getattr(est, "road_grade_imu_offset_rad", 0.0))
    trace.wheel_speed_lag_s = float(getattr(est, "wheel_speed_lag_s", 0.0))
    trace.wheel_speed_tooth_pitch_rad = float(getattr(est, "wheel_speed_tooth_pitch_rad", 0.0))
    trace.drive_slip = dict(getattr(est, "drive_slip", {}))
    trace.radius_rescales = list(getattr(est, "radius_rescales", ()))
    trace.radius_rescale_sources = list(getattr(est, "radius_rescale_sources", ()))
    trace.radius_rescales_refused = list(getattr(est, "radius_rescales_refused", ()))
    trace.fix_covariance_scale = float(getattr(est, "fix_covariance_scale", 1.0))
    trace.fix_covariance_changes = list(getattr(est, "fix_covariance_changes", ()))
    trace.model_change_t_ns = getattr(est, "model_change_t_ns", None)
    trace.rear_brake_decel_m_s2.append(float(getattr(est, "rear_brake_decel_m_s2", 0.0)))
    trace.n_eff.append(float(est.n_eff))
    trace.state.append(str(est.state))
    trace.reason.append(str(est.state_reason))
    trace.resample_count = int(est.resample_count)
    if est.baseline is not None:
        trace.baseline_radius_error_m.append(np.asarray(est.baseline.radius_error_m, dtype=float))
        trace.baseline_radius_error_std_m.append(
            np.asarray(est.baseline.radius_error_std_m, dtype=float)
        )


@dataclass
class LateralTrace:
    """Lateral estimates after every tyre-force sample: ``t_ns`` (K,), ``vx``/``vy``/``r``/
    ``sideslip`` (K,), ``linear`` (K,) relay state (1 linear, 2 nonlinear, 0 unknown)."""

    t_ns: list[int] = field(default_factory=list)
    vx_m_s: list[float] = field(default_factory=list)
    vy_m_s: list[float] = field(default_factory=list)
    yaw_rate_rad_s: list[float] = field(default_factory=list)
    sideslip_rad: list[float] = field(default_factory=list)
    relay: list[int] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The lists as arrays."""
        return {
            "t_ns": np.asarray(self.t_ns, dtype=np.int64),
            "vx_m_s": np.asarray(self.vx_m_s, dtype=float),
            "vy_m_s": np.asarray(self.vy_m_s, dtype=float),
            "yaw_rate_rad_s": np.asarray(self.yaw_rate_rad_s, dtype=float),
            "sideslip_rad": np.asarray(self.sideslip_rad, dtype=float),
            "relay": np.asarray(self.relay, dtype=np.int64),
        }


_RELAY_CODE = {"unknown": 0, "linear": 1, "nonlinear": 2}


class TyreForceRecorder:
    """Pipeline observer: the tyre-force KF's lateral estimate after every tyre-force sample
    (once its relay knows the regime)."""

    SAMPLE_KINDS: ClassVar[tuple[type, ...]] = (TireForces,)

    def __init__(self) -> None:
        self.trace = LateralTrace()

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Record the estimate a tyre-force sample gave."""
        if type(sample) is not TireForces or result is None or result.linearity == "unknown":
            return
        trace = self.trace
        trace.t_ns.append(int(result.t_ns))
        trace.vx_m_s.append(float(result.vx_m_s))
        trace.vy_m_s.append(float(result.vy_m_s))
        trace.yaw_rate_rad_s.append(float(result.yaw_rate_rad_s))
        trace.sideslip_rad.append(float(result.sideslip_rad))
        trace.relay.append(_RELAY_CODE.get(result.linearity, 0))

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """Outputs are not part of this trace."""

    def finish(self, pipeline: EstimationPipeline) -> LateralTrace:
        """The trace with the filter's drop counters."""
        if pipeline.tyre_force is not None:
            self.trace.dropped = dict(pipeline.tyre_force.stats)
        return self.trace


@dataclass
class ImuLateralTrace:
    """Estimates of an IMU-driven lateral estimator (stiffness MPF, linear single-track KF).

    Recorded after IMU samples, at most one per ``record_period_s``: ``t_ns`` (K,), ``vx_m_s``,
    ``vy_m_s`` (at the CG), ``yaw_rate_rad_s``, ``sideslip_rad`` (at the CG) (K,); for
    estimators that learn the stiffness also ``stiffness`` / ``stiffness_std`` (K, 3) in the
    order of ``stiffness_names``, ``active`` (K,) and ``gyro_bias_rad_s`` (K,) (yaw-rate bias).
    """

    t_ns: list[int] = field(default_factory=list)
    vx_m_s: list[float] = field(default_factory=list)
    vy_m_s: list[float] = field(default_factory=list)
    yaw_rate_rad_s: list[float] = field(default_factory=list)
    sideslip_rad: list[float] = field(default_factory=list)
    stiffness_names: tuple[str, ...] = ()
    nominal: NDArray[np.float64] | None = None
    stiffness: list[NDArray[np.float64]] = field(default_factory=list)
    stiffness_std: list[NDArray[np.float64]] = field(default_factory=list)
    active: list[bool] = field(default_factory=list)
    gyro_bias_rad_s: list[float] = field(default_factory=list)
    mean_log_predictive: float | None = None
    dropped: dict[str, int] = field(default_factory=dict)
    wall_s: float = 0.0
    steps: int = 0

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The lists as arrays."""
        k = len(self.stiffness_names)
        return {
            "t_ns": np.asarray(self.t_ns, dtype=np.int64),
            "vx_m_s": np.asarray(self.vx_m_s, dtype=float),
            "vy_m_s": np.asarray(self.vy_m_s, dtype=float),
            "yaw_rate_rad_s": np.asarray(self.yaw_rate_rad_s, dtype=float),
            "sideslip_rad": np.asarray(self.sideslip_rad, dtype=float),
            "stiffness": np.asarray(self.stiffness) if self.stiffness else np.zeros((0, k)),
            "stiffness_std": (
                np.asarray(self.stiffness_std) if self.stiffness_std else np.zeros((0, k))
            ),
            "active": np.asarray(self.active, dtype=bool),
            "gyro_bias_rad_s": np.asarray(self.gyro_bias_rad_s, dtype=float),
        }


class ImuLateralRecorder:
    """Pipeline observer: an IMU-driven lateral estimator's estimate after IMU samples, at
    most one per ``record_period_s``, once the estimator is initialized.

    Args:
        estimator: the estimator (the pipeline's stiffness MPF or one of its baselines); its
            ``initialized`` flag (or ``mpf.initialized``) says when an estimate exists.
        record_period_s: least time between recorded estimates, s.
    """

    SAMPLE_KINDS: ClassVar[tuple[type, ...]] = (ImuSample,)

    def __init__(self, estimator: Any, record_period_s: float = 0.01) -> None:
        self.estimator = estimator
        self.trace = ImuLateralTrace()
        self._period_ns = round(record_period_s * 1e9)
        self._next_ns: int | None = None
        mpf = getattr(estimator, "mpf", None)
        self._ready_of = mpf if mpf is not None else estimator
        # the stiffness MPF's trace row costs a fraction of its whole estimate
        self._row = getattr(estimator, "trace_row", estimator.estimate)

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Count IMU steps; record the estimate when due."""
        if type(sample) is not ImuSample:
            return
        trace = self.trace
        trace.steps += 1
        if not getattr(self._ready_of, "initialized", False):
            return
        t_ns = sample.t_ns
        next_ns = self._next_ns
        if next_ns is not None and t_ns < next_ns:
            return
        self._next_ns = t_ns + self._period_ns
        _record_lateral(trace, self._row(), t_ns, self.estimator)

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """Outputs are not part of this trace."""

    def finish(self, wall_s: float) -> ImuLateralTrace:
        """The trace with the estimator's drop counters and the run's wall time."""
        self.trace.wall_s = wall_s
        self.trace.dropped = dict(getattr(self.estimator, "stats", {}))
        return self.trace


class DeflationRecorder:
    """Pipeline observer: the deflation detector's statistics after every accepted estimate.

    ``t_ns`` (K,), per wheel in ``wheel_names`` order ``cusum_m`` and ``threshold_m`` (K, W)
    (NaN while a wheel is not seen), ``calibration_state`` (K,), and ``alarms`` as
    ``(wheel, t_ns)``, the common channel's with the wheel ``all``.
    """

    SAMPLE_KINDS: ClassVar[tuple[type, ...]] = ()

    def __init__(self) -> None:
        self.wheel_names: tuple[str, ...] = ()
        self.t_ns: list[int] = []
        self.cusum_m: list[list[float]] = []
        self.threshold_m: list[list[float]] = []
        self.calibration_state: list[int] = []
        self.alarms: list[tuple[str, int]] = []
        self.calibration_done_t_ns: int | None = None

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """Samples are not part of this trace."""

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """Record a detector status."""
        if type(output) is not DeflationOutput:
            return
        step = output.step
        status = step.status
        if not self.wheel_names:
            self.wheel_names = tuple(w.wheel_name for w in status.wheels)
        by_name = {w.wheel_name: w for w in status.wheels}
        nan = float("nan")
        self.t_ns.append(output.t_ns)
        self.cusum_m.append(
            [by_name[n].cusum_m if n in by_name else nan for n in self.wheel_names]
        )
        self.threshold_m.append(
            [by_name[n].threshold_m if n in by_name else nan for n in self.wheel_names]
        )
        self.calibration_state.append(int(status.calibration_state))
        if self.calibration_done_t_ns is None and int(status.calibration_state) == 2:
            self.calibration_done_t_ns = output.t_ns
        for wheel in step.new_alarms:
            alarm_t = by_name[wheel].alarm_t_ns
            self.alarms.append((wheel, output.t_ns if alarm_t is None else alarm_t))
        if step.new_common_alarm and status.common is not None:
            alarm_t = status.common.alarm_t_ns
            self.alarms.append(("all", output.t_ns if alarm_t is None else alarm_t))


def _record_lateral(trace: ImuLateralTrace, est: Any, t_ns: int, estimator: Any) -> None:
    """Append ``est`` (an estimate, or a stiffness filter's :class:`TraceRow`) of
    ``estimator``."""
    trace.t_ns.append(t_ns)
    trace.vx_m_s.append(float(est.vx_m_s))
    trace.vy_m_s.append(float(est.vy_m_s))
    trace.yaw_rate_rad_s.append(float(est.yaw_rate_rad_s))
    trace.sideslip_rad.append(float(est.sideslip_rad))
    if hasattr(est, "stiffness"):
        if not trace.stiffness_names:
            # a TraceRow has no names: the estimator's model has them (the driven axle's Cx)
            params = getattr(estimator, "params", None)
            default = STIFFNESS_NAMES if params is None else params.names
            trace.stiffness_names = tuple(getattr(est, "names", default))
            trace.nominal = np.array(estimator.nominal, dtype=float)
        # (np.array copies, as asarray followed by copy)
        trace.stiffness.append(np.array(est.stiffness, dtype=float))
        trace.stiffness_std.append(np.array(est.stiffness_std, dtype=float))
        trace.active.append(bool(est.active))
        bias = est.gyro_bias_rad_s
        trace.gyro_bias_rad_s.append(float(bias if isinstance(bias, float) else bias[2]))
    mean_log_predictive = getattr(est, "mean_log_predictive", None)
    if mean_log_predictive is not None:
        trace.mean_log_predictive = float(mean_log_predictive)
