"""Frozen, validated configuration of the tyre-radius estimators.

Every field is checked at construction; a bad value raises
:class:`~tire_estimation.errors.ConfigError` naming the field and the value.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from tire_estimation.core.resampling import RESAMPLERS
from tire_estimation.core.validation import (
    require_choice,
    require_int_range,
    require_non_negative,
    require_positive,
    require_range,
)
from tire_estimation.errors import ConfigError

WHEEL_MODES = ("rear", "all")


@dataclass(frozen=True)
class RadiusEstimatorConfig:
    """Configuration of :class:`~tire_estimation.core.radius.estimator.RadiusEstimator`.

    Equation numbers refer to Lundquist et al., IEEE T-ITS 2014.

    Attributes:
        n_particles: number of particles N of the MPF. Default 500.
        resampler: ``systematic`` (default), ``stratified``, ``multinomial`` or ``residual``.
        resample_threshold: resample when N_eff / N falls below this, (0, 1]. Default 0.5.
        forgetting_factor: lambda of the NiW time update (eq. 24), per wheel-speed sample; the
            statistics cover about ``1 / (1 - lambda)`` samples. Default 0.9998 (50 s at 100 Hz).
        prior_radius_error_m: initial mean radius error of every estimated wheel, m. Default 0.
        prior_radius_error_std_m: prior standard deviation of the mean radius error, m
            (sets gamma_0 of eq. 22b). Default 0.003.
        prior_radius_noise_std_m: prior expected fast radius variation (sqrt of E[Sigma],
            eq. 22c), m. Default 0.001.
        prior_dof: prior inverse-Wishart degrees of freedom nu_0 (> d + 1). Default 10.
        radius_random_walk_m_sqrt_s: random walk of every particle's NiW mean radius error,
            m/sqrt(s) (beyond the paper: artificial dynamics that keep the radius hypotheses
            diverse after resampling; 0 disables). Default 5e-5.
        kernel_shrinkage: Liu-West shrinkage ``a`` applied to the NiW means at each resampling
            (beyond the paper; keeps the mean and covariance of the cloud of means, refreshes
            duplicates), in [0, 1); 0 disables. Default 0.98.
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
        gnss_max_rejections: after this many consecutive rejected fixes the pose is
            re-initialized from GNSS (a genuine relocation). Default 5.
        gnss_max_gap_s: a fix arriving more than this after the last accepted one
            re-initializes the pose, s. Default 30.
        gnss_velocity_enabled: use the receiver's Doppler velocity (``/gnss/velocity``, ENU)
            when it is published: a likelihood for each particle's speed and heading (beyond
            the paper; :meth:`RadiusMPF.update_velocity`; without the topic the filter runs on
            the positions alone, as in the paper). Default true.
        gnss_velocity_default_std_m_s: std of each horizontal velocity component used when a
            velocity has no covariance, m/s. Default 0.1.
        gnss_velocity_lateral_std_m_s: std of the lateral velocity of ``base_link`` that the
            kinematic model sets to zero (rear-axle sideslip), added across the heading, m/s.
            Default 0.2.
        gnss_velocity_latency_s: compensated latency of the GNSS velocity (receivers often
            filter it more than the position): a velocity stamped ``t`` describes ``t -
            gnss_velocity_latency_s``, s. In [-1, 1]; default 0.
        gnss_velocity_latency_std_s: uncertainty of that latency: the speed's variance grows by
            ``(a std)^2`` at the acceleration ``a`` of the wheel speeds, s. Default 0.1.
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
        steering_heading_speed_m_s: below this speed, while the radii are not learned, the
            heading is propagated from the steer angle (eq. 31a) instead of the wheel-speed
            difference, m/s; while they are learned it always comes from the wheel-speed
            difference. Default 11 (paper).
        max_abs_ax_m_s2: pause when |longitudinal acceleration| exceeds this, m/s^2 (IMU when
            present, else derivative of the wheel speed). Default 2.0.
        max_abs_ay_m_s2: pause when |lateral acceleration| exceeds this, m/s^2 (IMU when
            present, else speed^2 tan(steer) / wheelbase, else estimated yaw rate x speed).
            Default 4.0.
        braking_decel_m_s2: a deceleration above this is treated as braking and pauses, m/s^2.
            Default 1.0.
        imu_timeout_s: IMU samples older than this are ignored by the gates, s. Default 0.5.
        accel_filter_time_constant_s: low-pass time constant of the wheel-speed derivative, s.
            Default 0.3.
        non_increasing_after_calibration: after ``calibration_time_s`` of active estimation
            the radii may only decrease (deflation, as in Section IV-B). Default False.
        calibration_time_s: active estimation time that ends the calibration, s. Default 1200.
        non_increasing_margin_m: tolerance above the calibrated radius error, m. Default 2e-4.
        wheels: ``rear`` (default, the paper) or ``all`` (adds the front radii, see
            ``radius_estimator``).
        run_aug_kf: also run the AUG-KF baseline (eq. 10-11). Default False.
        aug_kf_radius_random_walk_m_sqrt_s: random walk of the radius errors in the AUG-KF
            state, m/sqrt(s). Default 2e-5.
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
        locked_axle_gyro_heading: while the rear axle's two wheels turn alike in the turns
            (a locked axle or spool, ``axle_check.py``), take the heading change from the
            gyro and learn the axle's common radius. Default false: on 20 simulated spool
            drives it keeps the common radius within 0.1 %, but on 1 of 12 drives of the ECE
            R-64 medium campaign (free axles) the check locked falsely and the run changed.
        road_grade_correction_gain: switch of the road-grade correction (the wheels roll along
            the slope, GNSS measures the horizontal displacement): the grade ``theta`` is
            estimated online from the GNSS altitude against the wheel-travelled distance and
            every wheel speed is reduced by ``gain (1 - cos theta)`` times its axle's mean speed
            (the distance is corrected, the yaw rate from the left-right difference is not).
            0 = off (default), 1 = the geometric correction; in [0, 5].
        road_grade_window_m: travelled distance over which the grade is fitted (least-squares
            slope of the GNSS altitude over the wheel-travelled distance), m. In [20, 5000];
            default 100.
        rear_brake_slip_s2_per_m: braking slip ``k`` of the rear (non-driven) wheels per unit
            braking deceleration, s^2/m: ``kappa = -k b`` with ``b = max(0, -f_x - a_0)``
            (``f_x`` the longitudinal specific force, IMU when fresh, else the wheel-speed
            derivative of the gates; ``a_0`` = ``rear_brake_slip_onset_m_s2``); every rear wheel
            speed ``omega`` is divided by ``1 + kappa`` before use (ground speed
            ``omega r / (1 + kappa)``). Physically ``(1 - front brake share) m / C_x,rear``
            (rear-axle longitudinal stiffness): 3.5e-3 for the simulator's default vehicle
            (rear share 0.35, 1500 kg, 150 kN). In [0, 0.05]; default 0 (off).
        rear_brake_slip_onset_m_s2: the deceleration ``a_0`` that the driving resistances
            (rolling resistance, drag: body forces, not rear tyre forces) explain without
            braking, m/s^2. In [0, 3]; default 0.25 (the simulator's default vehicle:
            ``c_rr g + rho C_d A v^2 / (2 m)`` = 0.19 / 0.23 / 0.29 m/s^2 at 16 / 20 / 25 m/s).
        seed: seed for the node's ``np.random.Generator``. Default 0.
    """

    n_particles: int = 500
    resampler: str = "systematic"
    resample_threshold: float = 0.5
    forgetting_factor: float = 0.9998
    prior_radius_error_m: float = 0.0
    prior_radius_error_std_m: float = 0.003
    prior_radius_noise_std_m: float = 0.001
    prior_dof: float = 10.0
    radius_random_walk_m_sqrt_s: float = 5e-5
    kernel_shrinkage: float = 0.98
    position_process_noise_m_sqrt_s: float = 0.01
    yaw_process_noise_rad_sqrt_s: float = 0.002
    gnss_default_std_m: float = 1.5
    gnss_bias_std_m: float = 0.0
    gnss_bias_fraction: float = 0.5
    gnss_bias_time_constant_s: float = 120.0
    gnss_gate_probability: float = 0.9999
    gnss_max_rejections: int = 5
    gnss_max_gap_s: float = 30.0
    gnss_velocity_enabled: bool = True
    gnss_velocity_default_std_m_s: float = 0.1
    gnss_velocity_lateral_std_m_s: float = 0.2
    gnss_velocity_latency_s: float = 0.0
    gnss_velocity_latency_std_s: float = 0.1
    gnss_velocity_max_accel_m_s2: float = 0.5
    max_gap_s: float = 2.0
    init_min_distance_m: float = 10.0
    min_speed_m_s: float = 1.0
    steering_heading_speed_m_s: float = 11.0
    max_abs_ax_m_s2: float = 2.0
    max_abs_ay_m_s2: float = 4.0
    braking_decel_m_s2: float = 1.0
    imu_timeout_s: float = 0.5
    accel_filter_time_constant_s: float = 0.3
    non_increasing_after_calibration: bool = False
    calibration_time_s: float = 1200.0
    non_increasing_margin_m: float = 2e-4
    wheels: str = "rear"
    run_aug_kf: bool = False
    aug_kf_radius_random_walk_m_sqrt_s: float = 2e-5
    gnss_latency_s: float = 0.0
    wheel_speed_time_offset_s: float = 0.0
    gnss_antenna_offset_x_m: float = 0.0
    gnss_antenna_offset_y_m: float = 0.0
    radius_speed_coefficient_m_per_m2_s2: float = 0.0
    radius_load_coefficient_m_per_n: float = 0.0
    locked_axle_gyro_heading: bool = False
    road_grade_correction_gain: float = 0.0
    road_grade_window_m: float = 100.0
    rear_brake_slip_s2_per_m: float = 0.0
    rear_brake_slip_onset_m_s2: float = 0.25
    seed: int = 0

    def __post_init__(self) -> None:
        require_int_range("n_particles", self.n_particles, 10, 1_000_000)
        require_choice("resampler", self.resampler, RESAMPLERS)
        require_range("resample_threshold", self.resample_threshold, 1e-6, 1.0)
        require_range("forgetting_factor", self.forgetting_factor, 0.5, 1.0)
        require_range("prior_radius_error_m", self.prior_radius_error_m, -0.05, 0.05)
        require_range("prior_radius_error_std_m", self.prior_radius_error_std_m, 1e-6, 0.05)
        require_range("prior_radius_noise_std_m", self.prior_radius_noise_std_m, 1e-7, 0.05)
        require_range("prior_dof", self.prior_dof, 6.0, 1e9)
        require_range("radius_random_walk_m_sqrt_s", self.radius_random_walk_m_sqrt_s, 0.0, 0.01)
        require_range("kernel_shrinkage", self.kernel_shrinkage, 0.0, 0.999999)
        require_non_negative(
            "position_process_noise_m_sqrt_s", self.position_process_noise_m_sqrt_s
        )
        require_non_negative("yaw_process_noise_rad_sqrt_s", self.yaw_process_noise_rad_sqrt_s)
        require_positive("gnss_default_std_m", self.gnss_default_std_m)
        require_range("gnss_bias_std_m", self.gnss_bias_std_m, 0.0, 100.0)
        require_range("gnss_bias_fraction", self.gnss_bias_fraction, 0.0, 0.9)
        require_range("gnss_bias_time_constant_s", self.gnss_bias_time_constant_s, 0.1, 1e5)
        require_range("gnss_gate_probability", self.gnss_gate_probability, 0.5, 1.0 - 1e-15)
        require_int_range("gnss_max_rejections", self.gnss_max_rejections, 1, 1000)
        require_positive("gnss_max_gap_s", self.gnss_max_gap_s)
        if not isinstance(self.gnss_velocity_enabled, bool):
            raise ConfigError(
                "gnss_velocity_enabled", self.gnss_velocity_enabled, "must be a bool"
            )
        require_range(
            "gnss_velocity_default_std_m_s", self.gnss_velocity_default_std_m_s, 1e-4, 100.0
        )
        require_range(
            "gnss_velocity_lateral_std_m_s", self.gnss_velocity_lateral_std_m_s, 0.0, 100.0
        )
        require_range("gnss_velocity_latency_s", self.gnss_velocity_latency_s, -1.0, 1.0)
        require_range("gnss_velocity_latency_std_s", self.gnss_velocity_latency_std_s, 0.0, 1.0)
        require_range(
            "gnss_velocity_max_accel_m_s2", self.gnss_velocity_max_accel_m_s2, 0.01, 100.0
        )
        require_positive("max_gap_s", self.max_gap_s)
        require_positive("init_min_distance_m", self.init_min_distance_m)
        require_non_negative("min_speed_m_s", self.min_speed_m_s)
        require_non_negative("steering_heading_speed_m_s", self.steering_heading_speed_m_s)
        require_positive("max_abs_ax_m_s2", self.max_abs_ax_m_s2)
        require_positive("max_abs_ay_m_s2", self.max_abs_ay_m_s2)
        require_positive("braking_decel_m_s2", self.braking_decel_m_s2)
        require_positive("imu_timeout_s", self.imu_timeout_s)
        require_positive("accel_filter_time_constant_s", self.accel_filter_time_constant_s)
        if not isinstance(self.non_increasing_after_calibration, bool):
            raise ConfigError(
                "non_increasing_after_calibration",
                self.non_increasing_after_calibration,
                "must be a bool",
            )
        require_non_negative("calibration_time_s", self.calibration_time_s)
        require_non_negative("non_increasing_margin_m", self.non_increasing_margin_m)
        require_choice("wheels", self.wheels, WHEEL_MODES)
        if not isinstance(self.run_aug_kf, bool):
            raise ConfigError("run_aug_kf", self.run_aug_kf, "must be a bool")
        if not isinstance(self.locked_axle_gyro_heading, bool):
            raise ConfigError(
                "locked_axle_gyro_heading", self.locked_axle_gyro_heading, "must be a bool"
            )
        require_non_negative(
            "aug_kf_radius_random_walk_m_sqrt_s", self.aug_kf_radius_random_walk_m_sqrt_s
        )
        require_range("gnss_latency_s", self.gnss_latency_s, -1.0, 1.0)
        require_range("wheel_speed_time_offset_s", self.wheel_speed_time_offset_s, -1.0, 1.0)
        require_range("gnss_antenna_offset_x_m", self.gnss_antenna_offset_x_m, -5.0, 5.0)
        require_range("gnss_antenna_offset_y_m", self.gnss_antenna_offset_y_m, -5.0, 5.0)
        require_range(
            "radius_speed_coefficient_m_per_m2_s2",
            self.radius_speed_coefficient_m_per_m2_s2,
            -1e-4,
            1e-4,
        )
        require_range(
            "radius_load_coefficient_m_per_n", self.radius_load_coefficient_m_per_n, -1e-4, 1e-4
        )
        require_range("road_grade_correction_gain", self.road_grade_correction_gain, 0.0, 5.0)
        require_range("road_grade_window_m", self.road_grade_window_m, 20.0, 5000.0)
        require_range("rear_brake_slip_s2_per_m", self.rear_brake_slip_s2_per_m, 0.0, 0.05)
        require_range("rear_brake_slip_onset_m_s2", self.rear_brake_slip_onset_m_s2, 0.0, 3.0)
        require_int_range("seed", self.seed, 0, 2**63 - 1)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RadiusEstimatorConfig:
        """Build from a mapping (e.g. ROS parameters); unknown keys raise ConfigError."""
        if not isinstance(data, Mapping):
            raise ConfigError("radius_estimator", data, "must be a mapping")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(unknown[0], data[unknown[0]], "unknown key")
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
