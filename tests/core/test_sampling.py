"""Box-Muller standard normals (core/sampling.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from tire_estimation.core.sampling import Z_MAX, standard_normal


def test_box_muller_is_standard_normal():
    z = standard_normal(np.random.default_rng(0), (3, 200_001))
    assert z.shape == (3, 200_001) and z.dtype == np.float64
    x = z.ravel()
    assert abs(x.mean()) < 5e-3
    assert x.std() == pytest.approx(1.0, abs=5e-3)
    assert np.mean(x**4) == pytest.approx(3.0, abs=0.05)
    # the pairs (z1, z2) are independent
    assert abs(np.corrcoef(x[:300_000], x[300_000:600_000])[0, 1]) < 5e-3
    assert stats.kstest(x[:100_000], "norm").pvalue > 1e-3
    assert np.abs(x).max() <= Z_MAX + 1e-6


def test_box_muller_is_reproducible_and_odd_sizes_work():
    a = standard_normal(np.random.default_rng(3), (7,))
    b = standard_normal(np.random.default_rng(3), (7,))
    np.testing.assert_array_equal(a, b)
    assert standard_normal(np.random.default_rng(3), (0, 5)).shape == (0, 5)
