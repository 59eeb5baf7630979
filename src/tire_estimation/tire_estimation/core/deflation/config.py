"""Configuration of the CUSUM deflation detector (Lundquist et al. 2014, IV-B; module
docstring of :mod:`.detector`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

from tire_estimation.core.validation import (
    Checked,
    Flag,
    Fraction,
    NonNegative,
    Positive,
    in_range,
)
from tire_estimation.errors import ConfigError

KMH = 1.0 / 3.6  # m/s per km/h


@dataclass(frozen=True)
class DeflationDetectorConfig(Checked):
    """Configuration of :class:`DeflationDetector` (validated at construction).

    Attributes:
        drift_m: CUSUM drift nu, m; the filtered radius decrease must exceed it to accumulate.
            Default 0.4e-3 (paper).
        threshold_m: CUSUM alarm threshold rho_th, m (m summed per reference sample).
            Default 9e-3 (paper).
        reference_sample_period_s: T_ref, s; every CUSUM increment is weighted by dt / T_ref so
            nu and rho keep the paper's per-sample meaning at any input rate. Default 2.0 (the
            0.5 Hz GPS update of the paper's ECE R-64 data).
        lowpass_time_constant_s: time constant of the first-order low-pass filter on the radius
            change, s; 0 disables. Default 30.
        rate_limit_m_s: largest rate of change of the filtered radius change, m/s; 0 disables.
            Default 2e-5 (1.2 mm/min).
        adaptive_threshold: scale rho_th by the estimate's reported std, rho_k = rho_th *
            clip(std / adaptive_reference_std_m, 1, adaptive_max_factor). Default True.
        adaptive_reference_std_m: estimate std at or below which rho_th is used unchanged, m.
            Default 1e-3.
        adaptive_max_factor: largest factor the adaptive threshold applies to rho_th, 1.
            Default 4.
        min_speed_m_s: lower end of the speed window in which driving time counts, m/s.
            Default 11.111 (40 km/h, ECE R-64).
        max_speed_m_s: upper end of the speed window, m/s. Default 33.333 (120 km/h, ECE R-64).
        exclude_braking: driving time while braking does not count (ECE R-64). Default True.
        calibration_time_s: driving time in the window (braking excluded) that completes the
            calibration of a wheel, s. Default 1200 (20 min, ECE R-64).
        calibration_average_s: the calibrated radius error is the time-weighted mean of the
            estimate over the last this-many seconds of the calibration driving time, s
            (0 = the value at its end). Default 300.
        stale_timeout_s: a wheel with no estimate for longer than this is STALE, s. Default 5.
        max_sample_gap_s: the driving time credited to one sample is capped at this, s, so a
            gap in the estimates does not count as driving. Default 1.
        warn_fraction: WARN when g exceeds this fraction of the threshold, 1. Default 0.5.
        common_mode_fraction: lambda, the fraction of the mean radius decrease of the *other*
            calibrated wheels subtracted from each wheel's decrease before the CUSUM, 1
            (x_j <- x_j - lambda mean_{k != j} x_k; not in the paper). 0 = the paper (each wheel
            on its own); 1 = relative to the other wheels: a common wander of all estimates
            (GNSS errors move every radius together) cancels, and a deflation of one wheel no
            longer drags the others into an alarm, but an equal loss on every wheel is not
            seen (that is what common_channel is for). Default 1, with common_channel: in the
            ECE R-64 campaign traces (docs/results.md section 7) this pair had no false alarm
            in 103.3 h of robustness driving and 108 step cases and found 20 of 20 diffusions,
            where lambda = 0.5 alone (the previous default) gave the MPF 4 false alarms and
            missed 3 leaks on both rear tyres.
        common_channel: run the common-mode channel (module docstring; not in the paper): a
            CUSUM on the mean radius decrease of all covered wheels (at least two calibrated,
            all present and active in the sample; otherwise it holds) whose alarm is a
            vehicle-level warning that names no tyre (``DeflationStatusData.common``, and
            ``any_alarm``), raised only while no wheel alarm is latched. Default True. The
            paper's detector: common_mode_fraction = 0 and common_channel = False.
        common_drift_m: drift nu2 of the common channel, m. Default 0.35e-3.
        common_threshold_m: alarm threshold rho2 of the common channel, m (m summed per
            reference sample, as threshold_m). Default 9e-3.
        common_lowpass_time_constant_s: time constant of the common channel's low-pass
            filter, s (0 disables; the rate limit is rate_limit_m_s). Default 600: with 300 s
            a 5-min swing of 0.7 mm of both estimates (poor GNSS) raised a false alarm.
        common_calibration_average_s: the common channel's reference for each wheel is the
            time-weighted mean of its estimate over the last this-many seconds of calibration
            driving time (at most calibration_time_s), s. Default 900: the GNSS-driven wander
            of the estimates is correlated over about a minute, so a 5-min mean can sit
            0.36 mm off (ECE campaign, poor GNSS).
    """

    drift_m: Annotated[float, in_range(0.0, 0.05)] = 0.4e-3
    threshold_m: Annotated[float, in_range(1e-9, 10.0)] = 9e-3
    reference_sample_period_s: Positive = 2.0
    lowpass_time_constant_s: NonNegative = 30.0
    rate_limit_m_s: NonNegative = 2e-5
    adaptive_threshold: Flag = True
    adaptive_reference_std_m: Annotated[float, in_range(1e-9, 0.1)] = 1e-3
    adaptive_max_factor: Annotated[float, in_range(1.0, 1e6)] = field(
        default=4.0, metadata={"unit": "1"}
    )
    min_speed_m_s: NonNegative = 40.0 * KMH
    max_speed_m_s: Positive = 120.0 * KMH
    exclude_braking: Flag = True
    calibration_time_s: NonNegative = 1200.0
    calibration_average_s: NonNegative = 300.0
    stale_timeout_s: Positive = 5.0
    max_sample_gap_s: Positive = 1.0
    warn_fraction: Fraction = field(default=0.5, metadata={"unit": "1"})
    common_mode_fraction: Fraction = field(default=1.0, metadata={"unit": "1"})
    common_channel: Flag = True
    common_drift_m: Annotated[float, in_range(0.0, 0.05)] = 0.35e-3
    common_threshold_m: Annotated[float, in_range(1e-9, 10.0)] = 9e-3
    common_lowpass_time_constant_s: NonNegative = 600.0
    common_calibration_average_s: NonNegative = 900.0

    def check(self) -> None:
        if self.max_speed_m_s <= self.min_speed_m_s:
            raise ConfigError(
                "max_speed_m_s",
                self.max_speed_m_s,
                f"must be > min_speed_m_s={self.min_speed_m_s}",
            )
        if self.calibration_average_s > self.calibration_time_s:
            raise ConfigError(
                "calibration_average_s",
                self.calibration_average_s,
                f"must be <= calibration_time_s={self.calibration_time_s}",
            )
