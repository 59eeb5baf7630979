"""Random numbers of the compiled kernels: generator, normal and gamma distributions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from tire_estimation.core import kernel_random as kr

# the first outputs of the reference C implementation of xoshiro256++ (prng.di.unimi.it),
# compiled with gcc and run from this state
STATE = [0x0123456789ABCDEF, 0xFEDCBA9876543210, 0x0F1E2D3C4B5A6978, 0x8796A5B4C3D2E1F0]
REFERENCE = [
    0x8F4A04BF79702AE4,
    0x32A963A59BD690C3,
    0xCDB81CE05B969BEE,
    0x1E6545C924215805,
    0x2DC087DED5B8F4DB,
    0x7B25C30EBC2EE695,
]


def test_xoshiro256pp_matches_reference_c():
    state = np.array(STATE, dtype=np.uint64)
    out = np.zeros(len(REFERENCE), dtype=np.uint64)
    kr.fill_u64(state, out)
    assert [int(v) for v in out] == REFERENCE
    # the state advanced: the next words differ from the first
    again = np.zeros(len(REFERENCE), dtype=np.uint64)
    kr.fill_u64(state, again)
    assert [int(v) for v in again] != REFERENCE


def test_kernel_state_is_reproducible_and_advances_the_generator():
    a, b = np.random.default_rng(3), np.random.default_rng(3)
    s1, s2 = kr.kernel_state(a), kr.kernel_state(b)
    assert s1.dtype == np.uint64 and s1.shape == (4,)
    np.testing.assert_array_equal(s1, s2)
    # the generator moved on by four words: the next state differs
    assert not np.array_equal(kr.kernel_state(a), s1)


def test_ziggurat_tables_are_consistent():
    # strip edges decrease upwards, densities increase to f(0) = 1
    assert np.all(np.diff(kr.ZIG_WI[1:]) > 0)
    assert np.all(np.diff(kr.ZIG_FI) < 0)
    assert kr.ZIG_FI[0] == 1.0
    # each strip (1..255) has the same area v = x_i (f(x_{i-1}) - f(x_i)) (Marsaglia & Tsang)
    x = kr.ZIG_WI[1:] * 2.0**52
    area = x * (kr.ZIG_FI[:-1] - kr.ZIG_FI[1:])
    np.testing.assert_allclose(area, 4.92867323399e-3, rtol=1e-6)


def test_normal_distribution():
    state = kr.kernel_state(np.random.default_rng(11))
    x = np.empty(2_000_000)
    kr.fill_normal(state, x)
    assert abs(x.mean()) < 5 * 1.0 / np.sqrt(x.size)
    assert x.var() == pytest.approx(1.0, abs=5 * np.sqrt(2.0 / x.size))
    assert stats.kstest(x, "norm").pvalue > 1e-3
    # the tail beyond r = 3.654 (its own branch) and the wedges carry the right mass
    r = 3.6541528853610088
    expected = 2.0 * stats.norm.sf(r) * x.size
    assert abs(np.sum(np.abs(x) > r) - expected) < 5 * np.sqrt(expected)
    tail = np.abs(x[np.abs(x) > r])
    assert (
        stats.kstest(tail - r, lambda t: 1 - stats.norm.sf(r + t) / stats.norm.sf(r)).pvalue > 1e-3
    )
    # both signs in the tail
    assert np.sum(x > r) > 0.3 * tail.size and np.sum(x < -r) > 0.3 * tail.size


@pytest.mark.parametrize("shape", [0.3, 1.0, 5.5, 300.0])
def test_gamma_distribution(shape):
    state = kr.kernel_state(np.random.default_rng(12))
    g = np.empty(400_000)
    kr.fill_gamma(state, shape, g)
    assert np.all(g > 0)
    assert g.mean() == pytest.approx(shape, rel=5 * np.sqrt(1.0 / (shape * g.size)))
    assert stats.kstest(g, "gamma", args=(shape,)).pvalue > 1e-3
