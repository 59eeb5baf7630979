"""PNG plots a person looks at first after a replay (matplotlib, Agg backend)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import NDArray
from scipy import stats

from tire_estimation.core.arrays import F64


def save_figure(fig: Any, path: Path) -> None:
    """Lay out ``fig``, write it to ``path`` (PNG, 110 dpi) and close it."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _mark_events(
    ax: Any, events_s: Sequence[tuple[float, str]] | None, color: str, ls: str
) -> None:
    """A vertical line and its label at the top of ``ax`` for each ``(t_s, label)``."""
    for t_ev, label in events_s or []:
        ax.axvline(t_ev, color=color, ls=ls, lw=0.8)
        ax.text(t_ev, ax.get_ylim()[1], f" {label}", color=color, va="top", fontsize=8)


def plot_radius_errors(
    path: Path,
    t_s: F64,
    wheel_names: tuple[str, ...],
    estimate_m: F64,
    std_m: F64,
    truth: tuple[F64, tuple[str, ...], F64] | None = None,
    baseline_m: F64 | None = None,
    events_s: list[tuple[float, str]] | None = None,
) -> None:
    """Radius error per wheel (mm) with a +-2 std band, the truth and the AUG-KF baseline.

    ``truth`` = (t_s (T,), names, true radius error (T, W') in m).
    """
    n = len(wheel_names)
    fig, axes = plt.subplots(n, 1, figsize=(10, 2.6 * n), sharex=True, squeeze=False)
    for i, w in enumerate(wheel_names):
        ax = axes[i, 0]
        mm = 1e3 * estimate_m[:, i]
        band = 2e3 * std_m[:, i]
        ax.fill_between(t_s, mm - band, mm + band, color="C0", alpha=0.2, label="MPF ±2σ")
        ax.plot(t_s, mm, color="C0", lw=1.2, label="MPF estimate")
        if baseline_m is not None and baseline_m.size:
            ax.plot(t_s, 1e3 * baseline_m[:, i], color="C2", lw=1.0, label="AUG-KF baseline")
        if truth is not None and w in truth[1]:
            j = truth[1].index(w)
            ax.step(truth[0], 1e3 * truth[2][:, j], where="post", color="k", lw=1.2, label="truth")
        _mark_events(ax, events_s, "C3", "--")
        _label_wheel_axis(ax, f"{w}\nradius error [mm]", i == 0, "best")
    _save_wheel_figure(fig, axes, "Effective rolling-radius error (estimate minus nominal)", path)


def plot_trajectory(
    path: Path,
    estimate_en_m: F64,
    gnss_en_m: F64,
    reference_en_m: F64 | None = None,
    t_s: F64 | None = None,
    reference_label: str = "truth / reference",
) -> None:
    """Left: the estimated path, the GNSS fixes and the reference, in the local ENU frame.
    Right (with a reference at the estimate's times ``t_s``): the horizontal distance of the
    estimate from the reference over time, which the path view cannot show at the scale of a
    drive."""
    with_error = reference_en_m is not None and t_s is not None and reference_en_m.size > 0
    fig, axes = plt.subplots(
        1, 2 if with_error else 1, figsize=(15 if with_error else 8, 7), squeeze=False
    )
    ax = axes[0, 0]
    if gnss_en_m.size:
        ax.plot(gnss_en_m[:, 0], gnss_en_m[:, 1], ".", ms=2, color="0.6", label="GNSS fixes")
    if reference_en_m is not None and reference_en_m.size:
        ax.plot(reference_en_m[:, 0], reference_en_m[:, 1], "k-", lw=1.0, label=reference_label)
    if estimate_en_m.size:
        ax.plot(estimate_en_m[:, 0], estimate_en_m[:, 1], "C0-", lw=1.0, label="MPF estimate")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.grid(alpha=0.3)
    ax.legend(loc="best")
    ax.set_title("Trajectory in the local ENU frame")
    if with_error:
        assert reference_en_m is not None and t_s is not None
        ax = axes[0, 1]
        err = np.hypot(*(estimate_en_m - reference_en_m).T)
        ax.plot(t_s, err, "C0-", lw=1.0, label="MPF estimate")
        ax.set_xlabel("time since bag start [s]")
        ax.set_ylabel(f"horizontal distance from {reference_label} [m]")
        ax.set_ylim(bottom=0.0)
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
        ax.set_title("Position error over time")
    save_figure(fig, path)


def plot_innovations(
    path: Path, t_s: F64, innov_m: F64, innov_cov_m2: F64, nis: F64, accepted: NDArray[np.bool_]
) -> None:
    """GNSS innovations (east, north) with +-2 sqrt(S) bounds, and the NIS with chi2 bounds."""
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    for k, name in enumerate(("east", "north")):
        ax = axes[k]
        sd = np.sqrt(np.maximum(innov_cov_m2[:, k, k], 0.0)) if innov_cov_m2.size else t_s
        ax.plot(t_s, innov_m[:, k] if innov_m.size else t_s, ".", ms=1.5, color="C0")
        ax.plot(t_s, 2 * sd, "C1-", lw=0.8, label="±2√S")
        ax.plot(t_s, -2 * sd, "C1-", lw=0.8)
        ax.set_ylabel(f"{name} innovation [m]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    ax = axes[2]
    ax.semilogy(t_s[accepted], nis[accepted], ".", ms=1.5, color="C0", label="accepted")
    if (~accepted).any():
        ax.semilogy(t_s[~accepted], nis[~accepted], "x", ms=3, color="C3", label="rejected")
    ax.axhline(stats.chi2.ppf(0.95, 2), color="C1", lw=0.8, label="χ²(2) 95 %")
    ax.set_ylabel("NIS")
    ax.set_xlabel("time since bag start [s]")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.suptitle("GNSS innovations")
    save_figure(fig, path)


def plot_lateral_state(
    path: Path,
    start_ns: int,
    lr_m: float,
    series: dict[str, dict[str, NDArray[np.generic]]],
    reference: tuple[F64, F64, F64, str, str] | None,
) -> None:
    """Sideslip (deg) and yaw rate (deg/s) of each lateral estimator against the reference.

    ``series``: name -> arrays of an ``ImuLateralTrace`` (CG values). ``reference`` = (t_s,
    sideslip rad, yaw rate rad/s, label, point); with point ``base_link`` the estimates are
    moved to the rear axle (vy - lr r) before the sideslip is taken.
    """
    fig, axes = plt.subplots(2, 1, figsize=(11, 6), sharex=True)
    point = reference[4] if reference is not None else "cg"
    if reference is not None:
        # the reference on top of the estimates (drawn first, it would be hidden under them)
        for ax, values in zip(axes, (reference[1], reference[2]), strict=True):
            ax.plot(
                reference[0], np.degrees(values), color="k", lw=1.3, zorder=10,
                label=reference[3],
            )  # fmt: skip
    for i, (name, arr) in enumerate(series.items()):
        t_s = (np.asarray(arr["t_ns"], dtype=np.int64) - start_ns) * 1e-9
        vx = np.asarray(arr["vx_m_s"], dtype=float)
        vy = np.asarray(arr["vy_m_s"], dtype=float)
        r = np.asarray(arr["yaw_rate_rad_s"], dtype=float)
        if point == "base_link":
            vy = vy - lr_m * r
        beta = np.arctan2(vy, np.maximum(vx, 0.1))
        axes[0].plot(t_s, np.degrees(beta), color=f"C{i}", lw=0.9, label=name)
        axes[1].plot(t_s, np.degrees(r), color=f"C{i}", lw=0.9, label=name)
    axes[0].set_ylabel(f"sideslip at {point} [deg]")
    axes[1].set_ylabel("yaw rate [deg/s]")
    axes[1].set_xlabel("time from start of bag [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    save_figure(fig, path)


def plot_stiffness(
    path: Path,
    t_s: F64,
    names: tuple[str, ...],
    stiffness: F64,
    std: F64,
    truth: tuple[F64, tuple[str, ...], F64] | None = None,
) -> None:
    """Learned stiffness per name (kN per unit slip or kN/rad) with a +-2 std band, and the
    truth when the bag has it (``truth`` = (t_s, names, values (T, K)))."""
    n = len(names)
    fig, axes = plt.subplots(n, 1, figsize=(10, 2.4 * n), sharex=True, squeeze=False)
    for j, name in enumerate(names):
        ax = axes[j, 0]
        k = 1e-3 * stiffness[:, j]
        band = 2e-3 * std[:, j]
        ax.fill_between(t_s, k - band, k + band, color="C0", alpha=0.2, label="±2σ")
        ax.plot(t_s, k, color="C0", lw=1.0, label=name)
        if truth is not None and name in truth[1]:
            ax.step(
                truth[0], 1e-3 * truth[2][:, truth[1].index(name)], where="post", color="k",
                lw=1.2, zorder=10, label="truth",
            )  # fmt: skip
        unit = "kN/unit slip" if name.startswith("cx") else "kN/rad"
        ax.set_ylabel(f"{name} [{unit}]")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time from start of bag [s]")
    save_figure(fig, path)


def plot_detection(
    path: Path,
    t_s: F64,
    wheel_names: tuple[str, ...],
    cusum_m: F64,
    threshold_m: F64,
    calibration_done_s: float | None,
    alarms_s: list[tuple[str, float]],
    events_s: list[tuple[float, str]] | None = None,
) -> None:
    """The deflation detector's CUSUM statistic g per wheel against its threshold (mm), the end
    of the calibration, the alarms and the bag's events."""
    n = max(len(wheel_names), 1)
    fig, axes = plt.subplots(n, 1, figsize=(10, 2.2 * n), sharex=True, squeeze=False)
    for i, w in enumerate(wheel_names):
        ax = axes[i, 0]
        ax.plot(t_s, 1e3 * cusum_m[:, i], color="C0", lw=1.2, label="CUSUM g")
        ax.plot(t_s, 1e3 * threshold_m[:, i], color="C3", lw=1.0, ls="--", label="threshold")
        if calibration_done_s is not None:
            ax.axvline(calibration_done_s, color="C2", lw=0.8, label="calibration done")
        for wheel, t_alarm in alarms_s:
            if wheel in (w, "all"):
                ax.axvline(t_alarm, color="C3", lw=1.5, label=f"alarm ({wheel})")
        _mark_events(ax, events_s, "k", ":")
        _label_wheel_axis(ax, f"{w}\n[mm]", i == 0, "upper left")
    _save_wheel_figure(
        fig, axes, "Deflation detector: CUSUM of the radius decrease against its threshold", path
    )


def _label_wheel_axis(ax: Any, ylabel: str, legend: bool, legend_loc: str) -> None:
    """Y label and grid of one wheel's panel; the legend on the first panel only."""
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    if legend:
        ax.legend(loc=legend_loc, fontsize=8, ncol=4)


def _save_wheel_figure(fig: Any, axes: Any, title: str, path: Path) -> None:
    """Time axis label under the last wheel panel, the title, and the PNG."""
    axes[-1, 0].set_xlabel("time since bag start [s]")
    fig.suptitle(title)
    save_figure(fig, path)
