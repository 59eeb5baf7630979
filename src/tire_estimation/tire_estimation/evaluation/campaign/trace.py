"""Simulation and estimator traces of one case (:class:`CaseRun`) and their ``.npz``
files (``--save-traces``)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64


@dataclass
class CaseRun:
    """Simulation + estimator trace of one case (kept in the worker)."""

    t_ns: NDArray[np.int64]
    t_s: F64
    wheel_names: tuple[str, ...]
    mpf_m: F64
    mpf_std_m: F64
    kf_wheels: tuple[str, ...]
    kf_m: F64
    kf_std_m: F64
    speed_m_s: F64
    active: NDArray[np.bool_]
    truth_t_ns: NDArray[np.int64]
    truth_radius_m: F64  # (T, 4) in WHEELS order
    truth_ax_m_s2: F64
    nominal_m: float
    sim_s: float
    est_s: float


_RUN_NAMES = ("wheel_names", "kf_wheels")


def save_run(run: CaseRun, path: Path) -> None:
    """Write the estimator traces and truth of one case to ``path`` (``.npz``)."""
    arrays = {
        f.name: np.asarray(getattr(run, f.name))
        for f in dataclasses.fields(run)
        if f.name not in _RUN_NAMES
    }
    names = {n: np.asarray(getattr(run, n), dtype=str) for n in _RUN_NAMES}
    np.savez_compressed(path, **arrays, **names)


def load_run(path: Path) -> CaseRun:
    """Read a trace written by :func:`save_run`."""
    with np.load(path) as z:
        values: dict[str, Any] = {}
        for f in dataclasses.fields(CaseRun):
            v = z[f.name]
            if f.name in _RUN_NAMES:
                values[f.name] = tuple(str(x) for x in v)
            elif v.ndim == 0:
                values[f.name] = float(v)
            else:
                values[f.name] = v
    return CaseRun(**values)
