"""Filters behind the stiffness front-end: their interface, shared settings and model.

:class:`~tire_estimation.core.stiffness.frontend.StiffnessFrontEnd` checks the inputs, decides
when the stiffness is learned (Sec. V) and drives one filter object through
:class:`StiffnessFilter`: one :class:`Measurement` per IMU sample and the learning flags.
Algorithm 1 (Berntorp & Di Cairano, IEEE TCST 2018; ``core.stiffness.mpf``) is one such filter,
the point-mass filter of ``core.stiffness.grid`` another, and the paper's baselines (AUGPF, EKF,
KF + RLS, ``evaluation.stiffness_baselines``) the others.

The filters other than Algorithm 1 share the settings of :class:`BaselineConfig` with it and use
the single-track model of ``core.stiffness.model`` (eq. 1-12, with ``w = C - C_n``, eq. 7) in the
form of :func:`model`: state derivative and measurement mean per row of states and stiffness
deviations. With ``friction_coefficient`` mu > 0 that is Algorithm 1's friction-limited lateral
tyre (peak at the friction limit): ``Fy = mu Fz tanh(C alpha / (mu Fz))`` per axle,
i.e. ``C phi(alpha)`` with ``alpha_s = mu Fz / C`` at each row's own stiffness, in the shape
Algorithm 1 is given (``tyre_shape``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.config import BaselineConfig
from tire_estimation.core.stiffness.model import (
    SingleTrackParams,
    linearize,
    saturation_slip_at,
    stiffness_bounds,
)

#: Central-difference steps of the numeric Jacobians in [vX m/s, vY m/s, r rad/s].
JACOBIAN_STEP = np.array([1e-3, 1e-3, 1e-4])


@dataclass(frozen=True)
class Measurement:
    """One IMU step as the front-end hands it to a filter.

    Attributes:
        y: [ax, ay (roll compensated), r] of eq. (12), (3,).
        delta_rad: road-wheel angle, rad.
        wheel_speed_m_s: (front, rear) axle mean ``R_w omega``, m/s (both the measured speed
            without wheel speeds).
        speed_m_s: measured speed (undriven axle, or the velocity input), m/s.
        vx_measured: ``speed_m_s`` is a measured vX that replaces the estimate (no wheels).
    """

    y: F64
    delta_rad: float
    wheel_speed_m_s: tuple[float, float]
    speed_m_s: float
    vx_measured: bool


@dataclass(frozen=True)
class FilterEstimate:
    """Point estimate of a filter behind the front-end.

    Attributes:
        stiffness: [Cx, Cy_f, Cy_r], (3,).
        stiffness_std: std of the stiffness the filter reports, (3,).
        state: [vX, vY, r], (3,).
        state_cov: covariance of the state, (3, 3).
        n_eff: effective sample size (nan for the Kalman filters).
        bias: [b_ax, b_ay, b_r] where the filter estimates the IMU biases, else None.
    """

    stiffness: F64
    stiffness_std: F64
    state: F64
    state_cov: F64
    n_eff: float
    bias: F64 | None = None


class StiffnessFilter:
    """Interface of a filter driven by
    :class:`~tire_estimation.core.stiffness.frontend.StiffnessFrontEnd`.

    The front-end calls :meth:`initialize` once it has a speed (and after a gap, which clears
    :attr:`initialized`), then per IMU sample :meth:`predict` (not on the first) and
    :meth:`update`, with ``learn`` (lateral excitation, Sec. V) and ``learn_cx`` (longitudinal
    excitation as well).
    """

    initialized: bool = False

    def _set_model(self, config: BaselineConfig, params: SingleTrackParams) -> None:
        """Keep ``config`` and ``params``, the nominal stiffness ``C_n`` with its bounds, and
        ``R`` of eq. (12)."""
        self.config = config
        self.params = params
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower, self.upper = stiffness_bounds(self.nominal)
        self.r_cov = imu_noise_cov(config)

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """Start at state ``x0`` (3,) with std ``x0_std`` (3,) and the prior stiffness."""
        raise NotImplementedError

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """Time update by ``dt_s`` with the inputs of the last :meth:`update`."""
        raise NotImplementedError

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """Measurement update at one IMU sample."""
        raise NotImplementedError

    def estimate(self) -> FilterEstimate:
        """Current point estimate."""
        raise NotImplementedError


def friction_saturation(p: SingleTrackParams, w: F64) -> tuple[F64, F64] | None:
    """Per-row saturation slips ``alpha_s = mu Fz / C`` at ``C = C_n + w``, or None (linear).

    ``w`` (N, 3) -> two (N,) arrays (``stiffness_model.saturation_slip_at``); None where ``p``
    has the linear tyre (``friction_coefficient`` 0).
    """
    if p.saturation_slip_front_rad <= 0.0 and p.saturation_slip_rear_rad <= 0.0:
        return None
    c_n = np.asarray(p.nominal, dtype=float)
    return saturation_slip_at(p, c_n[1] + w[:, 1], c_n[2] + w[:, 2])


def model(
    x: F64, w: F64, delta_rad: float, wheel_speed_m_s: tuple[float, float], p: SingleTrackParams
) -> tuple[F64, F64, F64, F64]:
    """State derivative and measurement mean with stiffness ``C_n + w``, per row.

    ``x`` (N, 3), ``w`` (N, 3) -> ``rate`` (N, 3), ``y_hat`` (N, 3), ``a`` (N, 3, 3) and ``d``
    (N, 3, 3) of :func:`~tire_estimation.core.stiffness.model.linearize`. With the
    friction-limited tyre ``a`` and ``d`` are taken at each row's own ``alpha_s = mu Fz / C``
    (:func:`friction_saturation`), so ``rate`` and ``y_hat`` are the exact model at ``w``
    while ``a`` and ``d`` are secants, not derivatives.
    """
    lin = linearize(x, delta_rad, wheel_speed_m_s, p, friction_saturation(p, w))
    # eq. (9)-(10): dx/dt = rate_n(x) + a(x) w
    rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w)
    # eq. (12): y = h(x) + d(x) w + e
    y_hat = lin.h + np.einsum("nij,nj->ni", lin.d, w)
    return rate, y_hat, lin.a, lin.d


def imu_noise_cov(config: BaselineConfig) -> F64:
    """``R`` of eq. (12): diag(sigma_a^2, sigma_a^2, sigma_g^2), (3, 3)."""
    return np.diag(
        [
            config.accel_noise_std_m_s2**2,
            config.accel_noise_std_m_s2**2,
            config.gyro_noise_std_rad_s**2,
        ]
    )


__all__ = [
    "JACOBIAN_STEP",
    "BaselineConfig",
    "FilterEstimate",
    "Measurement",
    "StiffnessFilter",
    "friction_saturation",
    "imu_noise_cov",
    "model",
]
