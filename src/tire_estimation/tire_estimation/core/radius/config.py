"""Frozen, validated configuration of the tyre-radius estimators.

Every field is checked at construction; a bad value raises
:class:`~tire_estimation.errors.ConfigError` naming the field and the value.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Any

from tire_estimation.core.radius.effects import EFFECTS
from tire_estimation.core.radius.road_grade import GRADE_SOURCE_MODES
from tire_estimation.core.validation import (
    Checked,
    Flag,
    NonNegative,
    Positive,
    Rule,
    in_range,
    int_in_range,
    one_of,
    require_known_keys,
)

WHEEL_MODES = ("rear", "all")


def _effect(field: str) -> Rule:
    """The range of the effect that ``field`` switches on (:data:`.effects.EFFECTS`)."""
    (effect,) = [e for e in EFFECTS if e.config_field == field]
    return in_range(*effect.limits)


@dataclass(frozen=True)
class RadiusEstimatorConfig(Checked):
    """Configuration of :class:`~tire_estimation.core.radius.estimator.RadiusEstimator`.

    Equation numbers refer to Lundquist et al., IEEE T-ITS 2014. The fields of the switchable
    effects (``gnss_latency_s`` ... ``rear_brake_slip_s2_per_m``) are checked against the
    limits of their :class:`~.effects.Effect` (:data:`.effects.EFFECTS`); the internal
    constants of the filter are module constants next to the equation they serve.

    Attributes:
        n_particles: number of particles N of the MPF. Default 500.
        forgetting_factor: lambda of the NiW time update (eq. 24), per wheel-speed sample; the
            statistics cover about ``1 / (1 - lambda)`` samples. Default 0.9998 (50 s at 100 Hz).
        prior_radius_error_std_m: prior standard deviation of the mean radius error, m
            (sets gamma_0 of eq. 22b). Default 0.003.
        radius_random_walk_m_sqrt_s: random walk of every particle's NiW mean radius error,
            m/sqrt(s) (beyond the paper: artificial dynamics that keep the radius hypotheses
            diverse after resampling; 0 disables). Default 5e-5.
        position_process_noise_m_sqrt_s: additive random walk on east/north, m/sqrt(s).
            Default 0.01.
        yaw_process_noise_rad_sqrt_s: additive random walk on the heading, rad/sqrt(s).
            Default 0.002.
        gnss_default_std_m: horizontal GNSS std used when a fix has no covariance, m.
            Default 1.5.
        gnss_bias_std_m: stationary std per axis of a first-order Gauss-Markov GNSS position
            error (beyond the paper): marginalized in the MPF (per-particle Kalman filters with
            one shared covariance), two more states in the AUG-KF; the fix covariance is then
            read as white part plus this; 0 = take its size from each fix's covariance with
            ``gnss_bias_fraction``, m. Default 0.
        gnss_bias_fraction: when ``gnss_bias_std_m`` is 0, the share of each fix's reported
            horizontal variance taken as that Gauss-Markov error: ``sigma_b^2 = f
            lambda_min(R)`` per fix, the rest white; both 0 = white GNSS error only, as in the
            paper. In [0, 0.9]. Default 0.5, the simulator's split: a receiver's error drifts
            over minutes (multipath, atmosphere), and with a white model the filter reads that
            drift as a radius error and reports too small a std (docs/results.md section 3,
            "The GNSS error model").
        gnss_bias_time_constant_s: correlation time of that error, s. Default 120.
        gnss_gate_probability: chi-square (2 dof) probability of the innovation gate; fixes
            with a larger NIS are rejected as outliers. Default 0.9999 (NIS 18.4).
        gnss_velocity_enabled: use the receiver's Doppler velocity (``/gnss/velocity``, ENU)
            when it is published: a likelihood for each particle's speed and heading (beyond
            the paper; :meth:`RadiusMPF.update_velocity`; without the topic the filter runs on
            the positions alone, as in the paper). Default true.
        gnss_velocity_latency_s: compensated latency of the GNSS velocity (receivers often
            filter it more than the position): a velocity stamped ``t`` describes ``t -
            gnss_velocity_latency_s``, s. In [-1, 1]; default 0.
        gnss_velocity_max_accel_m_s2: a velocity is not used while the rear wheel speeds
            accelerate by more than this, m/s^2: an unknown latency ``tau`` leaves a speed
            error ``tau a`` of one sign for as long as the car accelerates, which a variance
            cannot absorb; the gate bounds it by ``tau`` times this value. Default 0.5.
        max_gap_s: a wheel-speed gap longer than this re-initializes the pose prediction (the
            learned radii are kept), s. Default 2.
        init_min_distance_m: distance between the two GNSS fixes that initialize the heading,
            m. Default 10.
        min_speed_m_s: the radius estimation pauses below this speed whatever the GNSS, m/s
            (creeping: the wheel-speed sensors lose their resolution). Default 1.
        max_abs_ax_m_s2: pause when |longitudinal acceleration| exceeds this, m/s^2 (IMU when
            present, else derivative of the wheel speed). Default 2.0.
        max_abs_ay_m_s2: pause when |lateral acceleration| exceeds this, m/s^2 (IMU when
            present, else speed^2 tan(steer) / wheelbase, else estimated yaw rate x speed).
            Default 4.0.
        braking_decel_m_s2: a deceleration above this is treated as braking and pauses, m/s^2.
            Default 1.0.
        wheels: ``rear`` (default, the paper) or ``all`` (adds the front radii, see
            ``radius_estimator``).
        run_aug_kf: also run the AUG-KF baseline (eq. 10-11; its radius random walk is
            :data:`~tire_estimation.core.radius.aug_kf.RADIUS_RANDOM_WALK_M_SQRT_S`). Default
            False.
        gnss_latency_s: compensated GNSS latency, s: a fix stamped ``t`` is taken to describe the
            antenna at ``t - gnss_latency_s`` (the measurement model extrapolates the pose back
            along the heading by ``speed * latency``). In [-1, 1]; default 0 (off).
        wheel_speed_time_offset_s: compensated wheel-speed stamp delay, s: a wheel-speed sample
            stamped ``t`` is taken to describe the wheels at ``t - offset`` (the pose is
            extrapolated forward by ``speed * offset`` before a fix). In [-1, 1]; default 0.
        gnss_antenna_offset_x_m: calibrated correction of the GNSS antenna position along
            ``base_link`` x (forward), m, added to ``VehicleParams.gnss_antenna_position_m``: the
            fix is taken as ``position + R(yaw) a`` with the corrected lever arm ``a``. In
            [-5, 5]; default 0 (off).
        gnss_antenna_offset_y_m: the same along ``base_link`` y (left), m. In [-5, 5]; default 0.
        radius_speed_coefficient_m_per_m2_s2: speed dependence ``k`` of the rolling radius,
            ``r = r0 + k v^2`` (centrifugal growth), m per (m/s)^2: every wheel speed ``omega``
            is scaled by ``1 + k omega^2 r_nominal`` before use, so the estimated radius errors
            are those of ``r0`` (at standstill). In [-1e-4, 1e-4]; default 0 (off); about 2e-6 is
            typical of passenger-car tyres.
        radius_load_coefficient_m_per_n: load dependence ``c`` of the rolling radius,
            ``r = r0 + c (Fz - Fz_static)``, m per N (negative: a loaded tyre rolls on a smaller
            radius). The load change of each wheel is the quasi-static load transfer of the
            measured specific force (IMU when fresh, else the fallbacks of the acceleration
            gates) with the mass, CG height, axle distances and track of ``VehicleParams``; every
            wheel speed ``omega`` is scaled by ``1 + c dFz / r_nominal`` before use, so the
            estimated radius errors are those at static load. In [-1e-4, 1e-4]; default 0 (off);
            about -5e-7 follows from Pacejka's effective-rolling-radius parameters.
        road_grade_correction_gain: gain of the road-grade correction (the wheels roll along
            the slope, GNSS measures the horizontal displacement): the grade ``theta`` is
            estimated online (``road_grade_source``) and every wheel speed is reduced by
            ``gain (1 - cos theta)`` times its axle's mean speed (the distance is corrected,
            the yaw rate from the left-right difference is not; the grade spans the last
            100 m, ``road_grade.ROAD_GRADE_WINDOW_M``). 0 = off, 1 = the geometric
            correction (default: the grade is checked against the IMU, so a wandering
            altitude is not read as hills); in [0, 5].
        road_grade_source: where the grade comes from. ``checked`` (default): the slope of the
            GNSS altitude over the wheel-travelled distance where the IMU's grade (specific
            force ``f_x = dv/dt + g sin theta`` over the same distance) agrees with it within
            a 99 % chi-square test, the IMU's grade where it does not, none without a fresh
            IMU. ``altitude``: the altitude's slope alone, unchecked (a consumer receiver's
            altitude wanders by tens of metres: on the Husky drive the fitted grades reach 27
            degrees). Counted per fix in ``RadiusEstimate.road_grade_counts``.
        rear_brake_slip_s2_per_m: braking slip ``k`` of the rear (non-driven) wheels per unit
            braking deceleration, s^2/m: ``kappa = -k b`` with ``b = max(0, -f_x - a_0)``
            (``f_x`` the longitudinal specific force, IMU when fresh, else the wheel-speed
            derivative of the gates; ``a_0`` = 0.25 m/s^2 the driving resistances, see
            ``effects.REAR_BRAKE_SLIP_ONSET_M_S2``); every rear wheel
            speed ``omega`` is divided by ``1 + kappa`` before use (ground speed
            ``omega r / (1 + kappa)``). Physically ``(1 - front brake share) m / C_x,rear``
            (rear-axle longitudinal stiffness): 3.5e-3 for the simulator's default vehicle
            (rear share 0.35, 1500 kg, 150 kN). In [0, 0.05]; default 0 (off).
        seed: seed for the node's ``np.random.Generator``. Default 0.
    """

    n_particles: Annotated[int, int_in_range(10, 1_000_000)] = 500
    forgetting_factor: Annotated[float, in_range(0.5, 1.0)] = 0.9998
    prior_radius_error_std_m: Annotated[float, in_range(1e-6, 0.05)] = 0.003
    radius_random_walk_m_sqrt_s: Annotated[float, in_range(0.0, 0.01)] = 5e-5
    position_process_noise_m_sqrt_s: NonNegative = 0.01
    yaw_process_noise_rad_sqrt_s: NonNegative = 0.002
    gnss_default_std_m: Positive = 1.5
    gnss_bias_std_m: Annotated[float, in_range(0.0, 100.0)] = 0.0
    gnss_bias_fraction: Annotated[float, in_range(0.0, 0.9)] = 0.5
    gnss_bias_time_constant_s: Annotated[float, in_range(0.1, 1e5)] = 120.0
    gnss_gate_probability: Annotated[float, in_range(0.5, 1.0 - 1e-15)] = 0.9999
    gnss_velocity_enabled: Flag = True
    gnss_velocity_latency_s: Annotated[float, _effect("gnss_velocity_latency_s")] = 0.0
    gnss_velocity_max_accel_m_s2: Annotated[float, in_range(0.01, 100.0)] = 0.5
    max_gap_s: Positive = 2.0
    init_min_distance_m: Positive = 10.0
    min_speed_m_s: NonNegative = 1.0
    max_abs_ax_m_s2: Positive = 2.0
    max_abs_ay_m_s2: Positive = 4.0
    braking_decel_m_s2: Positive = 1.0
    wheels: Annotated[str, one_of(WHEEL_MODES)] = "rear"
    run_aug_kf: Flag = False
    gnss_latency_s: Annotated[float, _effect("gnss_latency_s")] = 0.0
    wheel_speed_time_offset_s: Annotated[float, _effect("wheel_speed_time_offset_s")] = 0.0
    gnss_antenna_offset_x_m: Annotated[float, _effect("gnss_antenna_offset_x_m")] = 0.0
    gnss_antenna_offset_y_m: Annotated[float, _effect("gnss_antenna_offset_y_m")] = 0.0
    radius_speed_coefficient_m_per_m2_s2: Annotated[
        float, _effect("radius_speed_coefficient_m_per_m2_s2")
    ] = 0.0
    radius_load_coefficient_m_per_n: Annotated[
        float, _effect("radius_load_coefficient_m_per_n")
    ] = 0.0
    road_grade_correction_gain: Annotated[float, _effect("road_grade_correction_gain")] = 1.0
    rear_brake_slip_s2_per_m: Annotated[float, _effect("rear_brake_slip_s2_per_m")] = 0.0
    road_grade_source: Annotated[str, one_of(GRADE_SOURCE_MODES)] = "checked"
    seed: Annotated[int, int_in_range(0, 2**63 - 1)] = 0

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RadiusEstimatorConfig:
        """Build from a mapping (e.g. ROS parameters); unknown keys raise ConfigError."""
        data = require_known_keys(cls, data, "radius_estimator")
        kwargs = {}
        for f in dataclasses.fields(cls):
            if f.name in data:
                v = data[f.name]
                if f.type in ("float",) and isinstance(v, int) and not isinstance(v, bool):
                    v = float(v)
                kwargs[f.name] = v
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping of every field."""
        return dataclasses.asdict(self)
