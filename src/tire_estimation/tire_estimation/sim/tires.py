"""Tyre model of the simulator: Pacejka Magic Formula forces and the effective rolling radius.

Scalar ``math`` functions on purpose: they run inside the per-step integration loop, where NumPy
calls on tiny arrays would dominate the run time.

Magic Formula (Pacejka, "Tyre and Vehicle Dynamics", simple four-parameter form, as also used in
Tuononen 2009 eq. 11)::

    F = D sin(C atan(B x - E (B x - atan(B x))))

with D = mu Fz (peak force), C the shape factor, E the curvature factor and B the stiffness
factor. The small-slip slope is dF/dx = B C D. We keep the *stiffness* B C D of each tyre at its
configured value independent of the load (so the axle stiffness the estimators track is exactly
the truth value) and let the load and friction set only the saturation level D.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from tire_estimation.core.stiffness.model import CurvatureFactor, ShapeFactor
from tire_estimation.core.validation import (
    Checked,
    Fraction,
    in_range,
)

#: Smallest vertical load used in the force laws (a lifted wheel still gets a tiny D), N.
MIN_FZ_N = 100.0


@dataclass(frozen=True)
class TireModelConfig(Checked):
    """Tyre and resistance parameters (SI units in names; checked at construction).

    Attributes:
        nominal_pressure_kpa: cold inflation pressure at which the radius is nominal, kPa.
        pressure_sensitivity_mm_per_kpa: d r_eff / d p, mm per kPa (0.03 mm/kPa: a 20 % loss
            of 230 kPa shrinks the radius by ~1.4 mm, cf. Lundquist et al. 2014).
        radius_offset_std_mm: per-tyre manufacturing/wear offset of r_eff, mm (seeded draw).
        lateral_shape_c: Magic Formula C for the lateral force (1.3 typical).
        lateral_curvature_e: Magic Formula E for the lateral force.
        longitudinal_shape_c: Magic Formula C for the longitudinal force (1.65 typical); E = 0
            there so the force can be inverted in closed form.
        rolling_resistance_coefficient: F_rr = c_rr m g, 1.
        drag_area_m2: aerodynamic Cd * A, m^2.
        air_density_kg_m3: kg/m^3.
        max_drive_power_w: power limit of the powertrain at the wheels, W.
        brake_front_share: share of the braking force on the front axle, 1.
    """

    nominal_pressure_kpa: Annotated[float, in_range(50.0, 1000.0)] = 230.0
    pressure_sensitivity_mm_per_kpa: Annotated[float, in_range(0.0, 1.0)] = 0.03
    radius_offset_std_mm: Annotated[float, in_range(0.0, 10.0)] = 0.3
    lateral_shape_c: ShapeFactor = 1.3
    lateral_curvature_e: CurvatureFactor = -0.5
    longitudinal_shape_c: ShapeFactor = 1.65
    rolling_resistance_coefficient: Annotated[float, in_range(0.0, 0.1)] = 0.012
    drag_area_m2: Annotated[float, in_range(0.0, 20.0)] = 0.7
    air_density_kg_m3: Annotated[float, in_range(0.5, 2.0)] = 1.2
    max_drive_power_w: Annotated[float, in_range(1e3, 1e7)] = 110_000.0
    brake_front_share: Fraction = 0.65

    PREFIX = "tires."


def magic_formula(x: float, stiffness: float, shape_c: float, peak_d: float, e: float) -> float:
    """Force for slip ``x`` with small-slip slope ``stiffness`` (= B C D) and peak ``peak_d``."""
    # Pacejka: F = D sin(C atan(Bx - E(Bx - atan Bx))), B = stiffness / (C D)
    bx = stiffness / (shape_c * peak_d) * x
    return peak_d * math.sin(shape_c * math.atan(bx - e * (bx - math.atan(bx))))


def inverse_magic_formula_e0(
    force: float, stiffness: float, shape_c: float, peak_d: float
) -> float:
    """Slip on the rising branch giving ``force`` for E = 0 (force clipped to +-0.999 D)."""
    # F = D sin(C atan(Bx))  =>  x = tan(asin(F / D) / C) / B
    ratio = max(-0.999, min(0.999, force / peak_d))
    b = stiffness / (shape_c * peak_d)
    return math.tan(math.asin(ratio) / shape_c) / b
