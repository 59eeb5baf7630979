"""Virtual tyre sensors: the lateral force of a wheel without a sensor (Tuononen 2009, 3.2).

The missing wheel of an axle is estimated from the sensor wheel of the *same axle* by the
"similarity method": both tyres run at (nearly) the same slip angle, so the inverse Magic
Formula (eq. 11) gives the slip angle of the sensor tyre from its measured (Fy, Fz), and the
same formula gives the virtual tyre's force at that slip angle and its own load. The virtual
tyre's vertical load comes from the measured load change (eq. 12-13).

Units: forces N, slip angles rad. Functions are scalar (called once per axle and sample) and
compiled (Numba, ``cache=True``), except the peak search of :func:`peak_slip_factor` (once per
tyre).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numba

#: Fraction of the peak force above which the measured force is treated as saturated.
SATURATION_FRACTION = 0.999
#: Smallest vertical load used by the virtual sensors (a lifted wheel), N.
MIN_LOAD_N = 50.0

# Shape of the eq. (11) Magic Formula of the virtual sensors: typical passenger-car lateral
# values (Pacejka), the same as the simulator's tyres (``sim/tires.py``); under the similarity
# method only the shape of the curve matters, the sensor tyre fixes the operating point.
#: shape factor C, 1 (in (1, 2): the curve has a peak).
MF_SHAPE_C = 1.3
#: curvature factor E, 1 (< 1).
MF_CURVATURE_E = -0.5
#: peak friction coefficient, D = mu Fz, 1 (dry asphalt).
MF_FRICTION_MU = 1.0


@numba.njit(cache=True, error_model="numpy")
def _shape(x: float, e: float) -> float:
    """phi(x) = x - E (x - atan x), the inner argument of eq. (11) for x = B alpha."""
    return x - e * (x - math.atan(x))


@numba.njit(cache=True, error_model="numpy")
def magic_formula(alpha_rad: float, b_1_rad: float, c: float, d_n: float, e: float) -> float:
    """Lateral force of eq. (11), N, for slip angle ``alpha_rad`` (rad).

    Args:
        alpha_rad: slip angle, rad.
        b_1_rad: stiffness factor B, 1/rad.
        c: shape factor C, 1.
        d_n: peak factor D (= mu Fz), N.
        e: curvature factor E, 1.
    """
    x = b_1_rad * alpha_rad
    # Tuononen 2009 eq. (11): Fy = D sin(C atan(B a - E (B a - atan(B a))))
    return d_n * math.sin(c * math.atan(_shape(x, e)))


def peak_slip_factor(c: float, e: float) -> float:
    """x* = B alpha* at the force peak of eq. (11) (C atan(phi(x*)) = pi/2); needs 1 < C < 2.

    phi is strictly increasing for E < 1, so x* is the root of phi(x) = tan(pi / (2 C)).
    """
    from scipy.optimize import brentq  # here: scipy.optimize costs 0.12 s to import

    target = math.tan(math.pi / (2.0 * c))
    hi = max(1.0, 2.0 * target)
    while _shape(hi, e) < target:
        hi *= 2.0
    return float(brentq(lambda x: _shape(x, e) - target, 0.0, hi, xtol=1e-12))


def inverse_magic_formula(
    fy_n: float, b_1_rad: float, c: float, d_n: float, e: float, x_peak: float | None = None
) -> float:
    """Slip angle (rad) on the rising branch of eq. (11) that gives ``fy_n``.

    Solved in closed form up to the inner argument phi, whose inverse is found by a bracketed
    Newton iteration (:func:`_inverse_shape`); eq. (11) is odd in the
    slip angle, so the sign of the force is carried over. A force at or above the peak D
    (sensor noise, or a tyre beyond its peak) returns the peak slip angle.

    Args:
        fy_n: lateral force, N.
        b_1_rad, c, d_n, e: Magic Formula factors (B 1/rad, C, D N, E); ``d_n`` > 0.
        x_peak: B alpha at the peak (from :func:`peak_slip_factor`); computed when None.
    """
    xp = peak_slip_factor(c, e) if x_peak is None else x_peak
    return _inverse_magic_formula(fy_n, b_1_rad, c, d_n, e, xp)


@numba.njit(cache=True, error_model="numpy")
def _inverse_magic_formula(
    fy_n: float, b_1_rad: float, c: float, d_n: float, e: float, xp: float
) -> float:
    """:func:`inverse_magic_formula` with the peak's ``x_peak`` given."""
    alpha_peak = xp / b_1_rad
    f_abs = abs(fy_n)
    f_max = d_n  # sin(C atan(phi(x*))) = 1
    if f_abs >= SATURATION_FRACTION * f_max:
        return math.copysign(alpha_peak, fy_n)
    if f_abs == 0.0:
        return 0.0
    # Tuononen 2009 eq. (11) solved for alpha: D sin(C atan(phi(B alpha))) = |Fy| on the
    # rising branch gives phi(x) = tan(asin(|Fy| / D) / C), x = B alpha
    phi = math.tan(math.asin(f_abs / d_n) / c)
    x = _inverse_shape(phi, e, xp)
    return math.copysign(x / b_1_rad, fy_n)


@numba.njit(cache=True, error_model="numpy")
def _inverse_shape(phi: float, e: float, x_hi: float) -> float:
    """The x in [0, x_hi] with phi(x) = x - E (x - atan x) = ``phi`` (E < 1: phi is strictly
    increasing, phi'(x) = 1 - E + E / (1 + x^2) > 0). Newton's method kept inside a shrinking
    bracket (bisection when a step leaves it), to 1e-14 relative."""
    lo, hi = 0.0, x_hi
    x = min(max(phi, 0.0), x_hi)
    for _ in range(100):
        g = _shape(x, e) - phi
        if g > 0.0:
            hi = x
        else:
            lo = x
        # Newton step on phi(x) - phi_target, phi'(x) = 1 - E + E / (1 + x^2)
        step = g / (1.0 - e + e / (1.0 + x * x))
        x_new = x - step
        if not lo < x_new < hi:
            x_new = 0.5 * (lo + hi)
        if abs(x_new - x) <= 1e-14 * max(1.0, abs(x)):
            return x_new
        x = x_new
    return x


@numba.njit(cache=True, error_model="numpy")
def virtual_load(
    fz_measured_n: float, fz_measured_static_n: float, fz_virtual_static_n: float
) -> float:
    """Vertical load of the virtual tyre, N (longitudinal load transfer neglected).

    Args:
        fz_measured_n: measured vertical load Fz,1 of the sensor tyre, N.
        fz_measured_static_n: static load Fz,1,static of the sensor tyre, N.
        fz_virtual_static_n: static load Fz,2,static of the virtual tyre, N.
    """
    # Tuononen 2009 eq. (12): dFz,1 = Fz,1 - Fz,1,static
    delta_fz = fz_measured_n - fz_measured_static_n
    # Tuononen 2009 eq. (13): Fz,2 = Fz,2,static - dFz,1
    return max(MIN_LOAD_N, fz_virtual_static_n - delta_fz)


@dataclass(frozen=True)
class MagicFormulaTyre:
    """Lateral Magic Formula of one axle's tyres, with D = mu Fz (similarity in the load).

    B is set per load so that the small-slip stiffness B C D equals
    ``cornering_stiffness_n_rad`` (load-independent cornering stiffness, as the simulator's
    tyre).

    Attributes:
        cornering_stiffness_n_rad: small-slip stiffness of one tyre, N/rad.
        c: shape factor C, 1 (in (1, 2)).
        e: curvature factor E, 1 (< 1).
        mu: peak friction coefficient, D = mu Fz, 1.
    """

    cornering_stiffness_n_rad: float
    c: float = MF_SHAPE_C
    e: float = MF_CURVATURE_E
    mu: float = MF_FRICTION_MU

    @cached_property
    def x_peak(self) -> float:
        """B alpha at the force peak, 1."""
        return peak_slip_factor(self.c, self.e)

    def factors(self, fz_n: float) -> tuple[float, float]:
        """(B 1/rad, D N) at vertical load ``fz_n`` (N)."""
        return _factors(self.cornering_stiffness_n_rad, self.c, self.mu, fz_n)

    def force(self, alpha_rad: float, fz_n: float) -> float:
        """Eq. (11) at slip angle ``alpha_rad`` (rad) and load ``fz_n`` (N): Fy, N."""
        b, d = self.factors(fz_n)
        return magic_formula(alpha_rad, b, self.c, d, self.e)

    def slip_angle(self, fy_n: float, fz_n: float) -> float:
        """Inverse of eq. (11): slip angle (rad) for lateral force ``fy_n`` at load ``fz_n``."""
        b, d = self.factors(fz_n)
        return inverse_magic_formula(fy_n, b, self.c, d, self.e, self.x_peak)

    def virtual_force(
        self, fy_measured_n: float, fz_measured_n: float, fz_virtual_n: float
    ) -> float:
        """Virtual tyre lateral force, N, at the sensor tyre's slip angle."""
        return _virtual_force(
            fy_measured_n, fz_measured_n, fz_virtual_n, self.cornering_stiffness_n_rad,
            self.c, self.e, self.mu, self.x_peak,
        )  # fmt: skip


@numba.njit(cache=True, error_model="numpy")
def _factors(
    cornering_stiffness_n_rad: float, c: float, mu: float, fz_n: float
) -> tuple[float, float]:
    """(B 1/rad, D N) of :meth:`MagicFormulaTyre.factors`."""
    d = mu * max(MIN_LOAD_N, fz_n)
    # small-slip slope dFy/dalpha = B C D = cornering stiffness
    return cornering_stiffness_n_rad / (c * d), d


@numba.njit(cache=True, error_model="numpy")
def _virtual_force(
    fy_measured_n: float,
    fz_measured_n: float,
    fz_virtual_n: float,
    cornering_stiffness_n_rad: float,
    c: float,
    e: float,
    mu: float,
    x_peak: float,
) -> float:
    """:meth:`MagicFormulaTyre.virtual_force` in one compiled call."""
    b, d = _factors(cornering_stiffness_n_rad, c, mu, fz_measured_n)
    alpha = _inverse_magic_formula(fy_measured_n, b, c, d, e, x_peak)
    b_v, d_v = _factors(cornering_stiffness_n_rad, c, mu, fz_virtual_n)
    return magic_formula(alpha, b_v, c, d_v, e)
