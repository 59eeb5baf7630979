"""Linear single-track (bicycle) reference model (Tuononen 2009, section 3.4, eq. 23-28).

State ``x = [vy_cg m/s, r rad/s]``: lateral velocity of the centre of gravity and yaw rate, in
body axes (x forward, y left). Input: road-wheel steer angle delta (rad, positive left) and the
forward speed vx (m/s, a slowly varying parameter). Axle forces are linear in the slip angles
with the nominal cornering stiffnesses of :class:`~tire_estimation.core.vehicle.VehicleParams`.

Written out (Cf, Cr axle cornering stiffness N/rad; lf, lr m; m kg; Iz kg m^2)::

    m (dvy/dt + vx r) = Ff + Fr                          (23)
    Iz dr/dt          = lf Ff - lr Fr                    (24)
    Ff = Cf alpha_f,  Fr = Cr alpha_r                    (25, 26)
    alpha_f = delta - (vy + lf r) / vx                   (27)
    alpha_r = (lr r - vy) / vx                           (28)

so dx/dt = A(vx) x + B delta; it is discretized exactly (matrix exponential of the augmented
system, compiled in :mod:`.single_track_kernels`) over each step, for a steering angle that is
either held (zero-order hold) or, when the angle at the start of the step is given, linear
between its two samples (first-order hold).

The tyre-force KF uses the first-order hold: a steering sensor samples a continuous angle, and
holding the newest sample over the step that ends at it would advance the model's input by half
a step (5 ms at 100 Hz), a yaw-rate error proportional to the yaw acceleration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.lateral import single_track_kernels as kernels
from tire_estimation.core.vehicle import VehicleParams


@dataclass(frozen=True)
class SingleTrackParams:
    """Parameters of eq. (23-28) (SI units).

    Attributes:
        mass_kg: m, kg.
        yaw_inertia_kg_m2: Iz, kg m^2.
        lf_m: centre of gravity to front axle, m.
        lr_m: centre of gravity to rear axle, m.
        cf_n_rad: front-axle cornering stiffness Cf, N/rad.
        cr_n_rad: rear-axle cornering stiffness Cr, N/rad.
    """

    mass_kg: float
    yaw_inertia_kg_m2: float
    lf_m: float
    lr_m: float
    cf_n_rad: float
    cr_n_rad: float

    @classmethod
    def from_vehicle(cls, vehicle: VehicleParams) -> SingleTrackParams:
        """Take m, Iz, lf, lr and the nominal axle cornering stiffnesses from ``vehicle``."""
        return cls(
            mass_kg=vehicle.mass_kg,
            yaw_inertia_kg_m2=vehicle.yaw_inertia_kg_m2,
            lf_m=vehicle.lf_m,
            lr_m=vehicle.lr_m,
            cf_n_rad=vehicle.cornering_stiffness_front_n_rad,
            cr_n_rad=vehicle.cornering_stiffness_rear_n_rad,
        )


def slip_angles(
    p: SingleTrackParams, vy_m_s: float, r_rad_s: float, vx_m_s: float, delta_rad: float
) -> tuple[float, float]:
    """(alpha_f, alpha_r) in rad for the CG lateral velocity, yaw rate, speed and steer angle."""
    # Tuononen 2009 eq. (27): alpha_f = delta - (vy + lf r) / vx
    alpha_f = delta_rad - (vy_m_s + p.lf_m * r_rad_s) / vx_m_s
    # Tuononen 2009 eq. (28): alpha_r = (lr r - vy) / vx
    alpha_r = (p.lr_m * r_rad_s - vy_m_s) / vx_m_s
    return alpha_f, alpha_r


def axle_forces(
    p: SingleTrackParams, vy_m_s: float, r_rad_s: float, vx_m_s: float, delta_rad: float
) -> F64:
    """Nominal (linear) axle lateral forces [Ff, Fr], N, shape (2,)."""
    alpha_f, alpha_r = slip_angles(p, vy_m_s, r_rad_s, vx_m_s, delta_rad)
    # Tuononen 2009 eq. (25)-(26): Ff = Cf alpha_f, Fr = Cr alpha_r
    return np.array([p.cf_n_rad * alpha_f, p.cr_n_rad * alpha_r])


def continuous_matrices(p: SingleTrackParams, vx_m_s: float) -> tuple[F64, F64]:
    """(A (2, 2), B (2,)) of dx/dt = A x + B delta for x = [vy_cg, r] at speed ``vx_m_s``."""
    m, iz, lf, lr, cf, cr = p.mass_kg, p.yaw_inertia_kg_m2, p.lf_m, p.lr_m, p.cf_n_rad, p.cr_n_rad
    v = vx_m_s
    # eq. (23) with (25)-(28): dvy = (Cf af + Cr ar) / m - vx r
    # eq. (24) with (25)-(28): dr = (lf Cf af - lr Cr ar) / Iz
    a = np.array(
        [
            [-(cf + cr) / (m * v), -v - (cf * lf - cr * lr) / (m * v)],
            [-(cf * lf - cr * lr) / (iz * v), -(cf * lf * lf + cr * lr * lr) / (iz * v)],
        ]
    )
    b = np.array([cf / m, cf * lf / iz])
    return a, b


def steady_state(p: SingleTrackParams, vx_m_s: float, delta_rad: float) -> F64:
    """Steady-state [vy_cg m/s, r rad/s] of eq. (23-28) for constant vx and delta, shape (2,)."""
    a, b = continuous_matrices(p, vx_m_s)
    return np.asarray(np.linalg.solve(a, -b * delta_rad), dtype=np.float64)


def kinematic_state(p: SingleTrackParams, vx_m_s: float, delta_rad: float) -> F64:
    """Low-speed kinematic [vy_cg, r]: no rear-axle side slip, r = vx tan(delta) / (lf + lr)."""
    r = vx_m_s * math.tan(delta_rad) / (p.lf_m + p.lr_m)
    return np.array([p.lr_m * r, r])


class SingleTrackModel:
    """Open-loop integration of eq. (23-28); the reference model of the tyre-force KF.

    Args:
        params: model parameters.
        min_speed_m_s: below this speed the kinematic state replaces the dynamic model.
    """

    def __init__(self, params: SingleTrackParams, min_speed_m_s: float = 3.0) -> None:
        self.params = params
        self.min_speed_m_s = float(max(min_speed_m_s, 0.1))
        self._model = kernels.model_constants(
            params.mass_kg,
            params.yaw_inertia_kg_m2,
            params.lf_m,
            params.lr_m,
            params.cf_n_rad,
            params.cr_n_rad,
        )
        self.x: F64 = np.zeros(2)
        self.initialized = False

    def reset(self, vx_m_s: float, delta_rad: float) -> None:
        """Start at the steady state (kinematic state at low speed) of the current input."""
        self.x = self._rest(vx_m_s, delta_rad)
        self.initialized = True

    def _rest(self, vx_m_s: float, delta_rad: float) -> F64:
        if vx_m_s < self.min_speed_m_s:
            return kinematic_state(self.params, vx_m_s, delta_rad)
        return steady_state(self.params, vx_m_s, delta_rad)

    def step(
        self,
        dt_s: float,
        vx_m_s: float,
        delta_rad: float,
        delta_start_rad: float | None = None,
    ) -> F64:
        """Advance by ``dt_s``; return the new [vy_cg, r], shape (2,).

        vx is held over the step. ``delta_rad`` is the steer angle at the end of the step; with
        ``delta_start_rad`` (the angle at its start) the angle is taken as linear in between
        (first-order hold), else ``delta_rad`` is held over the whole step (zero-order hold).
        """
        if not self.initialized:
            self.reset(vx_m_s, delta_rad)
            return self.x.copy()
        if vx_m_s < self.min_speed_m_s:
            self.x = kinematic_state(self.params, vx_m_s, delta_rad)
            return self.x.copy()
        if delta_start_rad is None or dt_s <= 0.0:
            # zero-order-hold discretization: expm([[A, B], [0, 0]] T) = [[Ad, Bd], [0, 1]]
            zoh = np.empty((2, 3))
            kernels.zero_order_hold(self._model, vx_m_s, dt_s, zoh)
            self.x = zoh[:, :2] @ self.x + zoh[:, 2] * delta_rad
            return self.x.copy()
        # first-order hold: delta(s) = delta0 + w s on [0, T];
        # d/dt [x, delta, w] = [[A, B, 0], [0, 0, 1], [0, 0, 0]] [x, delta, w], so
        # x(T) = E11 x(0) + E12 delta0 + E13 w, E = expm(that matrix T)
        foh = np.empty((2, 4))
        kernels.first_order_hold(self._model, vx_m_s, dt_s, foh)
        slope = (delta_rad - delta_start_rad) / dt_s
        self.x = foh[:, :2] @ self.x + foh[:, 2] * delta_start_rad + foh[:, 3] * slope
        return self.x.copy()

    def axle_forces(self, vx_m_s: float, delta_rad: float) -> F64:
        """Nominal axle forces [Ff, Fr] (N) of eq. (25-28) at the model state, shape (2,)."""
        v = max(vx_m_s, self.min_speed_m_s)
        return axle_forces(self.params, float(self.x[0]), float(self.x[1]), v, delta_rad)
