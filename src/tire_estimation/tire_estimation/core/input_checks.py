"""The per-sample checks every estimator applies to what it is handed (one implementation).

Samples that entered through :mod:`tire_estimation.core.samples` are already checked; the
estimators still guard their own state (stamp order per stream, vector length, finiteness)
because tests, benchmarks and studies call them directly. Each check raises
:class:`~tire_estimation.errors.InputError` with the ``kind`` the caller counts.
"""

from __future__ import annotations

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
    if not is_int(t_ns):
        raise InputError("bad_stamp", f"{stream}: stamp must be an integer, got {t_ns!r}")
    t = int(t_ns)
    if last_ns is not None and t <= last_ns:
        kind = "duplicate" if t == last_ns else "out_of_order"
        raise InputError(kind, f"{stream}: stamp {t} not after {last_ns}")
    return t


def finite_vector(value: Any, n: int, what: str) -> F64:
    """``value`` as a float vector of ``n`` finite entries; else ``wrong_length`` or ``nan``."""
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (n,):
        raise InputError("wrong_length", f"{what}: need {n} values, got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise InputError("nan", f"{what}: non-finite value")
    return v
