"""Evaluation of the tyre-force KF (issue 6): JSON, PNG, sensitivity and the empty MPF slot."""

from __future__ import annotations

import json
import math
from pathlib import Path

from tire_estimation.evaluation import lateral_tyre


def test_main_writes_json_and_png(tmp_path: Path) -> None:
    assert lateral_tyre.main(["--out", str(tmp_path), "--seeds", "1", "--minutes", "0.1"]) == 0
    result = json.loads((tmp_path / "lateral_tyre.json").read_text())
    assert (tmp_path / "lateral_tyre_seed0.png").stat().st_size > 10_000
    summary = result["summary_mean_over_seeds"]
    for phase in ("overall", "nonlinear"):
        assert summary[phase][lateral_tyre.STIFFNESS_MPF_SLOT] is None
        for method in ("tyre_force_kf", "single_track"):
            assert set(summary[phase][method]) == {"vy_rmse_m_s", "yaw_rate_rmse_deg_s"}
    overall = summary["overall"]["tyre_force_kf"]
    assert math.isfinite(overall["vy_rmse_m_s"]) and math.isfinite(overall["yaw_rate_rmse_deg_s"])
    assert set(summary["sensitivity"]) == set(lateral_tyre.SENSITIVITY_CASES)
    seed0 = result["per_seed"]["0"]
    switching = seed0["relay_switching"]
    assert len(switching["t_s"]) == len(switching["nonlinear"]) == seed0["relay_switches"]


def test_perturbed_vehicle_keeps_the_wheelbase_consistent() -> None:
    from tire_estimation.core.vehicle import VehicleParams

    v = lateral_tyre.perturbed_vehicle(VehicleParams(), lf_factor=1.1)
    assert v.cg_to_front_axle_m == 1.1 * 1.1
    assert v.wheelbase_m == v.cg_to_front_axle_m + v.cg_to_rear_axle_m
