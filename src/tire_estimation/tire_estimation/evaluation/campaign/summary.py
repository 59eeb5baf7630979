"""Aggregation of case rows: the calibration study's accuracy and the ECE R-64
detection rates, times and false alarms per method."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from tire_estimation.evaluation.campaign.spec import (
    DIFFUSION_DEADLINE_S,
    STEP_DEADLINE_S,
    TARGET_ABSOLUTE_M,
    TARGET_RELATIVE_M,
)

_KINDS = ("step", "robustness", "diffusion", "calibration")


def _stats(values: Iterable[float | None], scale: float = 1.0) -> dict[str, Any]:
    v = np.array([x for x in values if x is not None and math.isfinite(x)], dtype=float) * scale
    if v.size == 0:
        return {"n": 0}
    a = np.abs(v)
    return {
        "n": int(v.size),
        "mean": float(v.mean()),
        "rms": float(np.sqrt(np.mean(v**2))),
        "median_abs": float(np.median(a)),
        "p95_abs": float(np.percentile(a, 95)),
        "max_abs": float(a.max()),
    }


def summarize_calibration(rows: Sequence[dict[str, Any]], at_s: float) -> dict[str, Any]:
    """Aggregate of the calibration study (errors in mm)."""
    ok = [r for r in rows if not r.get("error")]
    out: dict[str, Any] = {
        "study": "calibration",
        "n_cases": len(rows),
        "n_failed": len(rows) - len(ok),
        "at_s": at_s,
        "targets_mm": {
            "relative_rl_minus_rr": TARGET_RELATIVE_M * 1e3,
            "absolute_each": TARGET_ABSOLUTE_M * 1e3,
        },
    }
    for m in ("mpf", "aug_kf"):
        p = m + "_"
        mr = [r for r in ok if r.get(p + "ok")]
        rel = [r.get(p + "rel_err_at_m") for r in mr]
        absv = [r.get(p + "abs_err_rl_at_m") for r in mr] + [
            r.get(p + "abs_err_rr_at_m") for r in mr
        ]
        conv = [
            max(r[p + "converge_rl_s"], r[p + "converge_rr_s"])
            if r.get(p + "converge_rl_s") is not None and r.get(p + "converge_rr_s") is not None
            else None
            for r in mr
        ]
        n_rel = sum(1 for x in rel if x is not None and abs(x) <= TARGET_RELATIVE_M)
        n_abs = sum(
            1
            for r in mr
            if r.get(p + "abs_err_rl_at_m") is not None
            and abs(r[p + "abs_err_rl_at_m"]) <= TARGET_ABSOLUTE_M
            and abs(r[p + "abs_err_rr_at_m"]) <= TARGET_ABSOLUTE_M
        )
        out[m] = {
            "n": len(mr),
            "relative_error_at_mm": _stats(rel, 1e3),
            "absolute_error_at_mm": _stats(absv, 1e3),
            "final_relative_error_mm": _stats([r.get(p + "final_rel_err_m") for r in mr], 1e3),
            "final_absolute_error_mm": _stats(
                [r.get(p + "final_abs_err_rl_m") for r in mr]
                + [r.get(p + "final_abs_err_rr_m") for r in mr],
                1e3,
            ),
            "seeds_relative_within_target": n_rel,
            "seeds_absolute_within_target": n_abs,
            "seeds_meeting_all_targets": sum(1 for r in mr if r.get(p + "meets_targets_at")),
            "seeds_converged": sum(1 for c in conv if c is not None),
            "time_to_converge_s_both_rear": _stats(conv),
            "nees_mean": _stats(
                [r.get(p + "nees_rl") for r in mr] + [r.get(p + "nees_rr") for r in mr]
            ).get("mean"),
            "within_2std_mean": _stats(
                [r.get(p + "within_2std_rl") for r in mr]
                + [r.get(p + "within_2std_rr") for r in mr]
            ).get("mean"),
        }
    return out


def split_alarms(row: dict[str, Any], method: str) -> tuple[int, int]:
    """``(false_warnings, wrong_wheel_alarms)`` of one method in one case row.

    ECE R-64 asks for a warning when a tyre is under-inflated; the tell-tale need not name the
    tyre. A *false warning* is an alarm raised while no tyre is deflated (before the event, or
    on a drive without one); a *wrong-wheel alarm* comes after a real deflation but names a
    tyre that was not deflated (the driver is warned rightly, the tyre is misnamed). Both are
    counted in ``false_alarms`` (wheel level). A common-channel alarm (wheel ``all_wheels``)
    names no tyre: a false warning before the event or without one, neither after it.
    """
    from tire_estimation.core.deflation.status import ALL_WHEELS

    text = row.get(method + "_alarms") or ""
    event = row.get("event_s")
    deflated = set(str(row.get("deflated_wheels") or "").split(",")) - {""}
    false_warnings = wrong_wheel = 0
    for item in str(text).split(";"):
        if not item:
            continue
        wheel, _, t = item.partition("@")
        if event is None or float(t) < float(event):
            false_warnings += 1
        elif wheel not in deflated and wheel != ALL_WHEELS:
            wrong_wheel += 1
    return false_warnings, wrong_wheel


def summarize_detection(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Aggregate of an ECE R-64 campaign per method and case kind.

    False alarms are counted per wheel (``false_alarms``) and split into vehicle-level false
    warnings and wrong-wheel alarms (:func:`split_alarms`).
    """
    ok = [r for r in rows if not r.get("error")]
    out: dict[str, Any] = {
        "study": "ece_r64",
        "n_cases": len(rows),
        "n_failed": len(rows) - len(ok),
        "cases_by_kind": {k: sum(1 for r in rows if r["kind"] == k) for k in _KINDS},
        "deadline_s": {"step": STEP_DEADLINE_S, "diffusion": DIFFUSION_DEADLINE_S},
    }
    for m in ("mpf", "aug_kf"):
        p = m + "_"
        res: dict[str, Any] = {}
        for kind in ("step", "diffusion"):
            kr = [
                r
                for r in ok
                if r["kind"] == kind and r.get(p + "ok") and r.get(p + "observed") is not False
            ]
            det = [r for r in kr if r.get(p + "detected")]
            in_time = [r for r in kr if r.get(p + "detected_in_time")]
            times = [r[p + "detection_time_s"] for r in det]
            res[kind] = {
                "n": len(kr),
                "detected": len(det),
                "detected_in_time": len(in_time),
                "detection_rate": len(det) / len(kr) if kr else None,
                "detection_rate_in_time": len(in_time) / len(kr) if kr else None,
                "detection_time_s": _stats(times),
                "not_calibrated_before_event": sum(
                    1 for r in kr if not r.get(p + "calibrated_before_event")
                ),
                "false_alarms": sum(int(r.get(p + "false_alarms", 0)) for r in kr),
                "false_warnings": sum(split_alarms(r, m)[0] for r in kr),
                "wrong_wheel_alarms": sum(split_alarms(r, m)[1] for r in kr),
                "missed": [r["case_id"] for r in kr if not r.get(p + "detected")],
            }
            if kind == "step":
                res[kind]["estimated_change_mm"] = _stats(
                    [r.get(p + "estimated_change_m") for r in kr], 1e3
                )
                res[kind]["true_change_mm"] = _stats([r.get(p + "true_change_m") for r in kr], 1e3)
        rr = [r for r in ok if r["kind"] == "robustness" and r.get(p + "ok")]
        hours = sum(float(r.get(p + "monitored_h") or 0.0) for r in rr)
        fa = sum(int(r.get(p + "false_alarms", 0)) for r in rr)
        res["robustness"] = {
            "n": len(rr),
            "monitored_hours": hours,
            "driven_hours": sum(r["minutes"] for r in rr) / 60.0,
            "false_alarms": fa,
            "cases_with_false_alarm": sum(1 for r in rr if int(r.get(p + "false_alarms", 0))),
            "false_alarms_per_hour": fa / hours if hours > 0 else None,
            "max_cusum_over_threshold": _stats(
                [r.get(p + "max_cusum_over_threshold") for r in rr]
            ).get("max_abs"),
        }
        res["false_alarms_total"] = sum(int(r.get(p + "false_alarms", 0)) for r in ok)
        res["false_warnings_total"] = sum(split_alarms(r, m)[0] for r in ok if r.get(p + "ok"))
        res["wrong_wheel_alarms_total"] = sum(split_alarms(r, m)[1] for r in ok if r.get(p + "ok"))
        out[m] = res
    return out
