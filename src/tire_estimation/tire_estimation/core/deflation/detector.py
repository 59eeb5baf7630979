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

The configuration is in :mod:`.config`, the per-wheel state and the CUSUM step in :mod:`.cusum`,
the calibration phase in :mod:`.calibration`, the input and status types in :mod:`.status`;
:func:`.trace.run_detector_over_trace` runs the detector offline over arrays of estimates (for
the ECE R-64 campaign).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from tire_estimation.core import state_checks as checks
from tire_estimation.core.deflation.calibration import calibrate, wheel_progress
from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.cusum import (
    RADIUS_CHANGE_FACTOR,
    CommonState,
    StateLimits,
    WheelState,
    cusum_step,
)
from tire_estimation.core.deflation.status import (
    CalibrationState,
    CommonChannelData,
    DeflationStatusData,
    Level,
    RadiusErrors,
    WheelDeflationData,
)
from tire_estimation.core.wheels import WHEEL_INDEX, WHEELS
from tire_estimation.errors import InputError

STATE_VERSION = 1
#: keys of :attr:`DeflationDetector.stats` that count events, not dropped samples
INFO_STATS = frozenset({"accepted", "no_speed", "recalibrations"})


class DeflationDetector:
    """Per-wheel calibration + CUSUM deflation detector over radius-error estimates."""

    def __init__(
        self,
        config: DeflationDetectorConfig | None = None,
        nominal_tire_radius_m: float | None = None,
    ) -> None:
        self.config = config if config is not None else DeflationDetectorConfig()
        #: largest plausible |radius error| of a restored state, m (from the vehicle's nominal
        #: radius; the largest a vehicle description allows when not given)
        self.radius_error_limit_m = checks.radius_error_limit_m(nominal_tire_radius_m)
        self.stats: Counter[str] = Counter()
        self._wheels: dict[str, WheelState] = {}
        self._common = CommonState()
        self._driving_time_s = 0.0
        self._t_prev_ns: int | None = None
        self._t_resume_ns: int | None = None  # last sample time before a restore

    # --- public API -----------------------------------------------------------------------
    def step(
        self, radii: RadiusErrors, speed_m_s: float | None, braking: bool
    ) -> DeflationStatusData:
        """Consume one radius estimate; return the status at its stamp.

        ``speed_m_s`` None means unknown (the sample then only refreshes the staleness clock).
        A bad sample is dropped and counted in :attr:`stats`; never raises.
        """
        try:
            t, names, mu, std, act, speed = self._validate(radii, speed_m_s)
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
        detect: list[tuple[WheelState, float, float]] = []
        for name, m, s, a in zip(names, mu, std, act, strict=True):
            w = self._wheels.setdefault(name, WheelState(threshold_m=self.config.threshold_m))
            w.last_seen_ns = t
            w.last_estimate_m = m
            if not (valid and a and dt > 0.0):
                continue
            if w.calibrated_m is None:
                calibrate(w, self.config, t, m, dt)
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

    def latched_alarms(self) -> tuple[set[str], bool]:
        """The wheels whose alarm is latched and whether the common channel's is: the
        ``alarm`` flags of :meth:`status`, without making the status."""
        wheels = {name for name, w in self._wheels.items() if w.alarm_t_ns is not None}
        return wheels, self.config.common_channel and self._common.alarm_t_ns is not None

    def recalibrate(self) -> None:
        """Forget calibration, CUSUM sums and latched alarms; start a new calibration."""
        for name, old in self._wheels.items():
            fresh = WheelState(threshold_m=self.config.threshold_m)
            fresh.last_seen_ns = old.last_seen_ns
            fresh.last_estimate_m = old.last_estimate_m
            self._wheels[name] = fresh
        self._common = CommonState()
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
        """Restore :meth:`state_dict` output; raises InputError (kind ``bad_state``) naming the
        value if malformed or not plausible (calibrated values and estimates within
        :attr:`radius_error_limit_m`, the radius changes within ``RADIUS_CHANGE_FACTOR`` times
        it, times and weights consistent, CUSUM sums within what the saved driving time can
        accumulate); nothing changes then.

        Sample ordering and staleness restart with the next sample, so a restarted node accepts
        stamps older than those before the restart (e.g. a bag replayed again); a sample newer
        than the saved last one is credited the driving time since it (at most
        ``max_sample_gap_s``), so a save/restore continues exactly.
        """
        k = "bad_state"
        checks.require_keys(
            k, "saved detector state", state, ("version", "wheels"),
            ("driving_time_s", "t_last_ns", "common"),
        )  # fmt: skip
        checks.choice(k, "saved detector state version", state["version"], STATE_VERSION)
        raw_wheels = state["wheels"]
        if not isinstance(raw_wheels, Mapping):
            raise InputError(k, "saved detector state has no wheels mapping")
        driving = checks.bounded(
            k, "driving_time_s", state.get("driving_time_s", 0.0), 0.0, math.inf
        )
        # the CUSUM sums grow by at most the largest radius change per reference period of
        # counted driving
        change_m = RADIUS_CHANGE_FACTOR * self.radius_error_limit_m
        limits = StateLimits(
            radius_error_m=self.radius_error_limit_m,
            cusum_m=change_m * driving / self.config.reference_sample_period_s * (1.0 + 1e-9),
        )
        wheels: dict[str, WheelState] = {}
        for name, data in raw_wheels.items():
            if name not in WHEEL_INDEX:
                raise InputError(k, f"saved detector state has a bad wheel {checks.shown(name)}")
            try:
                wheels[name] = WheelState.from_dict(data, limits)
            except InputError as exc:
                raise InputError(k, f"{name}: {exc}") from exc
            if wheels[name].calib_time_s > driving * (1.0 + 1e-9) + 1e-9:
                raise InputError(
                    k,
                    f"{name}: calib_time_s={wheels[name].calib_time_s:g} exceeds "
                    f"driving_time_s={driving:g}",
                )
        # absent in states saved before the channel
        try:
            common = CommonState.from_dict(state.get("common", {}), limits)
        except InputError as exc:
            raise InputError(k, f"common: {exc}") from exc
        t_last = checks.stamp_ns(k, "t_last_ns", state.get("t_last_ns"))
        self._wheels = wheels
        self._common = common
        self._driving_time_s = driving
        self._t_prev_ns = None
        self._t_resume_ns = t_last

    # --- internals ------------------------------------------------------------------------
    def _validate(
        self, radii: RadiusErrors, speed_m_s: Any
    ) -> tuple[int, list[str], list[float], list[float], list[bool], float | None]:
        try:
            if isinstance(radii.t_ns, bool):
                raise TypeError
            t = int(radii.t_ns)
            names = [str(n) for n in radii.wheel_names]
            mu = [float(v) for v in radii.radius_error_m]
            std = [float(v) for v in radii.radius_error_std_m]
            act = [bool(v) for v in radii.active]
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

    def _detect(self, w: WheelState, t_ns: int, x: float, std_m: float, dt: float) -> None:
        """CUSUM of Table II on ``x``, the radius decrease since calibration, m."""
        cfg = self.config
        w.raw_m = x
        cusum_step(w, x, dt, cfg.lowpass_time_constant_s, cfg.rate_limit_m_s, cfg.drift_m,
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
        cusum_step(c, x, dt, cfg.common_lowpass_time_constant_s, cfg.rate_limit_m_s,
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

    def _level(self, w: WheelState, now_ns: int | None) -> Level:
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
                    calibration_progress=wheel_progress(w, self.config),
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
