"""Drive one :class:`RadiusEstimator` over recorded streams in header-stamp order.

This is the replay's inner loop; the ROS node drives the very same estimator object from its
callbacks. The merge is by measurement time (stable: on equal stamps wheel speeds, then steering,
then IMU, then GNSS), which is what the node's reorder buffer reproduces online.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.radius_estimator import RadiusEstimator
from tire_estimation.sim.streams import (
    GnssStream,
    ImuStream,
    SteeringStream,
    TireForceStream,
    WheelSpeedStream,
)

WHEEL, STEER, IMU, GNSS, FORCES = 0, 1, 2, 3, 4


@dataclass
class RadiusTrace:
    """What the estimator reported over a run, sampled after every GNSS fix.

    Shapes: ``t_ns`` (K,); per-wheel arrays (K, W) in the order of ``wheel_names``; ``pose``
    (K, 3) [east m, north m, yaw rad] in the estimator's local ENU frame; ``pose_var`` (K, 3).
    Innovations: ``innov_t_ns`` (J,), ``innov_m`` (J, 2) [east, north], ``innov_cov_m2``
    (J, 2, 2), ``nis`` (J,), ``accepted`` (J,). GNSS velocity innovations of the velocities the
    estimator computed one for (``gnss_velocity_enabled``, while learning): ``vel_t_ns`` (V,),
    ``vel_innov_m_s`` (V, 2), ``vel_innov_cov_m2_s2`` (V, 2, 2), ``vel_nis`` (V,),
    ``vel_accepted`` (V,).
    """

    wheel_names: tuple[str, ...] = ()
    t_ns: list[int] = field(default_factory=list)
    radius_error_m: list[NDArray[np.float64]] = field(default_factory=list)
    radius_error_std_m: list[NDArray[np.float64]] = field(default_factory=list)
    radius_noise_std_m: list[NDArray[np.float64]] = field(default_factory=list)
    active: list[NDArray[np.bool_]] = field(default_factory=list)
    pose: list[NDArray[np.float64]] = field(default_factory=list)
    pose_var: list[NDArray[np.float64]] = field(default_factory=list)
    speed_m_s: list[float] = field(default_factory=list)
    n_eff: list[float] = field(default_factory=list)
    state: list[str] = field(default_factory=list)
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
    rear_brake_decel_m_s2: list[float] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)
    resample_count: int = 0
    origin_lla: tuple[float, float, float] | None = None
    #: GNSS velocity summary: velocities that re-weighted the particles (``updates``), those with
    #: an innovation (``innovations``, gated ones included), the mean NIS of the accepted ones
    #: (2 for a consistent model) and the compensated latency, s (None: velocity not used)
    gnss_velocity: dict[str, Any] | None = None

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
        }


def merge_order(
    wheel_speeds: WheelSpeedStream,
    steering: SteeringStream | None,
    imu: ImuStream | None,
    gnss: GnssStream,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(stream id, row index) of every sample, sorted by stamp (stable on ties)."""
    parts_t = [wheel_speeds.t_ns]
    parts_s = [np.full(wheel_speeds.t_ns.size, WHEEL)]
    parts_i = [np.arange(wheel_speeds.t_ns.size)]
    for sid, stream in ((STEER, steering), (IMU, imu), (GNSS, gnss)):
        if stream is None:
            continue
        parts_t.append(stream.t_ns)
        parts_s.append(np.full(stream.t_ns.size, sid))
        parts_i.append(np.arange(stream.t_ns.size))
    t = np.concatenate(parts_t)
    s = np.concatenate(parts_s)
    i = np.concatenate(parts_i)
    order = np.lexsort((s, t))
    return s[order], i[order]


def run_radius_estimator(
    estimator: RadiusEstimator,
    wheel_speeds: WheelSpeedStream,
    gnss: GnssStream,
    steering: SteeringStream | None = None,
    imu: ImuStream | None = None,
    progress: Callable[[int], None] | None = None,
) -> RadiusTrace:
    """Feed every sample to ``estimator`` in stamp order; record a trace after each fix.

    ``progress`` (optional) is called with the number of samples processed, every 10 000.
    """
    streams, rows = merge_order(wheel_speeds, steering, imu, gnss)
    trace = RadiusTrace()
    w_t = wheel_speeds.t_ns.tolist()
    w_v = wheel_speeds.wheel_speed_rad_s
    g_t = gnss.t_ns.tolist()
    g_cov = gnss.position_covariance_m2
    lat, lon, alt = gnss.lat_deg.tolist(), gnss.lon_deg.tolist(), gnss.alt_m.tolist()
    s_t = steering.t_ns.tolist() if steering is not None else []
    s_v = steering.angle_rad.tolist() if steering is not None else []
    i_t = imu.t_ns.tolist() if imu is not None else []
    i_w = imu.angular_velocity_rad_s if imu is not None else None
    i_a = imu.linear_acceleration_m_s2 if imu is not None else None
    # the Doppler velocity of a fix (same stamp; NaN rows: none) follows its fix
    g_vel, g_vcov = gnss.velocity_enu_m_s, gnss.velocity_covariance_m2_s2
    use_vel = g_vel is not None and estimator.config.gnss_velocity_enabled
    g_has_vel = np.isfinite(g_vel[:, 0]).tolist() if use_vel and g_vel is not None else []
    for n, (sid, row) in enumerate(zip(streams.tolist(), rows.tolist(), strict=True)):
        if sid == WHEEL:
            estimator.on_wheel_speeds(w_t[row], w_v[row])
        elif sid == STEER:
            estimator.on_steering(s_t[row], s_v[row])
        elif sid == IMU:
            estimator.on_imu(i_t[row], i_w[row], i_a[row])  # type: ignore[index]
        else:
            upd = estimator.on_gnss_fix(g_t[row], lat[row], lon[row], alt[row], g_cov[row])
            if g_has_vel and g_has_vel[row]:
                vupd = estimator.on_gnss_velocity(
                    g_t[row], g_vel[row], None if g_vcov is None else g_vcov[row]
                )
                _record_velocity(trace, vupd)
            _record(trace, estimator, upd, g_t[row])
        if progress is not None and n % 10_000 == 0:
            progress(n)
    trace.dropped = dict(estimator.stats)
    if use_vel:
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
    if upd is not None and getattr(upd, "innovation_m", None) is not None:
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
    trace.road_grade_rad.append(float(getattr(est, "road_grade_rad", 0.0)))
    trace.rear_brake_decel_m_s2.append(float(getattr(est, "rear_brake_decel_m_s2", 0.0)))
    trace.n_eff.append(float(est.n_eff))
    trace.state.append(str(est.state))
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


def run_lateral_estimator(
    estimator: Any,
    tire_forces: TireForceStream,
    wheel_speeds: WheelSpeedStream | None,
    steering: SteeringStream | None,
    imu: ImuStream | None,
) -> LateralTrace:
    """Feed a tyre-force lateral estimator (``TyreForceEstimator``) in stamp order.

    On equal stamps wheel speeds, steering and IMU go before the tyre forces, so each force
    sample sees the inputs of its own instant.
    """
    parts: list[tuple[NDArray[np.int64], int]] = []
    if wheel_speeds is not None:
        parts.append((wheel_speeds.t_ns, WHEEL))
    if steering is not None:
        parts.append((steering.t_ns, STEER))
    if imu is not None:
        parts.append((imu.t_ns, IMU))
    parts.append((tire_forces.t_ns, FORCES))
    t = np.concatenate([p[0] for p in parts])
    s = np.concatenate([np.full(p[0].size, p[1]) for p in parts])
    i = np.concatenate([np.arange(p[0].size) for p in parts])
    order = np.lexsort((s, t))
    trace = LateralTrace()
    f = tire_forces
    for sid, row in zip(s[order].tolist(), i[order].tolist(), strict=True):
        if sid == WHEEL:
            estimator.on_wheel_speeds(
                int(wheel_speeds.t_ns[row]), wheel_speeds.wheel_speed_rad_s[row]
            )  # type: ignore[union-attr]
        elif sid == STEER:
            estimator.on_steering(int(steering.t_ns[row]), float(steering.angle_rad[row]))  # type: ignore[union-attr]
        elif sid == IMU:
            estimator.on_imu(
                int(imu.t_ns[row]),
                imu.angular_velocity_rad_s[row],
                imu.linear_acceleration_m_s2[row],
            )  # type: ignore[union-attr]
        else:
            est = estimator.on_tire_forces(
                int(f.t_ns[row]), f.fx_n[row], f.fy_n[row], f.fz_n[row], f.valid[row]
            )
            if est is None or est.linearity == "unknown":
                continue
            trace.t_ns.append(int(est.t_ns))
            trace.vx_m_s.append(float(est.vx_m_s))
            trace.vy_m_s.append(float(est.vy_m_s))
            trace.yaw_rate_rad_s.append(float(est.yaw_rate_rad_s))
            trace.sideslip_rad.append(float(est.sideslip_rad))
            trace.relay.append(_RELAY_CODE.get(est.linearity, 0))
    trace.dropped = dict(getattr(estimator, "stats", {}))
    return trace


VELOCITY = 5


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


def run_imu_lateral_estimator(
    estimator: Any,
    imu: ImuStream,
    steering: SteeringStream | None,
    wheel_speeds: WheelSpeedStream | None = None,
    velocity: Any = None,
    record_period_s: float = 0.01,
) -> ImuLateralTrace:
    """Feed an IMU-driven lateral estimator in stamp order; record its estimate.

    ``estimator`` has ``on_wheel_speeds``, ``on_steering``, ``on_imu``, ``on_velocity`` (used
    when ``velocity``, a :class:`~tire_estimation.sim.streams.SpeedStream`, is given) and
    ``estimate()``; its ``initialized`` flag (or ``mpf.initialized``) says when an estimate
    exists. On equal stamps speeds and steering go before the IMU sample they belong to.
    """
    parts: list[tuple[NDArray[np.int64], int]] = []
    if wheel_speeds is not None:
        parts.append((wheel_speeds.t_ns, WHEEL))
    if velocity is not None:
        parts.append((velocity.t_ns, VELOCITY))
    if steering is not None:
        parts.append((steering.t_ns, STEER))
    parts.append((imu.t_ns, IMU))
    t = np.concatenate([p[0] for p in parts])
    s = np.concatenate([np.full(p[0].size, p[1]) for p in parts])
    i = np.concatenate([np.arange(p[0].size) for p in parts])
    order = np.lexsort((s, t))
    trace = ImuLateralTrace()
    period_ns = round(record_period_s * 1e9)
    next_ns: int | None = None
    i_t = imu.t_ns.tolist()
    i_w, i_a = imu.angular_velocity_rad_s, imu.linear_acceleration_m_s2
    s_t = steering.t_ns.tolist() if steering is not None else []
    s_v = steering.angle_rad.tolist() if steering is not None else []
    v_t = velocity.t_ns.tolist() if velocity is not None else []
    v_v = velocity.vx_m_s.tolist() if velocity is not None else []
    w_t = wheel_speeds.t_ns.tolist() if wheel_speeds is not None else []
    mpf = getattr(estimator, "mpf", None)
    ready_of = mpf if mpf is not None else estimator
    wall0 = time.perf_counter()
    for sid, row in zip(s[order].tolist(), i[order].tolist(), strict=True):
        if sid == WHEEL:
            estimator.on_wheel_speeds(w_t[row], wheel_speeds.wheel_speed_rad_s[row])  # type: ignore[union-attr]
        elif sid == VELOCITY:
            estimator.on_velocity(v_t[row], v_v[row])
        elif sid == STEER:
            estimator.on_steering(s_t[row], s_v[row])
        else:
            t_row = i_t[row]
            estimator.on_imu(t_row, i_w[row], i_a[row])
            trace.steps += 1
            if not getattr(ready_of, "initialized", False):
                continue
            if next_ns is not None and t_row < next_ns:
                continue
            next_ns = t_row + period_ns
            _record_lateral(trace, estimator.estimate(), t_row)
    trace.wall_s = time.perf_counter() - wall0
    trace.dropped = dict(getattr(estimator, "stats", {}))
    return trace


def _record_lateral(trace: ImuLateralTrace, est: Any, t_ns: int) -> None:
    trace.t_ns.append(t_ns)
    trace.vx_m_s.append(float(est.vx_m_s))
    trace.vy_m_s.append(float(est.vy_m_s))
    trace.yaw_rate_rad_s.append(float(est.yaw_rate_rad_s))
    trace.sideslip_rad.append(float(est.sideslip_rad))
    if hasattr(est, "stiffness"):
        if not trace.stiffness_names:
            trace.stiffness_names = tuple(est.names)
            trace.nominal = np.asarray(est.nominal, dtype=float).copy()
        trace.stiffness.append(np.asarray(est.stiffness, dtype=float).copy())
        trace.stiffness_std.append(np.asarray(est.stiffness_std, dtype=float).copy())
        trace.active.append(bool(est.active))
        trace.gyro_bias_rad_s.append(float(est.gyro_bias_rad_s[2]))
    if getattr(est, "mean_log_predictive", None) is not None:
        trace.mean_log_predictive = float(est.mean_log_predictive)
