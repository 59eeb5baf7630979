"""Unmodelled effects of the radius model that can be switched on, one :class:`Effect` each.

An effect owns its switch (a field of :class:`~.config.RadiusEstimatorConfig`, 0 = off, with
its admissible range), its correction (applied by the estimator), the regressor its signature
is tested on in the GNSS innovations, its profile-likelihood scan grid and the sentence that
names it to a user (:mod:`tire_estimation.evaluation.residuals`). :data:`EFFECTS` is the one
list both sides enumerate; adding an effect is adding an object to it (plus the declaration of
its field in the configuration dataclass).

Corrections come in three kinds:

* a time shift of the GNSS fixes (``fix_delay_sign``) or velocities (``velocity_delay_sign``):
  the measurement is compared with the pose ``sign * value`` seconds later than its stamp;
* a correction of the antenna lever arm along ``base_link`` x or y (``antenna_axis``);
* a correction of the wheel speeds (``wheel_speeds``), before the pose prediction; the rolling
  ones (speed, load, brake slip) before the slope distance of the grade fit is accumulated,
  the horizontal projection of the grade (``after_slope_distance``) after it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.model import FL, FR, RL, RR

if TYPE_CHECKING:
    from tire_estimation.core.radius.estimator import RadiusEstimator


#: correction of the wheel speeds (4,): ``(estimator, value, t_ns, ws) -> ws``
WheelSpeedCorrection = Callable[["RadiusEstimator", float, int, F64], F64]

#: the deceleration ``a_0`` that the driving resistances (rolling resistance, drag: body
#: forces, not rear tyre forces) explain without braking, m/s^2: the simulator's default
#: vehicle has ``c_rr g + rho C_d A v^2 / (2 m)`` = 0.19 / 0.23 / 0.29 m/s^2 at 16 / 20 / 25 m/s
REAR_BRAKE_SLIP_ONSET_M_S2 = 0.25


@dataclass(frozen=True)
class Effect:
    """One switchable effect.

    Attributes:
        name: name in the residual analysis (``gnss_latency``, ...).
        config_field: the ``RadiusEstimatorConfig`` field that switches it on (0 = off).
        limits: admissible range of that field (inclusive).
        unit: unit of the field.
        regressor: regressor of its signature in the innovations.
        signature: what it does to the innovations.
        words: what it looks like to a user (``residuals.explain``).
        grid: profile-likelihood scan grid (the configured value is added to it).
        profile_settings: other fields its profile runs with (base point included).
        fix_delay_sign: the fix stamped ``t`` is compared with the pose at
            ``t + sign * value``.
        velocity_delay_sign: the same for the GNSS velocity.
        antenna_axis: the value corrects the lever arm along this ``base_link`` axis.
        wheel_speeds: correction of the wheel speeds.
        after_slope_distance: the wheel-speed correction is applied after the slope distance
            of the grade fit is accumulated (the horizontal projection).
    """

    name: str
    config_field: str
    limits: tuple[float, float]
    unit: str
    regressor: str
    signature: str
    words: str
    grid: tuple[float, ...]
    profile_settings: tuple[tuple[str, float], ...] = ()
    fix_delay_sign: float = 0.0
    velocity_delay_sign: float = 0.0
    antenna_axis: int | None = None
    wheel_speeds: WheelSpeedCorrection | None = None
    after_slope_distance: bool = False

    def value(self, config: Any) -> float:
        """The effect's value in ``config`` (0 = not modelled)."""
        return float(getattr(config, self.config_field))

    def overrides(self, value: float) -> dict[str, float]:
        """Configuration fields of a re-run with the effect at ``value``."""
        return {self.config_field: value, **dict(self.profile_settings)}


def _speed_dependent_radius(est: RadiusEstimator, k: float, t_ns: int, ws: F64) -> F64:
    """Speed-dependent radius ``r = r0 + k v^2``."""
    gain = k * est.vehicle.nominal_tire_radius_m
    # speed-dependent radius r = r_n + delta + k v^2 (r_n nominal, delta the radius
    # error at standstill); with k v^2 ~ k omega^2 r_n^2:
    # v = omega (r_n + delta + k omega^2 r_n^2) ~ omega (1 + k r_n omega^2) (r_n + delta)
    # (neglected: about 3 k r_n omega^2 delta of radius, 0.04 mm for k = 4e-6,
    # omega = 100 rad/s, delta = 1 mm); with the scaled speeds every model downstream
    # (eq. 6, front wheels, gates) estimates delta
    return ws * (1.0 + gain * ws * ws)


def _load_dependent_radius(est: RadiusEstimator, c: float, t_ns: int, ws: F64) -> F64:
    """Load-dependent radius ``r = r0 + c (Fz - Fz_static)``: per-wheel factor
    ``1 + c dFz_i / r_nominal`` of the wheel speeds."""
    veh = est.vehicle
    fx, fy = est.specific_force(t_ns, ws)
    # quasi-static load transfer per unit specific force, N per m/s^2 (the simulator's
    # geometry): longitudinal m h / (2 L) per wheel, lateral m h / l_T split between the
    # axles like the static loads (front lr / L, rear lf / L)
    wb = veh.cg_to_front_axle_m + veh.cg_to_rear_axle_m
    lat = veh.mass_kg * veh.cg_height_m / veh.track_width_m
    load_long = veh.mass_kg * veh.cg_height_m / (2.0 * wb)
    # quasi-static load transfer (Gillespie, Fundamentals of Vehicle Dynamics, eq. 2-7 and
    # ch. 9, roll stiffness split like the static loads): dFz = -+ m f_x h / (2 L) on the
    # front / rear wheels, -+ m f_y h / l_T (lr / L front, lf / L rear) on left / right
    d_long = load_long * fx
    d_f = lat * veh.cg_to_rear_axle_m / wb * fy
    d_r = lat * veh.cg_to_front_axle_m / wb * fy
    dfz = np.array([-d_long - d_f, -d_long + d_f, d_long - d_r, d_long + d_r])
    # r_i = r_n + delta_i + c dFz_i  ->  v_i = omega_i (r_n + delta_i) (1 + c dFz_i / r_n)
    # (neglected: c dFz_i delta_i / r_n, 1e-9 m for c = -5e-7, 600 N, delta_i = 1 mm)
    return ws * (1.0 + c / veh.nominal_tire_radius_m * dfz)


def braking_decel(fx_m_s2: float) -> float:
    """Braking deceleration ``b = max(0, -f_x - a_0)`` of the rear brake slip, m/s^2, from the
    longitudinal specific force ``f_x`` (m f_x = sum of the tyre forces - resistances): the
    brakes take what the driving resistances (``a_0``, body forces) do not explain."""
    return max(0.0, -fx_m_s2 - REAR_BRAKE_SLIP_ONSET_M_S2)


def _rear_brake_slip(est: RadiusEstimator, k: float, t_ns: int, ws: F64) -> F64:
    """Braked rear wheels: ``omega r = v (1 + kappa)``, ``kappa = -k b``."""
    est.brake_decel_m_s2 = b = braking_decel(est.specific_force(t_ns, ws, lateral=False)[0])
    if b <= 0.0:
        return ws
    # braked rear wheel: omega r = v (1 + kappa) with the slip kappa = -k b
    # (k = (1 - front brake share) m / C_x,rear), so the ground speed is
    # v = omega r / (1 + kappa); kappa floored at -0.5 (a locking wheel is not modelled)
    kappa = max(-0.5, -k * b)
    ws = ws.copy()
    ws[RL:] /= 1.0 + kappa
    return ws


def _road_grade(est: RadiusEstimator, gain: float, t_ns: int, ws: F64) -> F64:
    """Horizontal projection of the slope distance with the online grade."""
    grade = est.grade.grade_rad
    if not grade:
        return ws
    # the wheels roll along the slope, the pose and GNSS are horizontal:
    # ds_horizontal = ds cos(theta); the common mode of each axle is reduced by
    # gain (1 - cos theta), the left-right difference (the yaw rate) is kept
    eps = gain * (1.0 - math.cos(grade))
    mf = 0.5 * float(ws[FL] + ws[FR])
    mr = 0.5 * float(ws[RL] + ws[RR])
    return ws - eps * np.array([mf, mf, mr, mr])


_ALONG_ACCEL = "longitudinal_acceleration"

#: every switchable effect, in the order of the residual ranking; the wheel-speed corrections
#: are applied in this order
EFFECTS: tuple[Effect, ...] = (
    Effect(
        "gnss_latency", "gnss_latency_s", (-1.0, 1.0), "s", _ALONG_ACCEL,
        "along-track innovation = -speed x latency",
        "the fixes lag the wheel odometry (GNSS latency)",
        (0.0, 0.1, 0.2, 0.4), fix_delay_sign=-1.0,
    ),
    Effect(
        "wheel_speed_time_offset", "wheel_speed_time_offset_s", (-1.0, 1.0), "s", _ALONG_ACCEL,
        "along-track innovation = +speed x offset",
        "the wheel speeds lag the fixes (wheel-speed time offset)",
        (0.0, 0.1, 0.2, 0.4), fix_delay_sign=1.0, velocity_delay_sign=1.0,
    ),
    Effect(
        "gnss_lever_arm", "gnss_antenna_offset_x_m", (-5.0, 5.0), "m", "heading",
        "ENU innovation = R(heading) lever arm",
        "the GNSS antenna is not where vehicle.yaml puts it (lever arm)",
        (-1.0, 0.0, 1.0, 2.0, 4.0), antenna_axis=0,
    ),
    Effect(
        "gnss_lever_arm_y", "gnss_antenna_offset_y_m", (-5.0, 5.0), "m", "yaw_rate",
        "along-track drift = -yaw rate x lateral antenna offset",
        "the GNSS antenna sits off the centre line (lateral lever arm)",
        (-1.0, -0.5, 0.0, 0.5, 1.0), antenna_axis=1,
    ),
    Effect(
        "radius_speed_dependence", "radius_speed_coefficient_m_per_m2_s2", (-1e-4, 1e-4),
        "m/(m/s)^2", "speed^2",
        "along-track drift growing with speed^2 beyond speed",
        "the tyres grow with speed (speed-dependent radius)",
        (0.0, 2e-6, 4e-6, 6e-6, 8e-6), wheel_speeds=_speed_dependent_radius,
    ),
    Effect(
        "radius_load_dependence", "radius_load_coefficient_m_per_n", (-1e-4, 1e-4), "m/N",
        "speed*lateral_acceleration",
        "cross-track drift to the inside of curves (yaw-rate error ~ v a_y)",
        "the loaded tyres roll smaller in curves (load-dependent radius)",
        (-4e-6, -2e-6, -1e-6, 0.0, 1e-6), wheel_speeds=_load_dependent_radius,
    ),
    Effect(
        "road_grade", "road_grade_correction_gain", (0.0, 5.0), "1", "speed*(1-cos(grade))",
        "along-track drift = -v (1 - cos grade) (slope distance vs horizontal)",
        "the road is not flat (grades)",
        (0.0, 0.5, 1.0, 1.5), wheel_speeds=_road_grade, after_slope_distance=True,
    ),
    # the grid spans the physical value of the simulator's default vehicle, 3.5e-3 s^2/m
    Effect(
        "rear_brake_slip", "rear_brake_slip_s2_per_m", (0.0, 0.05), "s^2/m",
        "speed*brake_decel",
        "along-track drift = +v k b (braked rear wheels turn slower)",
        "the rear wheels slip when braking (brake slip)",
        (0.0, 2e-3, 4e-3, 6e-3), wheel_speeds=_rear_brake_slip,
    ),
    # scanned only when the run used the GNSS velocity; it shows only while the wheels
    # accelerate, which the velocity gate otherwise leaves out: its profile runs with the gate
    # open
    Effect(
        "gnss_velocity_latency", "gnss_velocity_latency_s", (-1.0, 1.0), "s", _ALONG_ACCEL,
        "along-track velocity innovation = -acceleration x velocity latency",
        "the receiver's velocity lags the wheel speeds (velocity latency)",
        (0.0, 0.1, 0.2, 0.3), profile_settings=(("gnss_velocity_max_accel_m_s2", 100.0),),
        velocity_delay_sign=-1.0,
    ),
)  # fmt: skip

#: the effects by name
BY_NAME: dict[str, Effect] = {e.name: e for e in EFFECTS}


def delay_s(config: Any, sign_of: Callable[[Effect], float]) -> float:
    """Sum of the signed time shifts ``sign_of(effect) * value`` of the effects that have one."""
    total = 0.0
    for e in EFFECTS:
        sign = sign_of(e)
        if sign:
            total += sign * e.value(config)
    return total
