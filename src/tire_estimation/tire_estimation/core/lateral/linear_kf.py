"""Linear single-track Kalman filter for the lateral state: the baseline of the lateral estimators.

State ``x = [vy_cg m/s, r rad/s]`` (centre of gravity, body axes, x forward, y left), the linear
single-track model of :mod:`.single_track` (Tuononen 2009 eq. 23-28, the
same model as Berntorp & Di Cairano 2018 eq. 1 with linear tyres and constant vx) with fixed
cornering stiffnesses::

    dx/dt = A(vx) x + B delta + noise,                         (single_track eq. 23-28)
    y = [ay_cg, r] = C(vx) x + D delta + v,   ay_cg = (Ff + Fr) / m

``ay`` is the accelerometer's lateral specific force moved to the CG (lever arm ``imu_x - lr``
along x: ``ay_cg = ay_imu - (imu_x - lr) dr/dt``, neglected here: the filter is meant as the
simple baseline the issue names, "a linear single-track Kalman filter", and the Revs IMU is at
the CG). Inputs: the road-wheel steer angle (first-order hold between samples, as the tyre-force
KF) and the longitudinal speed (measured, or the rear-axle wheel speed). The IMU drives the
steps; bad input is dropped and counted in :attr:`LinearLateralKF.stats` as
``<stream>:<kind>``, never raised.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import drop_key, finite_vector, stamp_after
from tire_estimation.core.lateral import single_track_kernels as kernels
from tire_estimation.core.lateral.estimate import LateralState
from tire_estimation.core.lateral.single_track import SingleTrackParams, steady_state
from tire_estimation.core.validation import (
    Checked,
    NonNegative,
    Positive,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError


@dataclass(frozen=True)
class LinearLateralKFConfig(Checked):
    """Tuning of the linear single-track Kalman filter; checked at construction.

    Attributes:
        cornering_stiffness_front_n_rad: front-axle cornering stiffness Cf, N/rad; 0 takes the
            vehicle's nominal value (default 0).
        cornering_stiffness_rear_n_rad: rear-axle cornering stiffness Cr, N/rad; 0 takes the
            vehicle's nominal value (default 0).
        vy_process_std_m_s_sqrt_s: process-noise density on dvy/dt, m/s/sqrt(s) (default 0.5).
        yaw_rate_process_std_rad_s_sqrt_s: process-noise density on dr/dt, rad/s/sqrt(s)
            (default 0.1).
        accel_y_std_m_s2: measurement-noise std of the lateral acceleration, m/s^2 (default 0.5;
            covers the model error of linear tyres as well as sensor noise).
        yaw_rate_std_rad_s: measurement-noise std of the gyro yaw rate, rad/s (default 0.005).
        min_speed_m_s: below this speed the filter holds its state and waits, m/s (default 3.0).
        max_gap_s: a larger gap between IMU samples restarts the filter, s (default 0.5).
        max_input_age_s: speed / steering older than this are stale, s (default 0.2).
    """

    cornering_stiffness_front_n_rad: NonNegative = 0.0
    cornering_stiffness_rear_n_rad: NonNegative = 0.0
    vy_process_std_m_s_sqrt_s: Positive = 0.5
    yaw_rate_process_std_rad_s_sqrt_s: Positive = 0.1
    accel_y_std_m_s2: Positive = 0.5
    yaw_rate_std_rad_s: Positive = 0.005
    min_speed_m_s: Positive = 3.0
    max_gap_s: Positive = 0.5
    max_input_age_s: Positive = 0.2


class LinearLateralKF:
    """Kalman filter on [vy_cg, r] with the linear single-track model (see module docstring)."""

    def __init__(self, config: LinearLateralKFConfig, vehicle: VehicleParams) -> None:
        self.config = config
        cf = config.cornering_stiffness_front_n_rad or vehicle.cornering_stiffness_front_n_rad
        cr = config.cornering_stiffness_rear_n_rad or vehicle.cornering_stiffness_rear_n_rad
        self.params = replace(
            SingleTrackParams.from_vehicle(vehicle), cf_n_rad=float(cf), cr_n_rad=float(cr)
        )
        self.wheel_radius_m = vehicle.nominal_tire_radius_m
        self.stats: dict[str, int] = {}
        self._q_density = np.diag(
            [config.vy_process_std_m_s_sqrt_s**2, config.yaw_rate_process_std_rad_s_sqrt_s**2]
        )
        self._r = np.diag([config.accel_y_std_m_s2**2, config.yaw_rate_std_rad_s**2])
        p = self.params
        # the compiled step's constants (single_track_kernels.kf_constants)
        self._constants = kernels.kf_constants(
            kernels.model_constants(
                p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m, p.lr_m, p.cf_n_rad, p.cr_n_rad
            ),
            float(self._q_density[0, 0]),
            float(self._q_density[1, 1]),
            float(self._r[0, 0]),
            float(self._r[1, 1]),
        )
        self.reset()

    def reset(self) -> None:
        """Forget the state and all inputs."""
        self.x: F64 = np.zeros(2)
        self.p: F64 = np.diag([1.0, 0.01])
        self.initialized = False
        self._vx: float | None = None
        self._t_vx: int | None = None
        self._steer: float | None = None
        self._t_steer: int | None = None
        self._steer_prev: float | None = None
        self._t_imu: int | None = None

    def _drop(self, stream: str, kind: str) -> None:
        key = drop_key(stream, kind)
        self.stats[key] = self.stats.get(key, 0) + 1

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr), rad/s; vx = mean rear wheel speed x nominal radius."""
        try:
            t = stamp_after("wheel speeds", t_ns, self._t_vx)
            ws = finite_vector(wheel_speed_rad_s, 4, "wheel speeds").tolist()
        except (InputError, TypeError, ValueError) as exc:
            self._drop("wheel_speeds", exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._t_vx, self._vx = t, float(0.5 * (ws[2] + ws[3]) * self.wheel_radius_m)

    def _scalar(self, stream: str, t_ns: int, last_ns: int | None, value: Any) -> float | None:
        """A checked scalar sample (its stamp after ``last_ns``), or None when dropped."""
        try:
            stamp_after(stream, t_ns, last_ns)
            return float(finite_vector(value, 1, stream)[0])
        except (InputError, TypeError, ValueError) as exc:
            self._drop(stream, exc.kind if isinstance(exc, InputError) else "bad_value")
            return None

    def on_velocity(self, t_ns: int, vx_m_s: float) -> None:
        """Measured longitudinal speed, m/s."""
        v = self._scalar("velocity", t_ns, self._t_vx, vx_m_s)
        if v is not None:
            self._t_vx, self._vx = int(t_ns), v

    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle, rad (positive left)."""
        a = self._scalar("steering", t_ns, self._t_steer, angle_rad)
        if a is not None:
            self._t_steer, self._steer = int(t_ns), a

    def _fresh(self, last: int | None, t_ns: int) -> bool:
        return last is not None and (t_ns - last) * 1e-9 <= self.config.max_input_age_s

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        """IMU sample in base_link axes: one predict + update step."""
        try:
            t = stamp_after("imu", t_ns, self._t_imu)
            gyro = finite_vector(gyro_rad_s, 3, "gyro").tolist()
            acc = finite_vector(accel_m_s2, 3, "accel").tolist()
        except (InputError, TypeError, ValueError) as exc:
            self._drop("imu", exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        last, self._t_imu = self._t_imu, t
        if not (self._fresh(self._t_vx, t) and self._vx is not None):
            self._drop("imu", "no_speed")
            return
        vx = self._vx
        delta = self._steer if (self._steer is not None and self._fresh(self._t_steer, t)) else 0.0
        delta0 = self._steer_prev if self._steer_prev is not None else delta
        self._steer_prev = delta
        if vx < self.config.min_speed_m_s:
            self.initialized = False
            return
        dt = None if last is None else (t - last) * 1e-9
        if dt is not None and dt > self.config.max_gap_s:
            self._drop("imu", "gap")
            self.initialized = False
        if not self.initialized:
            self.x = steady_state(self.params, vx, delta)
            self.x[1] = gyro[2]
            self.p = np.diag([1.0, self._r[1, 1]])
            self.initialized = True
            self._last_vx = vx
            return
        assert dt is not None
        self._step(dt, vx, delta0, delta, acc[1], gyro[2])
        self._last_vx = vx

    def _step(
        self, dt: float, vx: float, delta0: float, delta1: float, ay_m_s2: float, r_meas: float
    ) -> None:
        """Predict over ``dt`` (single-track eq. 23-28, exact first-order-hold discretization of
        the steer angle from ``delta0`` to ``delta1``; P' = F P F^T + Q T, a white
        process-noise density, first order in T) and update with y = [ay, r]: ay = (Ff + Fr) / m
        with eq. (25)-(28), the Joseph form keeping P symmetric positive definite. One compiled
        call (:func:`.single_track_kernels.kf_step`), in place on ``x`` and ``p``."""
        kernels.kf_step(self.x, self.p, self._constants, dt, vx, delta0, delta1, ay_m_s2, r_meas)

    def estimate(self) -> LateralState:
        """Current estimate of the CG (zeros before the first step); the covariance of vx is 0
        (an input)."""
        vx = float(self._vx) if self._vx is not None else 0.0
        cov = np.zeros((3, 3))
        cov[1:, 1:] = self.p
        vy, r = float(self.x[0]), float(self.x[1])
        return LateralState(
            t_ns=int(self._t_imu or 0),
            vx_m_s=vx,
            vy_m_s=vy,
            yaw_rate_rad_s=r,
            sideslip_rad=math.atan2(vy, max(vx, 1e-3)),
            covariance=cov,
        )


__all__ = ["LinearLateralKF", "LinearLateralKFConfig"]
