"""``/diagnostics`` of the estimator node: one status per estimator and one per wheel.

Dropped samples are reported as ``dropped.<stream>:<kind>``: on the radius estimator's status
those the message checks dropped (:mod:`.conversions`) with those the radius estimator dropped,
on the stiffness and tyre-force statuses those each of these estimators dropped.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from tire_estimation.core.input_checks import merged_counts
from tire_estimation.core.lateral.tyre_force_kf import TyreForceEstimator
from tire_estimation.core.pipeline import EstimationPipeline
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.wheels import WHEEL_INDEX

#: input streams reported on /diagnostics (rate and count)
INPUT_STREAMS = ("wheel_speeds", "steering", "imu", "gnss_fix", "gnss_velocity", "tire_forces")


def _status(name: str, hardware_id: str, level: int, message: str) -> DiagnosticStatus:
    st = DiagnosticStatus()
    st.name, st.hardware_id, st.level, st.message = name, hardware_id, level, message
    return st


def _values(values: Mapping[str, str]) -> list[KeyValue]:
    return [KeyValue(key=k, value=v) for k, v in values.items()]


def statuses(
    pipeline: EstimationPipeline,
    hardware_id: str,
    received: Mapping[str, int],
    dropped: Mapping[str, int],
    rates_hz: Mapping[str, float],
    persistence_note: str,
    clock: Mapping[str, Any] | None = None,
) -> list[DiagnosticStatus]:
    """The radius estimator's status (with the input counters), one per wheel it covers, and
    one for the stiffness MPF and the tyre-force KF when they run."""
    out: list[DiagnosticStatus] = []
    radius = pipeline.radius
    if radius is not None:
        est = radius.estimate()
        if est.state == "running":
            level, message = DiagnosticStatus.OK, "running"
        elif est.state == "paused":
            level, message = DiagnosticStatus.WARN, f"paused: {est.state_reason}"
        else:
            level, message = DiagnosticStatus.WARN, f"initializing: {est.state_reason}"
        main = _status("tire_estimation: radius estimator", hardware_id, level, message)
        values = {
            "state": est.state,
            "reason": est.state_reason,
            "effective_sample_size": f"{float(est.n_eff):.1f}",
            "resample_count": str(int(est.resample_count)),
            "particles": str(radius.config.n_particles),
            "persistence": persistence_note,
        }
        if radius.config.gnss_velocity_enabled:
            # velocities received minus these: dropped, gated, or while paused / initializing
            values["gnss_velocity.updates"] = str(int(radius.velocity_updates))
            values["gnss_velocity.skipped_accelerating"] = str(int(radius.velocity_skipped_accel))
        for stream in INPUT_STREAMS:
            values[f"rate_hz.{stream}"] = f"{rates_hz.get(stream, 0.0):.1f}"
            values[f"received.{stream}"] = str(received.get(stream, 0))
        # dropped by the message checks, the clock guard and the radius estimator, all as
        # <stream>:<kind>; new clocks adopted per stream
        drops = merged_counts(dropped, pipeline.clock.drop_counts(), radius.stats)
        for key, count in sorted(drops.items()):
            values[f"dropped.{key}"] = str(count)
        for stream, count in sorted(pipeline.clock.jumps.items()):
            values[f"clock_jumps.{stream}"] = str(count)
        # processed out of stamp order: arrived more than reorder_delay_s behind the wheel speeds
        for key, count in sorted(pipeline.buffer.late.items()):
            values[f"late.{key}"] = str(count)
        # the road grade of the slope-distance correction and where it came from
        values["road_grade_deg"] = f"{math.degrees(est.road_grade_rad):.2f}"
        values["road_grade.source"] = est.road_grade_source
        values["road_grade.imu_offset_deg"] = f"{math.degrees(est.road_grade_imu_offset_rad):.2f}"
        for source, count in sorted(est.road_grade_counts.items()):
            values[f"road_grade.fixes.{source}"] = str(count)
        # the wheel speeds' lag brought back before the prediction (half their sample period)
        values["wheel_speeds.lag_ms"] = f"{1e3 * est.wheel_speed_lag_s:.1f}"
        # an edge-timed ABS unit's teeth, from the values it holds at low speed (0: not seen);
        # there the lag brought back is a tooth period
        pitch = est.wheel_speed_tooth_pitch_rad
        values["wheel_speeds.teeth"] = f"{2.0 * math.pi / pitch:.1f}" if pitch else "0"
        # gross scale errors of the radii seen in the GNSS speed, corrected by rescaling
        values["speed_scale.rescales"] = str(len(est.radius_rescales))
        # the fixes' stated covariance scaled as their innovations have shown it
        values["gnss.covariance_scale"] = f"{est.fix_covariance_scale:.3g}"
        if est.drive_slip:
            values["drive_slip.source"] = str(est.drive_slip["source"])
            values["drive_slip.mean_pct"] = f"{100 * float(est.drive_slip['mean_slip']):.3f}"
        if pipeline.axles is not None:
            for axle in ("front", "rear"):
                values[f"axle.{axle}.split"] = pipeline.axles.status(axle).reason
                values[f"axle.{axle}.swapped"] = str(pipeline.axles.swapped[axle]).lower()
            # the gyro's yaw rate found turning against the GNSS course, negated since
            values["gyro.yaw_reversed"] = str(pipeline.axles.gyro_reversed).lower()
            # wheels whose speed turned backward while the GNSS moved forward, negated since
            reversed_wheels = pipeline.axles.signs.reversed_wheels
            values["wheels.sign_reversed"] = ",".join(reversed_wheels) or "none"
            # the front and rear names found exchanged in the turns (axle_order.py)
            values["axle.front_rear_exchanged"] = str(pipeline.axles.order.exchanged).lower()
        # the IMU's mounting yaw against the wheels (core/imu_mounting.py): "checking" until
        # decided; a large one is taken out of the IMU samples
        mount = pipeline.imu_mounting.result
        values["imu.mounting_yaw_deg"] = (
            f"{mount.yaw_deg:.1f}" if mount.decided and mount.yaw_deg is not None else "checking"
        )
        values["imu.rotated"] = str(mount.corrected).lower()
        values["imu.upside_down"] = str(mount.upside_down).lower()
        # the GNSS stamps against the wheel speeds' clock (core/clock_check.py), decided over
        # the first minutes: an offset is reported, not taken out
        lag = None if clock is None else clock.get("lag_s")
        values["clock.gnss_lag_s"] = (
            "checking" if clock is None else "unknown" if lag is None else f"{lag:.2f}"
        )
        if clock is not None and clock.get("offset"):
            main.level = DiagnosticStatus.WARN
            main.message = (
                f"GNSS stamps {lag:+.1f} s off the wheel speeds' clock (their speeds match "
                "that much later): the estimates assume one clock; fix the stamps at the source"
            )
        if any(dropped.values()) and main.level == DiagnosticStatus.OK:
            main.message = f"running; {sum(dropped.values())} input samples dropped"
        main.values = _values(values)
        out.append(main)
        learned_s = radius.active_time_s
        for i, wheel in enumerate(est.wheels):
            active = bool(est.active[i])
            if active:
                level, message = DiagnosticStatus.OK, "learning"
            elif learned_s > 0.0:
                level, message = DiagnosticStatus.OK, f"holding: {est.state_reason}"
            else:
                # the published radius is the prior: say so
                level, message = DiagnosticStatus.WARN, f"not learned yet: {est.state_reason}"
            axle = "front" if wheel in ("wheel_fl", "wheel_fr") else "rear"
            if pipeline.axles is not None and pipeline.axles.signal_lost(WHEEL_INDEX[wheel]):
                # the sensor reads (near) zero or nothing while the other wheels turn
                level = DiagnosticStatus.WARN
                message += "; wheel-speed signal lost"
            if (
                pipeline.axles is not None
                and pipeline.axles.status(axle).split_observable is False
            ):
                # the two tyres of this axle cannot be told apart: only their mean is learned
                level = DiagnosticStatus.WARN
                message += f"; {axle} left-right split unobservable (equal wheel speeds in turns)"
            st = _status(f"tire_estimation: {wheel}", hardware_id, level, message)
            st.values = _values(
                {
                    "radius_error_mm": f"{1e3 * float(est.radius_error_m[i]):.3f}",
                    "radius_error_std_mm": f"{1e3 * float(est.radius_error_std_m[i]):.3f}",
                    "radius_noise_std_mm": f"{1e3 * float(est.radius_noise_std_m[i]):.4f}",
                    "active": str(active).lower(),
                    "learned_s": f"{learned_s:.1f}",
                }
            )
            out.append(st)
    if pipeline.stiffness is not None:
        out.append(_stiffness_status(pipeline.stiffness, hardware_id, received))
    if pipeline.tyre_force is not None:
        out.append(_tyre_force_status(pipeline.tyre_force, hardware_id, received))
    return out


def _tyre_force_status(
    lateral: TyreForceEstimator, hardware_id: str, received: Mapping[str, int]
) -> DiagnosticStatus:
    """The tyre-force lateral KF: waiting for forces, or running with its relay."""
    est = lateral.estimate()
    n = received.get("tire_forces", 0)
    if n == 0:
        level, message = DiagnosticStatus.OK, "idle: no tyre forces received"
    elif est.linearity == "unknown":
        level, message = DiagnosticStatus.WARN, "initializing"
    else:
        level, message = DiagnosticStatus.OK, f"running ({est.linearity})"
    st = _status("tire_estimation: tyre-force lateral KF", hardware_id, level, message)
    values = {
        "linearity": str(est.linearity),
        "received.tire_forces": str(n),
        "lateral_velocity_m_s": f"{float(est.vy_m_s):.3f}",
        "yaw_rate_rad_s": f"{float(est.yaw_rate_rad_s):.4f}",
    }
    for key, count in sorted(lateral.stats.items()):
        values[f"dropped.{key}"] = str(count)
    st.values = _values(values)
    return st


def _stiffness_status(
    stiffness: StiffnessEstimator, hardware_id: str, received: Mapping[str, int]
) -> DiagnosticStatus:
    """The stiffness MPF: learning or holding and why, N_eff, estimates, drops."""
    est = stiffness.estimate()
    if not stiffness.mpf.initialized:
        level, message = DiagnosticStatus.WARN, f"initializing: {est.reason}"
    else:
        level = DiagnosticStatus.OK
        message = "learning" if est.active else f"holding: {est.reason}"
    st = _status("tire_estimation: stiffness estimator", hardware_id, level, message)
    values = {
        "active": str(bool(est.active)).lower(),
        "reason": est.reason,
        "effective_sample_size": f"{float(est.n_eff):.1f}",
        "resample_count": str(int(stiffness.mpf.resample_count)),
        "grid_handovers": str(stiffness.handover_count),
        "grid_rejections": str(stiffness.grid_rejection_count),
        "particles": str(stiffness.config.n_particles),
        "gyro_bias_z_rad_s": f"{float(est.gyro_bias_rad_s[2]):.5f}",
        "received.velocity": str(received.get("velocity", 0)),
    }
    for name, c, s in zip(est.names, est.stiffness, est.stiffness_std, strict=True):
        values[name] = f"{float(c):.0f}"
        values[f"{name}_std"] = f"{float(s):.0f}"
    for key, count in sorted(stiffness.stats.items()):
        values[f"dropped.{key}"] = str(count)
    st.values = _values(values)
    return st
