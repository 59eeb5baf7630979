"""Execution of case lists (evaluation.campaign.execute)."""

from __future__ import annotations

import pytest

from tire_estimation.evaluation.campaign.execute import execute_cases
from tire_estimation.evaluation.campaign.spec import (
    CampaignError,
    CaseSpec,
    calibration_cases,
)


def test_unknown_executor_and_bad_worker_count_are_campaign_errors() -> None:
    cases = calibration_cases(seeds=1)
    with pytest.raises(CampaignError):
        execute_cases(cases, executor="carrier-pigeon")
    with pytest.raises(CampaignError, match="n_workers"):
        execute_cases(cases, executor="serial", n_workers=0)


@pytest.mark.parametrize("executor", ["serial", "processes"])
def test_executors_keep_case_order(executor: str) -> None:
    specs = [
        CaseSpec(case_id=f"bad-{i}", kind="step", scenario="nope", seed=i, minutes=1.0)
        for i in range(3)
    ]
    rows = execute_cases(specs, executor=executor, n_workers=2)
    assert [r["case_id"] for r in rows] == ["bad-0", "bad-1", "bad-2"]
    assert all("ScenarioError" in r["error"] for r in rows)
