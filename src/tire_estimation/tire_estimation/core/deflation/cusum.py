"""State of the deflation detector per wheel and of its common channel, the CUSUM step of
Lundquist et al. 2014 (Table II) on it, and the checks that restore it from a saved state."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tire_estimation.core.wheels import WHEEL_INDEX
from tire_estimation.errors import InputError


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
    def from_dict(cls, data: Mapping[str, Any]) -> WheelState:
        w = cls()
        for key in cls._PERSISTED:
            value = data.get(key)
            if key in ("calibrated_m", "common_calibrated_m", "last_estimate_m"):
                setattr(w, key, None if value is None else finite_float(key, value))
            elif key in ("calibration_t_ns", "alarm_t_ns"):
                setattr(w, key, optional_int(key, value))
            else:
                setattr(w, key, 0.0 if value is None else finite_float(key, value))
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
    def from_dict(cls, data: Mapping[str, Any]) -> CommonState:
        names = data.get("wheel_names", [])
        if not isinstance(names, (list, tuple)) or any(n not in WHEEL_INDEX for n in names):
            raise InputError("bad_state", f"saved common channel has bad wheels {names!r}")
        c = cls(wheel_names=tuple(str(n) for n in names))
        for key in ("lp_m", "xbar_m", "raw_m", "g_m"):
            value = data.get(key)
            setattr(c, key, 0.0 if value is None else finite_float(key, value))
        c.alarm_t_ns = optional_int("alarm_t_ns", data.get("alarm_t_ns"))
        return c


def optional_int(key: str, value: Any) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not an integer")
    return value


def finite_float(key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not a number")
    out = float(value)
    if not math.isfinite(out):
        raise InputError("bad_state", f"saved detector state {key}={value!r} is not finite")
    return out


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
