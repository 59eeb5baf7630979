"""Closed-form 3x3 algebra over particles (core/stiffness/mat3.py) against numpy.linalg."""

from __future__ import annotations

import numpy as np

from tire_estimation.core.stiffness import mat3


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    a = rng.standard_normal((n, 3, 3))
    return a @ np.swapaxes(a, 1, 2) + 0.1 * np.eye(3)


def test_layout_round_trip() -> None:
    rng = np.random.default_rng(0)
    a = rng.standard_normal((7, 3, 3))
    x = rng.standard_normal((7, 3))
    s = mat3.soa(a)
    assert s.shape == (3, 3, 7) and s.flags.c_contiguous
    assert s[1, 2, 4] == a[4, 1, 2]
    np.testing.assert_array_equal(mat3.aos(s), a)
    np.testing.assert_array_equal(mat3.aos(mat3.soa(x)), x)
    assert mat3.soa(x)[2, 5] == x[5, 2]


def test_products_match_matmul() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal((2, 9, 3, 3))
    x = rng.standard_normal((9, 3))
    np.testing.assert_allclose(mat3.aos(mat3.mm(mat3.soa(a), mat3.soa(b))), a @ b, atol=1e-12)
    np.testing.assert_allclose(
        mat3.aos(mat3.mm_bt(mat3.soa(a), mat3.soa(b))), a @ np.swapaxes(b, 1, 2), atol=1e-12
    )
    np.testing.assert_allclose(
        mat3.aos(mat3.mv(mat3.soa(a), mat3.soa(x))), (a @ x[..., None])[..., 0], atol=1e-12
    )
    sym = mat3.aos(mat3.sym(mat3.soa(a)))
    np.testing.assert_allclose(sym, 0.5 * (a + np.swapaxes(a, 1, 2)))


def test_inverse_and_determinant_match_linalg() -> None:
    rng = np.random.default_rng(2)
    a = _spd(rng, 50)
    # a badly scaled one (yaw-rate variance 1e-6 next to accelerations of order 1)
    a[0] = np.diag([2.5e-3, 2.5e-3, 3e-6]) + 1e-7
    inv, det = mat3.inv_sym(mat3.soa(a))
    np.testing.assert_allclose(mat3.aos(inv), np.linalg.inv(a), rtol=1e-8)
    np.testing.assert_allclose(det, np.linalg.det(a), rtol=1e-10)
    # the result is exactly symmetric
    np.testing.assert_array_equal(inv, inv.transpose(1, 0, 2))


def test_cholesky_matches_linalg_and_flags_indefinite() -> None:
    rng = np.random.default_rng(3)
    a = _spd(rng, 40)
    chol = mat3.aos(mat3.cholesky(mat3.soa(a)))
    np.testing.assert_allclose(chol, np.linalg.cholesky(a), rtol=1e-10, atol=1e-12)
    assert np.all(np.triu(chol, 1) == 0.0)
    bad = np.diag([1.0, -1.0, 1.0])[None]
    with np.errstate(invalid="ignore"):
        assert np.isnan(mat3.cholesky(mat3.soa(bad))).any()
