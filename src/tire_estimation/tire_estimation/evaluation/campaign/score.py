"""Scoring of one case: CUSUM detection over each method's trace and the accuracy of the
radii against the simulator's truth (flat, JSON-ready result fields)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.arrays import F64
from tire_estimation.evaluation.campaign.spec import (
    TARGET_ABSOLUTE_M,
    TARGET_RELATIVE_M,
    CaseSpec,
)
from tire_estimation.evaluation.campaign.trace import CaseRun


def true_error(run: CaseRun, wheels: Sequence[str]) -> F64:
    """True radius error (effective minus nominal) at the trace times, (K, len(wheels))."""
    from tire_estimation.core.wheels import WHEEL_INDEX
    from tire_estimation.evaluation.metrics import hold_interp

    cols = [WHEEL_INDEX[w] for w in wheels]
    r = hold_interp(run.t_ns, run.truth_t_ns, run.truth_radius_m[:, cols])
    return np.asarray(r, dtype=float).reshape(run.t_ns.size, len(cols)) - run.nominal_m


def braking_signal(
    t_s: F64, speed_m_s: F64, decel_m_s2: float = 1.0, time_constant_s: float = 1.0
) -> NDArray[np.bool_]:
    """Braking flag from a speed series: low-passed deceleration above ``decel_m_s2``.

    The derivative of the speed is smoothed by a first-order low-pass filter with
    ``time_constant_s`` (GNSS-rate speed estimates are noisy) before the threshold.
    """
    n = t_s.size
    out = np.zeros(n, dtype=bool)
    if n < 2:
        return out
    dv = np.diff(speed_m_s)
    dt = np.maximum(np.diff(t_s), 1e-6)
    acc = 0.0
    for i in range(1, n):
        alpha = 1.0 - math.exp(-dt[i - 1] / time_constant_s)
        acc += alpha * (dv[i - 1] / dt[i - 1] - acc)
        out[i] = acc < -decel_m_s2
    return out


def _detector_config(spec: CaseSpec) -> Any:
    from tire_estimation.core.deflation.config import DeflationDetectorConfig

    cal = float(spec.detector_calibration_s)
    kwargs: dict[str, Any] = {
        "calibration_time_s": cal,
        "calibration_average_s": min(300.0, 0.25 * cal),
    }
    kwargs.update(spec.detector)
    return DeflationDetectorConfig(**kwargs)


def _at(t_s: F64, values: F64, at_s: float) -> F64 | None:
    k = int(np.searchsorted(t_s, at_s, side="right")) - 1
    if k < 0 or t_s.size == 0 or t_s[-1] < at_s:
        return None
    return values[k]


def _mean_window(t_s: F64, values: F64, t_from: float, t_to: float) -> F64 | None:
    sel = (t_s >= t_from) & (t_s <= t_to)
    if not sel.any():
        return None
    return np.nanmean(values[sel], axis=0)


def _f(x: Any) -> float | None:
    """JSON-safe float (None for None/NaN/inf)."""
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def evaluate_detection(spec: CaseSpec, run: CaseRun, method: str) -> dict[str, Any]:
    """Run a fresh CUSUM over one method's trace; flat result fields prefixed by ``method``."""
    from tire_estimation.core.deflation.status import ALL_WHEELS
    from tire_estimation.core.deflation.trace import run_detector_over_trace

    if method == "mpf":
        wheels, mu, std, act = run.wheel_names, run.mpf_m, run.mpf_std_m, run.active
    else:
        wheels, mu, std = run.kf_wheels, run.kf_m, run.kf_std_m
        act = None
    if spec.braking_source == "truth":
        from tire_estimation.evaluation.metrics import hold_interp

        ax = hold_interp(run.t_ns, run.truth_t_ns, run.truth_ax_m_s2)
        braking = np.asarray(ax, dtype=float) < -1.0
    else:
        braking = braking_signal(run.t_s, run.speed_m_s)
    p = method + "_"
    out: dict[str, Any] = {}
    if run.t_ns.size == 0 or mu.size == 0 or not np.isfinite(mu).any():
        out[p + "ok"] = False
        return out
    res = run_detector_over_trace(
        _detector_config(spec), run.t_ns, wheels, mu, std, run.speed_m_s, braking, act
    )
    from tire_estimation.sim import START_TIME_NS

    cal_s = (
        None
        if res.calibration_done_t_ns is None
        else (res.calibration_done_t_ns - START_TIME_NS) * 1e-9
    )
    observed = [w for w in spec.deflated_wheels if w in wheels]
    alarms_s = [(w, (t - START_TIME_NS) * 1e-9) for w, t in res.alarms]
    event = spec.event_s
    # a vehicle-level alarm of the common channel (ALL_WHEELS, names no tyre) after the event
    # of a deflation case is a right warning; it is a detection when the method estimates a
    # deflated wheel
    after = [(w, t) for w, t in alarms_s if event is not None and t >= event]
    true_alarms = [(w, t) for w, t in after if w in observed or (w == ALL_WHEELS and observed)]
    right_warnings = [(w, t) for w, t in after if w == ALL_WHEELS and spec.deflated_wheels]
    false_alarms = [
        (w, t) for w, t in alarms_s if (w, t) not in true_alarms and (w, t) not in right_warnings
    ]
    first = min((t for _, t in true_alarms), default=None)
    det_time = None if first is None or event is None else first - event
    detected_in_time = (
        det_time is not None and spec.deadline_s is not None and det_time <= spec.deadline_s
    )
    # monitored time: from the end of the detector's calibration to the end of the drive (the
    # false-alarm rate per hour is computed over the robustness cases only)
    end_s = float(run.t_s[-1])
    monitored_h = 0.0 if cal_s is None else max(0.0, end_s - cal_s) / 3600.0
    out[p + "ok"] = True
    # a deflation case counts for a method only if it estimates a deflated wheel (the AUG-KF
    # baseline has no front radii)
    out[p + "observed"] = bool(observed) if spec.deflated_wheels else None
    out[p + "calibration_done_s"] = _f(cal_s)
    out[p + "calibrated_before_event"] = bool(
        cal_s is not None and (event is None or cal_s <= event)
    )
    out[p + "alarms"] = ";".join(f"{w}@{t:.0f}" for w, t in alarms_s)
    out[p + "detected"] = bool(first is not None)
    out[p + "detected_in_time"] = bool(detected_in_time)
    out[p + "detection_time_s"] = _f(det_time)
    out[p + "false_alarms"] = len(false_alarms)
    out[p + "monitored_h"] = monitored_h
    # size of the estimated radius change on the first observed deflated wheel (paper Fig. 8):
    # mean over the last 2 min minus the mean over the 2 min before the event; same for truth
    if observed and event is not None:
        w = observed[0]
        j = wheels.index(w)
        before = _mean_window(run.t_s, mu[:, j], event - 120.0, event)
        after = _mean_window(run.t_s, mu[:, j], end_s - 120.0, end_s)
        tr = true_error(run, [w])[:, 0]
        tb = _mean_window(run.t_s, tr, event - 120.0, event)
        ta = _mean_window(run.t_s, tr, end_s - 120.0, end_s)
        out[p + "estimated_change_m"] = (
            None if before is None or after is None else _f(after - before)
        )
        out[p + "true_change_m"] = None if tb is None or ta is None else _f(ta - tb)
        finite = np.isfinite(res.radius_change_m[:, j])
        out[p + "detector_radius_change_m"] = (
            _f(res.radius_change_m[finite, j][-1]) if finite.any() else None
        )
        out[p + "max_cusum_over_threshold"] = _f(
            np.nanmax(res.cusum_m[:, j] / res.threshold_m[:, j])
            if np.isfinite(res.cusum_m[:, j]).any()
            else None
        )
    else:
        # wheels and the common channel (NaN when it is off)
        ratio = np.concatenate(
            [
                (res.cusum_m / res.threshold_m).ravel(),
                res.common_cusum_m / res.common_threshold_m,
            ]
        )
        out[p + "max_cusum_over_threshold"] = (
            _f(np.nanmax(ratio)) if np.isfinite(ratio).any() else None
        )
    common = res.common_cusum_m / res.common_threshold_m
    out[p + "max_common_cusum_over_threshold"] = (
        _f(np.nanmax(common)) if np.isfinite(common).any() else None
    )
    return out


def evaluate_accuracy(spec: CaseSpec, run: CaseRun, at_s: float) -> dict[str, Any]:
    """Errors vs truth of both methods at ``at_s`` and at the end, convergence, consistency."""
    from tire_estimation.evaluation.metrics import CONVERGED_M, time_to_converge_s

    out: dict[str, Any] = {}
    rear = ("wheel_rl", "wheel_rr")
    truth = true_error(run, rear)
    burn = run.t_s >= (run.t_s[0] + 300.0 if run.t_s.size else 0.0)
    for method, names, mu, std in (
        ("mpf", run.wheel_names, run.mpf_m, run.mpf_std_m),
        ("aug_kf", run.kf_wheels, run.kf_m, run.kf_std_m),
    ):
        p = method + "_"
        if run.t_s.size == 0 or any(w not in names for w in rear):
            out[p + "ok"] = False
            continue
        cols = [names.index(w) for w in rear]
        err = mu[:, cols] - truth
        sd = std[:, cols]
        e10 = _at(run.t_s, err, at_s)
        out[p + "ok"] = True
        out[p + "start_s"] = _f(run.t_s[0])
        if e10 is not None:
            out[p + "rel_err_at_m"] = _f(e10[0] - e10[1])
            out[p + "abs_err_rl_at_m"] = _f(e10[0])
            out[p + "abs_err_rr_at_m"] = _f(e10[1])
            out[p + "meets_targets_at"] = bool(
                abs(e10[0] - e10[1]) <= TARGET_RELATIVE_M
                and abs(e10[0]) <= TARGET_ABSOLUTE_M
                and abs(e10[1]) <= TARGET_ABSOLUTE_M
            )
        else:
            out[p + "meets_targets_at"] = False
        out[p + "final_rel_err_m"] = _f(err[-1, 0] - err[-1, 1])
        out[p + "final_abs_err_rl_m"] = _f(err[-1, 0])
        out[p + "final_abs_err_rr_m"] = _f(err[-1, 1])
        for i, w in enumerate(("rl", "rr")):
            out[p + f"converge_{w}_s"] = _f(time_to_converge_s(run.t_s, err[:, i], CONVERGED_M))
            if burn.any():
                z2 = (err[burn, i] / np.maximum(sd[burn, i], 1e-12)) ** 2
                out[p + f"nees_{w}"] = _f(np.mean(z2))
                out[p + f"within_2std_{w}"] = _f(np.mean(z2 <= 4.0))
                out[p + f"rmse_{w}_m"] = _f(np.sqrt(np.mean(err[burn, i] ** 2)))
    return out


def score_case(spec: CaseSpec, run: CaseRun, row: dict[str, Any], accuracy_at_s: float) -> None:
    """Add the result fields of ``spec`` to ``row``: the accuracy of a calibration case at
    ``accuracy_at_s``, else the detection of both methods (``mpf_*``, ``aug_kf_*``)."""
    if spec.kind == "calibration":
        row.update(evaluate_accuracy(spec, run, accuracy_at_s))
    else:
        row.update(evaluate_detection(spec, run, "mpf"))
        row.update(evaluate_detection(spec, run, "aug_kf"))
