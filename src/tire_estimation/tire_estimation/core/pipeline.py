"""The estimation pipeline: one object that takes every sample and runs every estimator.

The estimator node, the bag replay and the campaigns push the same typed samples
(:mod:`tire_estimation.core.samples`) into an :class:`EstimationPipeline`. It owns

* stamps that jump (:class:`~tire_estimation.core.clock.ClockGuard`: a far sample is held,
  a new clock adopted after a run of agreeing samples; outputs carry the stream's own clock)
  and the stamp ordering (:class:`~tire_estimation.core.ordering.ReorderBuffer`),
* the routing of each sample to the estimators that use it: the tyre-radius MPF
  (:class:`~tire_estimation.core.radius.estimator.RadiusEstimator`), the tyre-force lateral KF
  (:class:`~tire_estimation.core.lateral.tyre_force_kf.TyreForceEstimator`), the stiffness MPF
  (:class:`~tire_estimation.core.stiffness.estimator.StiffnessEstimator`) and any lateral
  baselines the caller adds,
* the random streams (``default_rng(seed)`` for the radius MPF,
  ``default_rng([seed, STIFFNESS_RNG_KEY])`` for the stiffness MPF),
* the outputs at their periods in header time, with the node's topics' meaning: odometry and
  radii after wheel-speed samples (with each radii output the wheel odometry corrected with the
  learned radii and the effective radii,
  :mod:`~tire_estimation.core.radius.wheel_odometry`), stiffness after IMU samples, the
  lateral state of the tyre-force KF while it runs and of the stiffness MPF otherwise,
* the deflation detector (:class:`~tire_estimation.core.deflation.monitor.DeflationMonitor`)
  fed with the published odometry and radii, exactly as the detector node is fed by topics,
* and exposes the radius MPF's check whether each axle's left-right split is observable
  (:attr:`axles`, :class:`~tire_estimation.core.radius.axle_check.AxleCheck`).

``push(sample)`` returns the outputs due; observers (:class:`Observer`) see every processed
sample with the estimator's result and every output, for traces and reports.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from tire_estimation.core.clock import ClockGuard, ClockGuardConfig
from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.monitor import DeflationMonitor, MonitorConfig, MonitorStep
from tire_estimation.core.deflation.status import RadiusErrors
from tire_estimation.core.imu_mounting import ImuMountingCheck
from tire_estimation.core.lateral.estimate import LateralEstimate
from tire_estimation.core.lateral.tyre_force_kf import TyreForceEstimator, TyreForceKFConfig
from tire_estimation.core.ordering import ReorderBuffer
from tire_estimation.core.radius.axle_check import AxleCheck
from tire_estimation.core.radius.config import RadiusEstimatorConfig
from tire_estimation.core.radius.estimator import RadiusEstimate, RadiusEstimator
from tire_estimation.core.radius.wheel_odometry import (
    CorrectedTwist,
    EffectiveRadii,
    WheelSpeedNoise,
    corrected_twist,
    estimate_radii,
)
from tire_estimation.core.samples import (
    GnssFix,
    GnssVelocity,
    ImuSample,
    MeasuredVelocity,
    Sample,
    Steering,
    TireForces,
    WheelSpeeds,
)
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.estimator import StiffnessEstimate, StiffnessEstimator
from tire_estimation.core.validation import (
    Checked,
    NonNegative,
    require_non_negative,
    require_positive,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

#: seed-sequence key of the stiffness MPF's generator: ``default_rng([seed, key])``
STIFFNESS_RNG_KEY = 1
#: the stiffness MPF gives the lateral state only when the tyre-force KF has not for this
#: long (header time), ns
TYRE_FORCE_PRIORITY_NS = 500_000_000
#: source name of the stiffness MPF's lateral state
STIFFNESS_SOURCE = "stiffness_mpf"


@dataclass(frozen=True)
class PublishPeriods:
    """Least periods between outputs of one kind, header time, s (0: after every sample).

    Attributes:
        odometry_s: odometry (pose, speed, yaw rate). Default 0.02.
        radii_s: tyre radii. Default 0.1.
        lateral_s: lateral state. Default 0.02.
        stiffness_s: tyre stiffness. Default 0.1.
    """

    odometry_s: float = 0.02
    radii_s: float = 0.1
    lateral_s: float = 0.02
    stiffness_s: float = 0.1

    def __post_init__(self) -> None:
        require_non_negative("odometry_publish_period_s", self.odometry_s)
        require_positive("radii_publish_period_s", self.radii_s)
        require_non_negative("lateral_publish_period_s", self.lateral_s)
        require_non_negative("stiffness_publish_period_s", self.stiffness_s)


@dataclass(frozen=True)
class PipelineConfig(Checked):
    """What runs in an :class:`EstimationPipeline` (an estimator is off when its config is None).

    Attributes:
        seed: seed of the random streams (the radius configuration's ``seed``).
        radius: the tyre-radius MPF.
        stiffness: the tyre-stiffness MPF.
        tyre_force: the tyre-force lateral KF (runs when tyre forces arrive).
        detector: the deflation detector, fed with the pipeline's own odometry and radii.
        monitor: how the detector takes speed and braking from the odometry.
        periods: output periods.
        max_hold_s: longest time a sample waits for the clock streams, s. Default 0.5.
        reorder_delay_s: the lag behind the wheel speeds (or measured speed) up to which a
            sample of another stream is still processed in stamp order, s; it delays every
            output by as much. Default 0.05.
        clock: when a stamp is far enough from the others to be held, and when a new clock
            is adopted.
    """

    seed: int = 0
    radius: RadiusEstimatorConfig | None = None
    stiffness: StiffnessEstimatorConfig | None = None
    tyre_force: TyreForceKFConfig | None = None
    detector: DeflationDetectorConfig | None = None
    monitor: MonitorConfig = field(default_factory=MonitorConfig)
    periods: PublishPeriods = field(default_factory=PublishPeriods)
    max_hold_s: NonNegative = 0.5
    reorder_delay_s: NonNegative = 0.05
    clock: ClockGuardConfig = field(default_factory=ClockGuardConfig)


@dataclass(frozen=True, slots=True)
class OdometryOutput:
    """The radius MPF's pose and motion (published as nav_msgs/Odometry)."""

    t_ns: int
    estimate: RadiusEstimate


@dataclass(frozen=True, slots=True)
class RadiiOutput:
    """The radius MPF's tyre radii (published as TireRadii)."""

    t_ns: int
    estimate: RadiusEstimate


@dataclass(frozen=True, slots=True)
class WheelOdometryOutput:
    """With every :class:`RadiiOutput`: the wheel odometry corrected with the learned radii
    (published as TwistWithCovarianceStamped) and the effective radii, multipliers and speed
    scale factor (published as JointState and Float64)."""

    t_ns: int
    twist: CorrectedTwist
    radii: EffectiveRadii


@dataclass(frozen=True, slots=True)
class StiffnessOutput:
    """The stiffness MPF's estimate (published as TireStiffness)."""

    t_ns: int
    estimate: StiffnessEstimate


@dataclass(frozen=True, slots=True)
class LateralOutput:
    """Lateral state of base_link (published as LateralState); ``estimate.source`` names the
    estimator."""

    t_ns: int
    estimate: LateralEstimate


@dataclass(frozen=True, slots=True)
class DeflationOutput:
    """The deflation detector's status after an accepted radius estimate."""

    t_ns: int
    step: MonitorStep


Output = (
    OdometryOutput
    | RadiiOutput
    | WheelOdometryOutput
    | StiffnessOutput
    | LateralOutput
    | DeflationOutput
)


#: the sample types the pipeline routes
SAMPLE_TYPES = (
    WheelSpeeds,
    Steering,
    ImuSample,
    GnssFix,
    GnssVelocity,
    MeasuredVelocity,
    TireForces,
)


class Observer(Protocol):
    """Sees what the pipeline does (trace recorders, reports). An observer may name the sample
    types its :meth:`on_sample` needs in a class attribute ``SAMPLE_KINDS`` (a tuple of
    types); without one it sees every sample."""

    def on_sample(self, pipeline: EstimationPipeline, sample: Sample, result: Any) -> None:
        """After ``sample`` was routed; ``result`` is the radius MPF's update for a GNSS fix or
        velocity, the tyre-force KF's estimate for tyre forces, else None."""

    def on_output(self, pipeline: EstimationPipeline, output: Output) -> None:
        """After an output was made."""


class LateralBaseline(Protocol):
    """An IMU-driven lateral estimator run beside the stiffness MPF on the same samples."""

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None: ...
    def on_steering(self, t_ns: int, angle_rad: float) -> None: ...
    def on_velocity(self, t_ns: int, vx_m_s: float) -> None: ...
    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None: ...
    def estimate(self) -> Any: ...
    def reset(self) -> None: ...


def lateral_from_stiffness(est: StiffnessEstimate, lr_m: float) -> LateralEstimate:
    """The stiffness MPF's CG state moved to base_link: ``vy_b = vy_cg - lr r`` (REP-103)."""
    vy_b = est.vy_m_s - lr_m * est.yaw_rate_rad_s
    # covariance of J [vx, vy_cg, r] with J = [[1, 0, 0], [0, 1, -lr], [0, 0, 1]]
    jac = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, -lr_m], [0.0, 0.0, 1.0]])
    cov = jac @ np.asarray(est.covariance, dtype=float) @ jac.T
    return LateralEstimate(
        t_ns=int(est.t_ns),
        vx_m_s=float(est.vx_m_s),
        vy_m_s=float(vy_b),
        yaw_rate_rad_s=float(est.yaw_rate_rad_s),
        sideslip_rad=float(math.atan2(vy_b, max(est.vx_m_s, 1e-3))),
        covariance=cov,
        axle_lateral_force_n=np.zeros(2),
        linearity="unknown",
        source=STIFFNESS_SOURCE,
    )


class EstimationPipeline:
    """Every estimator behind one ``push``.

    Args:
        config: what runs.
        vehicle: the vehicle description.
        baselines: lateral estimators run beside the stiffness MPF (evaluation only), by name.
        observers: see every processed sample and every output.
        outputs: make the odometry, radii, stiffness and lateral outputs (a node publishes
            them); False (a replay that only records traces) makes only what the deflation
            detector consumes, with the same values, and its statuses.
    """

    def __init__(
        self,
        config: PipelineConfig,
        vehicle: VehicleParams,
        baselines: Mapping[str, LateralBaseline] | None = None,
        observers: Sequence[Observer] = (),
        outputs: bool = True,
    ) -> None:
        self.config = config
        self.outputs = outputs
        self.vehicle = vehicle
        self.radius: RadiusEstimator | None = None
        #: whether each axle's left-right radius split is observable (with the radius MPF)
        self.axles: AxleCheck | None = None
        if config.radius is not None:
            self.radius = RadiusEstimator(
                config.radius, vehicle, np.random.default_rng(config.seed)
            )
            self.axles = self.radius.axles
        #: per-sample noise of the rear wheel speeds, for the corrected twist's covariance
        self.wheel_noise = WheelSpeedNoise()
        self.stiffness: StiffnessEstimator | None = None
        if config.stiffness is not None:
            rng = np.random.default_rng([config.seed, STIFFNESS_RNG_KEY])
            self.stiffness = StiffnessEstimator(config.stiffness, vehicle, rng)
        self.tyre_force: TyreForceEstimator | None = None
        if config.tyre_force is not None:
            self.tyre_force = TyreForceEstimator(config.tyre_force, vehicle)
        self.monitor: DeflationMonitor | None = None
        if config.detector is not None:
            self.monitor = DeflationMonitor(config.detector, config.monitor)
        self.baselines: dict[str, LateralBaseline] = dict(baselines or {})
        #: the IMU's mounting yaw, fitted against the wheels; rotates the IMU samples into
        #: base_link once a large one is decided
        self.imu_mounting = ImuMountingCheck(vehicle.nominal_tire_radius_m, vehicle.track_width_m)
        self._imu_turns = 0
        self._observers: tuple[Observer, ...] = ()
        self._sample_observers: dict[type, tuple[Observer, ...]] = {}
        self.add_observers(*observers)
        #: per-stream clock offsets in front of the ordering
        self.clock: ClockGuard[Sample] = ClockGuard(config.clock)
        self.buffer = ReorderBuffer(
            round(config.max_hold_s * 1e9), round(config.reorder_delay_s * 1e9)
        )
        #: samples received, per stream
        self.received: Counter[str] = Counter()
        periods = config.periods
        self._period_ns = {
            "odometry": round(periods.odometry_s * 1e9),
            "radii": round(periods.radii_s * 1e9),
            "lateral": round(periods.lateral_s * 1e9),
            "stiffness": round(periods.stiffness_s * 1e9),
        }
        self._last_ns = {"odometry": 0, "radii": 0, "lateral": 0, "stiffness": 0}
        self._last_tyre_force_ns: int | None = None
        self._lr_m = vehicle.lr_m
        # IMU-driven estimators that take speed, steering and IMU the same way
        self._lateral_imu: list[Any] = [self.stiffness] if self.stiffness is not None else []
        self._lateral_imu.extend(self.baselines.values())
        # the estimators' input methods per stream, in routing order (bound once: the
        # routing runs for every sample)
        radius, tyre_force, lateral = self.radius, self.tyre_force, self._lateral_imu
        self._to_wheel_speeds = tuple(
            e.on_wheel_speeds for e in (radius, tyre_force, *lateral) if e is not None
        )
        self._to_imu = tuple(e.on_imu for e in (radius, *lateral) if e is not None)
        self._to_steering = tuple(
            e.on_steering for e in (radius, tyre_force, *lateral) if e is not None
        )

    # ------------------------------------------------------------------ input
    def push(self, sample: Sample) -> list[Output]:
        """Take one sample; process what the stamp order allows; return the outputs due."""
        self.received[sample.KIND] += 1
        out: list[Output] = []
        for t_ns, admitted in self.clock.admit(sample.KIND, sample.t_ns, sample):
            self._order(admitted if t_ns == admitted.t_ns else replace(admitted, t_ns=t_ns), out)
        return out

    def _order(self, sample: Sample, out: list[Output]) -> None:
        """Through the ordering buffer and the estimators; outputs in the stream's own clock."""
        for ready in self.buffer.push(sample):
            n_before = len(out)
            self._process(ready, out)
            offset_ns = self.clock.offset_ns(ready.KIND)
            if offset_ns and len(out) > n_before:
                out[n_before:] = [replace(o, t_ns=o.t_ns - offset_ns) for o in out[n_before:]]

    def push_ordered(self, samples: Iterable[Sample]) -> None:
        """Process samples that are already in :func:`~tire_estimation.core.samples.order_key`
        order (a merged recording, :func:`~tire_estimation.core.samples.merge`): the buffer
        would release them in the same order, so it is passed by (same results as
        :meth:`push`). A sample out of that order, and every one after it, goes through the
        buffer (it is used late, as a live node uses a sample that arrives too late). Then
        :meth:`flush`. The outputs go to the observers."""
        received = self.received
        process = self._process
        admit_now = self.clock.admit_now
        admit = self.clock.admit
        buffer = self.buffer
        last: tuple[int, int] | None = None
        out: list[Output] = []
        for sample in samples:
            kind = sample.KIND
            received[kind] += 1
            # the common case, the sample alone goes on at once, without admit's list
            u_ns = admit_now(kind, sample.t_ns)
            released = admit(kind, sample.t_ns, sample) if u_ns is None else ((u_ns, sample),)
            for t_ns, admitted in released:
                if t_ns != admitted.t_ns:
                    admitted = replace(admitted, t_ns=t_ns)
                key = (t_ns, admitted.PRIORITY)
                if len(buffer) == 0 and (last is None or key > last):
                    last = key
                    process(admitted, out)
                else:
                    self._order(admitted, out)
                out.clear()
        self.flush()

    def push_all(self, samples: Iterable[Sample]) -> None:
        """Push every sample and then :meth:`flush` (the outputs go to the observers)."""
        push = self.push
        for sample in samples:
            push(sample)
        self.flush()

    def flush(self) -> list[Output]:
        """Process the samples still held for ordering (at the end of a recording); suspects
        of the clock guard that no new clock confirmed are dropped."""
        self.clock.discard_held()
        out: list[Output] = []
        for ready in self.buffer.flush():
            self._process(ready, out)
        return out

    def reset(self) -> None:
        """Forget what the estimators learned (radii, stiffness); the detector is untouched."""
        if self.radius is not None:
            self.radius.reset()
        if self.stiffness is not None:
            self.stiffness.reset()

    # ------------------------------------------------------------------ routing
    def _process(self, sample: Sample, out: list[Output]) -> None:
        result: Any = None
        t = sample.t_ns
        kind = type(sample)
        if kind is WheelSpeeds:
            ws = sample.wheel_speed_rad_s
            self.imu_mounting.on_wheel_speeds(t, ws)
            for on_wheel_speeds in self._to_wheel_speeds:
                on_wheel_speeds(t, ws)
            if self.radius is not None:
                if self.outputs:
                    self.wheel_noise.push(t, ws)
                self._radius_outputs(t, out)
        elif kind is ImuSample:
            mounting = self.imu_mounting
            gyro, acc = mounting.on_imu(
                t, sample.angular_velocity_rad_s, sample.linear_acceleration_m_s2
            )
            if mounting.turns != self._imu_turns:
                # the IMU-driven lateral estimators learned from other axes
                self._imu_turns = mounting.turns
                for est in self._lateral_imu:
                    est.reset()
            for on_imu in self._to_imu:
                on_imu(t, gyro, acc)
            if self.stiffness is not None and self.outputs:
                self._stiffness_outputs(self.stiffness, t, out)
        elif kind is Steering:
            angle = sample.angle_rad
            for on_steering in self._to_steering:
                on_steering(t, angle)
        elif kind is GnssFix:
            if self.radius is not None:
                result = self.radius.on_gnss_fix(
                    t, sample.lat_deg, sample.lon_deg, sample.alt_m, sample.covariance_m2
                )
        elif kind is GnssVelocity:
            if self.radius is not None and self.radius.config.gnss_velocity_enabled:
                result = self.radius.on_gnss_velocity(
                    t, sample.velocity_enu_m_s, sample.covariance_m2_s2
                )
        elif kind is MeasuredVelocity:
            for est in self._lateral_imu:
                est.on_velocity(t, sample.vx_m_s)
        elif kind is TireForces and self.tyre_force is not None:
            result = self.tyre_force.on_tire_forces(
                t, sample.fx_n, sample.fy_n, sample.fz_n, sample.valid
            )
            if result is not None:
                self._last_tyre_force_ns = t
                self._lateral_output(t, result, out)
        for obs in self._sample_observers[kind]:
            obs.on_sample(self, sample, result)

    # ------------------------------------------------------------------ observers
    @property
    def observers(self) -> tuple[Observer, ...]:
        """What sees the samples and outputs, in the order added."""
        return self._observers

    def add_observers(self, *observers: Observer) -> None:
        """Let ``observers`` see the samples (those of their ``SAMPLE_KINDS``, else all) and
        the outputs from now on."""
        self._observers = (*self._observers, *observers)
        self._sample_observers = {
            kind: tuple(o for o in self._observers if kind in getattr(o, "SAMPLE_KINDS", (kind,)))
            for kind in SAMPLE_TYPES
        }

    # ------------------------------------------------------------------ outputs
    def _emit(self, output: Output, out: list[Output]) -> None:
        out.append(output)
        for obs in self._observers:
            obs.on_output(self, output)

    def _due(self, kind: str, t_ns: int) -> bool:
        return t_ns - self._last_ns[kind] >= self._period_ns[kind]

    def _radius_outputs(self, t_ns: int, out: list[Output]) -> None:
        """Odometry and radii when their periods have elapsed; the detector sees both."""
        last, period = self._last_ns, self._period_ns
        odom_due = t_ns - last["odometry"] >= period["odometry"]
        radii_due = t_ns - last["radii"] >= period["radii"]
        if not (odom_due or radii_due):
            return
        radius = self.radius
        assert radius is not None
        monitor = self.monitor
        if not self.outputs:
            if monitor is None:
                return
            # what the detector consumes, the values the outputs would carry
            if odom_due:
                last["odometry"] = t_ns
                if radius.initialized:
                    monitor.on_odometry(t_ns, radius.speed_m_s())
            if radii_due:
                last["radii"] = t_ns
                self._deflation_output(t_ns, RadiusErrors(t_ns, *radius.radius_errors()), out)
            return
        est = radius.estimate()
        if odom_due:
            last["odometry"] = t_ns
            if est.state != "initializing":
                self._emit(OdometryOutput(t_ns, est), out)
                if monitor is not None:
                    monitor.on_odometry(t_ns, float(est.speed_m_s))
        if radii_due:
            last["radii"] = t_ns
            self._emit(RadiiOutput(t_ns, est), out)
            self._wheel_odometry_output(t_ns, est, out)
            if monitor is not None:
                radii = RadiusErrors(
                    t_ns,
                    est.wheels,
                    [float(v) for v in est.radius_error_m],
                    [float(v) for v in est.radius_error_std_m],
                    [bool(v) for v in est.active],
                )
                self._deflation_output(t_ns, radii, out)

    def _deflation_output(self, t_ns: int, radii: RadiusErrors, out: list[Output]) -> None:
        """The detector's status after ``radii``, when it accepts them."""
        assert self.monitor is not None
        step = self.monitor.on_radii(radii)
        if step is not None:
            self._emit(DeflationOutput(t_ns, step), out)

    def _wheel_odometry_output(self, t_ns: int, est: RadiusEstimate, out: list[Output]) -> None:
        """The corrected twist and effective radii of ``est``; an estimate they cannot be
        made of is counted as ``wheel_odometry:<kind>`` in the radius estimator's drops."""
        try:
            twist = corrected_twist(est, self.vehicle, self.wheel_noise.var_rad2_s2)
            radii = estimate_radii(est, self.vehicle)
        except InputError as exc:
            assert self.radius is not None
            key = f"wheel_odometry:{exc.kind}"
            self.radius.stats[key] = self.radius.stats.get(key, 0) + 1
            return
        self._emit(WheelOdometryOutput(t_ns, twist, radii), out)

    def _stiffness_outputs(
        self, stiffness: StiffnessEstimator, t_ns: int, out: list[Output]
    ) -> None:
        """Stiffness at its period and, while the tyre-force KF is silent, the lateral state
        (called only when the pipeline makes outputs)."""
        if not stiffness.mpf.initialized:
            return
        stiff_due = self._due("stiffness", t_ns)
        last_tf = self._last_tyre_force_ns
        lateral_due = (last_tf is None or t_ns - last_tf > TYRE_FORCE_PRIORITY_NS) and self._due(
            "lateral", t_ns
        )
        if not (stiff_due or lateral_due):
            return
        est = stiffness.estimate()
        if stiff_due:
            self._last_ns["stiffness"] = t_ns
            self._emit(StiffnessOutput(t_ns, est), out)
        if lateral_due:
            self._last_ns["lateral"] = t_ns
            self._emit(LateralOutput(t_ns, lateral_from_stiffness(est, self._lr_m)), out)

    def _lateral_output(self, t_ns: int, est: LateralEstimate, out: list[Output]) -> None:
        if self.outputs and self._due("lateral", t_ns):
            self._last_ns["lateral"] = t_ns
            self._emit(LateralOutput(t_ns, est), out)
