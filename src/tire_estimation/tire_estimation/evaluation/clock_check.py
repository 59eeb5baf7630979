"""Are the GNSS and the wheel speeds stamped by one clock? The lag that aligns the receiver's
speed with the wheels'.

The radius model compares each fix with the wheel odometry of the fix's stamp, so a clock
offset between the two streams (a receiver stamping in GPS time, seconds from UTC; two
computers without time sync) makes every comparison wrong. A fraction of a second is a latency
the sensor agreement sizes (:mod:`.agreement`); seconds are beyond its reach. This check bins
the speed of the receiver's Doppler velocity and the rear wheels' mean speed (nominal radius)
in :data:`BIN_S` bins by stamp and finds the lag, within :data:`MAX_LAG_S`, of the highest
correlation of the two speed profiles.
"""

from __future__ import annotations

import math
from typing import Any

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

_BIN_NS = round(BIN_S * 1e9)


class ClockCheck:
    """Pipeline observer: the binned speed profiles, and :meth:`result` after the run."""

    def __init__(self, nominal_radius_m: float) -> None:
        self._radius_m = nominal_radius_m
        # bin index -> [sum, count]
        self._wheel: dict[int, list[float]] = {}
        self._gnss: dict[int, list[float]] = {}
        self._last_wheel_bin: int | None = None

    def on_sample(self, pipeline: Any, sample: Any, result: Any) -> None:
        """Bin the first wheel-speed sample of each bin (mean rear speed; the wheel speeds are
        smooth against a bin) or every GNSS velocity (horizontal speed)."""
        kind = type(sample)
        if kind is WheelSpeeds:
            cell_index = sample.t_ns // _BIN_NS
            if cell_index == self._last_wheel_bin:
                return
            self._last_wheel_bin = cell_index
            w = sample.wheel_speed_rad_s.tolist()
            speed = 0.5 * self._radius_m * (abs(w[2]) + abs(w[3]))
            bins = self._wheel
        elif kind is GnssVelocity:
            cell_index = sample.t_ns // _BIN_NS
            v = sample.velocity_enu_m_s.tolist()
            speed = math.hypot(v[0], v[1])
            bins = self._gnss
        else:
            return
        if not math.isfinite(speed):
            return
        cell = bins.setdefault(cell_index, [0.0, 0.0])
        cell[0] += speed
        cell[1] += 1.0

    def on_output(self, pipeline: Any, output: Any) -> None:
        """Outputs are not read."""

    def result(self) -> dict[str, Any]:
        """``lag_s`` (positive: the GNSS stamps late against the wheels'), the correlation there
        and at no lag, and ``offset`` (a clock offset: at least :data:`FLAG_LAG_S` with a
        correlation of at least :data:`MIN_CORRELATION`); ``lag_s`` None when the profiles do
        not overlap enough (no GNSS velocity, a short drive, no speed change)."""
        none = {"lag_s": None, "correlation": None, "correlation_at_zero": None, "offset": False}
        if not self._wheel or not self._gnss:
            return none
        lo = min(min(self._wheel), min(self._gnss))
        hi = max(max(self._wheel), max(self._gnss))
        wheel = _profile(self._wheel, lo, hi)
        gnss = _profile(self._gnss, lo, hi)
        max_lag = round(MAX_LAG_S / BIN_S)
        best: tuple[float, int] | None = None
        at_zero = None
        for lag in range(-max_lag, max_lag + 1):
            # gnss(t) against wheel(t - lag): the GNSS describes what the wheels did lag earlier
            if lag >= 0:
                c = _correlation(gnss[lag:], wheel[: wheel.size - lag])
            else:
                c = _correlation(gnss[: gnss.size + lag], wheel[-lag:])
            if c is None:
                continue
            if lag == 0:
                at_zero = c
            if best is None or c > best[0]:
                best = (c, lag)
        if best is None:
            return none
        corr, lag = best
        lag_s = lag * BIN_S
        return {
            "lag_s": lag_s,
            "correlation": corr,
            "correlation_at_zero": at_zero,
            "offset": bool(abs(lag_s) >= FLAG_LAG_S and corr >= MIN_CORRELATION),
        }


def _profile(bins: dict[int, list[float]], lo: int, hi: int) -> np.ndarray:
    """Mean per bin from ``lo`` to ``hi``, NaN where a bin is empty."""
    out = np.full(hi - lo + 1, np.nan)
    for k, (total, count) in bins.items():
        out[k - lo] = total / count
    return out


def _correlation(a: np.ndarray, b: np.ndarray) -> float | None:
    """Pearson correlation of the pairs where both are finite (None: under :data:`MIN_PAIRS`
    pairs, or a constant profile)."""
    n = min(a.size, b.size)
    a, b = a[:n], b[:n]
    ok = np.isfinite(a) & np.isfinite(b)
    if int(ok.sum()) < MIN_PAIRS:
        return None
    x, y = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    den = math.sqrt(float(x @ x) * float(y @ y))
    return float(x @ y) / den if den > 0.0 else None
