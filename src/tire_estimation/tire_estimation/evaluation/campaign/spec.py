"""Campaign cases: targets, GNSS/road/tyre levels, :class:`CaseSpec` and the case lists
of the calibration study and of the ECE R-64 campaign (:func:`ece_r64_cases`).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tire_estimation.errors import TireEstimationError

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


#: the case kinds of an ECE R-64 campaign: kind -> (case id prefix, simulated scenario)
_CASE_KINDS = {
    "step": ("step", "ece_r64"),
    "robustness": ("rob", "robustness"),
    "diffusion": ("diff", "diffusion"),
}


def _planned_case(plan: EceCampaignPlan, **fields: Any) -> CaseSpec:
    """A case of ``plan``: its detector calibration time (:meth:`EceCampaignPlan.calibration_s`
    of the case's ``event_s`` and ``minutes``), the plan's estimator overrides (``wheels`` and
    the ``estimator`` options) and braking source."""
    est: dict[str, Any] = {"wheels": plan.wheels}
    est.update(plan.estimator)
    return CaseSpec(
        **fields,
        detector_calibration_s=plan.calibration_s(fields.get("event_s"), fields["minutes"]),
        estimator=est,
        braking_source=plan.braking_source,
    )


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

    def add(kind: str, i: int, minutes: float, **fields: Any) -> None:
        # the i-th case of its kind: id and scenario of the kind, the next seed (one per case)
        prefix, scenario = _CASE_KINDS[kind]
        cases.append(
            _planned_case(
                plan,
                case_id=f"{prefix}-{i:04d}",
                kind=kind,
                scenario=scenario,
                seed=plan.first_seed + len(cases),
                minutes=minutes,
                **fields,
            )
        )

    ev = plan.deflation_s
    if plan.step_cases and not 0.0 < ev < 60.0 * plan.step_minutes:
        raise CampaignError(
            f"deflation at {ev / 60:.1f} min is not inside the {plan.step_minutes} min drive"
        )
    for i in range(plan.step_cases):
        wheel, sens, gnss, road = factors(i)
        add(
            "step",
            i,
            plan.step_minutes,
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
        )
    rob_grid = list(itertools.product(gnss_levels, plan.road_levels))
    for i in range(plan.robustness_cases):
        gnss, road = rob_grid[i % len(rob_grid)]
        sens = sens_levels[i % len(sens_levels)]
        add(
            "robustness",
            i,
            plan.robustness_minutes,
            options={"pressure_sensitivity_mm_per_kpa": sens},
            sensors={**GNSS_LEVELS[gnss], **ROAD_LEVELS[road], **plan.sensors},
            labels={"tyre": f"{sens:g}", "gnss": gnss, "road": road},
        )
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
        add(
            "diffusion",
            i,
            plan.diffusion_minutes,
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
        )
    return cases
