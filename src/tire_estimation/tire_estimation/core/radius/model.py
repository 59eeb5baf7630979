"""Kinematic vehicle model with tyre-radius errors (Lundquist et al., T-ITS 2014, Section II).

State ``x = [east, north, yaw]`` of ``base_link`` (centre of the rear axle, REP-103) in a local ENU
frame; yaw 0 = east, counter-clockwise. The rear wheel speeds are the input (eq. 8) and the rear
radius errors ``delta = [delta_rl, delta_rr]`` (m) the process noise (eq. 12c).

The functions are vectorized: per-particle quantities have shape ``(N,)``; radius errors
``(N, 2)``; wheel speeds are ``(4,)`` in the order fl, fr, rl, rr.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.vehicle import VehicleParams

RL, RR = 2, 3  # rear wheel indices in the fl, fr, rl, rr order
FL, FR = 0, 1


@dataclass(frozen=True)
class RadiusMotionModel:
    """Motion model of eq. (3)-(7), (12) and (31a).

    Attributes:
        nominal_radius_m: nominal (static) radius r of every tyre, m.
        track_width_m: wheel track l_T, m.
        wheelbase_m: wheelbase l_b, m (eq. 31a and the front-wheel kinematics).
    """

    nominal_radius_m: float
    track_width_m: float
    wheelbase_m: float

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams) -> RadiusMotionModel:
        """Model of a :class:`VehicleParams`."""
        return cls(vehicle.nominal_tire_radius_m, vehicle.track_width_m, vehicle.wheelbase_m)

    def virtual_speed_yaw_rate(self, wheel_speed_rad_s: F64) -> tuple[F64, F64]:
        """Virtual speed (m/s) and yaw rate (rad/s) from wheel speeds ``(..., 4)`` (eq. 4)."""
        w3 = wheel_speed_rad_s[..., RL]
        w4 = wheel_speed_rad_s[..., RR]
        r = self.nominal_radius_m
        # eq. (4a) v_virt = (w3 r + w4 r) / 2
        v = 0.5 * r * (w3 + w4)
        # eq. (4b) yaw_rate_virt = (w4 r - w3 r) / l_T
        yr = r * (w4 - w3) / self.track_width_m
        return v, yr

    def speed_yaw_rate(self, wheel_speed_rad_s: F64, radius_error_m: F64) -> tuple[F64, F64]:
        """Speed and yaw rate with rear radius errors ``(N, 2)`` (eq. 6); returns ``(N,)`` each."""
        w3 = wheel_speed_rad_s[..., RL]
        w4 = wheel_speed_rad_s[..., RR]
        v_virt, yr_virt = self.virtual_speed_yaw_rate(wheel_speed_rad_s)
        d3 = radius_error_m[..., 0]
        d4 = radius_error_m[..., 1]
        # eq. (6a) v = v_virt + w3 d3 / 2 + w4 d4 / 2
        v = v_virt + 0.5 * (w3 * d3 + w4 * d4)
        # eq. (6b) yaw_rate = yaw_rate_virt + w4 d4 / l_T - w3 d3 / l_T
        yr = yr_virt + (w4 * d4 - w3 * d3) / self.track_width_m
        return v, yr

    def steering_yaw_rate(self, speed_m_s: F64, steer_angle_rad: float) -> F64:
        """Low-speed yaw rate from the steer angle (eq. 31a, second case).

        The paper writes ``delta_F v / l_b`` (small angle); the kinematic bicycle about the rear
        axle gives ``v tan(delta_F) / l_b``, used here.
        """
        # eq. (31a) yaw_rate = v tan(delta_F) / l_b
        return speed_m_s * (math.tan(steer_angle_rad) / self.wheelbase_m)

    @staticmethod
    def propagate(
        east_m: F64, north_m: F64, yaw_rad: F64, speed_m_s: F64, yaw_rate_rad_s: F64, dt_s: float
    ) -> None:
        """Euler step of the motion model (eq. 3), in place on ``(N,)`` arrays."""
        # eq. (3a) x_{k+1} = x_k + T v_k cos(psi_k)
        east_m += dt_s * speed_m_s * np.cos(yaw_rad)
        # eq. (3b) y_{k+1} = y_k + T v_k sin(psi_k)
        north_m += dt_s * speed_m_s * np.sin(yaw_rad)
        # eq. (3c) psi_{k+1} = psi_k + T yaw_rate_k
        yaw_rad += dt_s * yaw_rate_rad_s

    def noise_gain(self, yaw_rad: float, wheel_speed_rad_s: F64, dt_s: float) -> F64:
        """Gain ``g(x, u)`` of the radius errors in the motion model (eq. 12b), (3, 2)."""
        w3 = wheel_speed_rad_s[RL]
        w4 = wheel_speed_rad_s[RR]
        c, s = math.cos(yaw_rad), math.sin(yaw_rad)
        lt = self.track_width_m
        # eq. (12b)
        return dt_s * np.array(
            [
                [0.5 * w3 * c, 0.5 * w4 * c],
                [0.5 * w3 * s, 0.5 * w4 * s],
                [-w3 / lt, w4 / lt],
            ]
        )

    def front_wheel_geometry(self, steer_angle_rad: float) -> tuple[F64, F64]:
        """Rolling-speed coefficients of the front wheels, beyond the paper.

        With the rear axle free of lateral slip, the velocity of the front wheel centre ``i`` at
        ``(l_b, y_i)`` is ``(v - yaw_rate y_i, yaw_rate l_b)`` in ``base_link``; its component
        along the wheel plane (Ackermann angle ``delta_i``) is the rolling speed::

            v_roll_i = a_i v + b_i yaw_rate,
            a_i = cos(delta_i),  b_i = -y_i cos(delta_i) + l_b sin(delta_i).

        ``steer_angle_rad`` is the mean road-wheel angle. Returns ``(a, b)``, each (2,) for fl,
        fr.
        """
        lb = self.wheelbase_m
        half = 0.5 * self.track_width_m
        y = np.array([half, -half])
        t = math.tan(steer_angle_rad)
        if abs(t) < 1e-9:
            delta = np.zeros(2)
        else:
            # Ackermann: tan(delta_i) = l_b / (R - y_i) with turn radius R = l_b / tan(delta)
            radius = lb / t
            delta = np.arctan(lb / (radius - y))
        a = np.cos(delta)
        b = -y * np.cos(delta) + lb * np.sin(delta)
        return a, b

    def kinematic_wheel_speeds(
        self,
        speed_m_s: F64,
        yaw_rate_rad_s: F64,
        steer_angle_rad: F64,
        radius_m: F64,
    ) -> F64:
        """Slip-free wheel speeds ``(M, 4)`` of a trajectory (inverse of eq. 6 and front model).

        ``speed_m_s``, ``yaw_rate_rad_s``, ``steer_angle_rad`` are (M,) of ``base_link``;
        ``radius_m`` (4,) or (M, 4) effective rolling radii. Used to check the model and to build
        synthetic data.
        """
        v = np.asarray(speed_m_s, dtype=float)
        yr = np.asarray(yaw_rate_rad_s, dtype=float)
        st = np.asarray(steer_angle_rad, dtype=float)
        half = 0.5 * self.track_width_m
        out = np.empty((v.shape[0], 4))
        out[:, RL] = v - yr * half
        out[:, RR] = v + yr * half
        for k in np.unique(np.round(st, 12)):
            sel = np.round(st, 12) == k
            a, b = self.front_wheel_geometry(float(k))
            out[sel, FL] = a[0] * v[sel] + b[0] * yr[sel]
            out[sel, FR] = a[1] * v[sel] + b[1] * yr[sel]
        return out / radius_m


def gnss_bias_var(r_m2: F64, fraction: float) -> float:
    """Variance per axis of the Gauss-Markov GNSS error taken from a fix's reported (2, 2)
    covariance ``R`` (beyond the paper): ``sigma_b^2 = f lambda_min(R)``, the share ``f`` of
    the smaller principal variance, so that ``R_w = R - sigma_b^2 I`` keeps ``(1 - f) R``'s
    positive definiteness for ``f < 1``."""
    return float(fraction) * _lambda_min(r_m2)


def _lambda_min(r_m2: F64) -> float:
    """Smaller eigenvalue of a symmetric (2, 2) matrix, closed form:
    ``(a + c) / 2 - sqrt(((a - c) / 2)^2 + b^2)``."""
    a, b, c = float(r_m2[0, 0]), float(r_m2[0, 1]), float(r_m2[1, 1])
    return 0.5 * (a + c) - math.hypot(0.5 * (a - c), b)


def gnss_white_cov(r_m2: F64, bias_var_m2: float) -> F64:
    """White part ``R_w = R - c I`` (2, 2) of a fix covariance ``R`` read as white noise plus a
    Gauss-Markov error of variance ``bias_var_m2`` per axis (the GNSS error model of the MPF and
    the AUG-KF), with ``c = min(bias_var, 0.9 lambda_min(R))`` so that ``R_w`` stays positive
    definite when the receiver reports less than the configured error."""
    c = min(bias_var_m2, 0.9 * _lambda_min(r_m2))
    return np.asarray(r_m2, dtype=float) - c * np.eye(2)
