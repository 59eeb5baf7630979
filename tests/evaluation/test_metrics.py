"""Report metrics: the learning time per wheel, and a verdict that says when it cannot test."""

from __future__ import annotations

from collections import Counter

import numpy as np

from tire_estimation.evaluation import residuals as rs
from tire_estimation.evaluation.metrics import (
    NO_ESTIMATE,
    lateral_from_sums,
    lateral_sums,
    learning_metrics,
)


def test_a_gap_without_estimates_is_not_counted_as_learning() -> None:
    """Estimates every 0.1 s, learning, with a 30 s gap (pose re-initializing) in the middle:
    the gap is its own reason, not learning time."""
    t_s = np.concatenate([np.arange(0.0, 10.0, 0.1), np.arange(40.0, 50.0, 0.1)])
    t_ns = np.round(t_s * 1e9).astype(np.int64)
    active = np.ones((t_ns.size, 2), dtype=bool)
    out = learning_metrics(t_ns, ("wheel_rl", "wheel_rr"), active, ["estimating"] * t_ns.size)
    for w in out.values():
        assert abs(w["learned_s"] - 20.0) < 0.2
        assert abs(w["paused_s"][NO_ESTIMATE] - 29.9) < 0.2
        assert abs(w["share"] - 20.0 / 49.9) < 0.01


def test_a_slow_drive_is_tested_on_its_whole_run_innovations() -> None:
    """Fewer than 20 innovations while moving: no effect regression, but the whole-run tests
    still decide (here correlated innovations: not consistent), and with too few innovations
    for those the verdict is None, not True."""
    rng = np.random.default_rng(0)
    n = 400
    # strongly correlated innovations (a random walk), unit covariance
    nu = np.cumsum(rng.standard_normal((n, 2)) * 0.3, axis=0)
    cov = np.tile(np.eye(2), (n, 1, 1))
    nis = np.einsum("ki,ki->k", nu, nu)
    t_ns = np.arange(n, dtype=np.int64) * 100_000_000
    pose = np.zeros((n, 3))
    speed = np.full(n, 0.5)  # below the 1 m/s floor of the regressions
    res = rs.analyze(t_ns, nu, cov, nis, np.ones(n, bool), t_ns, pose, speed)
    assert res["consistent"] is False
    assert res["tests"]["white_normalized"] is False
    assert any("correlated" in line for line in rs.explain(res))
    few = rs.analyze(
        t_ns[:5], nu[:5], cov[:5], nis[:5], np.ones(5, bool), t_ns[:5], pose[:5], speed[:5]
    )
    assert few["consistent"] is None


def test_lateral_rmses_summed_over_parts_equal_those_of_the_whole_run() -> None:
    """Constant errors of 0.1 m/s in vy and 1 deg/s in yaw rate against a straight reference,
    half the samples marked nonlinear: the RMSEs are those errors, and summing two parts gives
    the same figures as the whole run."""
    t_ns = np.arange(10, dtype=np.int64) * 10_000_000
    ref_v = np.column_stack([np.full(10, 20.0), np.zeros(10)])
    ref_r = np.zeros(10)
    vy = np.full(10, 0.1)
    r = np.full(10, np.radians(1.0))
    beta = np.zeros(10)
    relay = np.array([1, 2] * 5, dtype=np.int64)
    whole = lateral_from_sums(lateral_sums(t_ns, vy, r, beta, relay, t_ns, ref_v, ref_r))
    assert abs(whole["vy_rmse_m_s"] - 0.1) < 1e-12
    assert abs(whole["yaw_rate_rmse_deg_s"] - 1.0) < 1e-12
    assert whole["sideslip_rmse_deg"] == 0.0
    assert whole["nonlinear_fraction"] == 0.5
    assert abs(whole["nonlinear_vy_rmse_m_s"] - 0.1) < 1e-12
    assert whole["samples"] == 10
    parts = lateral_sums(t_ns[:4], vy[:4], r[:4], beta[:4], relay[:4], t_ns, ref_v, ref_r)
    parts.update(lateral_sums(t_ns[4:], vy[4:], r[4:], beta[4:], relay[4:], t_ns, ref_v, ref_r))
    summed = lateral_from_sums(parts)
    assert summed.keys() == whole.keys()
    for key, value in whole.items():
        assert abs(summed[key] - value) < 1e-12, key
    empty = lateral_from_sums(Counter())
    assert empty == {"vy_rmse_m_s": None, "sideslip_rmse_deg": None, "yaw_rate_rmse_deg_s": None}
