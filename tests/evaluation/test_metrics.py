"""Report metrics: the learning time per wheel, and a verdict that says when it cannot test."""

from __future__ import annotations

import numpy as np

from tire_estimation.evaluation import residuals as rs
from tire_estimation.evaluation.metrics import NO_ESTIMATE, learning_metrics


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
