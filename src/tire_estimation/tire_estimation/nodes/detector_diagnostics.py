"""``/diagnostics`` of the detector node: one status per wheel it monitors."""

from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from tire_estimation.core.deflation.status import Level, WheelDeflationData

_DIAG_LEVEL = {
    Level.OK: DiagnosticStatus.OK,
    Level.WARN: DiagnosticStatus.WARN,
    Level.ALARM: DiagnosticStatus.ERROR,
    Level.STALE: DiagnosticStatus.STALE,
}
_LEVEL_TEXT = {
    Level.OK: "ok",
    Level.WARN: "CUSUM above half the threshold",
    Level.ALARM: "DEFLATION ALARM",
    Level.STALE: "no radius estimate",
}


def wheel_status(w: WheelDeflationData, now: int | None, hardware_id: str) -> DiagnosticStatus:
    """One wheel's deflation status: level, CUSUM against its threshold, calibration."""
    st = DiagnosticStatus(
        name=f"tire_estimation: deflation {w.wheel_name}",
        hardware_id=hardware_id,
    )
    st.level = _DIAG_LEVEL[w.level]
    st.message = _LEVEL_TEXT[w.level] if w.calibrated or w.alarm else "calibrating"
    if w.level == Level.STALE:
        st.message = _LEVEL_TEXT[Level.STALE]
    since_cal = ""
    if w.calibration_t_ns is not None and now is not None:
        since_cal = f"{max(0.0, (now - w.calibration_t_ns) * 1e-9):.1f}"
    age = ""
    if w.last_estimate_t_ns is not None and now is not None:
        age = f"{max(0.0, (now - w.last_estimate_t_ns) * 1e-9):.1f}"
    values = {
        "radius_change_mm": f"{1e3 * w.radius_change_m:.3f}",
        "cusum_g_mm": f"{1e3 * w.cusum_m:.3f}",
        "threshold_mm": f"{1e3 * w.threshold_m:.3f}",
        "calibrated": str(w.calibrated).lower(),
        "calibration_progress": f"{w.calibration_progress:.3f}",
        "time_since_calibration_s": since_cal,
        "calibrated_radius_error_mm": (
            ""
            if w.calibrated_radius_error_m is None
            else f"{1e3 * w.calibrated_radius_error_m:.3f}"
        ),
        "alarm": str(w.alarm).lower(),
        "alarm_time_s": "" if w.alarm_t_ns is None else f"{w.alarm_t_ns * 1e-9:.3f}",
        "estimate_age_s": age,
    }
    st.values = [KeyValue(key=k, value=v) for k, v in values.items()]
    return st
