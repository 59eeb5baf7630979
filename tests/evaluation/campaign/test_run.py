"""One case end to end (evaluation.campaign.run)."""

from __future__ import annotations

import numpy as np

from tire_estimation.evaluation.campaign.run import run_case
from tire_estimation.evaluation.campaign.spec import (
    CaseSpec,
    calibration_cases,
)
from tire_estimation.evaluation.campaign.summary import summarize_detection


def test_calibration_case_reports_errors_against_truth() -> None:
    spec = calibration_cases(seeds=1, minutes=2.0, first_seed=3)[0]
    row = run_case(spec, accuracy_at_s=90.0)
    assert row["error"] == ""
    for m in ("mpf", "aug_kf"):
        assert row[f"{m}_ok"] is True
        for key in ("rel_err_at_m", "abs_err_rl_at_m", "abs_err_rr_at_m", "final_rel_err_m"):
            assert np.isfinite(row[f"{m}_{key}"]), key
            assert abs(row[f"{m}_{key}"]) < 5e-3  # within the prior's reach after 1.5 min
        assert isinstance(row[f"{m}_meets_targets_at"], bool)


def test_failing_case_is_reported_not_raised() -> None:
    spec = CaseSpec(case_id="bad", kind="step", scenario="no_such_scenario", seed=0, minutes=1.0)
    row = run_case(spec)
    assert "ScenarioError" in row["error"]
    s = summarize_detection([row])
    assert s["n_failed"] == 1
