"""What the learned radii give the rest of a ROS stack: wheel odometry corrected with the
learned radii and its covariance, each wheel's effective radius and radius multiplier, and a
speed scale factor.

* :func:`corrected_twist`: speed and yaw rate of ``base_link`` from the rear wheel speeds and
  the learned rear radii (eq. 6 with the MMSE radius errors, the estimate's ``speed_m_s`` and
  ``yaw_rate_rad_s``), with the radius uncertainty propagated into a (2, 2) covariance.
* :func:`effective_radii`: ``radius = nominal + error`` per wheel, ``multiplier = radius /
  nominal`` (ros2_control ``diff_drive_controller``'s ``left_wheel_radius_multiplier`` and
  ``right_wheel_radius_multiplier`` against its ``wheel_radius``), and the speed scale factor
  ``mean(rear radii) / nominal`` (the factor that turns a speed computed with the nominal
  radius from the rear wheels into the true one, as Autoware's ``speed_scale_factor``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.model import RL, RR
from tire_estimation.core.radius.report import RadiusEstimate
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.core.wheels import REAR_WHEELS
from tire_estimation.errors import InputError

#: floor of the speed variance, (m/s)^2: (0.05 m/s)^2, the error of edge-timing wheel-speed
#: sensors at walking pace (fewer than two tooth edges per sample)
SPEED_VAR_FLOOR_M2_S2 = 0.05**2
#: floor of the yaw-rate variance, (rad/s)^2: (0.03 rad/s)^2, the same at walking pace
YAW_RATE_VAR_FLOOR_RAD2_S2 = 0.03**2
#: samples over which :class:`WheelSpeedNoise` averages (1 s at 100 Hz)
NOISE_AVERAGING_SAMPLES = 100


@dataclass(frozen=True)
class CorrectedTwist:
    """Speed and yaw rate of ``base_link`` from the wheel speeds and the learned radii.

    Attributes:
        t_ns: stamp of the wheel-speed sample they come from.
        vx_m_s: longitudinal speed, m/s.
        yaw_rate_rad_s: yaw rate, rad/s (REP-103: positive to the left).
        covariance: (2, 2) covariance of ``(vx_m_s, yaw_rate_rad_s)``.
    """

    t_ns: int
    vx_m_s: float
    yaw_rate_rad_s: float
    covariance: F64


@dataclass(frozen=True)
class EffectiveRadii:
    """Each wheel's learned effective rolling radius against the nominal one.

    Attributes:
        wheels: wheel names, in the order of the arrays.
        nominal_radius_m: the nominal radius the multipliers refer to, m.
        radius_m: effective rolling radius (nominal plus learned error), m.
        radius_std_m: standard deviation of ``radius_m``, m.
        multiplier: ``radius_m / nominal_radius_m``, 1.
        speed_scale_factor: mean rear effective radius over the nominal radius, 1.
    """

    wheels: tuple[str, ...]
    nominal_radius_m: float
    radius_m: F64
    radius_std_m: F64
    multiplier: F64
    speed_scale_factor: float

    def of(self, wheel: str) -> tuple[float, float]:
        """``(radius_m, multiplier)`` of ``wheel``."""
        k = self.wheels.index(wheel)
        return float(self.radius_m[k]), float(self.multiplier[k])


def effective_radii(
    wheels: Sequence[str],
    radius_error_m: Sequence[float] | F64,
    radius_error_std_m: Sequence[float] | F64,
    nominal_radius_m: float,
) -> EffectiveRadii:
    """Effective radii, multipliers and speed scale factor of learned radius errors.

    Raises:
        InputError: (kind ``radii``) the arrays do not match ``wheels``, a value is not
            finite, an effective radius is not positive, or a rear wheel is missing.
    """
    names = tuple(str(w) for w in wheels)
    err = np.asarray(radius_error_m, dtype=float).reshape(-1)
    std = np.asarray(radius_error_std_m, dtype=float).reshape(-1)
    if err.size != len(names) or std.size != len(names):
        raise InputError("radii", f"{len(names)} wheels but {err.size} errors and {std.size} stds")
    if not (math.isfinite(nominal_radius_m) and nominal_radius_m > 0.0):
        raise InputError("radii", f"nominal radius {nominal_radius_m!r} m is not positive")
    if not (np.isfinite(err).all() and np.isfinite(std).all()):
        raise InputError("radii", "a radius error or its std is not finite")
    missing = [w for w in REAR_WHEELS if w not in names]
    if missing:
        raise InputError("radii", f"no radius of {', '.join(missing)}")
    radius = nominal_radius_m + err
    if np.any(radius <= 0.0):
        bad = names[int(np.argmin(radius))]
        raise InputError("radii", f"effective radius of {bad} is not positive")
    multiplier = radius / nominal_radius_m
    rear = [names.index(w) for w in REAR_WHEELS]
    return EffectiveRadii(
        wheels=names,
        nominal_radius_m=float(nominal_radius_m),
        radius_m=radius,
        radius_std_m=np.abs(std),
        multiplier=multiplier,
        speed_scale_factor=float(np.mean(multiplier[rear])),
    )


def estimate_radii(est: RadiusEstimate, vehicle: VehicleParams) -> EffectiveRadii:
    """:func:`effective_radii` of a radius estimate."""
    return effective_radii(
        est.wheels, est.radius_error_m, est.radius_error_std_m, vehicle.nominal_tire_radius_m
    )


class WheelSpeedNoise:
    """Per-sample noise of the rear wheel speeds, measured from the wheel speeds themselves.

    The second difference ``w[k] - 2 w[k-1] + w[k-2]`` of a wheel speed sampled at a steady
    rate holds its white noise six times over and almost none of the motion (a smooth speed
    changes by ``dw/dt^2 T^2``: 2e-3 rad/s at 100 Hz for a 1.5 m/s^3 jerk); its square,
    divided by 6 and averaged exponentially over :data:`NOISE_AVERAGING_SAMPLES` samples, is
    the noise variance. Edge-timing ABS sensors show about 0.5-1 % per sample from the tooth
    pitch errors, which average out over a wheel turn and so are not in the radius filter's
    noise covariance. A sample whose stamp spacing differs from the previous one by more than
    half, or with a rear wheel speed not finite, restarts the differences.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Forget the samples and the averaged noise."""
        self._prev: tuple[int, float, float] | None = None
        self._prev2: tuple[int, float, float] | None = None
        self._sum = [0.0, 0.0]
        self._weight = 0.0

    def push(self, t_ns: int, wheel_speed_rad_s: F64) -> None:
        """Take one wheel-speed sample (fl, fr, rl, rr), rad/s."""
        try:
            w3, w4 = float(wheel_speed_rad_s[RL]), float(wheel_speed_rad_s[RR])
        except (IndexError, TypeError, ValueError):
            self._prev = self._prev2 = None
            return
        if not (math.isfinite(w3) and math.isfinite(w4)):
            self._prev = self._prev2 = None
            return
        cur = (int(t_ns), w3, w4)
        p1, p2 = self._prev, self._prev2
        self._prev2, self._prev = p1, cur
        if p1 is None or p2 is None:
            return
        dt1, dt2 = cur[0] - p1[0], p1[0] - p2[0]
        if dt1 <= 0 or dt2 <= 0 or abs(dt1 - dt2) > 0.5 * max(dt1, dt2):
            self._prev2 = None  # uneven spacing: start the differences again from p1, cur
            return
        keep = 1.0 - 1.0 / NOISE_AVERAGING_SAMPLES
        for i in (1, 2):
            d2 = cur[i] - 2.0 * p1[i] + p2[i]
            self._sum[i - 1] = keep * self._sum[i - 1] + d2 * d2 / 6.0
        self._weight = keep * self._weight + 1.0

    @property
    def var_rad2_s2(self) -> tuple[float, float]:
        """Noise variance of the rl and rr wheel speeds, (rad/s)^2; 0 before three evenly
        spaced samples."""
        if self._weight <= 0.0:
            return (0.0, 0.0)
        return (self._sum[0] / self._weight, self._sum[1] / self._weight)


def corrected_twist(
    est: RadiusEstimate,
    vehicle: VehicleParams,
    wheel_speed_var_rad2_s2: tuple[float, float] = (0.0, 0.0),
) -> CorrectedTwist:
    """Speed and yaw rate from the wheel speeds and the learned radii, with their covariance.

    The speed and yaw rate are the estimate's (eq. 6 with the rear wheel speeds ``w_rl``,
    ``w_rr`` and the learned effective radii ``R = r + d``)::

        vx = (w_rl R_rl + w_rr R_rr) / 2,  yaw_rate = (w_rr R_rr - w_rl R_rl) / l_T.

    The covariance of ``(vx, yaw_rate)`` is, with ``A = [[1 / 2, 1 / 2], [-1 / l_T, 1 / l_T]]``,
    ``W = diag(w_rl, w_rr)`` (recovered from ``vx``, the yaw rate and the radii) and
    ``R = diag(R_rl, R_rr)``::

        cov = A W P W A^T + A R N R A^T, floored at SPEED_VAR_FLOOR and YAW_RATE_VAR_FLOOR,

    * ``P``: the posterior covariance of the learned rear radius errors (how well the radii
      are known; this part is the same error in every message, a consumer cannot average it
      away),
    * ``N = diag(wheel_speed_var_rad2_s2)``: the per-sample noise of the rear wheel speeds
      (:class:`WheelSpeedNoise`, measured on the wheel speeds),
    * the floors :data:`SPEED_VAR_FLOOR_M2_S2` and :data:`YAW_RATE_VAR_FLOOR_RAD2_S2`: the
      wheel-speed sensors' loss of resolution near standstill, which the noise measurement
      does not see (a sensor holds its last speed when no tooth edge comes).

    Not included: slip (hard braking or acceleration, low friction), the lateral motion of the
    rear axle, and the filter's NiW noise covariance (its fast radius variation, learned on the
    GNSS innovations, is a share of the same wheel-speed noise). Without the estimate's
    covariance (``None``) the radius errors are taken as uncorrelated with variance
    ``radius_error_std_m ** 2``.
    """
    r = vehicle.nominal_tire_radius_m
    lt = vehicle.track_width_m
    idx = [est.wheels.index(w) for w in REAR_WHEELS]
    radii = r + np.asarray(est.radius_error_m, dtype=float)[idx]
    radii = np.maximum(radii, 1e-3)
    p = est.rear_radius_error_cov_m2
    if p is None:
        p = np.diag(np.asarray(est.radius_error_std_m, dtype=float)[idx] ** 2)
    vx, yr = float(est.speed_m_s), float(est.yaw_rate_rad_s)
    # rolling speeds of the rear wheel centres (inverse of eq. 6) over the radii
    omega = np.array([vx - 0.5 * lt * yr, vx + 0.5 * lt * yr]) / radii
    a = np.array([[0.5, 0.5], [-1.0 / lt, 1.0 / lt]])
    j_radius = a * omega  # d(vx, yaw_rate) / d(radius errors)
    j_speed = a * radii  # d(vx, yaw_rate) / d(wheel speeds)
    noise = np.diag([max(float(v), 0.0) for v in wheel_speed_var_rad2_s2])
    cov = j_radius @ np.asarray(p, dtype=float) @ j_radius.T + j_speed @ noise @ j_speed.T
    cov = 0.5 * (cov + cov.T)
    cov[0, 0] = max(cov[0, 0], SPEED_VAR_FLOOR_M2_S2)
    cov[1, 1] = max(cov[1, 1], YAW_RATE_VAR_FLOOR_RAD2_S2)
    return CorrectedTwist(int(est.t_ns), vx, yr, cov)
