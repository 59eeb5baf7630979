"""The per-sample checks every estimator applies to what it is handed (one implementation).

Samples that entered through :mod:`tire_estimation.core.samples` are already checked; the
estimators still guard their own state (stamp order per stream, vector length, finiteness)
because tests, benchmarks and studies call them directly. Each check raises
:class:`~tire_estimation.errors.InputError` with the ``kind`` the caller counts, as
``<stream>:<kind>`` (:func:`drop_key`). The checks of covariances and of repeated names are
shared by the node's message conversions, the bag reader and the estimators.
"""

from __future__ import annotations

import math
from collections.abc import Container, Mapping, Sequence
from typing import Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.errors import InputError


def is_int(x: Any) -> bool:
    """True for a Python or NumPy integer that is not a bool."""
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def stamp_after(stream: str, t_ns: Any, last_ns: int | None) -> int:
    """``t_ns`` as int when it is an integer stamp later than ``last_ns`` (None: the first);
    else ``bad_stamp``, ``duplicate`` or ``out_of_order``."""
    if type(t_ns) is int and (last_ns is None or t_ns > last_ns):
        return t_ns  # the common case, without the calls below
    if not is_int(t_ns):
        raise InputError("bad_stamp", f"{stream}: stamp must be an integer, got {t_ns!r}")
    t = int(t_ns)
    if last_ns is not None and t <= last_ns:
        kind = "duplicate" if t == last_ns else "out_of_order"
        raise InputError(kind, f"{stream}: stamp {t} not after {last_ns}")
    return t


_F64 = np.dtype(np.float64)


def finite_vector(value: Any, n: int, what: str) -> F64:
    """``value`` as a float vector of ``n`` finite entries; else ``wrong_length`` or ``nan``."""
    if type(value) is np.ndarray and value.dtype == _F64 and value.shape == (n,):
        # the common case: a float64 vector of n; finite when its sum is (a sum that
        # overflows is checked entry by entry below)
        total = sum(value.tolist())
        if total - total == 0.0:
            return value
    elif n == 1 and type(value) is float and value - value == 0.0:
        return np.array([value])
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (n,):
        raise InputError("wrong_length", f"{what}: need {n} values, got {v.shape[0]}")
    # (the few values as floats: cheaper than np.isfinite and np.all on a short vector)
    if not all(map(math.isfinite, v.tolist())):
        raise InputError("nan", f"{what}: non-finite value")
    return v


def drop_key(stream: str, kind: str) -> str:
    """The counter key of a dropped sample: ``<stream>:<kind>`` (``/diagnostics`` shows it as
    ``dropped.<stream>:<kind>``, ``metrics.json`` under ``dropped_samples``)."""
    return f"{stream}:{kind}"


def unique_names(names: Sequence[str], known: Container[str], kind: str) -> None:
    """Raise InputError ``kind`` (``duplicate_wheel``, ``duplicate_joint``) when one of the
    ``known`` names appears more than once in ``names`` (which value is meant is unknown)."""
    seen: set[str] = set()
    for name in names:
        if name in known:
            if name in seen:
                raise InputError(kind, f"{name!r} appears more than once in {list(names)}")
            seen.add(name)


#: relative tolerance of the symmetry and semi-definiteness checks of a covariance (rounding)
COVARIANCE_RTOL = 1e-9


#: largest variance accepted in a covariance (a std of 1000 km; larger is no measurement)
MAX_VARIANCE = 1e12


def checked_covariance(values: Any, what: str) -> F64 | None:
    """A covariance given as 9 (3x3) or 4 (2x2) values, row-major, first two axes horizontal
    (ENU east, north): the (dim, dim) matrix, or None when absent or all zero (ROS: not reported).

    Raises InputError ``wrong_length`` (another number of values) or ``bad_covariance``: a value
    not finite, the matrix not symmetric or not positive semi-definite, or its horizontal 2x2
    block not positive definite (the estimators invert it).
    """
    if values is None:
        return None
    try:
        flat = np.asarray(values, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise InputError("bad_covariance", f"{what}: {exc}") from exc
    dim = 3 if flat.size == 9 else 2 if flat.size == 4 else 0
    if dim == 0:
        raise InputError("wrong_length", f"{what}: need 9 (3x3) or 4 values, got {flat.size}")
    c = flat.tolist()
    total = sum(c)  # finite when every value is (a sum that overflows: checked one by one)
    if total - total != 0.0 and not all(map(math.isfinite, c)):
        raise InputError("bad_covariance", f"{what} is not finite: {c}")
    if not any(c):
        return None
    diag = [c[i * dim + i] for i in range(dim)]
    if min(diag) < 0.0:
        raise InputError("bad_covariance", f"{what} has a negative variance: {diag}")
    if max(diag) > MAX_VARIANCE:
        raise InputError("bad_covariance", f"{what} has a variance above {MAX_VARIANCE:g}")
    for i in range(dim):
        for j in range(i + 1, dim):
            cij, cji = c[i * dim + j], c[j * dim + i]
            scale = math.sqrt(diag[i] * diag[j])
            if abs(cij - cji) > COVARIANCE_RTOL * scale:
                raise InputError("bad_covariance", f"{what} is not symmetric: {c}")
            # every 2x2 principal minor of a positive semi-definite matrix is >= 0
            if diag[i] * diag[j] - cij * cji < -COVARIANCE_RTOL * diag[i] * diag[j]:
                raise InputError("bad_covariance", f"{what} is not positive semi-definite: {c}")
    if not (diag[0] > 0.0 and diag[0] * diag[1] - c[1] * c[dim] > 0.0):
        raise InputError("bad_covariance", f"{what}: horizontal block not positive definite")
    if dim == 3:
        det = (
            c[0] * (c[4] * c[8] - c[5] * c[7])
            - c[1] * (c[3] * c[8] - c[5] * c[6])
            + c[2] * (c[3] * c[7] - c[4] * c[6])
        )
        if det < -COVARIANCE_RTOL * diag[0] * diag[1] * diag[2]:
            raise InputError("bad_covariance", f"{what} is not positive semi-definite: {c}")
    return flat.reshape(dim, dim)


def merged_counts(*counts: Mapping[str, int]) -> dict[str, int]:
    """Counters summed key by key (the drops of the message checks and of an estimator)."""
    out: dict[str, int] = {}
    for c in counts:
        for key, n in c.items():
            out[key] = out.get(key, 0) + int(n)
    return out
