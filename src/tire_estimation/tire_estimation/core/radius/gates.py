"""Gates of the radius learning: when the estimator learns or pauses, and the accelerations and
heading source they read (part of :class:`~.estimator.RadiusEstimator`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius.effects import braking_decel
from tire_estimation.core.radius.model import RL, RR

if TYPE_CHECKING:
    from tire_estimation.core.radius.axle_check import AxleCheck
    from tire_estimation.core.radius.config import RadiusEstimatorConfig
    from tire_estimation.core.radius.model import RadiusMotionModel


#: IMU and steering samples older than this are ignored by the gates, s (a few periods of a
#: 50-100 Hz stream: a stalled stream falls back to the wheel speeds within half a second)
IMU_TIMEOUT_S = 0.5

#: low-pass time constant of the wheel-speed derivative (the longitudinal acceleration without
#: IMU), s: smooths the quantization of the wheel-speed sensors over a few tens of samples
ACCEL_FILTER_TIME_CONSTANT_S = 0.3

#: time constant of the gyro bias estimate (the gyro's yaw rate against the rear wheels' with
#: the learned radii), s: long against the turns, short against the bias's drift
GYRO_BIAS_TIME_CONSTANT_S = 30.0

#: the gyro bias is tracked from this speed, m/s (below, the wheel yaw rate is coarse)
GYRO_BIAS_MIN_SPEED_M_S = 2.0

#: below this speed, while the radii are not learned, the heading is propagated from the steer
#: angle (eq. 31a) instead of the wheel-speed difference, m/s (the value of Lundquist et al.)
STEERING_HEADING_SPEED_M_S = 11.0


class Gates:
    """The gate and heading-source part of :class:`~.estimator.RadiusEstimator`."""

    config: RadiusEstimatorConfig
    model: RadiusMotionModel
    axles: AxleCheck
    gyro_heading_samples: int
    _imu: tuple[int, Any, Any] | None
    _gyro_bias_rad_s: float
    _t_gyro_bias_ns: int | None
    _steer: tuple[int, float] | None
    _ax_lp: float
    _prev_v: float | None
    _radius_mean: tuple[float, float]
    _nominal_radius_m: float
    _track_width_m: float

    def _speed_yaw_rate(self, ws: F64) -> tuple[float, float]:
        """Eq. (6) with the learned mean rear radius errors, in Python floats."""
        return self._rear_speed_yaw_rate(float(ws[RL]), float(ws[RR]))

    def _rear_speed_yaw_rate(self, w3: float, w4: float) -> tuple[float, float]:
        """Eq. (6) from the rear wheel speeds (rad/s) with the learned mean radius errors."""
        d3, d4 = self._radius_mean
        r, lt = self._nominal_radius_m, self._track_width_m
        # eq. (6a) v = r (w3 + w4) / 2 + (w3 d3 + w4 d4) / 2
        v = 0.5 * (w3 * (r + d3) + w4 * (r + d4))
        # eq. (6b) yaw_rate = (w4 (r + d4) - w3 (r + d3)) / l_T
        return v, (w4 * (r + d4) - w3 * (r + d3)) / lt

    # an input stamped after the sample it is used with is not fresh (its age is negative)
    def _imu_fresh(self, t_ns: int) -> bool:
        return self._imu is not None and 0 <= t_ns - self._imu[0] <= IMU_TIMEOUT_S * 1e9

    def _steer_fresh(self, t_ns: int) -> bool:
        return self._steer is not None and 0 <= t_ns - self._steer[0] <= IMU_TIMEOUT_S * 1e9

    def specific_force(
        self, t_ns: int, ws: F64 | None, lateral: bool = True
    ) -> tuple[float, float]:
        """Longitudinal and lateral specific force in ``base_link``, m/s^2: the IMU's when fresh
        (the load transfer is driven by the contact forces, m f; the IMU's offset from the CG
        is neglected), else the fallbacks of the gates (the yaw rate of the wheel speeds
        ``ws``); the lateral one is 0 when not asked for."""
        imu = self._imu
        if imu is not None and self._imu_fresh(t_ns):
            return float(imu[2][0]), float(imu[2][1])
        fx = self._ax_lp
        if not lateral or ws is None:
            return fx, 0.0
        v, yr = self._speed_yaw_rate(ws)
        steer = self._steer
        if steer is not None and self._steer_fresh(t_ns):
            return fx, v * float(self.model.steering_yaw_rate(v, steer[1]))
        return fx, v * yr

    def braking_decel_at(self, t_ns: int) -> float:
        """Braking deceleration of the rear brake slip at ``t_ns``, m/s^2."""
        return braking_decel(self.specific_force(t_ns, None, lateral=False)[0])

    def _rear_heading_from_gyro(self, t_ns: int, ws: F64) -> F64:
        """A locked rear axle (both wheels turn alike): the rear wheel speeds are replaced by
        their mean -+ the half difference that eq. (6b) gives the gyro's yaw rate, so that the
        heading change comes from the gyro and the speed from the mean; only the common radius
        of the axle is then learned (the split the filter shows is not a measurement)."""
        imu = self._imu
        if imu is None or not self._imu_fresh(t_ns):
            return ws
        self.gyro_heading_samples += 1
        mean = 0.5 * float(ws[RL] + ws[RR])
        # eq. (6b) with equal radii: yaw_rate = r_n (w4 - w3) / l_T
        half = 0.5 * float(imu[1][2]) * self._track_width_m / self._nominal_radius_m
        out = ws.copy()
        out[RL], out[RR] = mean - half, mean + half
        return out

    def _track_gyro_bias(self, t_ns: int, ws: F64) -> None:
        """While both rear wheels are live and free: the gyro's yaw-rate bias, a first-order
        low-pass (:data:`GYRO_BIAS_TIME_CONSTANT_S`) of the gyro's yaw rate minus eq. (6b)'s
        with the learned radii (for :meth:`_rear_from_live_wheel`)."""
        imu = self._imu
        last, self._t_gyro_bias_ns = self._t_gyro_bias_ns, t_ns
        if imu is None or last is None or not self._imu_fresh(t_ns):
            return
        v, yaw_rate = self._rear_speed_yaw_rate(float(ws[RL]), float(ws[RR]))
        if v < GYRO_BIAS_MIN_SPEED_M_S:
            return
        dt = min(max((t_ns - last) * 1e-9, 0.0), 0.1)
        k = dt / (GYRO_BIAS_TIME_CONSTANT_S + dt)
        self._gyro_bias_rad_s += k * (float(imu[1][2]) - yaw_rate - self._gyro_bias_rad_s)

    def _rear_from_live_wheel(self, t_ns: int, ws: F64, lost: int) -> F64:
        """One rear wheel's signal is lost (:meth:`AxleCheck.signal_lost`): its speed is
        replaced by the one that gives, with the learned radii, the gyro's yaw rate less its
        bias (:meth:`_track_gyro_bias`) in eq. (6b), or, without a fresh gyro, a zero yaw rate,
        so that the pose keeps moving at the live wheel's speed; learning pauses meanwhile."""
        yaw_rate = 0.0
        imu = self._imu
        if imu is not None and self._imu_fresh(t_ns):
            yaw_rate = float(imu[1][2]) - self._gyro_bias_rad_s
        d3, d4 = self._radius_mean
        r, lt = self._nominal_radius_m, self._track_width_m
        out = ws.copy()
        # eq. (6b) yaw_rate l_T = (r + d4) w4 - (r + d3) w3, solved for the lost wheel
        if lost == RL:
            out[RL] = ((r + d4) * float(ws[RR]) - yaw_rate * lt) / (r + d3)
        else:
            out[RR] = ((r + d3) * float(ws[RL]) + yaw_rate * lt) / (r + d4)
        return out

    def _gates(
        self, t_ns: int, dt: float, w3: float, w4: float
    ) -> tuple[bool, str, float, float, float | None]:
        """Gates of the newest sample (rear wheel speeds ``w3``, ``w4``, rad/s): learn or pause
        and why, the accelerations used (m/s^2), the steer angle for eq. (31a) or None."""
        c = self.config
        # speed and yaw rate with the learned radii (eq. 6): the virtual yaw rate (eq. 4b) is
        # off by ~0.05 rad/s per mm of left-right radius difference (eq. 9b)
        v, yr = self._rear_speed_yaw_rate(w3, w4)
        if self._prev_v is not None and dt > 0:
            a = (v - self._prev_v) / dt
            # first-order low-pass of the wheel-speed derivative
            k = dt / (ACCEL_FILTER_TIME_CONSTANT_S + dt)
            self._ax_lp += k * (a - self._ax_lp)
        self._prev_v = v
        imu_ok = self._imu_fresh(t_ns)
        steer_ok = self._steer_fresh(t_ns)
        if imu_ok and self._imu is not None:
            ax, ay = self._imu[2][0], self._imu[2][1]
        elif steer_ok and self._steer is not None:
            # lateral acceleration from the steer angle (independent of the radius estimates,
            # which may still be wrong while the filter converges)
            ax, ay = self._ax_lp, v * float(self.model.steering_yaw_rate(v, self._steer[1]))
        else:
            ax, ay = self._ax_lp, v * yr
        steer = None
        if steer_ok and self._steer is not None and abs(v) < STEERING_HEADING_SPEED_M_S:
            steer = self._steer[1]
        if v <= -c.min_speed_m_s:
            return False, "reversing", ax, ay, steer
        if v < c.min_speed_m_s:
            return False, "low speed", ax, ay, steer
        if ax < -c.braking_decel_m_s2:
            return False, "braking", ax, ay, steer
        if abs(ax) > c.max_abs_ax_m_s2:
            return False, "longitudinal acceleration", ax, ay, steer
        if abs(ay) > c.max_abs_ay_m_s2:
            return False, "lateral acceleration", ax, ay, steer
        return True, "estimating", ax, ay, steer
