"""How well could any filter know the cornering stiffnesses of a simulated drive? (issue 5)

A posterior Cramér-Rao bound (Tichavsky et al. 1998; for a linear-Gaussian model it is the
Kalman filter's covariance) on the stiffness MPF's own single-track model, linearized along the
simulator's true trajectory. The unknowns are ``z = [vY, r, Cf, Cr]`` (vY at the CG, m/s; yaw
rate, rad/s; front and rear cornering stiffness, N/rad); vX, the steering and the wheel speeds
are inputs (the truth), the outputs the lateral accelerometer and the gyro. The model is
:func:`~tire_estimation.core.stiffness.model.linearize` at the stiffness itself (so with the
friction-limited tyre the force is exact), differentiated as the EKF baseline does
(:func:`~tire_estimation.evaluation.stiffness_baselines.model_jacobian`).

The noise model is the filter's: the accelerometer and gyro noise ``R``, the state jitter, and
the stiffness noise of the paper's eq. (8): ``w_k ~ N(mu, Sigma)`` drawn afresh at every IMU
step, which enters the state derivative (``a w``, eq. 9) and the lateral acceleration (``d w``,
eq. 12); ``a`` and ``d`` are taken here as the model's derivatives in ``w`` (with the
friction-limited tyre, not the secants of ``linearize``). With ``Sigma = 0`` and no jitter the
stiffness is a constant and the bound is the deterministic Cramér-Rao bound of the drive
(:func:`deterministic_crlb`). The gap between the two is what the filter's noise model costs;
the gap between the bound and the filter's error is what the filter loses on its own model.

The truth the bound is linearized on is read from the simulator; this is an evaluation tool.
Shapes: signals (M,) on the IMU grid; covariances (4, 4) in the order of ``z``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.filter import model
from tire_estimation.core.stiffness.model import SingleTrackParams
from tire_estimation.core.stiffness.mpf import (
    STATE_JITTER_VY_M_S_SQRT_S,
    STATE_JITTER_YAW_RATE_RAD_S_SQRT_S,
)
from tire_estimation.evaluation.stiffness_baselines import model_jacobian
from tire_estimation.sim.simulator import SimResult


@dataclass(frozen=True)
class DriveSignals:
    """The simulator's truth and inputs on the IMU grid, (M,) each.

    ``t_s`` from the first IMU sample; ``vx_m_s``, ``vy_cg_m_s`` and ``yaw_rate_rad_s`` the true
    body velocity at the CG and yaw rate; ``delta_rad`` the road-wheel angle; ``wheel_front_m_s``
    / ``wheel_rear_m_s`` the axle means of the wheel speeds times the radius (as the estimator
    forms them); ``stiffness_n_rad`` (M, 3) the true [Cx, Cy_front, Cy_rear].
    """

    t_s: F64
    vx_m_s: F64
    vy_cg_m_s: F64
    yaw_rate_rad_s: F64
    delta_rad: F64
    wheel_front_m_s: F64
    wheel_rear_m_s: F64
    stiffness_n_rad: F64


@dataclass(frozen=True)
class BoundNoise:
    """The noise model of the bound (the stiffness MPF's, by default of its configuration).

    ``stiffness_noise_std_n_rad`` (3,): square root of the diagonal of ``Sigma`` (eq. 8);
    ``jitter_vy_m_s_sqrt_s`` / ``jitter_yaw_rate_rad_s_sqrt_s``: state random walks;
    ``ay_std_m_s2`` / ``gyro_std_rad_s``: ``R``; ``prior_std`` (4,): std of ``z`` at the start
    (m/s, rad/s, N/rad, N/rad).
    """

    stiffness_noise_std_n_rad: F64
    jitter_vy_m_s_sqrt_s: float
    jitter_yaw_rate_rad_s_sqrt_s: float
    ay_std_m_s2: float
    gyro_std_rad_s: float
    prior_std: F64


def bound_noise(
    config: StiffnessEstimatorConfig,
    nominal_n_rad: F64,
    vy_std_m_s: float,
    yaw_rate_std_rad_s: float,
) -> BoundNoise:
    """The MPF's noise model of ``config`` with ``nominal_n_rad`` (3,) [Cx, Cyf, Cyr]:
    ``Sigma^0.5`` = ``stiffness_noise_std_fraction`` x nominal, the state jitter, ``R``; the prior
    of the stiffness ``initial_stiffness_std_fraction`` x nominal (the bound of a linearized
    model does not depend on where the prior is centred), and the given stds of vY and the yaw
    rate."""
    nominal = np.asarray(nominal_n_rad, dtype=float)
    c_std = config.initial_stiffness_std_fraction * nominal
    return BoundNoise(
        stiffness_noise_std_n_rad=config.stiffness_noise_std_fraction * nominal,
        jitter_vy_m_s_sqrt_s=STATE_JITTER_VY_M_S_SQRT_S,
        jitter_yaw_rate_rad_s_sqrt_s=STATE_JITTER_YAW_RATE_RAD_S_SQRT_S,
        ay_std_m_s2=config.accel_noise_std_m_s2,
        gyro_std_rad_s=config.gyro_noise_std_rad_s,
        prior_std=np.array([vy_std_m_s, yaw_rate_std_rad_s, c_std[1], c_std[2]]),
    )


def drive_signals(sim: SimResult, wheel_radius_m: float) -> DriveSignals:
    """The truth and inputs of ``sim`` interpolated on its IMU stamps."""
    t_ns = np.asarray(sim.imu.t_ns)
    t_s = (t_ns - t_ns[0]) * 1e-9
    tr = sim.truth
    t_tr = (np.asarray(tr.t_ns) - t_ns[0]) * 1e-9
    r = np.interp(t_s, t_tr, tr.yaw_rate_rad_s)
    vel = np.asarray(tr.velocity_m_s)
    # the truth's velocity is at base_link (rear axle): v_cg = v_base + lr r
    vy_cg = np.interp(t_s, t_tr, vel[:, 1]) + sim.vehicle.lr_m * r
    t_st = (np.asarray(sim.steering.t_ns) - t_ns[0]) * 1e-9
    t_ws = (np.asarray(sim.wheel_speeds.t_ns) - t_ns[0]) * 1e-9
    ws = np.asarray(sim.wheel_speeds.wheel_speed_rad_s) * wheel_radius_m
    idx = np.clip(np.searchsorted(np.asarray(tr.t_ns), t_ns), 0, len(t_tr) - 1)
    return DriveSignals(
        t_s=t_s,
        vx_m_s=np.interp(t_s, t_tr, vel[:, 0]),
        vy_cg_m_s=vy_cg,
        yaw_rate_rad_s=r,
        delta_rad=np.interp(t_s, t_st, sim.steering.angle_rad),
        wheel_front_m_s=np.interp(t_s, t_ws, 0.5 * (ws[:, 0] + ws[:, 1])),
        wheel_rear_m_s=np.interp(t_s, t_ws, 0.5 * (ws[:, 2] + ws[:, 3])),
        stiffness_n_rad=np.asarray(tr.stiffness, dtype=float)[idx],
    )


def _check_start(sig: DriveSignals, k0: int) -> None:
    if not 0 <= k0 < len(sig.t_s) - 1:
        raise ValueError(f"k0 must be a sample of the drive (0 .. {len(sig.t_s) - 2}), got {k0}")


def _x_w(z: F64, k: int, sig: DriveSignals, p: SingleTrackParams) -> tuple[F64, F64]:
    """The model's state ``[vX, vY, r]`` and stiffness deviation ``w`` (eq. 7) at ``z``."""
    nominal = np.asarray(p.nominal, dtype=float)
    x = np.array([sig.vx_m_s[k], z[0], z[1]])
    w = np.array([0.0, z[2] - nominal[1], z[3] - nominal[2]])
    return x, w


def _wheels(k: int, sig: DriveSignals) -> tuple[float, float]:
    return float(sig.wheel_front_m_s[k]), float(sig.wheel_rear_m_s[k])


def _jacobians(
    z: F64, k: int, sig: DriveSignals, p: SingleTrackParams
) -> tuple[F64, F64, F64, F64]:
    """Jacobians at sample ``k`` and ``z = [vY, r, Cf, Cr]``: of the rate of (vY, r) (2, 4) and
    of [ay, r] (2, 4) in ``z``, and the maps of the stiffness noise into the rate (2, 3) and into
    ay (3,) (the model and its central differences: ``stiffness_baselines.model_jacobian``, the
    EKF baseline's)."""
    x, w = _x_w(z, k, sig, p)
    _, _, rate_x, meas_x, rate_w, meas_w = model_jacobian(
        x, w, float(sig.delta_rad[k]), _wheels(k, sig), p
    )
    # z = [vY, r, Cf, Cr]: columns 1-2 of the x Jacobian, 1-2 of the w Jacobian (dC = dw)
    f_z = np.hstack([rate_x[1:, 1:], rate_w[1:, 1:]])
    # eq. (12) rows ay and gyro
    h_z = np.hstack([meas_x[1:, 1:], meas_w[1:, 1:]])
    return f_z, h_z, rate_w[1:, :], meas_w[1, :]


def posterior_bound(
    sig: DriveSignals,
    p: SingleTrackParams,
    k0: int,
    times_s: Sequence[float],
    noise: BoundNoise,
) -> F64:
    """Bound on the std of [Cf, Cr] (N/rad) at ``times_s`` after sample ``k0``, (len, 2), in
    ascending order of ``times_s``; NaN for a time after the end of the drive.

    An extended Kalman filter on ``z`` run along the true trajectory (so its covariance is the
    posterior Cramér-Rao bound of the linearized model): measurement update with ay and the
    gyro at each sample, then the Euler time update to the next one. The noise of ``w`` enters
    ay through ``d`` (variance ``d Sigma d^T``) and the state through ``dt a`` (``dt^2 a Sigma
    a^T``); its correlation between the two is left out (which loosens the bound a little).
    ``ValueError`` for a ``k0`` outside the drive or a prior std that is not (4,) and > 0.
    """
    _check_start(sig, k0)
    if np.shape(noise.prior_std) != (4,) or not np.all(np.asarray(noise.prior_std) > 0.0):
        raise ValueError(f"noise.prior_std must be 4 values > 0, got {noise.prior_std!r}")
    sigma = np.diag(np.asarray(noise.stiffness_noise_std_n_rad, dtype=float) ** 2)
    q_rw = np.array([noise.jitter_vy_m_s_sqrt_s, noise.jitter_yaw_rate_rad_s_sqrt_s]) ** 2
    cov = np.diag(np.asarray(noise.prior_std, dtype=float) ** 2)
    wanted = sorted(float(t) for t in times_s)
    out = np.full((len(wanted), 2), np.nan)
    t0 = sig.t_s[k0]
    j = 0
    k = k0
    while j < len(wanted) and k + 1 < len(sig.t_s):
        z = np.array(
            [
                sig.vy_cg_m_s[k],
                sig.yaw_rate_rad_s[k],
                sig.stiffness_n_rad[k, 1],
                sig.stiffness_n_rad[k, 2],
            ]
        )
        f_z, h_z, a, d = _jacobians(z, k, sig, p)
        # measurement update: R = diag(sigma_ay^2 + d Sigma d^T, sigma_r^2)
        r_cov = np.diag([noise.ay_std_m_s2**2 + d @ sigma @ d, noise.gyro_std_rad_s**2])
        s = h_z @ cov @ h_z.T + r_cov
        gain = cov @ h_z.T @ np.linalg.inv(s)
        cov = cov - gain @ h_z @ cov
        cov = 0.5 * (cov + cov.T)
        while j < len(wanted) and sig.t_s[k] - t0 >= wanted[j] - 1e-9:
            out[j] = np.sqrt(np.diag(cov)[2:])
            j += 1
        # time update: z+ = z + dt (f(z) + a w), Q = dt q_rw + dt^2 a Sigma a^T (states only)
        dt = float(sig.t_s[k + 1] - sig.t_s[k])
        phi = np.eye(4)
        phi[:2, :] += dt * f_z
        q = np.zeros((4, 4))
        q[:2, :2] = dt * np.diag(q_rw) + dt * dt * (a @ sigma @ a.T)
        cov = phi @ cov @ phi.T + q
        k += 1
    return out


def deterministic_crlb(
    sig: DriveSignals,
    p: SingleTrackParams,
    k0: int,
    duration_s: float,
    ay_std_m_s2: float,
    gyro_std_rad_s: float,
) -> F64:
    """Cramér-Rao bound (4, 4) of ``[vY0, r0, Cf, Cr]`` from ``duration_s`` of ay and gyro
    after sample ``k0``, with a constant stiffness and no process noise (no prior).

    The outputs are simulated from ``z`` at ``k0`` with the model of :func:`posterior_bound`
    (Euler on the IMU grid); the Fisher information ``J^T R^-1 J`` with ``J`` by central
    differences. The check of :func:`posterior_bound` with zero process noise. ``ValueError``
    for a ``k0`` outside the drive or a ``duration_s`` that is not > 0.
    """
    _check_start(sig, k0)
    if not duration_s > 0.0:
        raise ValueError(f"duration_s must be > 0, got {duration_s!r}")
    k1 = min(k0 + round(duration_s / float(np.median(np.diff(sig.t_s)))), len(sig.t_s) - 1)
    z0 = np.array(
        [
            sig.vy_cg_m_s[k0],
            sig.yaw_rate_rad_s[k0],
            sig.stiffness_n_rad[k0, 1],
            sig.stiffness_n_rad[k0, 2],
        ]
    )

    def outputs(z_start: F64) -> F64:
        z = z_start.copy()
        ys = np.empty((k1 - k0, 2))
        for i, k in enumerate(range(k0, k1)):
            x, w = _x_w(z, k, sig, p)
            rate, y_hat, _, _ = model(
                x[None, :], w[None, :], float(sig.delta_rad[k]), _wheels(k, sig), p
            )
            ys[i] = (y_hat[0, 1] / ay_std_m_s2, y_hat[0, 2] / gyro_std_rad_s)
            z[:2] += float(sig.t_s[k + 1] - sig.t_s[k]) * rate[0, 1:]
        return ys

    steps = np.array([1e-4, 1e-5, 1e-4 * abs(z0[2]), 1e-4 * abs(z0[3])])
    jac = np.empty((k1 - k0, 2, 4))
    for i, h in enumerate(steps):
        zp, zm = z0.copy(), z0.copy()
        zp[i] += h
        zm[i] -= h
        jac[:, :, i] = (outputs(zp) - outputs(zm)) / (2.0 * h)
    fisher = np.einsum("kai,kaj->ij", jac, jac)
    return np.asarray(np.linalg.inv(fisher), dtype=float)
