"""Checks of the estimator's input samples and of its outputs (finite values, shapes).

Bad input raises :class:`~tire_estimation.errors.InputError` (or TypeError / ValueError); the
estimator drops the sample and counts it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.wheels import WHEEL_INDEX
from tire_estimation.errors import InputError

_SHORT = {"fl": 0, "fr": 1, "rl": 2, "rr": 3}


def finite(kind: str, *values: float) -> None:
    """Raise InputError (kind ``nan``) unless every value is finite."""
    # fast path: a sum is finite when every term is (a finite sum that overflows is checked
    # term by term below)
    total = sum(values)
    if total - total == 0.0:
        return
    for v in values:
        if not math.isfinite(v):
            raise InputError("nan", f"{kind}: non-finite value {v!r}")


def floats(values: Any) -> list[float]:
    """A flat list of Python floats from a sequence or array (raises TypeError/ValueError)."""
    if isinstance(values, np.ndarray) and values.dtype == np.float64:
        return values.ravel().tolist()  # type: ignore[no-any-return]
    if isinstance(values, np.ndarray):
        return [float(v) for v in values.reshape(-1).tolist()]
    return [float(v) for v in np.asarray(values, dtype=float).reshape(-1).tolist()]


def parse_wheels(wheel_speed_rad_s: Any) -> F64:
    """Wheel speeds (4,) fl, fr, rl, rr from a sequence or a mapping of wheel names. A wheel
    may be NaN (not reported, the ROS convention) when a rear wheel is not; infinities and
    two NaN rear wheels are errors (kind ``nan``)."""
    if isinstance(wheel_speed_rad_s, Mapping):
        vals = [math.nan] * 4
        for name, value in wheel_speed_rad_s.items():
            idx = WHEEL_INDEX.get(name, _SHORT.get(name))
            if idx is None:
                raise InputError("unknown_wheel", f"unknown wheel name {name!r}")
            vals[idx] = float(value)
        if len(wheel_speed_rad_s) != 4:
            raise InputError("wrong_length", f"need 4 wheels, got {len(wheel_speed_rad_s)}")
    else:
        vals = floats(wheel_speed_rad_s)
        if len(vals) != 4:
            raise InputError("wrong_length", f"need 4 wheel speeds, got {len(vals)}")
    known = [v for v in vals if not math.isnan(v)]
    finite("wheel speeds", *known)
    if math.isnan(vals[2]) and math.isnan(vals[3]):
        raise InputError("nan", f"wheel speeds: no rear wheel reported: {vals}")
    if max(known) > 1000.0 or min(known) < -1000.0:
        raise InputError("out_of_range", f"wheel speed above 1000 rad/s: {vals}")
    return np.array(vals)


def is_int(x: Any) -> bool:
    """An integer stamp (not a bool)."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def finite_or_zero(x: Any) -> float:
    """``float(x)``, 0 when not finite."""
    v = float(x)
    return v if math.isfinite(v) else 0.0


def sanitize(a: Any, fill: float = 0.0) -> F64:
    """``a`` as a float array with non-finite elements replaced by ``+-fill``."""
    out = np.array(a, dtype=float)
    # every element finite (the sum of Python floats of these few elements is cheaper than
    # NumPy's reductions; an overflowing sum is checked below)
    if math.isfinite(sum(out.ravel().tolist())):
        return out
    if np.isfinite(out).all():
        return out
    return np.nan_to_num(out, nan=fill, posinf=fill, neginf=-fill)
