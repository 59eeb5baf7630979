"""Measurement-conditioned proposal of the measured states of the stiffness MPF (not in the
paper).

Algorithm 1 of Berntorp & Di Cairano (IEEE TCST 2018) samples the states from their dynamics
(eq. 9) and lets the measurements only weigh them (eq. 36). Two measurement rows are a state
plus noise, with no stiffness term (``d`` row = 0): the gyro, ``y_r = r + b_r + e_r`` (eq. 12),
and, in the ``kinematic`` speed model, the measured speed ``y_0 = vX + e_0``. With precise
sensors (an RTK-aided INS: 0.02 m/s, 0.005 rad/s) these rows are far narrower than the spread
the dynamics give the particles: weighing alone leaves the particles where the model (eq. 9,
or the kinematic ``dvX/dt = ax + vY r`` with its small ax errors) takes them, a few particles
carry all the weight, the filter resamples at almost every step, and the particles are chosen
by how well their vX and r match those two sensors rather than by the ax / ay rows.

With ``state_proposal = measured`` the random walk ``v ~ N(0, Q)``, ``Q = q^2 Ts`` (``q`` the
``state_jitter_*`` of the state), of each measured state ``x_j`` is drawn from the locally
optimal proposal given its measurement (Doucet, Godsill & Andrieu, "On sequential Monte Carlo
sampling methods for Bayesian filtering", Stat. Comput. 10, 2000, Sec. II-D: linear-Gaussian
observation), with the measurement offset (bias) ``b ~ N(b_hat, P_jj)`` of the particle
(eq. 29):

    p(x_j | x_j,pred, y_j) = N(x_j,pred + K nu, Q (1 - K)),   K = Q / S,
    nu = y_j - x_j,pred - b_hat,   S = Q + P_jj + R_jj,
    incremental weight  p(y_j | x_j,pred) = N(nu; 0, S).

These rows are then Gaussian (exact: they carry no ``d w`` term, so Approximation 1 of the
paper is needed only for the other rows), and the remaining rows (ax / ay, or ay alone in the
kinematic model) are weighed with the marginal of the paper's Student-t (eq. 35) on those rows,
at the new state:

    q_k = q_{k-1} prod_j N(nu_j; 0, S_j) St(e_bar_rest; mu_e_rest, Lambda~_e_rest, nu~),

the exact importance weight of this proposal for the factorized likelihood
``prod_j N(y_j; x_j + b_j, P_jj + R_jj) St(y_rest | x)`` (the density of the draw cancels).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tire_estimation.core import niw
from tire_estimation.core.arrays import F64


@dataclass(frozen=True)
class StateProposal:
    """Result of :func:`measured_state_proposal`, per particle.

    Attributes:
        state: the state drawn from the proposal, (N,).
        log_weight: log N(nu; 0, S), the incremental log weight of the measurement, (N,).
        nis: normalized squared innovation nu^2 / S, (N,).
    """

    state: F64
    log_weight: F64
    nis: F64


def measured_state_proposal(
    state_pred: F64,
    measured: float,
    offset: F64 | float,
    offset_var: F64 | float,
    noise_var: float,
    process_var: float,
    rng: np.random.Generator,
) -> StateProposal:
    """Draw a directly measured state given its measurement (module docstring), vectorized.

    Units are those of the state (yaw rate: rad/s; speed: m/s).

    Args:
        state_pred: predicted state x_pred (eq. 9 without the random walk), (N,).
        measured: the measurement y = x + b + e.
        offset: each particle's offset (bias) estimate b_hat, (N,) or scalar.
        offset_var: its variance P, (N,) or scalar.
        noise_var: measurement noise variance R.
        process_var: variance Q of the state's random walk over this step.
        rng: generator of the draw.
    """
    # y = x + b + e (eq. 12 gyro row; speed row of the kinematic model); x = x_pred + v
    nu = measured - state_pred - offset
    # S = Q + P + R (innovation variance given x_pred)
    s = process_var + offset_var + noise_var
    # K = Q / S
    k = process_var / s
    # p(x | x_pred, y) = N(x_pred + K nu, Q (1 - K))   (Doucet et al. 2000, Sec. II-D)
    std = np.sqrt(process_var * (1.0 - k))
    x = state_pred + k * nu + std * rng.standard_normal(np.shape(nu))
    nis = nu * nu / s
    # incremental weight p(y | x_pred) = N(nu; 0, S)
    log_w = -0.5 * (np.log(2.0 * math.pi * s) + nis)
    return StateProposal(state=x, log_weight=log_w, nis=nis)


def marginal_maha_logdet(z: F64, shape: F64, rows: tuple[int, ...] = (0, 1)) -> tuple[F64, F64]:
    """Squared Mahalanobis distance and log det of the ``rows`` x ``rows`` block of the shape.

    ``z`` (N, 3) = e_bar - mu_e, ``shape`` (N, 3, 3) = Lambda~_e of eq. (35), ``rows`` one or
    two row indices. The marginal of a multivariate Student-t on some components is the
    Student-t with the same dof and the sub-block of the shape, so
    ``niw.student_t_log_density(maha, logdet, nu~, len(rows))`` is the density of those rows.
    Returns two (N,) arrays.
    """
    if len(rows) == 1:
        (i,) = rows
        s00 = shape[:, i, i]
        return z[:, i] ** 2 / s00, np.log(s00)
    if len(rows) != 2:
        raise ValueError(f"rows must be one or two indices, got {rows}")
    i, j = rows
    s00, s01, s11 = shape[:, i, i], shape[:, i, j], shape[:, j, j]
    det = s00 * s11 - s01 * s01
    z0, z1 = z[:, i], z[:, j]
    # z^T B^-1 z with B^-1 = [[s11, -s01], [-s01, s00]] / det
    maha = (s11 * z0 * z0 - 2.0 * s01 * z0 * z1 + s00 * z1 * z1) / det
    return maha, np.log(det)


def marginal_log_likelihood(
    z: F64, shape: F64, dof: F64 | float, rows: tuple[int, ...] = (0, 1)
) -> F64:
    """Log of the Student-t (eq. 35) marginal of the measurement rows ``rows``, (N,).

    See :func:`marginal_maha_logdet`.
    """
    maha, logdet = marginal_maha_logdet(z, shape, rows)
    # eq. (36) restricted to the rows that carry d w (Student-t marginal, same dof)
    return niw.student_t_log_density(maha, logdet, dof, len(rows))


__all__ = [
    "StateProposal",
    "marginal_log_likelihood",
    "marginal_maha_logdet",
    "measured_state_proposal",
]
