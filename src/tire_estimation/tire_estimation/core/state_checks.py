"""Checks of a saved estimator state before it is restored.

A persisted state comes back from a file that a crash, a disk error or a hand edit may have
changed. Each estimator's ``load_state_dict`` reads every value through these checks before it
changes anything, so a rejected state leaves the estimator as it was; a check raises
:class:`~tire_estimation.errors.InputError` (of the estimator's ``kind``) naming the value and
the reason.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from typing import Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.validation import field_rules
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

#: Largest plausible radius error (effective minus nominal rolling radius) as a fraction of the
#: nominal radius: a worn tread (about -6 mm), a deflated tyre (a few mm), a nominal radius taken
#: from the tyre size (the Husky robot: -6.2 mm of 165 mm, 3.8 %) and one for another tyre size
#: than fitted (the radii rescaled by ``core/radius/speed_scale.py``) stay within it; beyond it
#: the wheel speeds' unit or a radius given as a diameter, not a radius error: a learned value is
#: a corrupt state, and the radii are not rescaled that far.
MAX_RADIUS_ERROR_FRACTION = 0.25
#: Smallest standard deviation a restored covariance may hold, as a fraction of the nominal
#: value of its quantity: below it the squares are at the rounding of a double, no learned
#: statistic.
MIN_STD_FRACTION = 1e-9
#: Largest restored inverse-Wishart degrees of freedom. The dof counts samples (``nu <- lambda
#: nu + 1``, at most ``1 / (1 - lambda)`` with forgetting); 1e9 is 115 days of 100 Hz samples
#: without forgetting. Far larger values overflow the scale ``noise_cov (nu - d - 1)``.
MAX_RESTORED_DOF = 1e9
#: Largest restored integer time stamp, ns (int64).
MAX_STAMP_NS = (1 << 63) - 1


def radius_error_limit_m(nominal_tire_radius_m: float | None = None) -> float:
    """Largest plausible |radius error|, m: :data:`MAX_RADIUS_ERROR_FRACTION` of the nominal
    radius, or of the largest nominal radius a vehicle description may give when unknown."""
    if nominal_tire_radius_m is None:
        high = field_rules(VehicleParams)["nominal_tire_radius_m"].high
        assert high is not None
        nominal_tire_radius_m = high
    return MAX_RADIUS_ERROR_FRACTION * float(nominal_tire_radius_m)


def shown(value: Any) -> str:
    """A short repr of a saved value for a message (huge numbers and long lists cut)."""
    try:
        text = repr(value)
    except ValueError:  # an int with more digits than Python prints
        return "<huge int>"
    return text if len(text) <= 60 else text[:57] + "..."


def require_keys(
    kind: str,
    what: str,
    data: Any,
    required: Collection[str],
    optional: Collection[str] = (),
) -> Mapping[str, Any]:
    """``data`` as a mapping holding every ``required`` key and no key outside both lists."""
    if not isinstance(data, Mapping):
        raise InputError(kind, f"{what} is not an object but {type(data).__name__}")
    missing = [k for k in required if k not in data]
    if missing:
        raise InputError(kind, f"{what} lacks {', '.join(missing)}")
    unknown = sorted(str(k) for k in data if k not in required and k not in optional)
    if unknown:
        raise InputError(kind, f"{what} has unknown keys {', '.join(unknown)}")
    return data


def number(kind: str, what: str, value: Any) -> float:
    """``value`` as a finite float (an int or a float, not a bool)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(kind, f"{what}={shown(value)} is not a number")
    try:
        out = float(value)
    except OverflowError as exc:
        raise InputError(kind, f"{what}={shown(value)} is too large") from exc
    if not math.isfinite(out):
        raise InputError(kind, f"{what}={shown(value)} is not finite")
    return out


def bounded(kind: str, what: str, value: Any, low: float, high: float) -> float:
    """``value`` as a finite float within ``[low, high]``."""
    out = number(kind, what, value)
    if not low <= out <= high:
        raise InputError(kind, f"{what}={out:g} is outside [{low:g}, {high:g}]")
    return out


def stamp_ns(kind: str, what: str, value: Any) -> int | None:
    """``value`` as an optional int time stamp within ``[0, MAX_STAMP_NS]``."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError(kind, f"{what}={shown(value)} is not an integer")
    if not 0 <= value <= MAX_STAMP_NS:
        raise InputError(kind, f"{what}={shown(value)} is outside [0, {MAX_STAMP_NS}]")
    return value


def vector(kind: str, what: str, value: Any, n: int, limit: float | None = None) -> F64:
    """``value`` as ``n`` finite floats, each with ``|x| <= limit`` when a limit is given."""
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise InputError(kind, f"{what}={shown(value)} is not a list of {n} numbers")
    out = np.array([number(kind, f"{what}[{i}]", v) for i, v in enumerate(value)])
    if limit is not None and np.any(np.abs(out) > limit):
        raise InputError(kind, f"{what}={out.tolist()} is outside +-{limit:g}")
    return out


def covariance(kind: str, what: str, value: Any, n: int, min_std: float, max_std: float) -> F64:
    """``value`` as a symmetric positive-definite ``(n, n)`` matrix whose standard deviations
    along its eigenvectors lie within ``[min_std, max_std]``."""
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise InputError(kind, f"{what}={shown(value)} is not a {n} x {n} matrix")
    a = np.array([vector(kind, f"{what}[{i}]", row, n) for i, row in enumerate(value)])
    scale = float(np.max(np.abs(a)))
    if float(np.max(np.abs(a - a.T))) > 1e-9 * scale:
        raise InputError(kind, f"{what} is not symmetric")
    a = 0.5 * (a + a.T)
    eig = np.linalg.eigvalsh(a)
    if not eig[0] > 0.0:
        raise InputError(kind, f"{what} is not positive definite (smallest eigenvalue {eig[0]:g})")
    # the bounds with the rounding of a saved and recomputed covariance
    if eig[0] < min_std**2 * (1.0 - 1e-9) or eig[-1] > max_std**2 * (1.0 + 1e-9):
        raise InputError(
            kind,
            f"{what} has standard deviations {math.sqrt(eig[0]):g} to {math.sqrt(eig[-1]):g} "
            f"outside [{min_std:g}, {max_std:g}]",
        )
    return a


def dof(kind: str, what: str, value: Any, d: int) -> float:
    """Inverse-Wishart degrees of freedom of dimension ``d``: finite, above ``d + 1`` (so that
    the expected covariance exists) and at most :data:`MAX_RESTORED_DOF`."""
    out = number(kind, what, value)
    if not d + 1.0 < out <= MAX_RESTORED_DOF:
        raise InputError(kind, f"{what}={out:g} is outside ({d + 1}, {MAX_RESTORED_DOF:g}]")
    return out


def choice(kind: str, what: str, value: Any, expected: object) -> None:
    """``value`` must equal ``expected`` (a version, a vehicle, a wheel order)."""
    if isinstance(value, bool) or value != expected:
        raise InputError(kind, f"{what}={shown(value)}, expected {expected!r}")
