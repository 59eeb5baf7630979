"""Are the GNSS and the wheel speeds stamped by one clock? The lag that aligns the receiver's
speed with the wheels'.

The radius model compares each fix with the wheel odometry of the fix's stamp, so a clock
offset between the two streams (a receiver stamping in GPS time, seconds from UTC; two
computers without time sync) makes every comparison wrong. A fraction of a second is a latency
the sensor agreement sizes (:mod:`.agreement`); seconds are beyond its reach. This check bins
the speed of the receiver's Doppler velocity and the rear wheels' mean speed (nominal radius)
in :data:`BIN_S` bins by stamp and finds the lag, within :data:`MAX_LAG_S`, of the highest
correlation of the two speed profiles, the GNSS profile interpolated at the wheel profile's
stamps plus the lag (refined to :data:`FINE_STEP_S` around a lag of a bin or more).

The replay runs it twice: over the first :data:`LEADING_S` of the bag before the estimation
(:func:`leading_check`; a lag found there is taken out of the GNSS stamps, the drive estimated
on one clock) and over the whole drive, as estimated, for the report. The node runs it over its
first :data:`LEADING_S` (:class:`LeadingClockCheck`) and reports an offset on ``/diagnostics``;
it cannot take it out (that would hold every estimate back by the offset).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any, ClassVar

import numpy as np

from tire_estimation.core.samples import GnssVelocity, WheelSpeeds

#: bin of the speed profiles, s
BIN_S = 0.5
#: lags scanned each way, s
MAX_LAG_S = 30.0
#: a lag of at least this is a clock offset, not a latency, s
FLAG_LAG_S = 1.0
#: ... when the profiles correlate at least this well there
MIN_CORRELATION = 0.9
#: pairs of bins a lag needs to be judged
MIN_PAIRS = 120
#: stamps the replay checks before the estimation, s from the first
LEADING_S = 300.0
#: step of the refinement of a lag of a bin or more, s
FINE_STEP_S = 0.01
#: the GNSS speed is interpolated between bins at most this far apart, s
GAP_S = 1.5

_BIN_NS = round(BIN_S * 1e9)


class ClockCheck:
    """Pipeline observer: the speed profiles, and :meth:`result` after the run."""

    SAMPLE_KINDS: ClassVar[tuple[type, ...]] = (WheelSpeeds, GnssVelocity)

    def __init__(self, nominal_radius_m: float) -> None:
        self._radius_m = nominal_radius_m
        self._t0_ns: int | None = None
        # wheel bin index -> (stamp since the first one s, speed m/s) of its first sample
        self._wheel: dict[int, tuple[float, float]] = {}
        # GNSS bin index -> [sum of stamps s, sum of speeds m/s, count]
        self._gnss: dict[int, list[float]] = {}
        self._last_wheel_bin: int | None = None

    def on_sample(self, pipeline: Any, sample: Any, result: Any) -> None:
        """Keep the first wheel-speed sample of each bin (mean rear speed; the wheel speeds are
        smooth against a bin) and the mean stamp and speed of the GNSS velocities of each bin
        (the profiles are compared at their own stamps, so the bins' sampling cancels)."""
        kind = type(sample)
        if kind is WheelSpeeds and sample.t_ns // _BIN_NS == self._last_wheel_bin:
            return  # the common case: a wheel bin already has its sample
        if kind is not WheelSpeeds and kind is not GnssVelocity:
            return
        t_ns = sample.t_ns
        if self._t0_ns is None:
            self._t0_ns = t_ns
        cell_index = t_ns // _BIN_NS
        t_s = (t_ns - self._t0_ns) * 1e-9
        if kind is WheelSpeeds:
            self._last_wheel_bin = cell_index
            if cell_index in self._wheel:
                return
            w = sample.wheel_speed_rad_s.tolist()
            speed = 0.5 * self._radius_m * (abs(w[2]) + abs(w[3]))
            if math.isfinite(speed):
                self._wheel[cell_index] = (t_s, speed)
            return
        v = sample.velocity_enu_m_s.tolist()
        speed = math.hypot(v[0], v[1])
        if math.isfinite(speed):
            cell = self._gnss.setdefault(cell_index, [0.0, 0.0, 0.0])
            cell[0] += t_s
            cell[1] += speed
            cell[2] += 1.0

    def on_output(self, pipeline: Any, output: Any) -> None:
        """Outputs are not read."""

    def result(self) -> dict[str, Any]:
        """``lag_s`` (positive: the GNSS stamps late against the wheels'), the correlation there
        and at no lag, and ``offset`` (a clock offset: at least :data:`FLAG_LAG_S` with a
        correlation of at least :data:`MIN_CORRELATION`); ``lag_s`` None when the profiles do
        not overlap enough (no GNSS velocity, a short drive, no speed change). A lag of a bin
        or more is refined to :data:`FINE_STEP_S` (a lag under a bin is a latency, for the
        sensor agreement to size)."""
        none = {"lag_s": None, "correlation": None, "correlation_at_zero": None, "offset": False}
        if not self._wheel or not self._gnss:
            return none
        wheel = np.array([self._wheel[k] for k in sorted(self._wheel)])
        cells = np.array([self._gnss[k] for k in sorted(self._gnss)])
        gnss_t, gnss_v = cells[:, 0] / cells[:, 2], cells[:, 1] / cells[:, 2]

        def corr_at(lag_s: float) -> float | None:
            # gnss(t) against wheel(t - lag): the GNSS speed interpolated at the wheel bins'
            # stamps plus the lag, where GNSS bins lie on both sides within GAP_S
            tq = wheel[:, 0] + lag_s
            i = np.searchsorted(gnss_t, tq)
            inside = (i > 0) & (i < gnss_t.size)
            i = np.clip(i, 1, gnss_t.size - 1)
            ok = inside & (gnss_t[i] - gnss_t[i - 1] <= GAP_S)
            return _correlation(np.interp(tq[ok], gnss_t, gnss_v), wheel[ok, 1])

        scanned = {
            lag: c
            for lag in np.arange(-MAX_LAG_S, MAX_LAG_S + 0.5 * BIN_S, BIN_S).round(6).tolist()
            if (c := corr_at(lag)) is not None
        }
        if not scanned:
            return none
        lag_s = max(scanned, key=lambda k: scanned[k])
        corr = scanned[lag_s]
        if abs(lag_s) >= BIN_S:
            for fine in np.arange(lag_s - BIN_S, lag_s + BIN_S, FINE_STEP_S).tolist():
                c = corr_at(fine)
                if c is not None and c > corr:
                    lag_s, corr = fine, c
        return {
            "lag_s": round(lag_s, 3),
            "correlation": corr,
            "correlation_at_zero": scanned.get(0.0),
            "offset": bool(abs(lag_s) >= FLAG_LAG_S and corr >= MIN_CORRELATION),
        }


def _correlation(a: np.ndarray, b: np.ndarray) -> float | None:
    """Pearson correlation of the pairs (None: under :data:`MIN_PAIRS` pairs, or a constant
    profile)."""
    if a.size < MIN_PAIRS:
        return None
    x, y = a - a.mean(), b - b.mean()
    den = math.sqrt(float(x @ x) * float(y @ y))
    return float(x @ y) / den if den > 0.0 else None


class LeadingClockCheck:
    """Pipeline observer: :class:`ClockCheck` over the samples of the first :data:`LEADING_S`
    after the first stamp, decided once (:attr:`result`); nothing is kept after that (the
    node's check, in bounded memory)."""

    def __init__(self, nominal_radius_m: float) -> None:
        self._check: ClockCheck | None = ClockCheck(nominal_radius_m)
        self._end_ns: int | None = None
        #: :meth:`ClockCheck.result` once the first LEADING_S have passed, else None
        self.result: dict[str, Any] | None = None

    def on_sample(self, pipeline: Any, sample: Any, result: Any) -> None:
        """Bin the sample while within the first LEADING_S; decide at the first one after."""
        check = self._check
        if check is None:
            return
        if self._end_ns is None:
            self._end_ns = sample.t_ns + round(LEADING_S * 1e9)
        elif sample.t_ns > self._end_ns:
            self.finish()
            return
        check.on_sample(pipeline, sample, result)

    def on_output(self, pipeline: Any, output: Any) -> None:
        """Outputs are not read."""

    def finish(self) -> dict[str, Any]:
        """Decide now (a drive shorter than LEADING_S) unless decided; the result."""
        if self.result is None and self._check is not None:
            self.result = self._check.result()
            self._check = None
        assert self.result is not None
        return self.result


def leading_check(samples: Iterable[Any], nominal_radius_m: float) -> dict[str, Any]:
    """:meth:`ClockCheck.result` over the samples (wheel speeds and GNSS velocities, in stamp
    order) of the first :data:`LEADING_S` after the first stamp; reads no further."""
    lead = LeadingClockCheck(nominal_radius_m)
    for sample in samples:
        lead.on_sample(None, sample, None)
        if lead.result is not None:
            break
    return lead.finish()
