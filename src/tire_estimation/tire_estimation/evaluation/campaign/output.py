"""Campaign files: ``cases.csv`` (written and read back), the plots and the result
directory."""

from __future__ import annotations

import csv
import io
import itertools
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.evaluation.campaign.spec import (
    DIFFUSION_DEADLINE_S,
    STEP_DEADLINE_S,
    TARGET_ABSOLUTE_M,
    TARGET_RELATIVE_M,
    CampaignError,
)
from tire_estimation.paths import prepare_out_dir


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    """One row per case; columns = union of the keys (first-seen order)."""
    keys: dict[str, None] = {}
    for r in rows:
        keys.update(dict.fromkeys(r))
    buffer = io.StringIO(newline="")
    writer = csv.DictWriter(buffer, fieldnames=list(keys), restval="")
    writer.writeheader()
    for r in rows:
        writer.writerow(r)
    atomic_write_text(path, buffer.getvalue())


def _csv_value(text: str) -> Any:
    """A ``cases.csv`` cell back to the row's value: '' -> None, True/False, int, float, str."""
    if text == "":
        return None
    if text in ("True", "False"):
        return text == "True"
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def read_csv_rows(path: Path) -> list[dict[str, Any]]:
    """Rows of a ``cases.csv`` written by :func:`write_csv`, with their types restored.

    An empty ``error`` cell stays ``""`` (a case without error), as :func:`run_case` writes it.
    """
    with path.open(newline="") as fh:
        rows = [{k: _csv_value(v) for k, v in r.items()} for r in csv.DictReader(fh)]
    for r in rows:
        if r.get("error") is None:
            r["error"] = ""
    return rows


def plot_calibration(path: Path, rows: Sequence[dict[str, Any]], at_s: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tire_estimation.evaluation.plots import save_figure

    seeds = [r["seed"] for r in rows]
    x = np.arange(len(rows))
    fig, axes = plt.subplots(3, 1, figsize=(max(8.0, 0.45 * len(rows)), 9.0), sharex=True)
    panels = (
        ("rel_err_at_m", "relative (rl − rr) error", TARGET_RELATIVE_M),
        ("abs_err_rl_at_m", "absolute error rl", TARGET_ABSOLUTE_M),
        ("abs_err_rr_at_m", "absolute error rr", TARGET_ABSOLUTE_M),
    )
    for ax, (key, title, target) in zip(axes, panels, strict=True):
        for off, m, lab in ((-0.2, "mpf", "MPF"), (0.2, "aug_kf", "AUG-KF")):
            vals = np.array(
                [np.nan if r.get(f"{m}_{key}") is None else 1e3 * r[f"{m}_{key}"] for r in rows]
            )
            ax.bar(x + off, vals, width=0.4, label=lab)
        for s in (-1, 1):
            ax.axhline(s * 1e3 * target, color="k", ls="--", lw=0.8)
        ax.set_ylabel("mm")
        ax.set_title(f"{title} at {at_s / 60:g} min (target ±{1e3 * target:g} mm)")
        ax.grid(alpha=0.3)
    axes[0].legend()
    axes[-1].set_xticks(x, [str(s) for s in seeds])
    axes[-1].set_xlabel("seed")
    save_figure(fig, path)


def plot_detection(out_dir: Path, rows: Sequence[dict[str, Any]]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from tire_estimation.evaluation.plots import save_figure

    written = []
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), squeeze=False)
    for ax, kind in zip(axes[0], ("step", "diffusion"), strict=True):
        data, labels = [], []
        for m, lab in (("mpf", "MPF+CUSUM"), ("aug_kf", "AUG-KF+CUSUM")):
            kr = [r for r in rows if r["kind"] == kind and not r.get("error")]
            t = [r[f"{m}_detection_time_s"] / 60.0 for r in kr if r.get(f"{m}_detected")]
            missed = sum(1 for r in kr if r.get(f"{m}_ok") and not r.get(f"{m}_detected"))
            data.append(t)
            labels.append(f"{lab} ({len(t)} found, {missed} missed)")
        limit_min = (STEP_DEADLINE_S if kind == "step" else DIFFUSION_DEADLINE_S) / 60.0
        top = max([limit_min, *itertools.chain.from_iterable(data)])
        if any(data):
            ax.hist(data, bins=np.linspace(0.0, top, 21), label=labels)
            ax.axvline(limit_min, color="k", ls="--", lw=0.8)
            ax.legend(fontsize=8)
        else:
            ax.text(0.5, 0.5, "\n".join(labels), ha="center", transform=ax.transAxes)
        ax.set_xlabel("detection time after the event, min")
        ax.set_ylabel("cases")
        ax.set_title(f"{kind}: detection times")
        ax.grid(alpha=0.3)
    p = out_dir / "detection_times.png"
    save_figure(fig, p)
    written.append(p.name)
    fig, ax = plt.subplots(figsize=(7, 4))
    steps = [r for r in rows if r["kind"] == "step" and not r.get("error")]
    for m, lab in (("mpf", "MPF"), ("aug_kf", "AUG-KF")):
        v = [
            1e3 * r[f"{m}_estimated_change_m"]
            for r in steps
            if r.get(f"{m}_estimated_change_m") is not None
        ]
        if v:
            ax.hist(v, bins=12, alpha=0.6, label=lab)
    tv = [1e3 * r["mpf_true_change_m"] for r in steps if r.get("mpf_true_change_m") is not None]
    if tv:
        ax.hist(tv, bins=12, histtype="step", color="k", label="truth")
    ax.set_xlabel("radius change after the 20 % step, mm")
    ax.set_ylabel("cases")
    ax.set_title("Estimated radius change (cf. paper Fig. 8)")
    if ax.get_legend_handles_labels()[0]:
        ax.legend()
    ax.grid(alpha=0.3)
    p = out_dir / "radius_change.png"
    save_figure(fig, p)
    written.append(p.name)
    return written


def prepare_out(out: Path | str, overwrite: bool) -> Path:
    path = Path(out)
    try:
        if path.exists() and not path.is_dir():
            raise CampaignError(f"--out {path}: exists and is not a directory")
    except OSError:  # a name too long: prepare_out_dir says so
        pass
    if path.is_dir() and (path / "summary.json").exists() and not overwrite:
        raise CampaignError(f"--out {path}: holds a summary.json (use --overwrite)")
    return prepare_out_dir(path)


def versions() -> dict[str, str]:
    out = {"python": sys.version.split()[0], "numpy": np.__version__}
    try:
        import dask
        import distributed

        out["dask"] = dask.__version__
        out["distributed"] = distributed.__version__
    except ImportError:
        pass
    return out
