"""The virtual tyre sensors' inverse Magic Formula (Tuononen 2009 eq. 11)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from tire_estimation.core.lateral.virtual_tyre import (
    inverse_magic_formula,
    magic_formula,
    peak_slip_factor,
)


@pytest.mark.parametrize(("c", "e"), [(1.3, -0.5), (1.9, 0.5), (1.1, 0.9), (1.5, -2.0)])
def test_inverse_is_the_root_of_eq_11_on_the_rising_branch(c: float, e: float) -> None:
    """Against Brent's method on eq. (11) over [0, alpha_peak], for random B, D and forces up
    to 99.8 % of the peak, both signs."""
    rng = np.random.default_rng(0)
    x_peak = peak_slip_factor(c, e)
    for _ in range(300):
        b, d = rng.uniform(5.0, 20.0), rng.uniform(1000.0, 8000.0)
        f = rng.uniform(-0.998, 0.998) * d
        alpha = inverse_magic_formula(f, b, c, d, e, x_peak)
        ref = brentq(
            lambda a, b=b, d=d, f=f: magic_formula(a, b, c, d, e) - abs(f),
            0.0,
            x_peak / b,
            xtol=1e-14,
        )
        assert alpha == pytest.approx(math.copysign(ref, f), abs=1e-12)
        assert magic_formula(alpha, b, c, d, e) == pytest.approx(f, rel=1e-9)


def test_saturated_and_zero_forces() -> None:
    x_peak = peak_slip_factor(1.3, -0.5)
    assert inverse_magic_formula(-5000.0, 10.0, 1.3, 5000.0, -0.5, x_peak) == -x_peak / 10.0
    assert inverse_magic_formula(0.0, 10.0, 1.3, 5000.0, -0.5, x_peak) == 0.0
