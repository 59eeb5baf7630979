"""Case lists of the campaigns (evaluation.campaign.spec)."""

from __future__ import annotations

from typing import Any

import pytest

from tire_estimation.errors import TireEstimationError
from tire_estimation.evaluation.campaign.spec import (
    DIFFUSION_DEADLINE_S,
    STEP_DEADLINE_S,
    CampaignError,
    EceCampaignPlan,
    calibration_cases,
    ece_r64_cases,
)


def test_ece_cases_are_deterministic_and_balanced() -> None:
    plan = EceCampaignPlan(step_cases=36, robustness_cases=6, diffusion_cases=8)
    a, b = ece_r64_cases(plan), ece_r64_cases(plan)
    assert [c.to_dict() for c in a] == [c.to_dict() for c in b]
    steps = [c for c in a if c.kind == "step"]
    assert len(steps) == 36
    # the full factor grid (2 rear wheels x 3 tyres x 3 GNSS x 2 roads) is covered exactly once
    combos = {
        (c.labels["wheel"], c.labels["tyre"], c.labels["gnss"], c.labels["road"]) for c in steps
    }
    assert len(combos) == 36
    assert {c.deflated_wheels[0] for c in steps} == {"wheel_rl", "wheel_rr"}
    assert len({c.seed for c in a}) == len(a)  # every case has its own seed
    for c in steps:
        assert c.options["deflation_fraction"] == 0.2
        assert c.deadline_s == STEP_DEADLINE_S
        # the CUSUM calibration completes before the step
        assert c.detector_calibration_s <= 0.8 * c.event_s
    diffs = [c for c in a if c.kind == "diffusion"]
    assert {len(c.deflated_wheels) for c in diffs} == {1, 2, 3, 4}
    for c in diffs:
        assert c.deadline_s == DIFFUSION_DEADLINE_S
        assert {"wheel_rl", "wheel_rr"} & set(c.deflated_wheels)  # observable in rear mode
    assert all(not c.deflated_wheels and c.event_s is None for c in a if c.kind == "robustness")


def test_front_wheels_only_with_all_mode() -> None:
    rear = ece_r64_cases(EceCampaignPlan(step_cases=20, robustness_cases=0, diffusion_cases=0))
    assert all(c.deflated_wheels[0].startswith("wheel_r") for c in rear)
    allw = ece_r64_cases(
        EceCampaignPlan(step_cases=72, robustness_cases=0, diffusion_cases=0, wheels="all")
    )
    assert {c.deflated_wheels[0] for c in allw} == {"wheel_fl", "wheel_fr", "wheel_rl", "wheel_rr"}
    assert all(c.estimator["wheels"] == "all" for c in allw)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"step_cases": -1},
        {"wheels": "front"},
        {"braking_source": "pedal"},
        {"gnss_levels": ("superb",)},
        {"tyre_sensitivities_mm_per_kpa": (0.0,)},
        {"step_minutes": 10.0, "deflation_min": 12.0},
    ],
)
def test_bad_plans_raise_campaign_errors(kwargs: dict[str, Any]) -> None:
    with pytest.raises(CampaignError):
        ece_r64_cases(EceCampaignPlan(**kwargs))
    assert issubclass(CampaignError, TireEstimationError)


def test_calibration_cases_and_bad_arguments() -> None:
    cases = calibration_cases(seeds=3, minutes=12.0, first_seed=5)
    assert [c.seed for c in cases] == [5, 6, 7]
    assert all(c.options == {"deflation_fraction": 0.0} and c.kind == "calibration" for c in cases)
    with pytest.raises(CampaignError):
        calibration_cases(seeds=0)
    with pytest.raises(CampaignError):
        calibration_cases(gnss="bad")
