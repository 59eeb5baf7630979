"""Accuracy and consistency metrics of a radius-estimation run against truth or reference.

All functions take plain arrays (time as int64 ns) and return JSON-ready dicts; nothing here
knows about bags or ROS.
"""

from __future__ import annotations

import math
from collections import Counter
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtrc, chdtri

from tire_estimation.core.arrays import F64

#: |error| below which a radius estimate counts as converged (issue 3 target), m.
CONVERGED_M = 0.5e-3


def hold_interp(t_query_ns: NDArray[np.int64], t_ns: NDArray[np.int64], values: F64) -> F64:
    """Zero-order hold of ``values`` (K, ...) sampled at ``t_ns`` at the query times.

    Queries before the first sample take the first value (truth topics publish on change).
    """
    idx = np.searchsorted(t_ns, t_query_ns, side="right") - 1
    return values[np.clip(idx, 0, len(t_ns) - 1)]


def _finite_or_none(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def time_to_converge_s(t_s: F64, error_m: F64, tol_m: float = CONVERGED_M) -> float | None:
    """First time after which |error| stays below ``tol_m`` to the end (None if never)."""
    bad = np.flatnonzero(np.abs(error_m) >= tol_m)
    if bad.size == 0:
        return float(t_s[0]) if t_s.size else None
    if bad[-1] == error_m.size - 1:
        return None
    return float(t_s[bad[-1] + 1])


#: an interval between estimates longer than this many typical ones is a gap without estimate
GAP_INTERVALS = 5.0
#: the reason given for such gaps
NO_ESTIMATE = "no estimate (pose re-initializing, or no GNSS)"


def learning_metrics(
    t_ns: NDArray[np.int64],
    wheel_names: tuple[str, ...],
    active: NDArray[np.bool_],
    reasons: list[str],
) -> dict[str, Any]:
    """Per wheel: how long the radius was learned (s and share of the time with an estimate)
    and, for the time it was not, the estimator's reasons (s each).

    ``t_ns`` (K,) the estimate times, ``active`` (K, W) learning flags, ``reasons`` (K,) the
    estimator's state reason; each sample stands for the time to the next one."""
    out: dict[str, Any] = {}
    if t_ns.size == 0:
        return {w: {"learned_s": 0.0, "share": 0.0, "paused_s": {}} for w in wheel_names}
    dt = np.diff(t_ns) * 1e-9
    typical = float(np.median(dt)) if dt.size else 0.0
    dt = np.append(dt, typical)
    # a gap of more than a few intervals had no estimate (the pose re-initializing, no fixes):
    # the sample before it stands for one interval, the rest is counted apart
    gap = np.maximum(dt - typical, 0.0) * (dt > GAP_INTERVALS * typical)
    dt = dt - gap
    no_estimate_s = float(gap.sum())
    total = float(dt.sum()) + no_estimate_s
    for j, w in enumerate(wheel_names):
        on = np.asarray(active[:, j], dtype=bool)
        paused: dict[str, float] = {}
        if no_estimate_s > 0.0:
            paused[NO_ESTIMATE] = no_estimate_s
        for k in np.flatnonzero(~on):
            paused[reasons[k]] = paused.get(reasons[k], 0.0) + float(dt[k])
        learned = float(dt[on].sum())
        out[w] = {
            "learned_s": learned,
            "share": learned / total if total > 0 else 0.0,
            "paused_s": dict(sorted(paused.items(), key=lambda kv: -kv[1])),
        }
    return out


def radius_metrics(
    t_ns: NDArray[np.int64],
    start_ns: int,
    wheel_names: tuple[str, ...],
    estimate_m: F64,
    std_m: F64,
    truth: tuple[NDArray[np.int64], tuple[str, ...], F64] | None,
    nominal_radius_m: float,
    burn_in_s: float = 300.0,
) -> dict[str, Any]:
    """Per-wheel final estimate, std and (with truth) RMSE, final error, convergence, NEES.

    ``estimate_m``/``std_m``: (K, W) radius errors (effective minus nominal) and their std.
    ``truth``: (t_ns (T,), names, radius (T, W')) true effective radii from /truth/wheel_radii.
    RMSE uses the samples after ``burn_in_s`` from the first estimate (all if the run is
    shorter than twice that).
    """
    out: dict[str, Any] = {
        "final_radius_error_m": {},
        "final_radius_error_std_m": {},
        "rmse_vs_truth_m": None,
    }
    if t_ns.size == 0:
        for w in wheel_names:
            out["final_radius_error_m"][w] = None
            out["final_radius_error_std_m"][w] = None
        return out
    for i, w in enumerate(wheel_names):
        out["final_radius_error_m"][w] = float(estimate_m[-1, i])
        out["final_radius_error_std_m"][w] = float(std_m[-1, i])
    if truth is None or truth[0].size == 0:
        return out
    t_truth, names, radius = truth
    t_s = (t_ns - start_ns) * 1e-9
    span = t_s[-1] - t_s[0]
    window = t_s >= t_s[0] + (burn_in_s if span > 2 * burn_in_s else 0.0)
    rmse: dict[str, float | None] = {}
    final_err: dict[str, float | None] = {}
    conv: dict[str, float | None] = {}
    nees: dict[str, float | None] = {}
    within_2std: dict[str, float | None] = {}
    true_err_all: dict[str, F64] = {}
    for i, w in enumerate(wheel_names):
        if w not in names:
            rmse[w] = final_err[w] = conv[w] = nees[w] = within_2std[w] = None
            continue
        true_err = hold_interp(t_ns, t_truth, radius[:, names.index(w)]) - nominal_radius_m
        true_err_all[w] = true_err
        err = estimate_m[:, i] - true_err
        rmse[w] = float(np.sqrt(np.mean(err[window] ** 2)))
        final_err[w] = float(err[-1])
        conv[w] = time_to_converge_s(t_s, err)
        z2 = (err[window] / np.maximum(std_m[window, i], 1e-12)) ** 2
        nees[w] = float(np.mean(z2))
        within_2std[w] = float(np.mean(z2 <= 4.0))
    out["rmse_vs_truth_m"] = rmse
    out["final_error_vs_truth_m"] = final_err
    out["time_to_converge_s"] = conv
    out["nees"] = nees
    out["fraction_within_2std"] = within_2std
    out["rmse_window_s"] = [float(t_s[window][0]), float(t_s[-1])] if window.any() else None
    if "wheel_rl" in true_err_all and "wheel_rr" in true_err_all:
        il, ir = wheel_names.index("wheel_rl"), wheel_names.index("wheel_rr")
        rel_est = estimate_m[:, il] - estimate_m[:, ir]
        rel_true = true_err_all["wheel_rl"] - true_err_all["wheel_rr"]
        out["final_relative_error_rl_minus_rr_vs_truth_m"] = float(rel_est[-1] - rel_true[-1])
    return out


def errors_at(
    t_ns: NDArray[np.int64],
    start_ns: int,
    at_s: float,
    wheel_names: tuple[str, ...],
    estimate_m: F64,
    truth: tuple[NDArray[np.int64], tuple[str, ...], F64],
    nominal_radius_m: float,
) -> dict[str, float] | None:
    """Estimate minus truth per wheel at ``at_s`` seconds after the bag start (None if later)."""
    t_s = (t_ns - start_ns) * 1e-9
    k = int(np.searchsorted(t_s, at_s, side="right")) - 1
    if k < 0 or t_s[-1] < at_s:
        return None
    t_truth, names, radius = truth
    out: dict[str, float] = {}
    for i, w in enumerate(wheel_names):
        if w in names:
            true_err = hold_interp(t_ns[k : k + 1], t_truth, radius[:, names.index(w)])[0]
            out[w] = float(estimate_m[k, i] - (true_err - nominal_radius_m))
    return out


def position_rmse_m(est_en_m: F64, ref_en_m: F64) -> float | None:
    """Horizontal RMSE between (K, 2) estimated and reference east/north positions."""
    if est_en_m.size == 0:
        return None
    d = est_en_m - ref_en_m
    return _finite_or_none(float(np.sqrt(np.mean(np.sum(d**2, axis=1)))))


def ljung_box(x: F64, lags: int = 10) -> tuple[float, float]:
    """Ljung-Box statistic Q and its p-value (chi-square with ``lags`` dof) of a series."""
    x = np.asarray(x, dtype=float)
    n = x.size
    if n <= lags + 1:
        return float("nan"), float("nan")
    x = x - x.mean()
    denom = float(np.dot(x, x))
    if denom <= 0:
        return 0.0, 1.0
    acf = np.array([np.dot(x[:-k], x[k:]) / denom for k in range(1, lags + 1)])
    # Ljung & Box (1978): Q = n (n + 2) sum_k rho_k^2 / (n - k)
    q = n * (n + 2) * float(np.sum(acf**2 / (n - np.arange(1, lags + 1))))
    return q, float(chdtrc(lags, q))  # chi-square survival function


def innovation_tests(
    innov_m: F64, innov_cov_m2: F64, nis: F64, accepted: NDArray[np.bool_], lags: int = 10
) -> dict[str, Any]:
    """NIS against its chi-square(2) bounds and whiteness of the normalized innovations.

    The run is called consistent when the mean NIS lies inside the two-sided 95 % bounds of
    the mean of ``n`` chi-square(2) variables and the normalized innovations pass a Ljung-Box
    test (p > 0.01) on both axes.
    """
    ok = accepted & np.isfinite(nis)
    n = int(ok.sum())
    if n < lags + 2:
        return {"consistent": True, "n": n, "note": "too few accepted innovations to test"}
    nis_ok = nis[ok]
    lo, hi = chdtri(2 * n, 1.0 - np.array([0.025, 0.975])) / n  # chi-square quantiles
    # whiten each innovation with its own covariance (Cholesky) before the whiteness test
    chol = np.linalg.cholesky(innov_cov_m2[ok])
    z = np.linalg.solve(chol, innov_m[ok][..., None])[..., 0]
    q_e, p_e = ljung_box(z[:, 0], lags)
    q_n, p_n = ljung_box(z[:, 1], lags)
    mean_nis = float(np.mean(nis_ok))
    nis_ok_flag = bool(lo <= mean_nis <= hi)
    white = bool(p_e > 0.01 and p_n > 0.01)
    return {
        "consistent": bool(nis_ok_flag and white),
        "n": n,
        "mean_nis": mean_nis,
        "mean_nis_bounds_95": [float(lo), float(hi)],
        "fraction_nis_above_chi2_95": float(np.mean(nis_ok > chdtri(2, 1.0 - 0.95))),
        "ljung_box_lags": lags,
        "ljung_box_p_east": p_e,
        "ljung_box_p_north": p_n,
        "ljung_box_q_east": q_e,
        "ljung_box_q_north": q_n,
        "rejected_fixes": int((~accepted).sum()),
    }


def lateral_sums(
    t_ns: NDArray[np.int64],
    vy_m_s: F64,
    yaw_rate_rad_s: F64,
    sideslip_rad: F64,
    relay: NDArray[np.int64],
    ref_t_ns: NDArray[np.int64],
    ref_velocity_m_s: F64,
    ref_yaw_rate_rad_s: F64,
) -> Counter[str]:
    """Sums of the squared errors of vy (m/s), sideslip (deg) and yaw rate (deg/s) of
    base_link against a reference, to be added up over the parts of a long run and turned into
    RMSEs by :func:`lateral_from_sums`.

    ``ref_velocity_m_s`` (T, >=2) [vx, vy] of base_link in base_link axes (T >= 1). Also the
    sums over the samples the relay marked nonlinear (``relay == 2``).
    """
    ref_vx = np.interp(t_ns, ref_t_ns, ref_velocity_m_s[:, 0])
    ref_vy = np.interp(t_ns, ref_t_ns, ref_velocity_m_s[:, 1])
    ref_r = np.interp(t_ns, ref_t_ns, ref_yaw_rate_rad_s)
    ref_beta = np.arctan2(ref_vy, np.maximum(ref_vx, 0.1))
    e_vy = vy_m_s - ref_vy
    e_beta = np.degrees(sideslip_rad - ref_beta)
    e_r = np.degrees(yaw_rate_rad_s - ref_r)
    nonlinear = relay == 2
    return Counter(
        {
            "n": int(t_ns.size),
            "n_nonlinear": int(nonlinear.sum()),
            "vy": float(np.sum(e_vy**2)),
            "sideslip": float(np.sum(e_beta**2)),
            "yaw_rate": float(np.sum(e_r**2)),
            "vy_nonlinear": float(np.sum(e_vy[nonlinear] ** 2)),
            "yaw_rate_nonlinear": float(np.sum(e_r[nonlinear] ** 2)),
        }
    )


def lateral_from_sums(sums: Counter[str]) -> dict[str, Any]:
    """RMSEs from the sums of :func:`lateral_sums` over a run's parts (None where empty)."""
    n, n_nl = sums["n"], sums["n_nonlinear"]
    if n == 0:
        return {"vy_rmse_m_s": None, "sideslip_rmse_deg": None, "yaw_rate_rmse_deg_s": None}

    def rms(key: str, count: int) -> float | None:
        return math.sqrt(sums[key] / count) if count else None

    return {
        "vy_rmse_m_s": rms("vy", n),
        "sideslip_rmse_deg": rms("sideslip", n),
        "yaw_rate_rmse_deg_s": rms("yaw_rate", n),
        "nonlinear_fraction": n_nl / n,
        "nonlinear_vy_rmse_m_s": rms("vy_nonlinear", n_nl),
        "nonlinear_yaw_rate_rmse_deg_s": rms("yaw_rate_nonlinear", n_nl),
        "samples": n,
    }
