"""Calibration phase of the deflation detector (Lundquist et al. 2014, IV-B; ECE R-64): each
wheel's calibrated radius error is the time-weighted mean of its estimate over the end of the
calibration driving time."""

from __future__ import annotations

from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.cusum import WheelState


def calibrate(
    w: WheelState, cfg: DeflationDetectorConfig, t_ns: int, mu_m: float, dt: float
) -> None:
    """One calibration step of wheel ``w``: ``dt`` s of counted driving with estimate ``mu_m``
    (m); completes the calibration after ``calibration_time_s``."""
    avg_start = cfg.calibration_time_s - cfg.calibration_average_s
    before = w.calib_time_s
    w.calib_time_s = before + dt
    # time-weighted mean of mu over the last calibration_average_s of calibration time
    weight = min(dt, max(0.0, w.calib_time_s - avg_start))
    if weight > 0.0:
        w.calib_sum_w += weight
        w.calib_sum_wx += weight * mu_m
    # the same over the last common_calibration_average_s (reference of the common channel)
    common_avg = min(cfg.common_calibration_average_s, cfg.calibration_time_s)
    weight = min(dt, max(0.0, w.calib_time_s - (cfg.calibration_time_s - common_avg)))
    if weight > 0.0:
        w.common_sum_w += weight
        w.common_sum_wx += weight * mu_m
    if w.calib_time_s >= cfg.calibration_time_s:
        w.calibrated_m = w.calib_sum_wx / w.calib_sum_w if w.calib_sum_w > 0 else mu_m
        w.common_calibrated_m = (
            w.common_sum_wx / w.common_sum_w if w.common_sum_w > 0 else w.calibrated_m
        )
        w.calibration_t_ns = t_ns
        w.lp_m = w.xbar_m = w.raw_m = w.g_m = 0.0
        w.threshold_m = cfg.threshold_m


def wheel_progress(w: WheelState, cfg: DeflationDetectorConfig) -> float:
    """Share of the calibration driving time wheel ``w`` has done, 1."""
    if w.calibrated_m is not None:
        return 1.0
    if cfg.calibration_time_s <= 0.0:
        return 0.0
    return min(1.0, w.calib_time_s / cfg.calibration_time_s)
