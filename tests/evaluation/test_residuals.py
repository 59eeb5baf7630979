"""Residual analysis with undeclared effects injected in the simulator (issue 7).

The simulated GNSS uses a small Gauss-Markov error (``gnss_gm_std_m=0.1``): the default 1 m,
120 s correlated error makes the innovations non-white even for a correct model.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pytest

from tire_estimation.core.config import RadiusEstimatorConfig
from tire_estimation.core.radius_estimator import RadiusEstimator
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.evaluation import residuals as rs
from tire_estimation.evaluation.runner import run_radius_estimator
from tire_estimation.sim import SensorConfig, simulate

LATENCY_S = 0.2
N_PARTICLES = 100
GRIDS = {"gnss_latency": (0.0, 0.1, 0.2, 0.3), "wheel_speed_time_offset": (0.0, 0.1, 0.2)}


@cache
def _sim(latency_s: float) -> Any:
    return simulate(
        "ece_r64",
        seed=3,
        minutes=1.5,
        sensors=SensorConfig(
            gnss_gm_std_m=0.1, tire_force_enabled=False, gnss_latency_s=latency_s
        ),
    )


@cache
def _run(latency_s: float, effect: str = "", value: float = 0.0) -> Any:
    sim = _sim(latency_s)
    overrides = {rs.CONFIG_FIELDS[effect]: value} if effect else {}
    cfg = RadiusEstimatorConfig(n_particles=N_PARTICLES, **overrides)
    est = RadiusEstimator(cfg, VehicleParams(), np.random.default_rng(0))
    return run_radius_estimator(est, sim.wheel_speeds, sim.gnss, sim.steering, sim.imu)


def _radius_error(latency_s: float, trace: Any) -> float:
    sim = _sim(latency_s)
    truth = sim.truth.wheel_radius_m[-1, 2:] - sim.vehicle.nominal_tire_radius_m
    return float(np.max(np.abs(trace.arrays()["radius_error_m"][-1] - truth)))


@cache
def _ranked(latency_s: float) -> tuple[dict[str, Any], ...]:
    base = _run(latency_s)
    ranked = rs.rank_effects(
        lambda effect, value: _run(latency_s, effect, value),
        GRIDS,
        baseline_nll=rs.neg_log_likelihood(base),
    )
    return tuple(ranked)


def test_profile_scan_finds_parabola_minimum() -> None:
    est, f = rs.profile_scan(lambda x: (x - 0.13) ** 2, (0.0, 0.1, 0.2, 0.3))
    assert est == pytest.approx(0.13, abs=1e-9)
    assert len(f) == 4


def test_analyze_contract_shape() -> None:
    res = rs.analyze_trace(_run(LATENCY_S))
    assert set(res) == {"consistent", "tests", "suspected_effects"}
    assert "regressions" in res["tests"]
    assert {"along_track", "cross_track"} <= set(res["tests"]["regressions"])
    for eff in res["suspected_effects"]:
        assert set(eff) >= {"effect", "score", "estimate", "unit", "regressor"}


@pytest.mark.slow
@pytest.mark.xfail(
    reason="issue 7 open: on the 1.5 min sim at N = 100, compensating the true 0.2 s latency "
    "raises the mean innovation NLL (1.44 -> 2.67; pose errors of 4-5 m around 40-50 s), so the "
    "profile does not find it; cause not found yet, see docs/closing_the_loop.md",
    strict=False,
)
def test_undeclared_gnss_latency_is_found_sized_and_closed() -> None:
    res = rs.analyze_trace(_run(LATENCY_S))
    assert res["consistent"] is False  # (a)
    ranked = _ranked(LATENCY_S)
    assert ranked[0]["effect"] == "gnss_latency"  # (b)
    assert ranked[0]["score"] >= rs.SCORE_THRESHOLD
    assert ranked[0]["estimate"] == pytest.approx(LATENCY_S, rel=0.3)  # (c)
    after = _run(LATENCY_S, "gnss_latency", round(float(ranked[0]["estimate"]), 3))
    clean = _radius_error(0.0, _run(0.0))
    assert _radius_error(LATENCY_S, after) <= 2.0 * max(clean, 2e-4)  # (d)
    assert rs.neg_log_likelihood(after) < rs.neg_log_likelihood(_run(LATENCY_S))


@pytest.mark.slow
def test_no_injection_no_false_attribution() -> None:
    ranked = _ranked(0.0)
    for eff in ranked:
        assert eff["score"] < rs.SCORE_THRESHOLD, eff
        assert abs(eff["estimate"]) <= 0.05, eff
