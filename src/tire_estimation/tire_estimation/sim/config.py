"""Sensor configuration of the simulator (rates, noise, and effects the estimator does not know).

Defaults describe a production passenger car with ESC: ABS wheel-speed sensors on a 48-tooth
tone ring read by edge timing, an automotive MEMS yaw-rate/acceleration cluster, a
standard-precision GNSS receiver (single point, no RTK), and (optionally, as in Tuononen 2009)
optical tyre-force sensors on ``wheel_fl`` and ``wheel_rr``.

Numbers behind the defaults (all per sample unless named ``_sqrt_s``):

* Wheel speed: 100 Hz, 48 teeth, 1 us capture timer, tooth pitch error std 1e-3 rad (0.057 deg,
  ~0.8 % of the 7.5 deg pitch) -> ~0.15 % speed noise at 90 rad/s and 10 ms windows.
* Steering: 100 Hz, noise 5e-4 rad road-wheel angle (~0.4 deg at the hand wheel for ratio 15),
  resolution 1e-4 rad (0.1 deg hand-wheel CAN resolution / 15).
* Gyro: 100 Hz, white noise 1.75e-3 rad/s (0.1 deg/s), initial bias std 5e-3 rad/s (0.3 deg/s,
  residual after ESC offset learning), bias random walk 1e-4 rad/s/sqrt(s).
* Accelerometer: white noise 0.05 m/s^2, initial bias std 0.1 m/s^2, bias random walk
  5e-4 m/s^2/sqrt(s).
* GNSS: 10 Hz, white 1.0 m per horizontal axis (1.5 m vertical) plus first-order Gauss-Markov
  error with sigma 1.0 m horizontal (1.5 m vertical) and tau 120 s, so the total horizontal error
  per axis is sqrt(1.0^2 + 1.0^2) = 1.41 m. Reported covariance = the true total variance (times
  ``gnss_covariance_scale``^2). Doppler velocity on by default (0.05 m/s; its reported
  covariance times ``gnss_velocity_covariance_scale``^2).
* Tyre forces: 100 Hz on wheel_fl and wheel_rr, noise 100 N (fx), 150 N (fy), 100 N (fz).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Annotated, Any

from tire_estimation.core.validation import (
    Checked,
    Flag,
    NonNegative,
    in_range,
    int_in_range,
    one_of,
    require_range,
    require_vector3,
)
from tire_estimation.core.wheels import WHEELS
from tire_estimation.errors import ConfigError


@dataclass(frozen=True)
class SensorConfig(Checked):
    """Rates, noise and injected effects of the simulated sensors (SI units in the names).

    Injected effects (``*_time_offset_s``, ``gnss_latency_s``, ``gnss_velocity_latency_s``,
    ``radius_*_coefficient_*``, ``road_grade_*``, ``gyro_bias_rad_s``) default to zero: they
    model what an estimator may not know. The GNSS antenna position (lever arm) is
    ``VehicleParams.gnss_antenna_position_m``.
    """

    # --- ABS wheel speeds (edge timing on a tone ring) ---
    wheel_speed_rate_hz: Annotated[float, in_range(10.0, 1000.0)] = 100.0
    wheel_speed_teeth: Annotated[int, int_in_range(4, 1000)] = 48
    wheel_speed_timer_resolution_s: Annotated[float, in_range(0.0, 1e-3)] = 1.0e-6
    wheel_speed_tooth_pitch_error_std_rad: float = 1.0e-3
    #: With no tooth edge in a period, the last speed is held (decaying as pitch / time since
    #: the last edge) until this long after the last edge, then 0 is reported.
    wheel_speed_timeout_s: Annotated[float, in_range(0.0, 10.0)] = 0.2
    #: Injected: stamps are late by this much (the stamp of a sample is measurement time + this).
    wheel_speed_time_offset_s: Annotated[float, in_range(-1.0, 1.0)] = 0.0
    #: Injected: a locked rear axle (spool): both rear wheels turn at the mean of their
    #: free-rolling speeds (the scrubbing tyres' yaw moment is not simulated).
    wheel_speed_rear_locked: Flag = False
    #: Injected: this wheel's sensor reads 0 from ``wheel_speed_lost_from_s`` (time since the
    #: drive's start) for ``wheel_speed_lost_duration_s`` ("none": no such fault).
    wheel_speed_lost_wheel: Annotated[str, one_of(("none", *WHEELS))] = "none"
    wheel_speed_lost_from_s: Annotated[float, in_range(0.0, 1e6)] = 0.0
    wheel_speed_lost_duration_s: Annotated[float, in_range(0.0, 1e6)] = 0.0

    # --- steering (mean road-wheel angle) ---
    steering_rate_hz: Annotated[float, in_range(1.0, 1000.0)] = 100.0
    steering_noise_std_rad: Annotated[float, in_range(0.0, 0.1)] = 5.0e-4
    steering_resolution_rad: Annotated[float, in_range(0.0, 0.1)] = 1.0e-4
    #: Injected: constant offset added to the reported steer angle, rad.
    steering_offset_rad: Annotated[float, in_range(-0.2, 0.2)] = 0.0

    # --- IMU (MEMS, base_link axes, at VehicleParams.imu_position_m) ---
    imu_rate_hz: Annotated[float, in_range(1.0, 2000.0)] = 100.0
    gyro_noise_std_rad_s: Annotated[float, in_range(0.0, 1.0)] = 1.75e-3
    gyro_bias_initial_std_rad_s: Annotated[float, in_range(0.0, 1.0)] = 5.0e-3
    gyro_bias_random_walk_rad_s_sqrt_s: Annotated[float, in_range(0.0, 1.0)] = 1.0e-4
    #: Injected: deterministic gyro bias (x, y, z) added on top of the random bias, rad/s.
    gyro_bias_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_noise_std_m_s2: Annotated[float, in_range(0.0, 10.0)] = 0.05
    accel_bias_initial_std_m_s2: Annotated[float, in_range(0.0, 10.0)] = 0.1
    accel_bias_random_walk_m_s2_sqrt_s: Annotated[float, in_range(0.0, 10.0)] = 5.0e-4
    #: Injected: the IMU turned by this angle about z on its mount (or published in its own
    #: axes): it reports base_link's horizontal vectors rotated by minus this angle, deg.
    imu_mounting_yaw_deg: Annotated[float, in_range(-180.0, 180.0)] = 0.0
    #: Injected: the IMU upside down (turned 180 deg about x, before the yaw above).
    imu_upside_down: Flag = False
    #: Injected: the IMU pitched nose-up by this angle on its mount (about y, after the yaw),
    #: deg: its x axis sees g sin of it on a level road.
    imu_mounting_pitch_deg: Annotated[float, in_range(-30.0, 30.0)] = 0.0

    # --- GNSS (antenna at VehicleParams.gnss_antenna_position_m) ---
    gnss_rate_hz: Annotated[float, in_range(0.1, 100.0)] = 10.0
    gnss_white_std_m: Annotated[float, in_range(0.0, 100.0)] = 1.0
    gnss_white_vertical_std_m: Annotated[float, in_range(0.0, 100.0)] = 1.5
    gnss_gm_std_m: Annotated[float, in_range(0.0, 100.0)] = 1.0
    gnss_gm_vertical_std_m: Annotated[float, in_range(0.0, 100.0)] = 1.5
    gnss_gm_tau_s: Annotated[float, in_range(0.01, 1e5)] = 120.0
    #: Reported covariance = (scale * true std)^2; 1.0 reports the true total error variance.
    gnss_covariance_scale: Annotated[float, in_range(0.01, 100.0)] = 1.0
    #: The same for the Doppler velocity's reported covariance.
    gnss_velocity_covariance_scale: Annotated[float, in_range(0.01, 100.0)] = 1.0
    #: Publish the receiver's Doppler velocity (``/gnss/velocity``), as receivers do.
    gnss_velocity_enabled: Flag = True
    gnss_velocity_noise_std_m_s: Annotated[float, in_range(0.0, 10.0)] = 0.05
    gnss_velocity_vertical_noise_std_m_s: Annotated[float, in_range(0.0, 10.0)] = 0.1
    #: Injected: a fix stamped t describes the antenna at t - latency, s.
    gnss_latency_s: Annotated[float, in_range(0.0, 2.0)] = 0.0
    #: Injected: a Doppler velocity stamped t (the fix's stamp) describes the antenna at
    #: t - this, s (receivers often filter the velocity more than the position).
    gnss_velocity_latency_s: Annotated[float, in_range(0.0, 2.0)] = 0.0
    #: Injected: the receiver stamps its fixes and velocities this far ahead of the other
    #: sensors' clock, s (a receiver stamping in GPS time, 18 s ahead of UTC).
    gnss_clock_offset_s: Annotated[float, in_range(-60.0, 60.0)] = 0.0
    #: Injected: no fix and no velocity from ``gnss_outage_from_s`` (time since the drive's
    #: start) for ``gnss_outage_duration_s`` (a tunnel, a car park).
    gnss_outage_from_s: Annotated[float, in_range(0.0, 1e6)] = 0.0
    gnss_outage_duration_s: Annotated[float, in_range(0.0, 1e6)] = 0.0

    # --- tyre force sensors (Tuononen 2009: optical tyre sensors on fl and rr) ---
    tire_force_enabled: Flag = True
    tire_force_rate_hz: Annotated[float, in_range(1.0, 2000.0)] = 100.0
    tire_force_wheels: tuple[str, ...] = ("wheel_fl", "wheel_rr")
    tire_force_noise_fx_n: NonNegative = 100.0
    tire_force_noise_fy_n: NonNegative = 150.0
    tire_force_noise_fz_n: NonNegative = 100.0

    # --- injected tyre/road effects ---
    #: r_eff += coefficient * v^2 (centrifugal tyre growth), m per (m/s)^2; ~2e-6 is realistic.
    radius_speed_coefficient_m_per_m2_s2: Annotated[float, in_range(-1e-4, 1e-4)] = 0.0
    #: r_eff += coefficient * (Fz - Fz_static); negative shrinks a loaded tyre, m per N.
    radius_load_coefficient_m_per_n: Annotated[float, in_range(-1e-4, 1e-4)] = 0.0
    #: Road grade = amplitude * sin(2 pi s / wavelength) along the travelled distance s, rad.
    road_grade_amplitude_rad: Annotated[float, in_range(0.0, 0.3)] = 0.0
    road_grade_wavelength_m: Annotated[float, in_range(10.0, 1e6)] = 1000.0

    PREFIX = "sensors."

    def check(self) -> None:
        p = self.PREFIX
        pitch = 2.0 * math.pi / self.wheel_speed_teeth
        require_range(
            p + "wheel_speed_tooth_pitch_error_std_rad",
            self.wheel_speed_tooth_pitch_error_std_rad,
            0.0,
            0.1 * pitch,
        )
        require_vector3(p + "gyro_bias_rad_s", self.gyro_bias_rad_s, 1.0, unit=" rad/s")
        if not isinstance(self.tire_force_wheels, tuple) or any(
            w not in WHEELS for w in self.tire_force_wheels
        ):
            raise ConfigError(
                p + "tire_force_wheels", self.tire_force_wheels, f"must be a tuple of {WHEELS}"
            )

    @property
    def gnss_total_std_m(self) -> float:
        """True total horizontal error std per axis (white and Gauss-Markov), m."""
        return math.hypot(self.gnss_white_std_m, self.gnss_gm_std_m)

    @property
    def gnss_total_vertical_std_m(self) -> float:
        """True total vertical error std (white and Gauss-Markov), m."""
        return math.hypot(self.gnss_white_vertical_std_m, self.gnss_gm_vertical_std_m)

    def to_dict(self) -> dict[str, Any]:
        """Plain YAML-serializable mapping of every field."""
        out = dataclasses.asdict(self)
        out["gyro_bias_rad_s"] = [float(v) for v in self.gyro_bias_rad_s]
        out["tire_force_wheels"] = list(self.tire_force_wheels)
        return out
