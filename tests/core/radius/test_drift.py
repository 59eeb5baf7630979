"""Drift test of the fix innovations and the cloud's inflation factor."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import chdtri
from scipy.stats import f

from tire_estimation.core.radius.drift import (
    DRIFT_WINDOW_FIXES,
    DriftTest,
    f2_quantile,
    inflation_factor,
)

GATE = float(chdtri(2, 1e-4))
S = np.array([[1.0, 0.2], [0.2, 0.8]])


def _white(test, rng, cov, n):
    chol = np.linalg.cholesky(cov)
    return [test.push(chol @ rng.standard_normal(2), S) for _ in range(n)]


def test_white_innovations_of_the_predicted_covariance_rarely_fire():
    test = DriftTest(GATE)
    fired = sum(m is not None for m in _white(test, np.random.default_rng(3), S, 5000))
    # overlapping windows at a 1e-4 false-alarm probability each
    assert fired <= 2


def test_innovations_wider_than_predicted_are_measured_against_their_own_scatter():
    """Innovations of twice the predicted covariance (a filter whose noise model does not fit):
    the window mean's statistic is 2 chi2_2 and passes the chi-square quantile once in a hundred
    windows; against the past windows' scatter it rarely fires."""
    test = DriftTest(GATE)
    fired = sum(m is not None for m in _white(test, np.random.default_rng(5), 2.0 * S, 5000))
    assert fired <= 2
    assert test.threshold() == pytest.approx(test._scatter_gates[-1] * 2.0, rel=0.4)


def test_a_mean_offset_within_the_single_fix_gate_fires_once_the_window_is_full():
    # 2 innovation std along east: each fix has NIS of about 4, far inside the gate
    offset = np.array([2.0 * np.sqrt(S[0, 0]), 0.0])
    assert offset @ np.linalg.solve(S, offset) < GATE
    test = DriftTest(GATE)
    # no scatter measured yet: nothing fires
    assert all(test.push(offset, S) is None for _ in range(DRIFT_WINDOW_FIXES))
    test = DriftTest(GATE)
    assert all(
        m is None for m in _white(test, np.random.default_rng(4), S, 30 * DRIFT_WINDOW_FIXES)
    )
    test.clear()
    out = [test.push(offset, S) for _ in range(DRIFT_WINDOW_FIXES)]
    assert all(m is None for m in out[:-1])
    np.testing.assert_allclose(out[-1], offset)
    test.clear()
    assert test.push(offset, S) is None


def test_f2_quantile_is_the_f_distribution_tail():
    assert f2_quantile(1e-4, 60) == pytest.approx(float(f.isf(1e-4, 2, 60)), rel=1e-9)
    assert f2_quantile(0.05, 8) == pytest.approx(float(f.isf(0.05, 2, 8)), rel=1e-9)


def test_inflation_factor_matches_the_mean_to_the_widened_cloud():
    cloud = np.array([[0.04, 0.01], [0.01, 0.09]])
    m = np.array([1.0, -2.0])
    a = inflation_factor(m, cloud)
    assert m @ np.linalg.solve(a * a * cloud, m) == pytest.approx(2.0)
    assert inflation_factor(np.array([0.05, 0.0]), cloud) == 1.0
    assert inflation_factor(m, np.zeros((2, 2))) == 1.0
