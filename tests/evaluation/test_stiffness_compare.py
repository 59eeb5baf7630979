"""The comparison of Algorithm 1 with its baselines on the sine drives (issue 5)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tire_estimation.evaluation.stiffness import sine_study
from tire_estimation.evaluation.stiffness_compare import (
    METHODS,
    configs,
    run_sine_seed,
    sine_summary,
)


def test_configs_share_fields_and_take_per_method_overrides() -> None:
    cfg = configs(
        40,
        None,
        friction_coefficient=0.3,
        initial_stiffness_factor=0.75,
        **{
            "augpf.stiffness_walk_std_fraction_sqrt_s": 0.05,
            "ekf.process_vy_m_s_sqrt_s": 0.01,
            "grid.grid_points": 15,
        },
    )
    for m in METHODS:
        assert cfg[m].friction_coefficient == 0.3
        assert cfg[m].initial_stiffness_factor == 0.75
    assert cfg["augpf"].n_particles == 40
    assert cfg["augpf"].stiffness_walk_std_fraction_sqrt_s == 0.05
    assert cfg["ekf"].process_vy_m_s_sqrt_s == 0.01
    assert cfg["grid"].grid_points == 15
    # the per-method keys do not leak into the other methods
    assert cfg["ekf"].stiffness_walk_std_fraction_sqrt_s != 0.05
    assert cfg["rls"].process_vy_m_s_sqrt_s != 0.01


def _row(mean: list[float], top: list[float], settle: list[float]) -> dict[str, Any]:
    return {
        "steady_mean_rel_error": [0.0, *mean],
        "steady_max_abs_rel_error": [0.0, *top],
        "settling_s": [float("nan"), *settle],
        "vy_rmse_m_s": 0.01,
        "step_ms": 0.5,
    }


def test_sine_summary_counts_runs_and_settling() -> None:
    rows = [
        _row([0.01, 0.02], [0.02, 0.025], [0.5, 1.5]),
        _row([-0.03, 0.04], [0.035, 0.05], [2.5, float("nan")]),
    ]
    per_run = [dict.fromkeys(METHODS, r) for r in rows]
    s = sine_summary(per_run)["alg1"]
    assert s["cy_steady_mean_error_mean_pct"] == pytest.approx([-1.0, 3.0])
    assert s["cy_steady_abs_mean_error_mean_pct"] == pytest.approx([2.0, 3.0])
    assert s["cy_steady_max_abs_error_max_pct"] == pytest.approx([3.5, 5.0])
    assert s["runs_above_max_error"] == 1
    assert s["cy_settled_within_2s_share"] == pytest.approx([0.5, 0.5])


def test_algorithm_1_in_the_comparison_is_the_sine_study_run() -> None:
    over = {"friction_coefficient": 0.3, "niw_update": "rao_blackwellized"}
    got = run_sine_seed(3, "snow_sine", 1.5, 50, over)
    ref = sine_study("snow_sine", 1.5, 1, n=50, first_seed=3, overrides=over)["per_run"][0]
    np.testing.assert_allclose(
        got["alg1"]["steady_mean_rel_error"], ref["steady_mean_rel_error"], rtol=1e-12
    )
    np.testing.assert_allclose(got["alg1"]["settling_s"], ref["settling_s"], rtol=1e-12)
    assert set(got) == set(METHODS)
    for m in METHODS:
        assert np.isfinite(got[m]["vy_rmse_m_s"])
        assert got[m]["activation_s"] == pytest.approx(ref["activation_s"], abs=0.05)
    # a subset of the methods gives the same scores as the full comparison
    alone = run_sine_seed(3, "snow_sine", 1.5, 50, over, methods=("grid",))
    assert set(alone) == {"grid"}
    np.testing.assert_array_equal(alone["grid"]["settling_s"], got["grid"]["settling_s"])
    np.testing.assert_array_equal(
        alone["grid"]["steady_mean_rel_error"], got["grid"]["steady_mean_rel_error"]
    )
