"""Drift test of the fix innovations and the cloud's inflation factor."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import chdtri

from tire_estimation.core.radius.drift import DRIFT_WINDOW_FIXES, DriftTest, inflation_factor

GATE = float(chdtri(2, 1e-4))
S = np.array([[1.0, 0.2], [0.2, 0.8]])


def test_white_innovations_of_the_predicted_covariance_rarely_fire():
    rng = np.random.default_rng(3)
    chol = np.linalg.cholesky(S)
    test = DriftTest(GATE)
    fired = sum(test.push(chol @ rng.standard_normal(2), S) is not None for _ in range(5000))
    # overlapping windows at a 1e-4 false-alarm probability each
    assert fired <= 2


def test_a_mean_offset_within_the_single_fix_gate_fires_once_the_window_is_full():
    # 1.5 innovation std along east: each fix has NIS of about 2.3, far inside the gate
    offset = np.array([1.5 * np.sqrt(S[0, 0]), 0.0])
    assert offset @ np.linalg.solve(S, offset) < GATE
    test = DriftTest(GATE)
    out = [test.push(offset, S) for _ in range(DRIFT_WINDOW_FIXES)]
    assert all(m is None for m in out[:-1])
    np.testing.assert_allclose(out[-1], offset)
    test.clear()
    assert test.push(offset, S) is None


def test_inflation_factor_matches_the_mean_to_the_widened_cloud():
    cloud = np.array([[0.04, 0.01], [0.01, 0.09]])
    m = np.array([1.0, -2.0])
    a = inflation_factor(m, cloud)
    assert m @ np.linalg.solve(a * a * cloud, m) == pytest.approx(2.0)
    assert inflation_factor(np.array([0.05, 0.0]), cloud) == 1.0
    assert inflation_factor(m, np.zeros((2, 2))) == 1.0
