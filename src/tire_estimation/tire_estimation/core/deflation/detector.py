"""Tyre deflation detector: calibration phase + per-wheel CUSUM (Lundquist et al. 2014, IV-B).

The detector watches the radius-error estimates mu_{i,k} of the radius estimator. After a
calibration phase (ECE R-64: at least 20 min of driving between 40 and 120 km/h, braking
excluded) it remembers each wheel's calibrated radius error and runs, per wheel, the CUSUM test
of Table II on the difference "calibrated minus current" (positive = the tyre got smaller):

    x_{i,k}    = mu_cal_i - mu_{i,k}
    xbar_{i,k} = LP rate limit(x_{i,k})                (Table II, line 3)
    g_{i,k}    = max(0, g_{i,k-1} + xbar_{i,k} - nu)   (Table II, lines 4-5)
    alarm when g_{i,k} > rho_th                        (Table II, line 6)

Units. The paper's mu is a radius error in metres (Fig. 4 reaches about 1.5 mm), so its
nu = 0.4e-3 is in m and its rho_th = 9e-3 is in m summed over samples ("m x samples"). The paper
does not state the CUSUM sample period; the radius estimate receives new information at the GPS
measurement updates, 0.5 Hz in the ECE R-64 data of Section IV-B. Because our estimator may
publish at any rate, each CUSUM increment here is weighted by dt / T_ref with
``reference_sample_period_s`` T_ref = 2 s: g and rho stay in metres exactly as in the paper
when one sample arrives every T_ref, and the test does not change with the publishing rate.

Tuning note: with the paper's nu = 0.4 mm the detector tolerates about 0.15 mm (std) of slowly
varying (~1 min correlated) error in the radius estimate without false alarms over hours; at
0.2 mm it starts to raise them (tests/core/deflation/). The ECE R-64 campaign should
confirm nu and rho on real estimator output.

Common-mode channel (not in the paper; ``common_channel``). The per-wheel input may have the
other wheels' mean decrease removed (``common_mode_fraction`` lambda; lambda = 1 makes each
wheel's test relative to the others, so the common wander of all estimates that GNSS errors
cause no longer alarms, but neither does an equal loss on every tyre). The common channel
watches that equal loss on its own: one CUSUM on the mean decrease of the covered wheels, with
a reference averaged over a longer part of the calibration, a slower low-pass filter and its
own drift and threshold. Its alarm is a vehicle-level warning ("all wheels", no tyre named),
raised only while no wheel alarm is latched:

    c_k    = mean_j (mu_cal2_j - mu_{j,k})             (mu_cal2: mean over the last
                                                        common_calibration_average_s)
    cbar_k = LP_tau2 rate limit(c_k)
    G_k    = max(0, G_{k-1} + (cbar_k - nu2) dt / T_ref);  alarm when G_k > rho2

Only driving time inside the speed window and without braking counts, for the calibration and
for the detection alike (Section IV-B); outside it the filters and g are held. Alarms latch
until :meth:`DeflationDetector.recalibrate`. Bad samples are dropped and counted in
:attr:`DeflationDetector.stats`; :meth:`DeflationDetector.step` never raises.

:func:`run_detector_over_trace` runs the same detector offline over arrays of estimates (for the
ECE R-64 campaign).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any

import numpy as np

from tire_estimation.core.validation import (
    require_non_negative,
    require_positive,
    require_range,
)
from tire_estimation.core.wheels import WHEEL_INDEX, WHEELS
from tire_estimation.errors import ConfigError, InputError

KMH = 1.0 / 3.6  # m/s per km/h
STATE_VERSION = 1
#: wheel name of a common-channel alarm in :attr:`TraceResult.alarms` (names no tyre)
ALL_WHEELS = "all_wheels"
#: keys of :attr:`DeflationDetector.stats` that count events, not dropped samples
INFO_STATS = frozenset({"accepted", "no_speed", "recalibrations"})


class CalibrationState(IntEnum):
    """Calibration phase; values equal the ``DeflationStatus.CALIBRATION_*`` constants."""

    NOT_STARTED = 0
    IN_PROGRESS = 1
    DONE = 2


class Level(IntEnum):
    """Per-wheel level; values equal the ``WheelDeflation.LEVEL_*`` constants."""

    OK = 0
    WARN = 1
    ALARM = 2
    STALE = 3


@dataclass(frozen=True)
class DeflationDetectorConfig:
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

    drift_m: float = field(default=0.4e-3, metadata={"unit": "m"})
    threshold_m: float = field(default=9e-3, metadata={"unit": "m"})
    reference_sample_period_s: float = field(default=2.0, metadata={"unit": "s"})
    lowpass_time_constant_s: float = field(default=30.0, metadata={"unit": "s"})
    rate_limit_m_s: float = field(default=2e-5, metadata={"unit": "m/s"})
    adaptive_threshold: bool = True
    adaptive_reference_std_m: float = field(default=1e-3, metadata={"unit": "m"})
    adaptive_max_factor: float = field(default=4.0, metadata={"unit": "1"})
    min_speed_m_s: float = field(default=40.0 * KMH, metadata={"unit": "m/s"})
    max_speed_m_s: float = field(default=120.0 * KMH, metadata={"unit": "m/s"})
    exclude_braking: bool = True
    calibration_time_s: float = field(default=1200.0, metadata={"unit": "s"})
    calibration_average_s: float = field(default=300.0, metadata={"unit": "s"})
    stale_timeout_s: float = field(default=5.0, metadata={"unit": "s"})
    max_sample_gap_s: float = field(default=1.0, metadata={"unit": "s"})
    warn_fraction: float = field(default=0.5, metadata={"unit": "1"})
    common_mode_fraction: float = field(default=1.0, metadata={"unit": "1"})
    common_channel: bool = True
    common_drift_m: float = field(default=0.35e-3, metadata={"unit": "m"})
    common_threshold_m: float = field(default=9e-3, metadata={"unit": "m"})
    common_lowpass_time_constant_s: float = field(default=600.0, metadata={"unit": "s"})
    common_calibration_average_s: float = field(default=900.0, metadata={"unit": "s"})

    def __post_init__(self) -> None:
        require_range("drift_m", self.drift_m, 0.0, 0.05)
        require_range("threshold_m", self.threshold_m, 1e-9, 10.0)
        require_positive("reference_sample_period_s", self.reference_sample_period_s)
        require_non_negative("lowpass_time_constant_s", self.lowpass_time_constant_s)
        require_non_negative("rate_limit_m_s", self.rate_limit_m_s)
        for name in ("adaptive_threshold", "exclude_braking", "common_channel"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(name, getattr(self, name), "must be a bool")
        require_range("adaptive_reference_std_m", self.adaptive_reference_std_m, 1e-9, 0.1)
        require_range("adaptive_max_factor", self.adaptive_max_factor, 1.0, 1e6)
        require_non_negative("min_speed_m_s", self.min_speed_m_s)
        require_positive("max_speed_m_s", self.max_speed_m_s)
        if self.max_speed_m_s <= self.min_speed_m_s:
            raise ConfigError(
                "max_speed_m_s",
                self.max_speed_m_s,
                f"must be > min_speed_m_s={self.min_speed_m_s}",
            )
        require_non_negative("calibration_time_s", self.calibration_time_s)
        require_non_negative("calibration_average_s", self.calibration_average_s)
        if self.calibration_average_s > self.calibration_time_s:
            raise ConfigError(
                "calibration_average_s",
                self.calibration_average_s,
                f"must be <= calibration_time_s={self.calibration_time_s}",
            )
        require_positive("stale_timeout_s", self.stale_timeout_s)
        require_positive("max_sample_gap_s", self.max_sample_gap_s)
        require_range("warn_fraction", self.warn_fraction, 0.0, 1.0)
        require_range("common_mode_fraction", self.common_mode_fraction, 0.0, 1.0)
        require_range("common_drift_m", self.common_drift_m, 0.0, 0.05)
        require_range("common_threshold_m", self.common_threshold_m, 1e-9, 10.0)
        require_non_negative("common_lowpass_time_constant_s", self.common_lowpass_time_constant_s)
        require_non_negative("common_calibration_average_s", self.common_calibration_average_s)


@dataclass(frozen=True)
class WheelDeflationData:
    """Detector state of one wheel (mirrors ``WheelDeflation.msg``)."""

    wheel_name: str
    level: Level
    radius_change_m: float  # filtered xbar: calibrated minus current (positive = smaller tyre)
    raw_radius_change_m: float  # unfiltered x of the last detection step
    cusum_m: float
    threshold_m: float
    alarm: bool
    alarm_t_ns: int | None
    calibrated: bool
    calibrated_radius_error_m: float | None
    calibration_t_ns: int | None
    calibration_progress: float
    last_estimate_t_ns: int | None


@dataclass(frozen=True)
class CommonChannelData:
    """State of the common-mode channel (all covered wheels together; vehicle level)."""

    wheel_names: tuple[str, ...]  # the wheels of the last update
    radius_change_m: float  # filtered mean decrease since calibration (positive = smaller)
    raw_radius_change_m: float  # unfiltered mean decrease of the last update
    cusum_m: float
    threshold_m: float
    alarm: bool
    alarm_t_ns: int | None


@dataclass(frozen=True)
class DeflationStatusData:
    """Detector output for one instant (mirrors ``DeflationStatus.msg``)."""

    t_ns: int | None
    accepted: bool  # False when the sample handed to step() was dropped
    calibration_state: CalibrationState
    calibration_progress: float
    calibrated_driving_time_s: float
    wheels: tuple[WheelDeflationData, ...]
    any_alarm: bool  # a wheel's alarm or the common channel's
    common: CommonChannelData | None = None  # None unless config.common_channel

    def wheel(self, name: str) -> WheelDeflationData:
        """Entry of wheel ``name`` (KeyError when the detector has not seen it)."""
        for w in self.wheels:
            if w.wheel_name == name:
                return w
        raise KeyError(name)


@dataclass
class _Wheel:
    """Mutable per-wheel state."""

    calib_time_s: float = 0.0
    calib_sum_w: float = 0.0
    calib_sum_wx: float = 0.0
    calibrated_m: float | None = None
    calibration_t_ns: int | None = None
    common_sum_w: float = 0.0
    common_sum_wx: float = 0.0
    common_calibrated_m: float | None = None
    lp_m: float = 0.0
    xbar_m: float = 0.0
    raw_m: float = 0.0
    g_m: float = 0.0
    threshold_m: float = 0.0
    alarm_t_ns: int | None = None
    last_estimate_m: float | None = None
    last_seen_ns: int | None = None

    _PERSISTED = (
        "calib_time_s",
        "calib_sum_w",
        "calib_sum_wx",
        "calibrated_m",
        "calibration_t_ns",
        "common_sum_w",
        "common_sum_wx",
        "common_calibrated_m",
        "lp_m",
        "xbar_m",
        "raw_m",
        "g_m",
        "threshold_m",
        "alarm_t_ns",
        "last_estimate_m",
    )

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self._PERSISTED}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> _Wheel:
        w = cls()
        for key in cls._PERSISTED:
            value = data.get(key)
            if key in ("calibrated_m", "common_calibrated_m", "last_estimate_m"):
                setattr(w, key, None if value is None else _finite_float(key, value))
            elif key in ("calibration_t_ns", "alarm_t_ns"):
                setattr(w, key, _optional_int(key, value))
            else:
                setattr(w, key, 0.0 if value is None else _finite_float(key, value))
        return w


@dataclass
class _Common:
    """Mutable state of the common-mode channel."""

    wheel_names: tuple[str, ...] = ()
    lp_m: float = 0.0
    xbar_m: float = 0.0
    raw_m: float = 0.0
    g_m: float = 0.0
    alarm_t_ns: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "wheel_names": list(self.wheel_names),
            "lp_m": self.lp_m,
            "xbar_m": self.xbar_m,
            "raw_m": self.raw_m,
            "g_m": self.g_m,
            "alarm_t_ns": self.alarm_t_ns,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> _Common:
        names = data.get("wheel_names", [])
        if not isinstance(names, (list, tuple)) or any(n not in WHEEL_INDEX for n in names):
            raise InputError("bad_state", f"saved common channel has bad wheels {names!r}")
        c = cls(wheel_names=tuple(str(n) for n in names))
        for key in ("lp_m", "xbar_m", "raw_m", "g_m"):
            value = data.get(key)
            setattr(c, key, 0.0 if value is None else _finite_float(key, value))
        c.alarm_t_ns = _optional_int("alarm_t_ns", data.get("alarm_t_ns"))
        return c


def _optional_int(key: str, value: Any) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not an integer")
    return value


def _finite_float(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not a number")
    out = float(value)
    if not math.isfinite(out):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not finite")
    return out


def _cusum_step(
    s: Any, x: float, dt: float, tau_s: float, rate_m_s: float, drift_m: float, t_ref_s: float
) -> None:
    """One CUSUM step of Table II on the input ``x`` (m) over ``dt`` (s), updating ``s.lp_m``,
    ``s.xbar_m`` and ``s.g_m`` in place (a wheel's state or the common channel's)."""
    # Table II line 3, LP: y_k = y_{k-1} + (1 - exp(-dt / tau)) (x_k - y_{k-1})
    if tau_s > 0.0:
        s.lp_m += (1.0 - math.exp(-dt / tau_s)) * (x - s.lp_m)
    else:
        s.lp_m = x
    # Table II line 3, rate limit: xbar_k = xbar_{k-1} + clip(y_k - xbar_{k-1}, +-r dt)
    if rate_m_s > 0.0:
        step = rate_m_s * dt
        s.xbar_m += min(step, max(-step, s.lp_m - s.xbar_m))
    else:
        s.xbar_m = s.lp_m
    # Table II line 4: g_k = g_{k-1} + xbar_k - nu (weighted by dt / T_ref);
    # line 5: g_k = 0 if g_k < 0
    s.g_m = max(0.0, s.g_m + (s.xbar_m - drift_m) * dt / t_ref_s)


class DeflationDetector:
    """Per-wheel calibration + CUSUM deflation detector over radius-error estimates."""

    def __init__(self, config: DeflationDetectorConfig | None = None) -> None:
        self.config = config if config is not None else DeflationDetectorConfig()
        self.stats: Counter[str] = Counter()
        self._wheels: dict[str, _Wheel] = {}
        self._common = _Common()
        self._driving_time_s = 0.0
        self._t_prev_ns: int | None = None
        self._t_resume_ns: int | None = None  # last sample time before a restore

    # --- public API -----------------------------------------------------------------------
    def step(
        self,
        t_ns: int,
        wheel_names: Sequence[str],
        radius_error_m: Sequence[float],
        radius_error_std_m: Sequence[float],
        active: Sequence[bool],
        speed_m_s: float | None,
        braking: bool,
    ) -> DeflationStatusData:
        """Consume one TireRadii-like sample; return the status at ``t_ns``.

        ``radius_error_m`` is the estimator's mu (effective minus nominal radius, m) per wheel of
        ``wheel_names``; ``speed_m_s`` None means unknown (the sample then only refreshes the
        staleness clock). A bad sample is dropped and counted in :attr:`stats`; never raises.
        """
        try:
            t, names, mu, std, act, speed = self._validate(
                t_ns, wheel_names, radius_error_m, radius_error_std_m, active, speed_m_s
            )
        except InputError as exc:
            self.stats[exc.kind] += 1
            return self._status(self._t_prev_ns, accepted=False)
        self.stats["accepted"] += 1
        dt = 0.0
        t_prev = self._t_prev_ns if self._t_prev_ns is not None else self._t_resume_ns
        if t_prev is not None and t > t_prev:
            dt = min((t - t_prev) * 1e-9, self.config.max_sample_gap_s)
        self._t_prev_ns = t
        self._t_resume_ns = None
        valid = speed is not None and self._driving_counts(speed, bool(braking))
        if speed is None:
            self.stats["no_speed"] += 1
        if valid:
            self._driving_time_s += dt
        detect: list[tuple[_Wheel, float, float]] = []
        for name, m, s, a in zip(names, mu, std, act, strict=True):
            w = self._wheels.setdefault(name, _Wheel(threshold_m=self.config.threshold_m))
            w.last_seen_ns = t
            w.last_estimate_m = m
            if not (valid and a and dt > 0.0):
                continue
            if w.calibrated_m is None:
                self._calibrate(w, t, m, dt)
            else:
                # x_k = mu_cal - mu_k: radius decrease since calibration (positive = smaller)
                detect.append((w, w.calibrated_m - m, s))
        lam = self.config.common_mode_fraction
        total = sum(x for _, x, _ in detect)
        for w, x, s in detect:
            if lam > 0.0 and len(detect) > 1:
                # x_j - lambda mean_{k != j} x_k (common_mode_fraction)
                x -= lam * (total - x) / (len(detect) - 1)
            self._detect(w, t, x, s, dt)
        if self.config.common_channel:
            self._detect_common(t, names, act, dt if valid else 0.0)
        return self._status(t, accepted=True)

    def check_stale(self, now_ns: int) -> DeflationStatusData:
        """Status at ``now_ns`` (same clock as the sample stamps); late wheels become STALE."""
        return self._status(int(now_ns), accepted=True)

    def status(self) -> DeflationStatusData:
        """Status at the last accepted sample."""
        return self._status(self._t_prev_ns, accepted=True)

    def recalibrate(self) -> None:
        """Forget calibration, CUSUM sums and latched alarms; start a new calibration."""
        for name, old in self._wheels.items():
            fresh = _Wheel(threshold_m=self.config.threshold_m)
            fresh.last_seen_ns = old.last_seen_ns
            fresh.last_estimate_m = old.last_estimate_m
            self._wheels[name] = fresh
        self._common = _Common()
        self._driving_time_s = 0.0
        self.stats["recalibrations"] += 1

    @property
    def dropped(self) -> dict[str, int]:
        """Counts of dropped samples by kind (``nan``, ``wrong_length``, ``out_of_order``, ...)."""
        return {k: v for k, v in sorted(self.stats.items()) if k not in INFO_STATS}

    @property
    def calibration_state(self) -> CalibrationState:
        """NOT_STARTED before any counted driving, DONE when every seen wheel is calibrated."""
        if self._wheels and all(w.calibrated_m is not None for w in self._wheels.values()):
            return CalibrationState.DONE
        if self._driving_time_s > 0.0 or any(w.calib_time_s > 0 for w in self._wheels.values()):
            return CalibrationState.IN_PROGRESS
        return CalibrationState.NOT_STARTED

    def state_dict(self) -> dict[str, Any]:
        """JSON-able state for persistence (calibration, filters, CUSUM sums, alarms)."""
        return {
            "version": STATE_VERSION,
            "driving_time_s": self._driving_time_s,
            "t_last_ns": self._t_prev_ns if self._t_prev_ns is not None else self._t_resume_ns,
            "wheels": {name: w.to_dict() for name, w in self._wheels.items()},
            "common": self._common.to_dict(),
        }

    def load_state_dict(self, state: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output; raises InputError (kind ``bad_state``) if malformed.

        Sample ordering and staleness restart with the next sample, so a restarted node accepts
        stamps older than those before the restart (e.g. a bag replayed again); a sample newer
        than the saved last one is credited the driving time since it (at most
        ``max_sample_gap_s``), so a save/restore continues exactly.
        """
        if not isinstance(state, Mapping) or state.get("version") != STATE_VERSION:
            raise InputError("bad_state", "saved detector state has an unknown version")
        raw_wheels = state.get("wheels")
        if not isinstance(raw_wheels, Mapping):
            raise InputError("bad_state", "saved detector state has no wheels mapping")
        wheels: dict[str, _Wheel] = {}
        for name, data in raw_wheels.items():
            if name not in WHEEL_INDEX or not isinstance(data, Mapping):
                raise InputError("bad_state", f"saved detector state has a bad wheel {name!r}")
            wheels[name] = _Wheel.from_dict(data)
        raw_common = state.get("common", {})  # absent in states saved before the channel
        if not isinstance(raw_common, Mapping):
            raise InputError("bad_state", "saved detector state has a bad common channel")
        common = _Common.from_dict(raw_common)
        driving = _finite_float("driving_time_s", state.get("driving_time_s", 0.0))
        t_last = _optional_int("t_last_ns", state.get("t_last_ns"))
        self._wheels = wheels
        self._common = common
        self._driving_time_s = driving
        self._t_prev_ns = None
        self._t_resume_ns = t_last

    # --- internals ------------------------------------------------------------------------
    def _validate(
        self,
        t_ns: Any,
        wheel_names: Any,
        radius_error_m: Any,
        radius_error_std_m: Any,
        active: Any,
        speed_m_s: Any,
    ) -> tuple[int, list[str], list[float], list[float], list[bool], float | None]:
        try:
            if isinstance(t_ns, bool):
                raise TypeError
            t = int(t_ns)
            names = [str(n) for n in wheel_names]
            mu = [float(v) for v in radius_error_m]
            std = [float(v) for v in radius_error_std_m]
            act = [bool(v) for v in active]
            speed = None if speed_m_s is None else float(speed_m_s)
        except (TypeError, ValueError) as exc:
            raise InputError("invalid", f"malformed sample: {exc}") from exc
        if t <= 0:
            raise InputError("no_stamp", "sample time is not positive")
        if self._t_prev_ns is not None and t <= self._t_prev_ns:
            raise InputError("out_of_order", "sample is not newer than the previous one")
        if not names:
            raise InputError("empty", "sample has no wheels")
        if not len(names) == len(mu) == len(std) == len(act):
            raise InputError("wrong_length", "wheel_names and value arrays differ in length")
        if len(set(names)) != len(names):
            raise InputError("duplicate_wheel", f"duplicate wheel names {names}")
        if any(n not in WHEEL_INDEX for n in names):
            raise InputError("unknown_wheel", f"wheel names {names} not among {WHEELS}")
        if not all(math.isfinite(v) for v in (*mu, *std)):
            raise InputError("nan", "radius error or std is not finite")
        if any(s < 0.0 for s in std):
            raise InputError("negative_std", "radius error std is negative")
        if speed is not None and not math.isfinite(speed):
            raise InputError("nan", "speed is not finite")
        return t, names, mu, std, act, speed

    def _driving_counts(self, speed_m_s: float, braking: bool) -> bool:
        cfg = self.config
        if cfg.exclude_braking and braking:
            return False
        return cfg.min_speed_m_s <= speed_m_s <= cfg.max_speed_m_s

    def _calibrate(self, w: _Wheel, t_ns: int, mu_m: float, dt: float) -> None:
        cfg = self.config
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

    def _detect(self, w: _Wheel, t_ns: int, x: float, std_m: float, dt: float) -> None:
        """CUSUM of Table II on ``x``, the radius decrease since calibration, m."""
        cfg = self.config
        w.raw_m = x
        _cusum_step(w, x, dt, cfg.lowpass_time_constant_s, cfg.rate_limit_m_s, cfg.drift_m,
                    cfg.reference_sample_period_s)  # fmt: skip
        # adaptive rho_th: scaled up while the estimator reports a large std
        w.threshold_m = self._threshold(std_m)
        # Table II line 6: alarm if g_k > rho_th (latched until recalibrate)
        if w.alarm_t_ns is None and w.g_m > w.threshold_m:
            w.alarm_t_ns = t_ns

    def _detect_common(
        self, t_ns: int, names: Sequence[str], active: Sequence[bool], dt: float
    ) -> None:
        """Common-mode channel: CUSUM on the mean decrease of all covered wheels."""
        cfg = self.config
        c = self._common
        calibrated = [n for n, w in self._wheels.items() if w.calibrated_m is not None]
        present = {n for n, a in zip(names, active, strict=True) if a}
        # needs >= 2 calibrated wheels, every one of them in this sample; otherwise hold
        if dt <= 0.0 or len(calibrated) < 2 or not present.issuperset(calibrated):
            return
        decreases = []
        for n in calibrated:
            w = self._wheels[n]
            ref = w.common_calibrated_m if w.common_calibrated_m is not None else w.calibrated_m
            if ref is None or w.last_estimate_m is None:
                return
            decreases.append(ref - w.last_estimate_m)
        c.wheel_names = tuple(sorted(calibrated, key=WHEEL_INDEX.__getitem__))
        # c_k = mean_j (mu_cal2_j - mu_{j,k})
        x = sum(decreases) / len(decreases)
        c.raw_m = x
        # cbar_k = LP_tau2 rate limit(c_k); G_k = max(0, G_{k-1} + (cbar_k - nu2) dt / T_ref)
        _cusum_step(c, x, dt, cfg.common_lowpass_time_constant_s, cfg.rate_limit_m_s,
                    cfg.common_drift_m, cfg.reference_sample_period_s)  # fmt: skip
        # alarm when G_k > rho2 (latched until recalibrate); not once a wheel alarm is latched:
        # the warning is on already and names the tyre
        wheel_alarm = any(w.alarm_t_ns is not None for w in self._wheels.values())
        if c.alarm_t_ns is None and not wheel_alarm and c.g_m > cfg.common_threshold_m:
            c.alarm_t_ns = t_ns

    def _threshold(self, std_m: float) -> float:
        cfg = self.config
        if not cfg.adaptive_threshold:
            return cfg.threshold_m
        factor = min(cfg.adaptive_max_factor, max(1.0, std_m / cfg.adaptive_reference_std_m))
        return cfg.threshold_m * factor

    def _wheel_progress(self, w: _Wheel) -> float:
        if w.calibrated_m is not None:
            return 1.0
        if self.config.calibration_time_s <= 0.0:
            return 0.0
        return min(1.0, w.calib_time_s / self.config.calibration_time_s)

    def _level(self, w: _Wheel, now_ns: int | None) -> Level:
        if w.alarm_t_ns is not None:
            return Level.ALARM
        timeout_ns = self.config.stale_timeout_s * 1e9
        if now_ns is not None and (w.last_seen_ns is None or now_ns - w.last_seen_ns > timeout_ns):
            return Level.STALE
        if w.calibrated_m is not None and w.g_m > self.config.warn_fraction * w.threshold_m:
            return Level.WARN
        return Level.OK

    def _status(self, now_ns: int | None, accepted: bool) -> DeflationStatusData:
        entries = []
        for name in sorted(self._wheels, key=WHEEL_INDEX.__getitem__):
            w = self._wheels[name]
            entries.append(
                WheelDeflationData(
                    wheel_name=name,
                    level=self._level(w, now_ns),
                    radius_change_m=w.xbar_m,
                    raw_radius_change_m=w.raw_m,
                    cusum_m=w.g_m,
                    threshold_m=w.threshold_m,
                    alarm=w.alarm_t_ns is not None,
                    alarm_t_ns=w.alarm_t_ns,
                    calibrated=w.calibrated_m is not None,
                    calibrated_radius_error_m=w.calibrated_m,
                    calibration_t_ns=w.calibration_t_ns,
                    calibration_progress=self._wheel_progress(w),
                    last_estimate_t_ns=w.last_seen_ns,
                )
            )
        progress = min((e.calibration_progress for e in entries), default=0.0)
        c = self._common
        common = (
            CommonChannelData(
                wheel_names=c.wheel_names,
                radius_change_m=c.xbar_m,
                raw_radius_change_m=c.raw_m,
                cusum_m=c.g_m,
                threshold_m=self.config.common_threshold_m,
                alarm=c.alarm_t_ns is not None,
                alarm_t_ns=c.alarm_t_ns,
            )
            if self.config.common_channel
            else None
        )
        return DeflationStatusData(
            t_ns=now_ns,
            accepted=accepted,
            calibration_state=self.calibration_state,
            calibration_progress=progress,
            calibrated_driving_time_s=self._driving_time_s,
            wheels=tuple(entries),
            any_alarm=any(e.alarm for e in entries) or (common is not None and common.alarm),
            common=common,
        )


@dataclass(frozen=True)
class TraceResult:
    """Output of :func:`run_detector_over_trace`; arrays are ``(K,)`` or ``(K, W)``.

    Entries of a wheel the detector has not seen yet, and of dropped rows, are NaN; the
    ``common_*`` arrays are NaN throughout unless ``config.common_channel``.
    """

    # (wheel, alarm t_ns), in time order; a common-channel alarm has wheel ALL_WHEELS
    alarms: list[tuple[str, int]]
    wheel_names: tuple[str, ...]
    t_ns: np.ndarray
    cusum_m: np.ndarray
    threshold_m: np.ndarray
    radius_change_m: np.ndarray
    calibration_state: np.ndarray  # (K,) int, CalibrationState values
    calibration_done_t_ns: int | None
    stats: dict[str, int]
    common_cusum_m: np.ndarray  # (K,)
    common_threshold_m: np.ndarray  # (K,)
    common_radius_change_m: np.ndarray  # (K,)


def run_detector_over_trace(
    config: DeflationDetectorConfig,
    t_ns: Sequence[int] | np.ndarray,
    wheel_names: Sequence[str],
    radius_error_m: np.ndarray,
    radius_error_std_m: np.ndarray,
    speed_m_s: np.ndarray,
    braking: np.ndarray,
    active: np.ndarray | None = None,
) -> TraceResult:
    """Run a fresh :class:`DeflationDetector` offline over a trace of radius estimates.

    ``radius_error_m``, ``radius_error_std_m`` (and ``active``, default all True) are ``(K, W)``
    with columns in ``wheel_names`` order; ``t_ns``, ``speed_m_s`` (NaN = unknown) and
    ``braking`` are ``(K,)``. A wheel whose value or std is NaN in a row is left out of that row.
    """
    times = np.asarray(t_ns, dtype=np.int64).reshape(-1)
    mu = np.asarray(radius_error_m, dtype=float)
    std = np.asarray(radius_error_std_m, dtype=float)
    speed = np.asarray(speed_m_s, dtype=float).reshape(-1)
    brake = np.asarray(braking, dtype=bool).reshape(-1)
    names = tuple(wheel_names)
    k, n_w = len(times), len(names)
    act = np.ones((k, n_w), dtype=bool) if active is None else np.asarray(active, dtype=bool)
    for label, arr, shape in (
        ("radius_error_m", mu, (k, n_w)),
        ("radius_error_std_m", std, (k, n_w)),
        ("active", act, (k, n_w)),
        ("speed_m_s", speed, (k,)),
        ("braking", brake, (k,)),
    ):
        if arr.shape != shape:
            raise InputError("wrong_shape", f"{label} has shape {arr.shape}, expected {shape}")
    detector = DeflationDetector(config)
    cusum = np.full((k, n_w), np.nan)
    threshold = np.full((k, n_w), np.nan)
    change = np.full((k, n_w), np.nan)
    common_g = np.full(k, np.nan)
    common_th = np.full(k, np.nan)
    common_change = np.full(k, np.nan)
    calib = np.zeros(k, dtype=int)
    alarms: list[tuple[str, int]] = []
    alarmed: set[str] = set()
    done_t: int | None = None
    for i in range(k):
        cols = [j for j in range(n_w) if math.isfinite(mu[i, j]) and math.isfinite(std[i, j])]
        sp = float(speed[i]) if math.isfinite(speed[i]) else None
        status = detector.step(
            int(times[i]),
            [names[j] for j in cols],
            [float(mu[i, j]) for j in cols],
            [float(std[i, j]) for j in cols],
            [bool(act[i, j]) for j in cols],
            sp,
            bool(brake[i]),
        )
        calib[i] = int(status.calibration_state)
        if done_t is None and status.calibration_state == CalibrationState.DONE:
            done_t = int(times[i])
        if not status.accepted:
            continue
        for entry in status.wheels:
            j = names.index(entry.wheel_name)
            cusum[i, j] = entry.cusum_m
            threshold[i, j] = entry.threshold_m
            change[i, j] = entry.radius_change_m
            if entry.alarm and entry.wheel_name not in alarmed and entry.alarm_t_ns is not None:
                alarmed.add(entry.wheel_name)
                alarms.append((entry.wheel_name, entry.alarm_t_ns))
        c = status.common
        if c is not None:
            common_g[i], common_th[i] = c.cusum_m, c.threshold_m
            common_change[i] = c.radius_change_m
            if c.alarm and ALL_WHEELS not in alarmed and c.alarm_t_ns is not None:
                alarmed.add(ALL_WHEELS)
                alarms.append((ALL_WHEELS, c.alarm_t_ns))
    return TraceResult(
        alarms=alarms,
        wheel_names=names,
        t_ns=times,
        cusum_m=cusum,
        threshold_m=threshold,
        radius_change_m=change,
        calibration_state=calib,
        calibration_done_t_ns=done_t,
        stats=dict(detector.stats),
        common_cusum_m=common_g,
        common_threshold_m=common_th,
        common_radius_change_m=common_change,
    )
