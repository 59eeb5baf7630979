"""AUG-KF baseline: EKF on the pose augmented with the rear radius errors (eq. 10-11).

State ``x_a = [east, north, yaw, delta_rl, delta_rr]`` (eq. 10). The radius errors follow a random
walk (artificial dynamics); the fast radius variation ``w`` (eq. 11c) enters through ``g`` (eq.
11b). Same inputs (rear wheel speeds, optional steer angle for eq. 31a) and measurements (GNSS
position of the antenna) as the MPF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.gnss_bias import GnssErrorSize
from tire_estimation.core.radius.model import RL, RR, RadiusMotionModel, gnss_white_cov

#: random walk of the radius errors in the AUG-KF baseline's state, m/sqrt(s)
RADIUS_RANDOM_WALK_M_SQRT_S = 2e-5


@dataclass(frozen=True)
class AugKfUpdate:
    """Innovation of one GNSS update: ``innovation_m`` (2,), ``innovation_cov_m2`` (2, 2), NIS."""

    innovation_m: F64
    innovation_cov_m2: F64
    nis: float


class AugKf(GnssErrorSize):
    """Extended Kalman filter of eq. (10)-(11).

    Args:
        model: the motion model.
        prior_radius_error_m: initial radius errors (2,), m.
        prior_radius_error_std_m: their initial std, m.
        radius_noise_std_m: std of the fast radius variation ``w`` per sample (eq. 11c), m.
        radius_random_walk_m_sqrt_s: random walk of the radius errors, m/sqrt(s).
        position_noise_m_sqrt_s: additive random walk on east/north, m/sqrt(s).
        yaw_noise_rad_sqrt_s: additive random walk on the yaw, rad/sqrt(s).
        gnss_bias_std_m: stationary std per axis of a first-order Gauss-Markov GNSS error,
            appended to the state as ``[b_east, b_north]`` (beyond the paper; the MPF
            marginalizes the same model); 0 = not modelled (5 states), m.
        gnss_bias_time_constant_s: its correlation time, s.
        gnss_bias_fraction: with ``gnss_bias_std_m`` 0, that error's variance is this share
            of each fix's covariance (:meth:`observe_fix_cov`); both 0: five states.
    """

    def __init__(
        self,
        model: RadiusMotionModel,
        prior_radius_error_m: F64,
        prior_radius_error_std_m: float,
        radius_noise_std_m: float,
        radius_random_walk_m_sqrt_s: float,
        position_noise_m_sqrt_s: float,
        yaw_noise_rad_sqrt_s: float,
        gnss_bias_std_m: float = 0.0,
        gnss_bias_time_constant_s: float = 120.0,
        gnss_bias_fraction: float = 0.0,
    ) -> None:
        self.model = model
        bias_on = self._bias_size(gnss_bias_std_m, gnss_bias_time_constant_s, gnss_bias_fraction)
        #: state size: 5, or 7 with the GNSS bias
        self.nx = 7 if bias_on else 5
        self.x = np.zeros(self.nx)
        self.p = np.eye(self.nx)
        if self.nx == 7:
            self.p[5:, 5:] = np.eye(2) * self.bias_var
        self.x[3:5] = prior_radius_error_m
        self.p[3:5, 3:5] = np.eye(2) * prior_radius_error_std_m**2
        self._prior = (np.array(self.x[3:5]), prior_radius_error_std_m)
        self.w_var = radius_noise_std_m**2
        self.rw_q = radius_random_walk_m_sqrt_s**2
        self.pos_q = position_noise_m_sqrt_s**2
        self.yaw_q = yaw_noise_rad_sqrt_s**2
        self.speed_m_s = 0.0
        self.yaw_rate_rad_s = 0.0
        #: rear wheel speeds (rl, rr) of the last prediction, rad/s
        self.rear_wheel_speed_rad_s = (0.0, 0.0)
        self._f = np.eye(self.nx)
        self._g = np.zeros((self.nx, 2))

    def reset_radii(self) -> None:
        """Back to the prior radius errors."""
        self.x[3:5] = self._prior[0]
        self.p[3:5, :] = 0.0
        self.p[:, 3:5] = 0.0
        self.p[3:5, 3:5] = np.eye(2) * self._prior[1] ** 2

    def scale_radii(self, factor: float) -> None:
        """As :meth:`RadiusMPF.scale_radii`: the prior again, centred on the common radius
        (nominal plus the mean error) times ``factor``."""
        r_n = self.model.nominal_radius_m
        common = (r_n + float(self.x[3:5].mean())) * factor - r_n
        self.reset_radii()
        self.x[3:5] = common

    def init_pose(self, mean: F64, cov: F64) -> None:
        """Set the pose ``[east, north, yaw]`` (3,) and its covariance (3, 3); keep the radii."""
        self.x[:3] = mean
        self.p[:3, :] = 0.0
        self.p[:, :3] = 0.0
        self.p[:3, :3] = cov
        if self.nx == 7:
            # the fix the pose was initialized from holds the current GNSS error
            self.x[5:] = 0.0
            self.p[5:, :] = 0.0
            self.p[:, 5:] = 0.0
            self.p[5:, 5:] = np.eye(2) * self.bias_var

    def predict(
        self,
        dt_s: float,
        wheel_speed_rad_s: F64,
        learn: bool = True,
        steer_angle_rad: float | None = None,
    ) -> None:
        """EKF time update over ``dt_s`` with wheel speeds (4,) (eq. 11).

        ``learn=False`` freezes the radius errors (no random walk, no cross-covariance
        build-up with the pose through the radius noise).
        """
        w3 = float(wheel_speed_rad_s[RL])
        w4 = float(wheel_speed_rad_s[RR])
        m = self.model
        lt = m.track_width_m
        r = m.nominal_radius_m
        x = self.x
        psi, d3, d4 = float(x[2]), float(x[3]), float(x[4])
        # eq. (6a) v = v_virt + (w3 d3 + w4 d4) / 2
        v = 0.5 * (w3 * (r + d3) + w4 * (r + d4))
        c, s = math.cos(psi), math.sin(psi)
        dv3, dv4 = 0.5 * w3, 0.5 * w4
        if steer_angle_rad is None:
            # eq. (6b) yaw_rate = yaw_rate_virt + (w4 d4 - w3 d3) / l_T
            yr = (w4 * (r + d4) - w3 * (r + d3)) / lt
            dy3, dy4 = -w3 / lt, w4 / lt
        else:
            # eq. (31a) low-speed heading from the steer angle
            k = math.tan(steer_angle_rad) / m.wheelbase_m
            yr = v * k
            dy3, dy4 = k * dv3, k * dv4
        # eq. (11b) noise gain of the fast radius variation, columns for w3 and w4
        g = self._g
        g[0, 0], g[0, 1] = dt_s * c * dv3, dt_s * c * dv4
        g[1, 0], g[1, 1] = dt_s * s * dv3, dt_s * s * dv4
        g[2, 0], g[2, 1] = dt_s * dy3, dt_s * dy4
        # Jacobian of f (eq. 11a) with respect to x_a = [e, n, psi, d3, d4]
        f = self._f
        f[0, 2] = -dt_s * v * s
        f[1, 2] = dt_s * v * c
        if learn:
            f[:3, 3:5] = g[:3]
        else:
            f[:3, 3:5] = 0.0
        phi = 1.0
        if self.nx == 7:
            # Gauss-Markov GNSS error: b = phi b, phi = exp(-dt / tau)
            phi = math.exp(-dt_s / self.bias_tau_s)
            f[5, 5] = f[6, 6] = phi
            x[5:] *= phi
        # eq. (11a) state prediction
        x[0] += dt_s * v * c
        x[1] += dt_s * v * s
        x[2] += dt_s * yr
        p = f @ self.p @ f.T
        if learn:
            p += self.w_var * (g @ g.T)
            # eq. (11b)-(11c): random walk of the radius errors
            p[3, 3] += self.rw_q * dt_s
            p[4, 4] += self.rw_q * dt_s
        p[0, 0] += self.pos_q * dt_s
        p[1, 1] += self.pos_q * dt_s
        p[2, 2] += self.yaw_q * dt_s
        if self.nx == 7:
            p[5, 5] += self.bias_var * (1.0 - phi * phi)
            p[6, 6] += self.bias_var * (1.0 - phi * phi)
        self.p = p
        self.speed_m_s = v
        self.yaw_rate_rad_s = yr
        self.rear_wheel_speed_rad_s = (w3, w4)

    def innovation(
        self, y_m: F64, r_m2: F64, lever_arm_m: F64, extrapolate_s: float = 0.0
    ) -> tuple[AugKfUpdate, F64]:
        """Innovation statistics and measurement Jacobian ``H`` (2, 5) for a fix (eq. 13)."""
        e, n, psi = self.x[:3]
        c, s = math.cos(psi), math.sin(psi)
        ax = float(lever_arm_m[0]) + extrapolate_s * self.speed_m_s
        ay = float(lever_arm_m[1])
        # eq. (13b) with the antenna lever arm
        h = np.array([e + ax * c - ay * s, n + ax * s + ay * c])
        hj = np.zeros((2, self.nx))
        if self.nx == 7:
            # y = h(x) + b + v: the fix covariance is the total, R_w = R - c I (as the MPF)
            h = h + self.x[5:]
            hj[0, 5] = hj[1, 6] = 1.0
            r_m2 = gnss_white_cov(r_m2, self.bias_var)
        hj[0, 0] = 1.0
        hj[1, 1] = 1.0
        hj[0, 2] = -ax * s - ay * c
        hj[1, 2] = ax * c - ay * s
        innov = np.asarray(y_m, dtype=float) - h
        s_mat = hj @ self.p @ hj.T + r_m2
        nis = float(innov @ np.linalg.solve(s_mat, innov))
        return AugKfUpdate(innov, s_mat, nis), hj

    def velocity_innovation(
        self,
        v_m_s: F64,
        r_m2_s2: F64,
        lever_arm_m: F64,
        lateral_std_m_s: float,
        rear_wheel_speed_rad_s: tuple[float, float] | None = None,
        along_var_m2_s2: float = 0.0,
        heading_offset_rad: float = 0.0,
    ) -> tuple[AugKfUpdate, F64]:
        """Innovation and Jacobian ``H`` (2, nx) of a GNSS Doppler velocity (beyond the paper;
        the model of :meth:`RadiusMPF.update_velocity`): the antenna moves with
        ``R(psi) [v(delta) - r(delta) l_y, u + r(delta) l_x]``, v and r of eq. (6) with the
        rear wheel speeds ``(w3, w4)`` at the velocity's time (default: those of the last
        prediction), ``u ~ N(0, sigma_u^2)`` the unmodelled lateral velocity. The noise adds
        the fast radius variation ``w`` (eq. 11c) of that speed along the heading:
        ``R + sigma_u^2 n n' + (var(w) (w3^2 + w4^2) / 4 + along_var) t t'`` (t, n: along /
        across). ``heading_offset_rad`` is added to the heading to get the one at the
        velocity's time (``-r tau`` for a velocity ``tau`` seconds before the pose)."""
        w3, w4 = (
            self.rear_wheel_speed_rad_s
            if rear_wheel_speed_rad_s is None
            else (float(rear_wheel_speed_rad_s[0]), float(rear_wheel_speed_rad_s[1]))
        )
        m = self.model
        lt = m.track_width_m
        psi = float(self.x[2]) + float(heading_offset_rad)
        c, s = math.cos(psi), math.sin(psi)
        lx, ly = float(lever_arm_m[0]), float(lever_arm_m[1])
        # eq. (6a), (6b) with the current radius errors
        v_a, yr_a = m.speed_yaw_rate(np.array([0.0, 0.0, w3, w4]), self.x[3:5])
        v, yr = float(v_a), float(yr_a)
        vbx = v - yr * ly
        vby = yr * lx
        h = np.array([c * vbx - s * vby, s * vbx + c * vby])
        # derivatives of (vbx, vby) with respect to d3, d4
        bx3, bx4 = 0.5 * w3 + ly * w3 / lt, 0.5 * w4 - ly * w4 / lt
        by3, by4 = -lx * w3 / lt, lx * w4 / lt
        hj = np.zeros((2, self.nx))
        hj[0, 2] = -s * vbx - c * vby
        hj[1, 2] = c * vbx - s * vby
        hj[0, 3], hj[1, 3] = c * bx3 - s * by3, s * bx3 + c * by3
        hj[0, 4], hj[1, 4] = c * bx4 - s * by4, s * bx4 + c * by4
        t_vec = np.array([c, s])
        n_vec = np.array([-s, c])
        w_speed_var = self.w_var * (w3 * w3 + w4 * w4) / 4.0 + float(along_var_m2_s2)
        noise = (
            np.asarray(r_m2_s2, dtype=float)
            + float(lateral_std_m_s) ** 2 * np.outer(n_vec, n_vec)
            + w_speed_var * np.outer(t_vec, t_vec)
        )
        innov = np.asarray(v_m_s, dtype=float)[:2] - h
        s_mat = hj @ self.p @ hj.T + noise
        nis = float(innov @ np.linalg.solve(s_mat, innov))
        return AugKfUpdate(innov, s_mat, nis), hj

    def update(self, upd: AugKfUpdate, hj: F64, learn: bool = True) -> None:
        """EKF measurement update (Joseph form). ``learn=False`` corrects the pose only."""
        k = self.p @ hj.T @ np.linalg.inv(upd.innovation_cov_m2)
        if not learn:
            k[3:5] = 0.0
        self.x = self.x + k @ upd.innovation_m
        ikh = np.eye(self.nx) - k @ hj
        r = upd.innovation_cov_m2 - hj @ self.p @ hj.T
        self.p = ikh @ self.p @ ikh.T + k @ r @ k.T
        self.p = 0.5 * (self.p + self.p.T)
