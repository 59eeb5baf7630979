"""State of the deflation detector per wheel and of its common channel, the CUSUM step of
Lundquist et al. 2014 (Table II) on it, and the checks that restore it from a saved state."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tire_estimation.core import state_checks as checks
from tire_estimation.core.wheels import WHEEL_INDEX
from tire_estimation.errors import InputError

#: keys of :class:`WheelState` that may be None (not calibrated, no estimate yet)
_OPTIONAL = ("calibrated_m", "common_calibrated_m", "last_estimate_m")
#: relative tolerance of the consistency checks of a restored state (float rounding)
_REL_TOL = 1e-9
#: A radius change the CUSUM filters (``x_j - lambda mean_{k != j} x_k``, x a difference of
#: two radius errors) is at most this many times the largest radius error.
RADIUS_CHANGE_FACTOR = 4.0


@dataclass(frozen=True)
class StateLimits:
    """Plausible values of a saved detector state.

    Attributes:
        radius_error_m: largest |radius error| (a calibrated value, the last estimate), m
            (:func:`~tire_estimation.core.state_checks.radius_error_limit_m`).
        cusum_m: largest CUSUM sum, m: the largest radius change accumulated over the saved
            driving time in reference sample periods.
    """

    radius_error_m: float
    cusum_m: float

    def range_of(self, key: str) -> tuple[float, float]:
        """``[low, high]`` of a float of the saved state."""
        if key in _OPTIONAL:
            return -self.radius_error_m, self.radius_error_m
        if key in ("lp_m", "xbar_m", "raw_m"):
            change = RADIUS_CHANGE_FACTOR * self.radius_error_m
            return -change, change
        if key == "g_m":
            return 0.0, self.cusum_m
        if key.endswith("_sum_wx"):
            return -math.inf, math.inf  # checked against its weights
        return 0.0, math.inf  # times, time weights, thresholds


@dataclass
class WheelState:
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
    def from_dict(cls, data: Mapping[str, Any], limits: StateLimits) -> WheelState:
        """The saved state of one wheel; raises InputError (kind ``bad_state``) naming a value
        that is malformed or not plausible (:class:`StateLimits`). A missing key takes its
        default (states saved before the key existed)."""
        checks.require_keys("bad_state", "saved wheel", data, (), cls._PERSISTED)
        w = cls()
        for key in cls._PERSISTED:
            value = data.get(key)
            if key in ("calibration_t_ns", "alarm_t_ns"):
                setattr(w, key, checks.stamp_ns("bad_state", key, value))
            elif value is None and key in _OPTIONAL:
                setattr(w, key, None)
            elif value is not None:
                setattr(w, key, checks.bounded("bad_state", key, value, *limits.range_of(key)))
        for weights, sums in (("calib_sum_w", "calib_sum_wx"), ("common_sum_w", "common_sum_wx")):
            total = getattr(w, weights)
            # time weights of the calibration: each at most the driving time it credits
            if total > w.calib_time_s * (1.0 + _REL_TOL) + _REL_TOL:
                raise InputError(
                    "bad_state", f"{weights}={total:g} exceeds calib_time_s={w.calib_time_s:g}"
                )
            # the weighted sum of estimates: a mean within the radius-error limit
            if abs(getattr(w, sums)) > limits.radius_error_m * total * (1.0 + _REL_TOL):
                raise InputError(
                    "bad_state",
                    f"{sums}={getattr(w, sums):g} is not a mean within "
                    f"+-{limits.radius_error_m:g} m over {weights}={total:g}",
                )
        return w


@dataclass
class CommonState:
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
    def from_dict(cls, data: Mapping[str, Any], limits: StateLimits) -> CommonState:
        """The saved common channel; raises InputError (kind ``bad_state``) as
        :meth:`WheelState.from_dict`."""
        keys = ("wheel_names", "lp_m", "xbar_m", "raw_m", "g_m", "alarm_t_ns")
        checks.require_keys("bad_state", "saved common channel", data, (), keys)
        names = data.get("wheel_names", [])
        if not isinstance(names, (list, tuple)) or any(
            not isinstance(n, str) or n not in WHEEL_INDEX for n in names
        ):
            raise InputError(
                "bad_state", f"saved common channel has bad wheels {checks.shown(names)}"
            )
        c = cls(wheel_names=tuple(names))
        for key in ("lp_m", "xbar_m", "raw_m", "g_m"):
            value = data.get(key)
            if value is not None:
                setattr(c, key, checks.bounded("bad_state", key, value, *limits.range_of(key)))
        c.alarm_t_ns = checks.stamp_ns("bad_state", "alarm_t_ns", data.get("alarm_t_ns"))
        return c


def cusum_step(
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
