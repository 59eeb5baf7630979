"""Evaluation campaigns on simulated drives: calibration accuracy and ECE R-64 detection.

Two studies (Lundquist et al., IEEE T-ITS 2014, Section IV):

* :func:`run_calibration_study` -- ``ece_r64`` drives without deflation; MPF and AUG-KF side by
  side (one :class:`RadiusEstimator` with ``run_aug_kf=True``); errors against the simulator's
  true radii at a fixed time (10 min), at the end, time to converge within 0.5 mm, and the
  consistency of the reported std (NEES, fraction within 2 std).
* :func:`run_ece_r64_campaign` -- one-wheel 20 % step deflations, robustness drives without
  deflation and slow diffusion on up to four wheels; the MPF and the AUG-KF estimates of the
  *same* run each feed a fresh CUSUM detector (:func:`run_detector_over_trace`). Detection rate,
  detection times, false alarms (count and rate per monitored hour), estimated radius change.

Every case is a picklable :class:`CaseSpec`; :func:`run_case` turns one into a flat result row
(JSON-ready). Cases run on Dask (``dask.distributed``; a LocalCluster by default, or a remote
scheduler), on a process pool, or serially (:func:`execute_cases`). All randomness comes from the
case seed: the simulator's seed and the particle filter's generator (``seed + 1_000_003``).

``add_campaign_parser`` adds the ``campaign`` sub-command to the ``tire-estimation`` CLI.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import itertools
import json
import math
import os
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import yamlio
from tire_estimation.errors import ConfigError, TireEstimationError

F64 = NDArray[np.float64]

#: Issue-3 targets at 10 min: |relative error rl - rr| and each |absolute error|, m.
TARGET_RELATIVE_M = 0.2e-3
TARGET_ABSOLUTE_M = 0.5e-3
#: ECE R-64 allowed detection time: one-wheel step 10 min, diffusion 60 min, s.
STEP_DEADLINE_S = 600.0
DIFFUSION_DEADLINE_S = 3600.0
#: Offset between the simulator seed and the particle-filter seed of a case.
PF_SEED_OFFSET = 1_000_003

#: GNSS quality levels (SensorConfig overrides); total horizontal std per axis in the comment.
GNSS_LEVELS: dict[str, dict[str, float]] = {
    "good": {"gnss_white_std_m": 0.5, "gnss_gm_std_m": 0.5},  # 0.71 m
    "standard": {"gnss_white_std_m": 1.0, "gnss_gm_std_m": 1.0},  # 1.41 m (simulator default)
    "calibration": {
        "gnss_white_std_m": 1.5 / math.sqrt(2.0),
        "gnss_gm_std_m": 1.5 / math.sqrt(2.0),
    },
    "poor": {"gnss_white_std_m": 2.0, "gnss_gm_std_m": 2.0},  # 2.83 m
}
#: Road levels. The simulator has no road-roughness model; the only road knob is the grade
#: (SensorConfig.road_grade_*), so "hilly" stands in for a rougher, non-flat road.
ROAD_LEVELS: dict[str, dict[str, float]] = {
    "flat": {},
    "hilly": {"road_grade_amplitude_rad": 0.03, "road_grade_wavelength_m": 800.0},
}
#: Tyre sets: radius sensitivity to pressure, mm/kPa (scenario option).
TYRE_SENSITIVITIES_MM_PER_KPA: tuple[float, ...] = (0.015, 0.03, 0.05)


class CampaignError(TireEstimationError, ValueError):
    """A campaign cannot be set up (bad option, output directory, missing executor)."""


# ---------------------------------------------------------------------------------------------
# case description


@dataclass(frozen=True)
class CaseSpec:
    """One simulated drive and how to evaluate it (picklable, JSON-ready via ``to_dict``).

    Attributes:
        case_id: unique name, used in the CSV.
        kind: ``step`` (one-wheel pressure step), ``robustness`` (no deflation), ``diffusion``
            (slow loss) or ``calibration`` (no deflation, accuracy only).
        scenario: simulator scenario (``ece_r64``, ``robustness``, ``diffusion``).
        seed: simulator seed (the particle filter uses ``seed + PF_SEED_OFFSET``).
        minutes: drive length, min.
        options: scenario options.
        sensors: SensorConfig overrides.
        labels: factor levels for the report (``gnss``, ``road``, ``tyre``, ...).
        deflated_wheels: wheels whose pressure drops (empty for robustness/calibration).
        event_s: time of the pressure step / start of the diffusion, s (None: no event).
        deadline_s: allowed detection time after ``event_s``, s.
        detector_calibration_s: CUSUM calibration driving time, s (ECE R-64: 1200).
        estimator: RadiusEstimatorConfig overrides (``run_aug_kf`` is always on).
        braking_source: ``estimate`` (deceleration of the estimator's speed) or ``truth``.
        trace_dir: when set, the estimator traces of the case are saved there as
            ``<case_id>.npz`` (:func:`save_run`), so that detection can be re-run on them
            without simulating again (:func:`redetect_case`).
        detector: DeflationDetectorConfig overrides for this case.
    """

    case_id: str
    kind: str
    scenario: str
    seed: int
    minutes: float
    options: dict[str, Any] = field(default_factory=dict)
    sensors: dict[str, Any] = field(default_factory=dict)
    labels: dict[str, str] = field(default_factory=dict)
    deflated_wheels: tuple[str, ...] = ()
    event_s: float | None = None
    deadline_s: float | None = None
    detector_calibration_s: float = 1200.0
    estimator: dict[str, Any] = field(default_factory=dict)
    braking_source: str = "estimate"
    trace_dir: str = ""
    detector: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (lists for tuples)."""
        d = dataclasses.asdict(self)
        d["deflated_wheels"] = list(self.deflated_wheels)
        return d

    @staticmethod
    def from_dict(d: dict[str, Any]) -> CaseSpec:
        """Inverse of :meth:`to_dict` (``cases.json``); unknown keys are refused."""
        names = {f.name for f in dataclasses.fields(CaseSpec)}
        unknown = sorted(set(d) - names)
        if unknown:
            raise CampaignError(f"case {d.get('case_id')!r}: unknown keys {unknown}")
        return CaseSpec(**{**d, "deflated_wheels": tuple(d.get("deflated_wheels", ()))})


# ---------------------------------------------------------------------------------------------
# one case


@dataclass
class _Run:
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


def _simulate_and_estimate(spec: CaseSpec) -> _Run:
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.wheels import REAR_WHEELS
    from tire_estimation.evaluation.runner import run_radius
    from tire_estimation.sim import START_TIME_NS, SensorConfig, simulate
    from tire_estimation.sources import sim_samples

    t0 = time.perf_counter()
    sensors = SensorConfig(**spec.sensors)
    sim = simulate(
        spec.scenario, seed=spec.seed, minutes=spec.minutes, sensors=sensors, **spec.options
    )
    t1 = time.perf_counter()
    cfg = RadiusEstimatorConfig.from_dict(
        {**spec.estimator, "run_aug_kf": True, "seed": spec.seed + PF_SEED_OFFSET}
    )
    trace = run_radius(cfg, sim.vehicle, sim_samples(sim, tire_forces=False))
    t2 = time.perf_counter()
    a = trace.arrays()
    names = trace.wheel_names or (REAR_WHEELS if cfg.wheels == "rear" else ())
    k = a["t_ns"].size
    kf = a["baseline_radius_error_m"]
    kf_std = a["baseline_radius_error_std_m"]
    if kf.shape[0] != k:
        kf = np.full((k, len(REAR_WHEELS)), np.nan)
        kf_std = np.full((k, len(REAR_WHEELS)), np.nan)
    return _Run(
        t_ns=a["t_ns"],
        t_s=(a["t_ns"] - START_TIME_NS) * 1e-9,
        wheel_names=tuple(names),
        mpf_m=np.asarray(a["radius_error_m"], dtype=float).reshape(k, len(names)),
        mpf_std_m=np.asarray(a["radius_error_std_m"], dtype=float).reshape(k, len(names)),
        kf_wheels=REAR_WHEELS,
        kf_m=np.asarray(kf, dtype=float).reshape(k, len(REAR_WHEELS)),
        kf_std_m=np.asarray(kf_std, dtype=float).reshape(k, len(REAR_WHEELS)),
        speed_m_s=np.asarray(a["speed_m_s"], dtype=float),
        active=np.asarray(a["active"], dtype=bool).reshape(k, len(names)),
        truth_t_ns=sim.truth.t_ns,
        truth_radius_m=sim.truth.wheel_radius_m,
        truth_ax_m_s2=sim.truth.acceleration_m_s2[:, 0],
        nominal_m=float(sim.vehicle.nominal_tire_radius_m),
        sim_s=t1 - t0,
        est_s=t2 - t1,
    )


_RUN_NAMES = ("wheel_names", "kf_wheels")


def save_run(run: _Run, path: Path) -> None:
    """Write the estimator traces and truth of one case to ``path`` (``.npz``)."""
    arrays = {
        f.name: np.asarray(getattr(run, f.name))
        for f in dataclasses.fields(run)
        if f.name not in _RUN_NAMES
    }
    names = {n: np.asarray(getattr(run, n), dtype=str) for n in _RUN_NAMES}
    np.savez_compressed(path, **arrays, **names)


def load_run(path: Path) -> _Run:
    """Read a trace written by :func:`save_run`."""
    with np.load(path) as z:
        values: dict[str, Any] = {}
        for f in dataclasses.fields(_Run):
            v = z[f.name]
            if f.name in _RUN_NAMES:
                values[f.name] = tuple(str(x) for x in v)
            elif v.ndim == 0:
                values[f.name] = float(v)
            else:
                values[f.name] = v
    return _Run(**values)


def _true_error(run: _Run, wheels: Sequence[str]) -> F64:
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
    from tire_estimation.core.deflation.detector import DeflationDetectorConfig

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


def _evaluate_detection(spec: CaseSpec, run: _Run, method: str) -> dict[str, Any]:
    """Run a fresh CUSUM over one method's trace; flat result fields prefixed by ``method``."""
    from tire_estimation.core.deflation.detector import ALL_WHEELS, run_detector_over_trace

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
        tr = _true_error(run, [w])[:, 0]
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


def _evaluate_accuracy(spec: CaseSpec, run: _Run, at_s: float) -> dict[str, Any]:
    """Errors vs truth of both methods at ``at_s`` and at the end, convergence, consistency."""
    from tire_estimation.evaluation.metrics import CONVERGED_M, time_to_converge_s

    out: dict[str, Any] = {}
    rear = ("wheel_rl", "wheel_rr")
    truth = _true_error(run, rear)
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


def _case_row(spec: CaseSpec) -> dict[str, Any]:
    row: dict[str, Any] = {
        "case_id": spec.case_id,
        "kind": spec.kind,
        "scenario": spec.scenario,
        "seed": spec.seed,
        "minutes": spec.minutes,
        "deflated_wheels": ",".join(spec.deflated_wheels),
        "event_s": spec.event_s,
        "deadline_s": spec.deadline_s,
        **{f"label_{k}": v for k, v in spec.labels.items()},
        "error": "",
    }
    return row


def run_case(spec: CaseSpec, accuracy_at_s: float = 600.0) -> dict[str, Any]:
    """Simulate, estimate (MPF + AUG-KF) and evaluate one case; a flat JSON-ready row.

    Never raises for a failing case: the row then has ``error`` set (so one bad case does not
    lose a campaign).
    """
    row = _case_row(spec)
    try:
        run = _simulate_and_estimate(spec)
        if spec.trace_dir:
            save_run(run, Path(spec.trace_dir) / f"{spec.case_id}.npz")
        row["sim_s"] = round(run.sim_s, 2)
        row["estimate_s"] = round(run.est_s, 2)
        row["trace_samples"] = int(run.t_ns.size)
        _evaluate(spec, run, row, accuracy_at_s)
    except Exception as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
    return row


def _evaluate(spec: CaseSpec, run: _Run, row: dict[str, Any], accuracy_at_s: float) -> None:
    if spec.kind == "calibration":
        row.update(_evaluate_accuracy(spec, run, accuracy_at_s))
    else:
        row.update(_evaluate_detection(spec, run, "mpf"))
        row.update(_evaluate_detection(spec, run, "aug_kf"))


def redetect_case(spec: CaseSpec, run: _Run) -> dict[str, Any]:
    """The row of :func:`run_case` from a saved trace (no simulation), e.g. with other
    detector settings in ``spec.detector``."""
    row = _case_row(spec)
    row["trace_samples"] = int(run.t_ns.size)
    try:
        _evaluate(spec, run, row, 600.0)
    except Exception as exc:
        row["error"] = f"{type(exc).__name__}: {exc}"
    return row


# ---------------------------------------------------------------------------------------------
# case generation


def _check_positive(name: str, value: float, low: float = 0.0) -> None:
    if not (math.isfinite(value) and value > low):
        raise CampaignError(f"{name}={value!r}: must be > {low}")


def calibration_cases(
    seeds: int = 20,
    minutes: float = 12.0,
    first_seed: int = 0,
    gnss: str = "calibration",
    estimator: dict[str, Any] | None = None,
    sensors: dict[str, Any] | None = None,
) -> list[CaseSpec]:
    """``seeds`` no-deflation ``ece_r64`` drives of ``minutes`` (issue-3 accuracy study);
    ``sensors`` overrides :class:`SensorConfig` fields over the GNSS level's."""
    if seeds < 1:
        raise CampaignError(f"seeds={seeds!r}: must be >= 1")
    _check_positive("minutes", minutes, 0.5)
    if gnss not in GNSS_LEVELS:
        raise CampaignError(f"gnss={gnss!r}: must be one of {tuple(GNSS_LEVELS)}")
    return [
        CaseSpec(
            case_id=f"cal-{first_seed + i:04d}",
            kind="calibration",
            scenario="ece_r64",
            seed=first_seed + i,
            minutes=float(minutes),
            options={"deflation_fraction": 0.0},
            sensors={**GNSS_LEVELS[gnss], **(sensors or {})},
            labels={"gnss": gnss},
            estimator=dict(estimator or {}),
        )
        for i in range(seeds)
    ]


@dataclass(frozen=True)
class EceCampaignPlan:
    """Sizes and timing of an ECE R-64 campaign (see :func:`ece_r64_cases`)."""

    step_cases: int = 12
    robustness_cases: int = 4
    diffusion_cases: int = 4
    step_minutes: float = 35.0
    deflation_min: float | None = None
    robustness_minutes: float = 60.0
    diffusion_minutes: float = 60.0
    diffusion_start_min: float | None = None
    detector_calibration_s: float = 1200.0
    wheels: str = "rear"
    braking_source: str = "estimate"
    first_seed: int = 1000
    estimator: dict[str, Any] = field(default_factory=dict)
    tyre_sensitivities_mm_per_kpa: tuple[float, ...] = TYRE_SENSITIVITIES_MM_PER_KPA
    gnss_levels: tuple[str, ...] = ("good", "standard", "poor")
    road_levels: tuple[str, ...] = tuple(ROAD_LEVELS)
    #: SensorConfig overrides applied to every drive over its GNSS and road level (e.g.
    #: ``gnss_velocity_enabled``)
    sensors: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.tyre_sensitivities_mm_per_kpa or any(
            not 0.0 < s <= 1.0 for s in self.tyre_sensitivities_mm_per_kpa
        ):
            raise CampaignError(
                f"tyre sensitivities {self.tyre_sensitivities_mm_per_kpa!r}: must be in (0, 1]"
            )
        for name, levels, known in (
            ("gnss", self.gnss_levels, GNSS_LEVELS),
            ("road", self.road_levels, ROAD_LEVELS),
        ):
            if not levels or any(v not in known for v in levels):
                raise CampaignError(f"{name} levels {levels!r}: must be some of {tuple(known)}")
        for name in ("step_cases", "robustness_cases", "diffusion_cases"):
            if getattr(self, name) < 0:
                raise CampaignError(f"{name}={getattr(self, name)!r}: must be >= 0")
        for name in ("step_minutes", "robustness_minutes", "diffusion_minutes"):
            _check_positive(name, getattr(self, name), 0.5)
        _check_positive("detector_calibration_s", self.detector_calibration_s)
        if self.wheels not in ("rear", "all"):
            raise CampaignError(f"wheels={self.wheels!r}: must be rear or all")
        if self.braking_source not in ("estimate", "truth"):
            raise CampaignError(f"braking={self.braking_source!r}: must be estimate or truth")

    @property
    def deflation_s(self) -> float:
        """Deflation time of the step cases, s (default 63 % of the drive, at most 22 min)."""
        if self.deflation_min is not None:
            return 60.0 * self.deflation_min
        return min(22.0 * 60.0, 0.63 * 60.0 * self.step_minutes)

    def calibration_s(self, event_s: float | None, minutes: float) -> float:
        """Detector calibration driving time: the configured time, capped at 80 % of the time
        before the event (or of half the drive without one) so that it completes before."""
        limit = 0.8 * (event_s if event_s is not None else 30.0 * minutes)
        return float(min(self.detector_calibration_s, limit))


def _estimator_overrides(plan: EceCampaignPlan) -> dict[str, Any]:
    est: dict[str, Any] = {"wheels": plan.wheels}
    est.update(plan.estimator)
    return est


def ece_r64_cases(plan: EceCampaignPlan) -> list[CaseSpec]:
    """Deterministic case list of an ECE R-64 campaign.

    Step cases cycle through the factor grid (deflated wheel x tyre sensitivity x GNSS level x
    road): every block of ``wheels x tyres x GNSS x roads`` cases covers the grid once and
    short prefixes stay balanced (the wheel changes fastest, the other factors are shifted);
    front wheels are deflated only with ``wheels='all'``. Robustness cases cycle through
    GNSS x road levels.
    Diffusion cases lose pressure on 1-4 wheels (at least one estimated) at 0.8-2 kPa/min from
    the end of the calibration, detection allowed within 60 min.
    """
    from tire_estimation.core.wheels import REAR_WHEELS, WHEELS

    rng = np.random.default_rng(plan.first_seed)
    wheels = REAR_WHEELS if plan.wheels == "rear" else WHEELS
    estimated = set(wheels)
    gnss_levels = plan.gnss_levels
    sens_levels = plan.tyre_sensitivities_mm_per_kpa
    roads = plan.road_levels
    n_s, n_g, n_r = len(sens_levels), len(gnss_levels), len(roads)
    n_rest = n_s * n_g * n_r

    def factors(i: int) -> tuple[str, float, str, str]:
        # wheel cycles fastest; the other factors follow a shifted mixed-radix count (a
        # bijection over each block of len(wheels) * n_rest cases, and balanced prefixes)
        j = (i // len(wheels)) % n_rest
        d0, d1, d2 = j % n_s, (j // n_s) % n_g, (j // (n_s * n_g)) % n_r
        return (
            wheels[i % len(wheels)],
            sens_levels[d0],
            gnss_levels[(d1 + d0) % n_g],
            roads[(d2 + d1 + d0) % n_r],
        )

    cases: list[CaseSpec] = []
    seed = plan.first_seed
    ev = plan.deflation_s
    if plan.step_cases and not 0.0 < ev < 60.0 * plan.step_minutes:
        raise CampaignError(
            f"deflation at {ev / 60:.1f} min is not inside the {plan.step_minutes} min drive"
        )
    for i in range(plan.step_cases):
        wheel, sens, gnss, road = factors(i)
        cal = plan.calibration_s(ev, plan.step_minutes)
        cases.append(
            CaseSpec(
                case_id=f"step-{i:04d}",
                kind="step",
                scenario="ece_r64",
                seed=seed,
                minutes=plan.step_minutes,
                options={
                    "deflate_wheel": wheel,
                    "deflation_fraction": 0.2,
                    "deflation_time_min": ev / 60.0,
                    "pressure_sensitivity_mm_per_kpa": sens,
                },
                sensors={**GNSS_LEVELS[gnss], **ROAD_LEVELS[road], **plan.sensors},
                labels={"wheel": wheel, "tyre": f"{sens:g}", "gnss": gnss, "road": road},
                deflated_wheels=(wheel,),
                event_s=ev,
                deadline_s=STEP_DEADLINE_S,
                detector_calibration_s=cal,
                estimator=_estimator_overrides(plan),
                braking_source=plan.braking_source,
            )
        )
        seed += 1
    rob_grid = list(itertools.product(gnss_levels, plan.road_levels))
    for i in range(plan.robustness_cases):
        gnss, road = rob_grid[i % len(rob_grid)]
        sens = sens_levels[i % len(sens_levels)]
        cal = plan.calibration_s(None, plan.robustness_minutes)
        cases.append(
            CaseSpec(
                case_id=f"rob-{i:04d}",
                kind="robustness",
                scenario="robustness",
                seed=seed,
                minutes=plan.robustness_minutes,
                options={"pressure_sensitivity_mm_per_kpa": sens},
                sensors={**GNSS_LEVELS[gnss], **ROAD_LEVELS[road], **plan.sensors},
                labels={"tyre": f"{sens:g}", "gnss": gnss, "road": road},
                detector_calibration_s=cal,
                estimator=_estimator_overrides(plan),
                braking_source=plan.braking_source,
            )
        )
        seed += 1
    start_s = (
        60.0 * plan.diffusion_start_min
        if plan.diffusion_start_min is not None
        else min(plan.detector_calibration_s + 120.0, 0.4 * 60.0 * plan.diffusion_minutes)
    )
    dgnss = "standard" if "standard" in gnss_levels else gnss_levels[0]
    for i in range(plan.diffusion_cases):
        n_w = 1 + i % 4
        picks = tuple(str(w) for w in rng.permutation(np.array(WHEELS))[:n_w])
        if not estimated.intersection(picks):
            picks = (*picks[:-1], str(rng.choice(np.array(sorted(estimated)))))
        picks = tuple(w for w in WHEELS if w in picks)
        rate = float(np.round(rng.uniform(0.8, 2.0), 2))
        sens = sens_levels[i % len(sens_levels)]
        cal = plan.calibration_s(start_s, plan.diffusion_minutes)
        cases.append(
            CaseSpec(
                case_id=f"diff-{i:04d}",
                kind="diffusion",
                scenario="diffusion",
                seed=seed,
                minutes=plan.diffusion_minutes,
                options={
                    "wheels": list(picks),
                    "rate_kpa_per_min": rate,
                    "start_min": start_s / 60.0,
                    "pressure_sensitivity_mm_per_kpa": sens,
                },
                sensors={**GNSS_LEVELS[dgnss], **plan.sensors},
                labels={"tyre": f"{sens:g}", "gnss": dgnss, "rate": f"{rate:g}"},
                deflated_wheels=picks,
                event_s=start_s,
                deadline_s=DIFFUSION_DEADLINE_S,
                detector_calibration_s=cal,
                estimator=_estimator_overrides(plan),
                braking_source=plan.braking_source,
            )
        )
        seed += 1
    return cases


# ---------------------------------------------------------------------------------------------
# execution


def execute_cases(
    cases: Sequence[CaseSpec],
    executor: str = "dask",
    n_workers: int = 2,
    scheduler: str | None = None,
    threads: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    accuracy_at_s: float = 600.0,
) -> list[dict[str, Any]]:
    """Run every case; rows in the order of ``cases``.

    ``executor``: ``dask`` (``scheduler`` address, else a LocalCluster of ``n_workers``
    single-threaded worker processes, or threads only with ``threads=True``), ``processes``
    (``concurrent.futures.ProcessPoolExecutor``) or ``serial``.
    """
    if n_workers < 1:
        raise CampaignError(f"n_workers={n_workers!r}: must be >= 1")
    rows: dict[str, dict[str, Any]] = {}
    total = len(cases)

    def done(row: dict[str, Any]) -> None:
        rows[row["case_id"]] = row
        if progress is not None:
            progress(row, len(rows), total)

    if executor == "serial":
        for spec in cases:
            done(run_case(spec, accuracy_at_s))
    elif executor == "processes":
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=n_workers) as pool:
            futures = [pool.submit(run_case, spec, accuracy_at_s) for spec in cases]
            for fut in as_completed(futures):
                done(fut.result())
    elif executor == "dask":
        try:
            from dask.distributed import Client, LocalCluster, as_completed
        except ImportError as exc:  # pragma: no cover - dask is a pinned dependency
            raise CampaignError(
                "dask.distributed is not installed; use --executor processes"
            ) from exc
        cluster = None
        if scheduler:
            client = Client(scheduler)
        else:
            cluster = LocalCluster(
                n_workers=n_workers,
                threads_per_worker=1,
                processes=not threads,
                dashboard_address=":0",
            )
            client = Client(cluster)
        try:
            futures = client.map(run_case, list(cases), accuracy_at_s=accuracy_at_s, pure=False)
            for fut in as_completed(futures):
                done(fut.result())
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    else:
        raise CampaignError(f"executor={executor!r}: must be dask, processes or serial")
    return [rows[spec.case_id] for spec in cases]


# ---------------------------------------------------------------------------------------------
# aggregation and output


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
    from tire_estimation.core.deflation.detector import ALL_WHEELS

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


_KINDS = ("step", "robustness", "diffusion", "calibration")


def write_csv(path: Path, rows: Sequence[dict[str, Any]]) -> None:
    """One row per case; columns = union of the keys (first-seen order)."""
    keys: dict[str, None] = {}
    for r in rows:
        keys.update(dict.fromkeys(r))
    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(keys), restval="")
        writer.writeheader()
        for r in rows:
            writer.writerow(r)


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


def _plot_calibration(path: Path, rows: Sequence[dict[str, Any]], at_s: float) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _plot_detection(out_dir: Path, rows: Sequence[dict[str, Any]]) -> list[str]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

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
    fig.tight_layout()
    p = out_dir / "detection_times.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
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
    fig.tight_layout()
    p = out_dir / "radius_change.png"
    fig.savefig(p, dpi=110)
    plt.close(fig)
    written.append(p.name)
    return written


def _prepare_out(out: Path | str, overwrite: bool) -> Path:
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise CampaignError(f"--out {path}: exists and is not a directory")
    if path.is_dir() and (path / "summary.json").exists() and not overwrite:
        raise CampaignError(f"--out {path}: holds a summary.json (use --overwrite)")
    path.mkdir(parents=True, exist_ok=True)
    return path


def _versions() -> dict[str, str]:
    out = {"python": sys.version.split()[0], "numpy": np.__version__}
    try:
        import dask
        import distributed

        out["dask"] = dask.__version__
        out["distributed"] = distributed.__version__
    except ImportError:
        pass
    return out


def run_calibration_study(
    out: Path | str,
    seeds: int = 20,
    minutes: float = 12.0,
    at_min: float = 10.0,
    first_seed: int = 0,
    gnss: str = "calibration",
    executor: str = "dask",
    n_workers: int = 2,
    scheduler: str | None = None,
    threads: bool = False,
    overwrite: bool = False,
    estimator: dict[str, Any] | None = None,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    sensors: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Issue-3 study: ``summary.json``, ``cases.csv``, ``calibration_errors.png`` in ``out``."""
    if not 0.0 < at_min <= minutes:
        raise CampaignError(f"at_min={at_min!r}: must be within (0, minutes={minutes}]")
    out_dir = _prepare_out(out, overwrite)
    cases = calibration_cases(seeds, minutes, first_seed, gnss, estimator, sensors)
    t0 = time.perf_counter()
    rows = execute_cases(
        cases, executor, n_workers, scheduler, threads, progress, accuracy_at_s=60.0 * at_min
    )
    summary = summarize_calibration(rows, 60.0 * at_min)
    summary["config"] = {
        "seeds": seeds,
        "first_seed": first_seed,
        "minutes": minutes,
        "at_min": at_min,
        "gnss": {gnss: GNSS_LEVELS[gnss]},
        "estimator_overrides": estimator or {},
        "sensor_overrides": sensors or {},
        "executor": executor,
        "n_workers": n_workers,
    }
    summary["wall_time_s"] = time.perf_counter() - t0
    summary["versions"] = _versions()
    write_csv(out_dir / "cases.csv", rows)
    _plot_calibration(out_dir / "calibration_errors.png", rows, 60.0 * at_min)
    summary["files"] = ["summary.json", "cases.csv", "calibration_errors.png"]
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def run_ece_r64_campaign(
    out: Path | str,
    plan: EceCampaignPlan,
    executor: str = "dask",
    n_workers: int = 2,
    scheduler: str | None = None,
    threads: bool = False,
    overwrite: bool = False,
    progress: Callable[[dict[str, Any], int, int], None] | None = None,
    save_traces: bool = False,
) -> dict[str, Any]:
    """Issue-4 campaign: ``summary.json``, ``cases.csv``, ``cases.json`` and PNGs in ``out``.

    ``save_traces`` keeps every case's estimator traces in ``out/traces`` (about 2 MB per
    25-min case) for :func:`redetect_campaigns`.
    """
    out_dir = _prepare_out(out, overwrite)
    cases = ece_r64_cases(plan)
    if not cases:
        raise CampaignError("the campaign has no cases")
    if save_traces:
        trace_dir = out_dir / "traces"
        trace_dir.mkdir(exist_ok=True)
        cases = [dataclasses.replace(c, trace_dir=str(trace_dir.resolve())) for c in cases]
    (out_dir / "cases.json").write_text(json.dumps([c.to_dict() for c in cases], indent=1))
    t0 = time.perf_counter()
    rows = execute_cases(cases, executor, n_workers, scheduler, threads, progress)
    summary = summarize_detection(rows)
    plan_d = dataclasses.asdict(plan)
    plan_d["deflation_s"] = plan.deflation_s
    summary["config"] = {
        "plan": plan_d,
        "executor": executor,
        "n_workers": n_workers,
        "scheduler": scheduler,
        "braking": (
            "deceleration of the estimator's speed, low-passed (1 s), > 1 m/s^2"
            if plan.braking_source == "estimate"
            else "true longitudinal deceleration > 1 m/s^2"
        ),
        "gnss_levels": GNSS_LEVELS,
        "road_levels": ROAD_LEVELS,
        "road_roughness": "not modelled by the simulator; 'hilly' varies the road grade",
    }
    summary["wall_time_s"] = time.perf_counter() - t0
    summary["versions"] = _versions()
    write_csv(out_dir / "cases.csv", rows)
    summary["files"] = ["summary.json", "cases.csv", "cases.json", *_plot_detection(out_dir, rows)]
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _write_pooled(
    out: Path | str, rows: list[dict[str, Any]], config: dict[str, Any], overwrite: bool
) -> dict[str, Any]:
    """``summary.json``, ``cases.csv`` and the plots of pooled detection rows in ``out``."""
    out_dir = _prepare_out(out, overwrite)
    summary = summarize_detection(rows)
    summary["config"] = config
    summary["versions"] = _versions()
    write_csv(out_dir / "cases.csv", rows)
    summary["files"] = ["summary.json", "cases.csv", *_plot_detection(out_dir, rows)]
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def merge_ece_r64_campaigns(
    out: Path | str, shards: Sequence[Path | str], overwrite: bool = False
) -> dict[str, Any]:
    """One ``summary.json`` (and ``cases.csv``, PNGs) over several campaign directories.

    A long campaign can run as shards (different ``--first-seed``, on different machines or one
    after the other, each complete on its own); this pools their per-case rows. Two shards that
    contain the same simulator seed are refused (the same drive counted twice). Each row gets a
    ``shard`` column with its directory name.
    """
    rows: list[dict[str, Any]] = []
    seen: dict[int, str] = {}
    configs = []
    for shard in shards:
        d = Path(shard)
        csv_path, summary_path = d / "cases.csv", d / "summary.json"
        if not csv_path.is_file() or not summary_path.is_file():
            raise CampaignError(f"{d}: not a finished campaign (no cases.csv / summary.json)")
        summary = json.loads(summary_path.read_text())
        if summary.get("study") != "ece_r64":
            raise CampaignError(f"{d}: not an ece-r64 campaign ({summary.get('study')!r})")
        configs.append({"shard": d.name, **summary.get("config", {})})
        for r in read_csv_rows(csv_path):
            seed = int(r["seed"])
            if seed in seen:
                raise CampaignError(f"seed {seed} is in both {seen[seed]} and {d}")
            seen[seed] = str(d)
            rows.append({"shard": d.name, **r})
    if not rows:
        raise CampaignError("the shards have no cases")
    config = {"merged_from": [str(Path(x)) for x in shards], "shards": configs}
    return _write_pooled(out, rows, config, overwrite)


def redetect_campaigns(
    out: Path | str,
    campaigns: Sequence[Path | str],
    detector: dict[str, Any] | None = None,
    overwrite: bool = False,
) -> dict[str, Any]:
    """Detection re-run on the saved traces of finished campaigns (``--save-traces``).

    No simulation and no estimator: every case of each campaign's ``cases.json`` is evaluated
    again from ``traces/<case_id>.npz`` with the detector settings of the campaign overridden by
    ``detector`` (DeflationDetectorConfig fields). Writes ``summary.json``, ``cases.csv`` and
    the plots to ``out``. Several campaign directories are pooled as by
    :func:`merge_ece_r64_campaigns` (duplicate seeds refused).
    """
    detector = dict(detector or {})
    rows: list[dict[str, Any]] = []
    seen: dict[int, str] = {}
    for camp in campaigns:
        d = Path(camp)
        specs_path = d / "cases.json"
        if not specs_path.is_file():
            raise CampaignError(f"{d}: no cases.json")
        for item in json.loads(specs_path.read_text()):
            spec = CaseSpec.from_dict(item)
            trace = d / "traces" / f"{spec.case_id}.npz"
            if not trace.is_file():
                raise CampaignError(f"{trace}: missing (run the campaign with --save-traces)")
            if spec.seed in seen:
                raise CampaignError(f"seed {spec.seed} is in both {seen[spec.seed]} and {d}")
            seen[spec.seed] = str(d)
            spec = dataclasses.replace(spec, detector={**spec.detector, **detector})
            rows.append({"shard": d.name, **redetect_case(spec, load_run(trace))})
    if not rows:
        raise CampaignError("the campaigns have no cases")
    config = {
        "redetected_from": [str(Path(x)) for x in campaigns],
        "detector": detector,
    }
    return _write_pooled(out, rows, config, overwrite)


# ---------------------------------------------------------------------------------------------
# command line


def _print_progress(row: dict[str, Any], n: int, total: int) -> None:
    bits = [f"[{n}/{total}] {row['case_id']}"]
    if row.get("error"):
        bits.append(f"ERROR {row['error']}")
    elif row["kind"] == "calibration":
        for m in ("mpf", "aug_kf"):
            rel = row.get(f"{m}_rel_err_at_m")
            if rel is not None:
                bits.append(
                    f"{m}: rel {1e3 * rel:+.3f} rl {1e3 * row[f'{m}_abs_err_rl_at_m']:+.3f} "
                    f"rr {1e3 * row[f'{m}_abs_err_rr_at_m']:+.3f} mm"
                )
    else:
        for m in ("mpf", "aug_kf"):
            t = row.get(f"{m}_detection_time_s")
            bits.append(
                f"{m}: {'det ' + format(t / 60, '.1f') + ' min' if t is not None else 'no det'}"
                f", fa {row.get(f'{m}_false_alarms', '?')}"
            )
    bits.append(f"({row.get('sim_s', 0) + row.get('estimate_s', 0):.0f} s)")
    print("  ".join(bits), flush=True)


def _estimator_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.core.radius.config import RadiusEstimatorConfig

    d = dict(items or [])
    try:
        RadiusEstimatorConfig.from_dict(d)
    except ConfigError as exc:
        raise CampaignError(f"--estimator {exc}") from exc
    return d


def _sensor_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.sim import SensorConfig

    d = dict(items or [])
    try:
        SensorConfig(**d)
    except TypeError as exc:
        raise CampaignError(f"--sensor: {exc}") from exc
    except ConfigError as exc:
        raise CampaignError(f"--sensor {exc}") from exc
    return d


def _add_sensor_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sensor",
        action="append",
        type=_key_value,
        metavar="KEY=VALUE",
        help="SensorConfig override of the simulated drives, e.g. gnss_velocity_enabled=true "
        "(repeatable)",
    )


def _key_value(text: str) -> tuple[str, Any]:

    if "=" not in text:
        raise argparse.ArgumentTypeError(f"expected key=value, got {text!r}")
    key, raw = text.split("=", 1)
    return key.strip(), yamlio.safe_load(raw)


def _float_list(text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in text.split(",") if v.strip())
    except ValueError as exc:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas: {text!r}"
        ) from exc


def _str_list(text: str) -> tuple[str, ...]:
    return tuple(v.strip() for v in text.split(",") if v.strip())


def _add_exec_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", required=True, type=Path, help="result directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    p.add_argument(
        "--executor",
        choices=("dask", "processes", "serial"),
        default="dask",
        help="dask.distributed (default), a local process pool, or serial",
    )
    p.add_argument("--workers", type=int, default=2, help="local workers (default 2)")
    p.add_argument(
        "--scheduler", default=None, help="address of a running Dask scheduler (tcp://host:8786)"
    )
    p.add_argument(
        "--threads", action="store_true", help="Dask LocalCluster with threads, no processes"
    )
    p.add_argument(
        "--estimator",
        action="append",
        type=_key_value,
        metavar="KEY=VALUE",
        help="RadiusEstimatorConfig override (repeatable)",
    )


def _p95(stats: dict[str, Any]) -> float:
    return float(stats.get("p95_abs", float("nan")))


def _cmd_calibration(args: argparse.Namespace) -> int:
    summary = run_calibration_study(
        args.out,
        seeds=args.seeds,
        minutes=args.minutes,
        at_min=args.at_min,
        first_seed=args.first_seed,
        gnss=args.gnss,
        executor=args.executor,
        n_workers=args.workers,
        scheduler=args.scheduler,
        threads=args.threads,
        overwrite=args.overwrite,
        estimator=_estimator_options(args.estimator),
        progress=_print_progress,
        sensors=_sensor_options(args.sensor),
    )
    for m in ("mpf", "aug_kf"):
        s = summary[m]
        print(
            f"{m}: {s['seeds_meeting_all_targets']}/{s['n']} seeds meet both targets at "
            f"{args.at_min:g} min; |rel| p95 {_p95(s['relative_error_at_mm']):.3f} mm, "
            f"|abs| p95 {_p95(s['absolute_error_at_mm']):.3f} mm"
        )
    print(f"wrote {args.out}/summary.json")
    return 0


def _cmd_ece_r64(args: argparse.Namespace) -> int:
    plan = EceCampaignPlan(
        step_cases=args.step_cases,
        robustness_cases=args.robustness_cases,
        diffusion_cases=args.diffusion_cases,
        step_minutes=args.minutes,
        deflation_min=args.deflation_min,
        robustness_minutes=args.robustness_minutes,
        diffusion_minutes=args.diffusion_minutes,
        diffusion_start_min=args.diffusion_start_min,
        detector_calibration_s=60.0 * args.calibration_min,
        wheels=args.wheels,
        braking_source=args.braking,
        first_seed=args.first_seed,
        estimator=_estimator_options(args.estimator),
        tyre_sensitivities_mm_per_kpa=tuple(args.tyres),
        gnss_levels=tuple(args.gnss),
        road_levels=tuple(args.roads),
        sensors=_sensor_options(args.sensor),
    )
    summary = run_ece_r64_campaign(
        args.out,
        plan,
        executor=args.executor,
        n_workers=args.workers,
        scheduler=args.scheduler,
        threads=args.threads,
        overwrite=args.overwrite,
        progress=_print_progress,
        save_traces=args.save_traces,
    )
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json")
    return 0


def _print_detection_summary(summary: dict[str, Any]) -> None:
    for m in ("mpf", "aug_kf"):
        s = summary[m]
        st, rb = s["step"], s["robustness"]
        print(
            f"{m}: step {st['detected']}/{st['n']} detected ({st['detected_in_time']} within "
            f"10 min), diffusion {s['diffusion']['detected']}/{s['diffusion']['n']}, "
            f"robustness {rb['false_alarms']} false alarms in {rb['monitored_hours']:.2f} h, "
            f"false alarms total {s['false_alarms_total']} (false warnings "
            f"{s['false_warnings_total']}, wrong wheel {s['wrong_wheel_alarms_total']})"
        )


def _cmd_redetect(args: argparse.Namespace) -> int:
    summary = redetect_campaigns(
        args.out, args.campaigns, _detector_options(args.detector), overwrite=args.overwrite
    )
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json ({summary['n_cases']} cases)")
    return 0


def _detector_options(items: Sequence[tuple[str, Any]] | None) -> dict[str, Any]:
    from tire_estimation.core.deflation.detector import DeflationDetectorConfig

    names = {f.name for f in dataclasses.fields(DeflationDetectorConfig)}
    out = dict(items or [])
    for k in out:
        if k not in names:
            raise CampaignError(f"--detector {k}: not a DeflationDetectorConfig field")
    return out


def _cmd_merge(args: argparse.Namespace) -> int:
    summary = merge_ece_r64_campaigns(args.out, args.shards, overwrite=args.overwrite)
    _print_detection_summary(summary)
    print(f"wrote {args.out}/summary.json ({summary['n_cases']} cases)")
    return 0


def add_campaign_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add ``campaign {calibration,ece-r64}`` to ``subparsers`` (handlers ``(args) -> int``)."""
    camp = subparsers.add_parser(
        "campaign", help="evaluation campaigns on simulated drives (calibration, ECE R-64)"
    )
    sub = camp.add_subparsers(dest="campaign_command", required=True)

    cal = sub.add_parser(
        "calibration", help="MPF vs AUG-KF radius accuracy after calibration over many seeds"
    )
    cal.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    cal.add_argument("--first-seed", type=int, default=0)
    cal.add_argument("--minutes", type=float, default=12.0, help="drive length (default 12)")
    cal.add_argument("--at-min", type=float, default=10.0, help="evaluation time (default 10)")
    cal.add_argument(
        "--gnss",
        choices=tuple(GNSS_LEVELS),
        default="calibration",
        help="GNSS level (default: calibration, 1.5 m total per axis)",
    )
    _add_sensor_arg(cal)
    _add_exec_args(cal)
    cal.set_defaults(func=_cmd_calibration)

    ece = sub.add_parser("ece-r64", help="ECE R-64 detection campaign (MPF vs AUG-KF + CUSUM)")
    ece.add_argument("--step-cases", type=int, default=12)
    ece.add_argument("--robustness-cases", type=int, default=4)
    ece.add_argument("--diffusion-cases", type=int, default=4)
    ece.add_argument("--minutes", type=float, default=35.0, help="step-case drive length")
    ece.add_argument(
        "--deflation-min", type=float, default=None, help="step time (default 63 %%, <= 22 min)"
    )
    ece.add_argument("--robustness-minutes", type=float, default=60.0)
    ece.add_argument("--diffusion-minutes", type=float, default=60.0)
    ece.add_argument("--diffusion-start-min", type=float, default=None)
    ece.add_argument(
        "--calibration-min",
        type=float,
        default=20.0,
        help="CUSUM calibration driving time (ECE R-64: 20), capped at 80 %% of the time "
        "before the event",
    )
    ece.add_argument("--wheels", choices=("rear", "all"), default="rear")
    ece.add_argument("--braking", choices=("estimate", "truth"), default="estimate")
    ece.add_argument(
        "--tyres",
        type=_float_list,
        default=TYRE_SENSITIVITIES_MM_PER_KPA,
        help="tyre radius sensitivities, mm/kPa, comma separated (default 0.015,0.03,0.05)",
    )
    ece.add_argument(
        "--gnss",
        type=_str_list,
        default=("good", "standard", "poor"),
        help=f"GNSS levels, comma separated, of {','.join(GNSS_LEVELS)}",
    )
    ece.add_argument(
        "--roads",
        type=_str_list,
        default=tuple(ROAD_LEVELS),
        help=f"road levels, comma separated, of {','.join(ROAD_LEVELS)}",
    )
    ece.add_argument("--first-seed", type=int, default=1000)
    ece.add_argument(
        "--save-traces",
        action="store_true",
        help="keep each case's estimator traces in OUT/traces (for campaign redetect)",
    )
    _add_sensor_arg(ece)
    _add_exec_args(ece)
    ece.set_defaults(func=_cmd_ece_r64)

    mrg = sub.add_parser(
        "merge", help="pool finished ece-r64 campaign directories (shards) into one summary"
    )
    mrg.add_argument("shards", nargs="+", type=Path, help="campaign directories")
    mrg.add_argument("--out", type=Path, required=True, help="result directory")
    mrg.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    mrg.set_defaults(func=_cmd_merge)

    red = sub.add_parser(
        "redetect",
        help="re-run only the detection on the saved traces of campaigns (--save-traces)",
    )
    red.add_argument("campaigns", nargs="+", type=Path, help="campaign directories")
    red.add_argument("--out", type=Path, required=True, help="result directory")
    red.add_argument(
        "--detector",
        type=_key_value,
        action="append",
        metavar="KEY=VALUE",
        help="DeflationDetectorConfig override (repeatable)",
    )
    red.add_argument("--overwrite", action="store_true", help="replace an existing summary.json")
    red.set_defaults(func=_cmd_redetect)
    return camp


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry point (``python -m tire_estimation.evaluation.campaign``)."""
    parser = argparse.ArgumentParser(prog="tire-estimation")
    subparsers = parser.add_subparsers(dest="command", required=True)
    add_campaign_parser(subparsers)
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except TireEstimationError as exc:
        print(f"tire-estimation: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
