"""Resamplers: unbiased copy counts, low variance where promised, ESS."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from tire_estimation.core.resampling import (
    RESAMPLERS,
    ess,
    log_of_weights,
    normalize_log_weights,
)


@pytest.mark.parametrize("name", sorted(RESAMPLERS))
def test_resampler_is_unbiased(name):
    rng = np.random.default_rng(10)
    n = 50
    w = rng.random(n) ** 3
    w /= w.sum()
    reps = 4000
    counts = np.zeros(n)
    for _ in range(reps):
        idx = RESAMPLERS[name](w, rng)
        assert idx.shape == (n,)
        assert np.all((idx >= 0) & (idx < n))
        counts += np.bincount(idx, minlength=n)
    mean_counts = counts / reps
    # standard error of the mean count <= sqrt(N w (1 - w) / reps)
    tol = 5 * np.sqrt(n * w * (1 - w) / reps) + 1e-9
    assert np.all(np.abs(mean_counts - n * w) <= tol)


@pytest.mark.parametrize("name", ["systematic", "stratified", "residual"])
def test_low_variance_schemes_keep_floor_copies(name):
    rng = np.random.default_rng(11)
    w = np.array([0.5, 0.25, 0.125, 0.125])
    for _ in range(100):
        c = np.bincount(RESAMPLERS[name](w, rng), minlength=4)
        if name == "systematic" or name == "residual":
            assert np.all(c >= np.floor(4 * w))
        assert c.sum() == 4


def test_systematic_copies_are_within_one_of_expectation():
    rng = np.random.default_rng(12)
    w = rng.random(100)
    w /= w.sum()
    for _ in range(200):
        c = np.bincount(RESAMPLERS["systematic"](w, rng), minlength=100)
        assert np.all(np.abs(c - 100 * w) < 1.0 + 1e-12)


def test_ess_and_log_weight_normalization():
    assert ess(np.full(10, 0.1)) == pytest.approx(10.0)
    assert ess(np.array([1.0, 0.0, 0.0])) == pytest.approx(1.0)
    w, lz = normalize_log_weights(np.array([-1000.0, -1000.0 + np.log(3.0), -np.inf]))
    np.testing.assert_allclose(w, [0.25, 0.75, 0.0])
    assert lz == pytest.approx(-1000.0 + np.log(4.0))
    w, _ = normalize_log_weights(np.array([np.nan, -np.inf]))
    np.testing.assert_allclose(w, [0.5, 0.5])


def test_log_of_weights_gives_minus_inf_for_a_zero_weight_without_a_warning() -> None:
    weights = np.array([0.0, 0.25, 0.75])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        log_w = log_of_weights(weights)
    assert log_w[0] == -np.inf
    np.testing.assert_allclose(log_w[1:], np.log([0.25, 0.75]))
    # such a particle keeps weight zero through the normalization
    w, _ = normalize_log_weights(log_w)
    np.testing.assert_allclose(w, weights)
