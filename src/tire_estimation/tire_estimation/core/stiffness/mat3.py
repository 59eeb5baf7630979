"""Small-matrix algebra for many particles at once, in closed form.

The stiffness MPF works with one 3x3 matrix per particle. NumPy's batched ``linalg`` routines
and ``einsum`` on ``(N, 3, 3)`` arrays spend most of their time in per-matrix overhead; here the
particle axis is moved last (``(3, 3, N)``, "structure of arrays"), so that every product or
cofactor is an element-wise operation on contiguous ``(N,)`` rows.

Layouts: ``aos`` = ``(N, 3, 3)`` / ``(N, 3)`` (the filter's arrays), ``soa`` = ``(3, 3, N)`` /
``(3, N)`` (this module's). :func:`soa` and :func:`aos` convert (one contiguous copy each).
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from tire_estimation.core.arrays import F64

T = TypeVar("T", float, F64)


_TO_SOA = {2: (1, 0), 3: (1, 2, 0)}
_TO_AOS = {2: (1, 0), 3: (2, 0, 1)}


def soa(a: F64) -> F64:
    """``(N, 3)`` or ``(N, 3, 3)`` -> contiguous ``(3, N)`` or ``(3, 3, N)``."""
    return np.ascontiguousarray(a.transpose(_TO_SOA[a.ndim]))


def aos(a: F64) -> F64:
    """``(3, N)`` or ``(3, 3, N)`` -> contiguous ``(N, 3)`` or ``(N, 3, 3)``."""
    return np.ascontiguousarray(a.transpose(_TO_AOS[a.ndim]))


def mm(a: F64, b: F64) -> F64:
    """``a @ b`` per particle, ``(3, 3, N) x (3, 3, N) -> (3, 3, N)``."""
    return np.einsum("ijn,jkn->ikn", a, b)


def mm_bt(a: F64, b: F64) -> F64:
    """``a @ b^T`` per particle, ``(3, 3, N) x (3, 3, N) -> (3, 3, N)``."""
    return np.einsum("ijn,kjn->ikn", a, b)


def mv(a: F64, x: F64) -> F64:
    """``a @ x`` per particle, ``(3, 3, N) x (3, N) -> (3, N)``."""
    return np.einsum("ijn,jn->in", a, x)


def sym(a: F64) -> F64:
    """Symmetric part ``(a + a^T) / 2``, ``(3, 3, N)``."""
    return 0.5 * (a + a.transpose(1, 0, 2))


def sym_cofactors(a00: T, a01: T, a02: T, a11: T, a12: T, a22: T) -> tuple[T, ...]:
    """Cofactors ``C00, C01, C02, C11, C12, C22`` and the determinant of the symmetric 3x3 with
    the upper triangle ``a00 ... a22`` (floats or arrays; also compiled in ``kernels``)."""
    # cofactors C_ij (symmetric for symmetric a)
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    # det = a_0j C_0j (Laplace expansion along row 0)
    det = a00 * c00 + a01 * c01 + a02 * c02
    return c00, c01, c02, c11, c12, c22, det


def inv_sym(a: F64) -> tuple[F64, F64]:
    """Inverse and determinant of symmetric 3x3 matrices ``(3, 3, N)`` by cofactors.

    Only the upper triangle of ``a`` is read. Returns ``(a^-1 (3, 3, N), det (N,))``; the
    determinant is not checked (a singular matrix gives inf/nan, as ``np.linalg.inv`` raises).
    """
    c00, c01, c02, c11, c12, c22, det = sym_cofactors(
        a[0, 0], a[0, 1], a[0, 2], a[1, 1], a[1, 2], a[2, 2]
    )
    # a^-1 = C^T / det
    inv_det = 1.0 / det
    out = np.empty_like(a)
    out[0, 0] = c00 * inv_det
    out[1, 1] = c11 * inv_det
    out[2, 2] = c22 * inv_det
    out[0, 1] = out[1, 0] = c01 * inv_det
    out[0, 2] = out[2, 0] = c02 * inv_det
    out[1, 2] = out[2, 1] = c12 * inv_det
    return out, det


def cholesky(a: F64) -> F64:
    """Lower Cholesky factor of SPD 3x3 matrices ``(3, 3, N)``, closed form.

    Only the lower triangle of ``a`` is read. A matrix that is not positive definite gives nan
    in the affected rows (``np.linalg.cholesky`` raises instead).
    """
    out = np.zeros_like(a)
    # L00 = sqrt(a00), L10 = a10 / L00, L20 = a20 / L00
    l00 = np.sqrt(a[0, 0])
    l10 = a[1, 0] / l00
    l20 = a[2, 0] / l00
    # L11 = sqrt(a11 - L10^2), L21 = (a21 - L20 L10) / L11
    l11 = np.sqrt(a[1, 1] - l10 * l10)
    l21 = (a[2, 1] - l20 * l10) / l11
    # L22 = sqrt(a22 - L20^2 - L21^2)
    l22 = np.sqrt(a[2, 2] - l20 * l20 - l21 * l21)
    out[0, 0], out[1, 0], out[2, 0] = l00, l10, l20
    out[1, 1], out[2, 1], out[2, 2] = l11, l21, l22
    return out
