"""The deflation detector run offline over arrays of radius estimates (ECE R-64 campaign)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.deflation.config import DeflationDetectorConfig
from tire_estimation.core.deflation.detector import DeflationDetector
from tire_estimation.core.deflation.status import ALL_WHEELS, CalibrationState, RadiusErrors
from tire_estimation.errors import InputError


@dataclass(frozen=True)
class TraceResult:
    """Output of :func:`run_detector_over_trace`; arrays are ``(K,)`` or ``(K, W)``.

    Entries of a wheel the detector has not seen yet, and of dropped rows, are NaN; the
    ``common_*`` arrays are NaN throughout unless ``config.common_channel``.
    """

    # (wheel, alarm t_ns), in time order; a common-channel alarm has wheel ALL_WHEELS
    alarms: list[tuple[str, int]]
    wheel_names: tuple[str, ...]
    t_ns: np.ndarray
    cusum_m: np.ndarray
    threshold_m: np.ndarray
    radius_change_m: np.ndarray
    calibration_state: np.ndarray  # (K,) int, CalibrationState values
    calibration_done_t_ns: int | None
    stats: dict[str, int]
    common_cusum_m: np.ndarray  # (K,)
    common_threshold_m: np.ndarray  # (K,)
    common_radius_change_m: np.ndarray  # (K,)


def run_detector_over_trace(
    config: DeflationDetectorConfig,
    t_ns: Sequence[int] | np.ndarray,
    wheel_names: Sequence[str],
    radius_error_m: np.ndarray,
    radius_error_std_m: np.ndarray,
    speed_m_s: np.ndarray,
    braking: np.ndarray,
    active: np.ndarray | None = None,
) -> TraceResult:
    """Run a fresh :class:`DeflationDetector` offline over a trace of radius estimates.

    ``radius_error_m``, ``radius_error_std_m`` (and ``active``, default all True) are ``(K, W)``
    with columns in ``wheel_names`` order; ``t_ns``, ``speed_m_s`` (NaN = unknown) and
    ``braking`` are ``(K,)``. A wheel whose value or std is NaN in a row is left out of that row.
    """
    times = np.asarray(t_ns, dtype=np.int64).reshape(-1)
    mu = np.asarray(radius_error_m, dtype=float)
    std = np.asarray(radius_error_std_m, dtype=float)
    speed = np.asarray(speed_m_s, dtype=float).reshape(-1)
    brake = np.asarray(braking, dtype=bool).reshape(-1)
    names = tuple(wheel_names)
    k, n_w = len(times), len(names)
    act = np.ones((k, n_w), dtype=bool) if active is None else np.asarray(active, dtype=bool)
    for label, arr, shape in (
        ("radius_error_m", mu, (k, n_w)),
        ("radius_error_std_m", std, (k, n_w)),
        ("active", act, (k, n_w)),
        ("speed_m_s", speed, (k,)),
        ("braking", brake, (k,)),
    ):
        if arr.shape != shape:
            raise InputError("wrong_shape", f"{label} has shape {arr.shape}, expected {shape}")
    detector = DeflationDetector(config)
    cusum = np.full((k, n_w), np.nan)
    threshold = np.full((k, n_w), np.nan)
    change = np.full((k, n_w), np.nan)
    common_g = np.full(k, np.nan)
    common_th = np.full(k, np.nan)
    common_change = np.full(k, np.nan)
    calib = np.zeros(k, dtype=int)
    alarms: list[tuple[str, int]] = []
    alarmed: set[str] = set()
    done_t: int | None = None
    for i in range(k):
        cols = [j for j in range(n_w) if math.isfinite(mu[i, j]) and math.isfinite(std[i, j])]
        sp = float(speed[i]) if math.isfinite(speed[i]) else None
        radii = RadiusErrors(
            int(times[i]),
            [names[j] for j in cols],
            [float(mu[i, j]) for j in cols],
            [float(std[i, j]) for j in cols],
            [bool(act[i, j]) for j in cols],
        )
        status = detector.step(radii, sp, bool(brake[i]))
        calib[i] = int(status.calibration_state)
        if done_t is None and status.calibration_state == CalibrationState.DONE:
            done_t = int(times[i])
        if not status.accepted:
            continue
        for entry in status.wheels:
            j = names.index(entry.wheel_name)
            cusum[i, j] = entry.cusum_m
            threshold[i, j] = entry.threshold_m
            change[i, j] = entry.radius_change_m
            if entry.alarm and entry.wheel_name not in alarmed and entry.alarm_t_ns is not None:
                alarmed.add(entry.wheel_name)
                alarms.append((entry.wheel_name, entry.alarm_t_ns))
        c = status.common
        if c is not None:
            common_g[i], common_th[i] = c.cusum_m, c.threshold_m
            common_change[i] = c.radius_change_m
            if c.alarm and ALL_WHEELS not in alarmed and c.alarm_t_ns is not None:
                alarmed.add(ALL_WHEELS)
                alarms.append((ALL_WHEELS, c.alarm_t_ns))
    return TraceResult(
        alarms=alarms,
        wheel_names=names,
        t_ns=times,
        cusum_m=cusum,
        threshold_m=threshold,
        radius_change_m=change,
        calibration_state=calib,
        calibration_done_t_ns=done_t,
        stats=dict(detector.stats),
        common_cusum_m=common_g,
        common_threshold_m=common_th,
        common_radius_change_m=common_change,
    )
