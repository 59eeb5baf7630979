"""Algorithm 1 against AUGPF, EKF, KF + RLS and the grid on ``stiffness_step`` and the sine drives.

Berntorp & Di Cairano, IEEE TCST 2018, Sec. VI: the same bias-free ``stiffness_step`` drives
(simulator seeds) go through Algorithm 1 (:class:`StiffnessEstimator` with
:func:`~tire_estimation.evaluation.stiffness.eval_config`, initial stiffness 0.7 of nominal)
and the baselines of :mod:`tire_estimation.evaluation.stiffness_baselines`, and the point-mass
filter of :mod:`tire_estimation.core.stiffness.grid` (not in the paper), which share every setting
of the same name with that configuration (``BaselineConfig.sharing``) and run behind Algorithm 1's
front-end (:class:`~tire_estimation.core.stiffness.frontend.StiffnessFrontEnd`)::

    python -m tire_estimation.evaluation.stiffness_compare --out DIR --runs R \\
        --particles 50 100 200 500 [--seeds S ...] [--jobs J]

writes ``compare.json`` (per run and summary), ``fig5_vy_rmse.png`` (time-averaged RMSE of vY
at the CG against N for Algorithm 1 and AUGPF, EKF, RLS and the grid as horizontal lines),
``fig6_cy_front.png`` (histograms over the runs of the steady-state mean relative error of
Cy_front and of its reported std relative to the truth, at the largest N) and
``timing.png`` (time per IMU step). Steady state as :mod:`~tire_estimation.evaluation.stiffness`:
15-29.5 s and after 45 s from the first IMU sample.

On the sine drives (``snow_sine``, ``asphalt_sine``; scored as
:func:`~tire_estimation.evaluation.stiffness.sine_study`: steady state the last 5 s, settling
within 5 % after activation), every method from each factor x the drive's truth::

    python -m tire_estimation.evaluation.stiffness_compare --out DIR --sine snow_sine \\
        --runs 50 --particles 200 --jobs 2 --set friction_coefficient=0.3 \\
        [--set niw_update=rao_blackwellized] [--set augpf.FIELD=VALUE ...]

writes ``compare_snow_sine.json`` and prints one table per factor. Shared settings (e.g. the
friction-limited tyre's ``friction_coefficient``) reach the baselines too.

The reported std is not the same quantity for every method: Algorithm 1 reports the std of
the stiffness noise ``w`` (eq. 27b), the baselines the posterior std of their estimate.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.ticker import NullFormatter

from tire_estimation.atomic_io import atomic_write_text
from tire_estimation.core.stiffness.estimator import StiffnessEstimator
from tire_estimation.core.stiffness.frontend import StiffnessFrontEnd
from tire_estimation.core.stiffness.grid import GridConfig
from tire_estimation.evaluation.stiffness import (
    NO_BIAS,
    eval_config,
    feed,
    parse_set,
    sine_aggregate,
    sine_run_scores,
    truth_at,
    truth_over_nominal,
)
from tire_estimation.evaluation.stiffness_baselines import (
    AugPfConfig,
    BaselineEstimator,
    EkfConfig,
    RlsConfig,
)
from tire_estimation.sim import SimResult, simulate

#: Initial stiffness of every method as a fraction of nominal (paper Sec. VI-A: 70 %).
INITIAL_STIFFNESS_FACTOR = 0.7
#: Generator seed of the particle filters = simulator seed + this (as ``stiffness.main``).
FILTER_SEED_OFFSET = 100
#: On the sine drives: seed 1000 + simulator seed, as ``stiffness.sine_study``.
SINE_FILTER_SEED_OFFSET = 1000
#: A run with a vY RMSE above this diverged (counted in the summary), m/s.
DIVERGED_VY_RMSE_M_S = 1.0
METHODS = ("alg1", "augpf", "ekf", "rls", "grid")
LABELS = {
    "alg1": "Algorithm 1",
    "augpf": "AUGPF",
    "ekf": "EKF",
    "rls": "KF + RLS",
    "grid": "grid + EKFs",
}
#: Methods with one run per drive (no particle count), their plot colours.
DETERMINISTIC = (("ekf", "C2"), ("rls", "C1"), ("grid", "C4"))
#: Methods that do not estimate Cx (held at the initial guess).
NO_CX = ("rls", "grid")


def replay(
    sim: SimResult, est: StiffnessFrontEnd[Any], ready: Callable[[], bool]
) -> dict[str, np.ndarray]:
    """Feed ``sim`` through ``est`` in stamp order; arrays on the IMU grid.

    Keys: ``t_s`` (from the first IMU sample), ``c``/``std`` (K, 3), ``vy`` (CG), ``ready``,
    ``active`` (learning on),
    ``truth_c`` (stiffness at the next truth sample), ``truth_vy`` (CG, interpolated) and
    ``step_ms`` (mean wall time of ``on_imu``).
    """
    t_ns: list[int] = []
    c: list[np.ndarray] = []
    std: list[np.ndarray] = []
    vy: list[float] = []
    rdy: list[bool] = []
    act: list[bool] = []

    def record(t: int) -> None:
        e = est.estimate()
        t_ns.append(t)
        c.append(e.stiffness)
        std.append(e.stiffness_std)
        vy.append(e.vy_m_s)
        rdy.append(ready())
        act.append(bool(e.active))

    busy_s = feed(sim, est, record)
    tt = np.asarray(t_ns)
    truth_c, _, truth_vy = truth_at(sim, tt)
    return {
        "t_s": (tt - tt[0]) * 1e-9,
        "c": np.asarray(c),
        "std": np.asarray(std),
        "vy": np.asarray(vy),
        "ready": np.asarray(rdy, dtype=bool),
        "active": np.asarray(act, dtype=bool),
        "truth_c": truth_c,
        "truth_vy": truth_vy,
        "step_ms": np.asarray(1e3 * busy_s / max(len(t_ns), 1)),
    }


def scores(res: dict[str, np.ndarray]) -> dict[str, Any]:
    """vY RMSE (ready samples), steady-state relative stiffness error and std, step time."""
    m = res["ready"]
    t_s = res["t_s"]
    steady = m & (((t_s > 15.0) & (t_s < 29.5)) | (t_s > 45.0))
    rel = res["c"] / res["truth_c"] - 1.0
    rel_std = res["std"] / res["truth_c"]
    err = res["vy"][m] - res["truth_vy"][m]
    return {
        "vy_rmse_m_s": float(np.sqrt(np.mean(err * err))) if err.size else float("nan"),
        "steady_mean_rel_error": rel[steady].mean(axis=0).tolist(),
        "steady_rel_std": rel_std[steady].mean(axis=0).tolist(),
        "final_rel_error": rel[m][-1].tolist() if m.any() else None,
        "step_ms": float(res["step_ms"]),
    }


def configs(n: int, initial_vy_std_m_s: float | None, **overrides: Any) -> dict[str, Any]:
    """Configurations of the four methods at ``n`` particles (shared values from Alg. 1's).

    ``overrides``: ``StiffnessEstimatorConfig`` fields of Algorithm 1 (after the initial factor
    and ``initial_vy_std_m_s``); the baselines take those they share (``BaselineConfig``). A
    key ``augpf.FIELD``, ``ekf.FIELD``, ``rls.FIELD`` or ``grid.FIELD`` sets a field of that
    method only (e.g. ``augpf.stiffness_walk_std_fraction_sqrt_s``, ``grid.grid_points``).
    """
    extra: dict[str, Any] = {"initial_stiffness_factor": INITIAL_STIFFNESS_FACTOR}
    if initial_vy_std_m_s is not None:
        extra["initial_vy_std_m_s"] = initial_vy_std_m_s
    own: dict[str, dict[str, Any]] = {"augpf": {}, "ekf": {}, "rls": {}, "grid": {}}
    for key, value in overrides.items():
        method, dot, field = key.partition(".")
        if dot and method in own:
            own[method][field] = value
        else:
            extra[key] = value
    alg1 = eval_config(n, **extra)
    return {
        "alg1": alg1,
        "augpf": AugPfConfig.sharing(alg1, **{"n_particles": n, **own["augpf"]}),
        "ekf": EkfConfig.sharing(alg1, **own["ekf"]),
        "rls": RlsConfig.sharing(alg1, **own["rls"]),
        "grid": GridConfig.sharing(alg1, **own["grid"]),
    }


def run_seed(seed: int, particles: list[int], initial_vy_std_m_s: float | None) -> dict[str, Any]:
    """Every method on the ``stiffness_step`` drive of ``seed`` -> {method: {N: scores}}."""
    sim = simulate("stiffness_step", seed=seed, minutes=1.0, sensors=NO_BIAS)
    out: dict[str, Any] = {m: {} for m in METHODS}
    fseed = seed + FILTER_SEED_OFFSET
    for n in particles:
        cfg = configs(n, initial_vy_std_m_s)
        alg1 = StiffnessEstimator(cfg["alg1"], sim.vehicle, np.random.default_rng(fseed))
        out["alg1"][str(n)] = scores(replay(sim, alg1, lambda e=alg1: e.mpf.initialized))
        aug = BaselineEstimator(cfg["augpf"], sim.vehicle, np.random.default_rng(fseed))
        out["augpf"][str(n)] = scores(replay(sim, aug, lambda e=aug: e.initialized))
    cfg = configs(particles[0], initial_vy_std_m_s)
    for m, _ in DETERMINISTIC:
        est = BaselineEstimator(cfg[m], sim.vehicle)
        out[m]["-"] = scores(replay(sim, est, lambda e=est: e.initialized))
    return out


def sine_scores(res: dict[str, np.ndarray]) -> dict[str, Any]:
    """Scores of one method on a sine drive: :func:`~.stiffness.sine_run_scores` (activation,
    settling, steady mean and maximum relative error), the vY RMSE at the CG over the ready
    samples, and the step time.
    """
    m = res["ready"]
    err = res["vy"][m] - res["truth_vy"][m]
    return {
        **sine_run_scores(res["t_s"], res["c"] / res["truth_c"] - 1.0, res["active"]),
        "vy_rmse_m_s": float(np.sqrt(np.mean(err * err))) if err.size else float("nan"),
        "step_ms": float(res["step_ms"]),
    }


def run_sine_seed(
    seed: int,
    scenario: str,
    factor: float,
    n: int,
    overrides: dict[str, Any],
    methods: tuple[str, ...] = METHODS,
) -> dict[str, Any]:
    """Every method on the sine drive ``scenario`` of ``seed``, started at ``factor`` x truth.

    As :func:`~.stiffness.sine_study` (bias-free, all stiffnesses scaled alike, Algorithm 1
    seeded 1000 + seed); the AUGPF gets the same seed. ``overrides`` go to Algorithm 1's
    configuration and, where the names are shared, to the baselines' (e.g.
    ``friction_coefficient``). ``methods``: which of :data:`METHODS` run. -> {method: scores}.
    """
    sim = simulate(scenario, seed=seed, sensors=NO_BIAS)
    start = factor * truth_over_nominal(sim)
    cfg = configs(n, None, **{**overrides, "initial_stiffness_factor": start})
    fseed = SINE_FILTER_SEED_OFFSET + seed
    out: dict[str, Any] = {}
    for m in methods:
        est, ready = _estimator(m, cfg, sim, fseed)
        out[m] = sine_scores(replay(sim, est, ready))
    return out


def _estimator(
    method: str, cfg: dict[str, Any], sim: SimResult, fseed: int
) -> tuple[StiffnessFrontEnd[Any], Callable[[], bool]]:
    """The estimator of ``method`` (a key of :func:`configs`) for ``sim`` and its ready test;
    the particle filters take the generator seed ``fseed``."""
    if method == "alg1":
        alg1 = StiffnessEstimator(cfg["alg1"], sim.vehicle, np.random.default_rng(fseed))
        return alg1, lambda: alg1.mpf.initialized
    rng = np.random.default_rng(fseed) if method == "augpf" else None
    base = BaselineEstimator(cfg[method], sim.vehicle, rng)
    return base, lambda: base.initialized


def sine_summary(
    per_run: list[dict[str, Any]], max_error: float = 0.03, methods: tuple[str, ...] = METHODS
) -> dict[str, Any]:
    """Per method over the runs, cornering stiffness front / rear (as ``sine_study``), in %.

    Mean of the steady mean error, mean |steady mean error|, p95 and maximum of the steady
    maximum |error|, runs whose steady maximum |error| (front or rear) exceeds ``max_error``,
    share of runs settled within 2 s of activation, median settling time, mean vY RMSE.
    """
    out: dict[str, Any] = {}
    for m in methods:
        rows = [r[m] for r in per_run]
        agg = sine_aggregate(rows)
        top = np.array([r["steady_max_abs_rel_error"][1:] for r in rows])
        out[m] = {
            "cy_steady_mean_error_mean_pct": _pct(agg["cy_steady_mean_rel_error_mean"]),
            "cy_steady_abs_mean_error_mean_pct": _pct(agg["cy_steady_mean_abs_rel_error_mean"]),
            "cy_steady_max_abs_error_p95_pct": _pct(agg["cy_steady_max_abs_rel_error_p95"]),
            "cy_steady_max_abs_error_max_pct": _pct(agg["cy_steady_max_abs_rel_error_max"]),
            "runs_above_max_error": int(np.sum(top.max(axis=1) > max_error)),
            "cy_settled_within_2s_share": agg["cy_settled_within_2s_share"],
            "cy_settling_s_median": agg["cy_settling_s_median"],
            "cy_settling_s_max": agg["cy_settling_s_max"],
            "vy_rmse_mean_m_s": float(np.mean([r["vy_rmse_m_s"] for r in rows])),
            "step_ms_mean": float(np.mean([r["step_ms"] for r in rows])),
        }
    return out


def _pct(values: list[float]) -> list[float]:
    return [100.0 * v for v in values]


def _sine_table(summary: dict[str, Any], runs: int) -> str:
    """Markdown table of :func:`sine_summary` (front / rear)."""
    lines = [
        "| method | mean steady error | mean \\|steady error\\| | p95 / max steady max "
        f"\\|error\\| | runs > 3 % (of {runs}) | settled within 2 s | vY RMSE m/s |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in summary:
        s = summary[m]
        f, r = s["cy_steady_mean_error_mean_pct"]
        af, ar = s["cy_steady_abs_mean_error_mean_pct"]
        pf, pr = s["cy_steady_max_abs_error_p95_pct"]
        xf, xr = s["cy_steady_max_abs_error_max_pct"]
        sf, sr = s["cy_settled_within_2s_share"]
        lines.append(
            f"| {LABELS[m]} | {f:+.2f} / {r:+.2f} % | {af:.2f} / {ar:.2f} % | {pf:.1f} / {pr:.1f}"
            f" and {xf:.1f} / {xr:.1f} % | {s['runs_above_max_error']} | {100 * sf:.0f} / "
            f"{100 * sr:.0f} % | {s['vy_rmse_mean_m_s']:.3f} |"
        )
    return "\n".join(lines)


def _summary(per_run: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """Mean / median / std over the runs for every method and N (Cy_front = index 1)."""
    runs = list(per_run.values())
    out: dict[str, Any] = {}
    for m in METHODS:
        out[m] = {}
        for key in runs[0][m]:
            rows = [r[m][key] for r in runs]
            vy = np.array([r["vy_rmse_m_s"] for r in rows])
            err = 100.0 * np.array([r["steady_mean_rel_error"] for r in rows])
            sd = 100.0 * np.array([r["steady_rel_std"] for r in rows])
            out[m][key] = {
                "vy_rmse_mean_m_s": float(np.mean(vy)),
                "vy_rmse_median_m_s": float(np.median(vy)),
                "vy_rmse_std_m_s": float(np.std(vy)),
                "diverged_runs": int(np.sum(vy > DIVERGED_VY_RMSE_M_S)),
                "cy_front_steady_error_mean_pct": float(np.mean(err[:, 1])),
                "cy_front_steady_error_std_pct": float(np.std(err[:, 1])),
                "cy_front_steady_abs_error_mean_pct": float(np.mean(np.abs(err[:, 1]))),
                "cy_front_reported_std_mean_pct": float(np.mean(sd[:, 1])),
                "cy_rear_steady_abs_error_mean_pct": float(np.mean(np.abs(err[:, 2]))),
                "cx_steady_abs_error_mean_pct": (
                    None if m in NO_CX else float(np.mean(np.abs(err[:, 0])))
                ),
                "step_ms_mean": float(np.mean([r["step_ms"] for r in rows])),
            }
    return out


def plot_fig5(path: Path, summary: dict[str, Any], particles: list[int]) -> None:
    """Time-averaged vY RMSE against N (Fig. 5 style), mean (solid) and median (dashed)."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    ns = np.array(particles, dtype=float)
    for m, color in (("alg1", "C3"), ("augpf", "C0")):
        mean = [summary[m][str(n)]["vy_rmse_mean_m_s"] for n in particles]
        med = [summary[m][str(n)]["vy_rmse_median_m_s"] for n in particles]
        ax.plot(ns, mean, "o-", color=color, label=f"{LABELS[m]} (mean)")
        ax.plot(ns, med, "s--", color=color, alpha=0.6, label=f"{LABELS[m]} (median)")
    for m, color in DETERMINISTIC:
        v = summary[m]["-"]["vy_rmse_mean_m_s"]
        ax.axhline(v, color=color, ls=":", label=f"{LABELS[m]} (mean)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xticks(ns)
    ax.set_xticklabels([str(n) for n in particles])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel("number of particles N")
    ax.set_ylabel("time-averaged RMSE of vY at the CG [m/s]")
    ax.set_title("stiffness_step, bias-free (Fig. 5 style)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_fig6(path: Path, per_run: dict[str, dict[str, Any]], n_max: int) -> None:
    """Histograms of the steady mean error of Cy_front and of its reported std (Fig. 6 style)."""
    runs = list(per_run.values())
    keys = {"alg1": str(n_max), "augpf": str(n_max), **{m: "-" for m, _ in DETERMINISTIC}}
    colors = {"alg1": "C3", "augpf": "C0", **dict(DETERMINISTIC)}
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for i, (field, title) in enumerate(
        (
            ("steady_mean_rel_error", "steady-state mean error of Cy_front [% of truth]"),
            ("steady_rel_std", "reported std of Cy_front [% of truth]"),
        )
    ):
        vals = {m: np.array([100.0 * r[m][keys[m]][field][1] for r in runs]) for m in METHODS}
        allv = np.concatenate(list(vals.values()))
        lo, hi = np.percentile(allv, [1, 99]) if allv.size else (0.0, 1.0)
        bins = np.linspace(lo, hi if hi > lo else lo + 1.0, 41)
        for m in METHODS:
            label = LABELS[m] + (f" N={n_max}" if m in ("alg1", "augpf") else "")
            axes[i].hist(
                np.clip(vals[m], bins[0], bins[-1]),
                bins=bins,
                weights=np.full(vals[m].size, 1.0 / max(vals[m].size, 1)),
                histtype="stepfilled",
                alpha=0.35,
                edgecolor=colors[m],
                lw=1.5,
                color=colors[m],
                label=label,
            )
        axes[i].set_xlabel(title)
        axes[i].set_ylabel("fraction of runs")
        axes[i].grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"stiffness_step, {len(runs)} runs (Fig. 6 style; outliers clipped to the axis)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_timing(path: Path, summary: dict[str, Any], particles: list[int]) -> None:
    """Mean wall time per IMU step against N."""
    fig, ax = plt.subplots(figsize=(6.5, 4.2))
    for m, color in (("alg1", "C3"), ("augpf", "C0")):
        ax.plot(
            particles,
            [summary[m][str(n)]["step_ms_mean"] for n in particles],
            "o-",
            color=color,
            label=LABELS[m],
        )
    for m, color in DETERMINISTIC:
        ax.axhline(summary[m]["-"]["step_ms_mean"], color=color, ls=":", label=LABELS[m])
    ax.set_xlabel("number of particles N")
    ax.set_ylabel("time per IMU step [ms] (Python, shared machine)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def plot_all(
    out: Path, summary: dict[str, Any], per_run: dict[str, dict[str, Any]], particles: list[int]
) -> None:
    """Write ``fig5_vy_rmse.png``, ``fig6_cy_front.png`` and ``timing.png`` to ``out``."""
    plot_fig5(out / "fig5_vy_rmse.png", summary, particles)
    plot_fig6(out / "fig6_cy_front.png", per_run, particles[-1])
    plot_timing(out / "timing.png", summary, particles)


def _config_record(initial_vy_std_m_s: float | None, n: int) -> dict[str, Any]:
    return {m: dataclasses.asdict(c) for m, c in configs(n, initial_vy_std_m_s).items()}


def _table(summary: dict[str, Any]) -> str:
    lines = [
        f"{'method':<12}{'N':>5}{'vY RMSE mean':>14}{'median':>9}{'div':>5}"
        f"{'Cyf err mean':>14}{'|err|':>8}{'std rep':>9}{'ms/step':>9}"
    ]
    for m in METHODS:
        for key, s in summary[m].items():
            lines.append(
                f"{LABELS[m]:<12}{key:>5}{s['vy_rmse_mean_m_s']:>14.4f}"
                f"{s['vy_rmse_median_m_s']:>9.4f}{s['diverged_runs']:>5d}"
                f"{s['cy_front_steady_error_mean_pct']:>13.2f}%"
                f"{s['cy_front_steady_abs_error_mean_pct']:>7.2f}%"
                f"{s['cy_front_reported_std_mean_pct']:>8.2f}%{s['step_ms_mean']:>9.3f}"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    """Command line entry point."""
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--runs", type=int, default=2, help="drives (seeds 0 .. runs-1)")
    ap.add_argument("--seeds", type=int, nargs="+", help="simulator seeds (overrides --runs)")
    ap.add_argument("--particles", type=int, nargs="+", default=[50, 100, 200, 500])
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (one drive each)")
    ap.add_argument(
        "--initial-vy-std",
        type=float,
        default=None,
        help="prior std of vY for every method, m/s (default: eval_config's)",
    )
    ap.add_argument("--replot", action="store_true", help="only redraw from DIR/compare.json")
    ap.add_argument(
        "--sine",
        metavar="SCENARIO",
        help="compare on this sine drive (snow_sine, asphalt_sine) instead, at the first "
        "--particles value, from each --factors x truth; writes compare_SCENARIO.json",
    )
    ap.add_argument("--factors", type=float, nargs="+", default=[1.5, 0.75])
    ap.add_argument(
        "--methods",
        nargs="+",
        choices=METHODS,
        default=list(METHODS),
        help="with --sine: the methods to run (default: all)",
    )
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="FIELD=VALUE",
        help="with --sine: a StiffnessEstimatorConfig field of Algorithm 1, shared with the "
        "baselines where they have it (e.g. friction_coefficient=0.3)",
    )
    args = ap.parse_args(argv)
    if args.sine:
        _main_sine(args)
        return
    if args.replot:
        old = json.loads((args.out / "compare.json").read_text())
        plot_all(args.out, old["summary"], old["per_run"], old["particles"])
        print(_table(old["summary"]))
        return
    seeds = list(args.seeds) if args.seeds else list(range(args.runs))
    particles = sorted(set(args.particles))
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    per_run: dict[str, dict[str, Any]] = {}
    if args.jobs > 1:
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            futures = {s: pool.submit(run_seed, s, particles, args.initial_vy_std) for s in seeds}
            for s, f in futures.items():
                per_run[str(s)] = f.result()
                print(f"seed {s} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    else:
        for s in seeds:
            per_run[str(s)] = run_seed(s, particles, args.initial_vy_std)
            print(f"seed {s} done ({time.perf_counter() - t0:.0f} s)", flush=True)
    summary = _summary(per_run)
    report = {
        "scenario": "stiffness_step",
        "sensors": "NO_BIAS",
        "seeds": seeds,
        "particles": particles,
        "jobs": args.jobs,
        "wall_s": time.perf_counter() - t0,
        "notes": {
            "vy": "RMSE of vY at the CG over the samples after initialization, m/s",
            "steady": "15-29.5 s and after 45 s; errors relative to the true stiffness",
            "std": "alg1: std of the stiffness noise w (eq. 27b); baselines: posterior std",
            "rls": "Cx not estimated (fixed at the initial guess)",
            "grid": "point-mass filter with an EKF per cell; Cx not estimated (initial guess)",
            "timing": "wall time of on_imu per IMU step, ms, with --jobs workers running",
        },
        "configs": _config_record(args.initial_vy_std, particles[-1]),
        "summary": summary,
        "per_run": per_run,
    }
    atomic_write_text(args.out / "compare.json", json.dumps(report, indent=2))
    plot_all(args.out, summary, per_run, particles)
    print(_table(summary))
    print(f"wrote {args.out / 'compare.json'} ({report['wall_s']:.0f} s)")


def _main_sine(args: argparse.Namespace) -> None:
    """``--sine``: every method on the sine drives, ``--runs`` (or ``--seeds``) per factor."""
    overrides = parse_set(args.set)
    methods = tuple(m for m in METHODS if m in args.methods)
    seeds = list(args.seeds) if args.seeds else list(range(args.runs))
    n = args.particles[0]
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    jobs = [(f, s) for f in args.factors for s in seeds]
    results: dict[tuple[float, int], dict[str, Any]] = {}
    with ProcessPoolExecutor(max_workers=max(args.jobs, 1)) as pool:
        futures = {
            job: pool.submit(run_sine_seed, job[1], args.sine, job[0], n, overrides, methods)
            for job in jobs
        }
        for job, fut in futures.items():
            results[job] = fut.result()
    report: dict[str, Any] = {
        "scenario": args.sine,
        "sensors": "NO_BIAS",
        "seeds": seeds,
        "n_particles": n,
        "methods": list(methods),
        "overrides": overrides,
        "wall_s": time.perf_counter() - t0,
        "notes": {
            "steady": "last 5 s of the drive; errors relative to the true stiffness",
            "settling": "time after activation from which |error| stays within 5 %",
            "start": "every stiffness at factor x the drive's truth",
        },
        "by_factor": {},
    }
    for f in args.factors:
        per_run = [results[(f, s)] for s in seeds]
        summary = sine_summary(per_run, methods=methods)
        report["by_factor"][str(f)] = {"summary": summary, "per_run": per_run}
        print(f"{args.sine} from {f:.0%} of the truth, N = {n}, {len(seeds)} runs:")
        print(_sine_table(summary, len(seeds)))
    path = args.out / f"compare_{args.sine}.json"
    atomic_write_text(path, json.dumps(report, indent=2))
    print(f"wrote {path} ({report['wall_s']:.0f} s)")


if __name__ == "__main__":
    main()
