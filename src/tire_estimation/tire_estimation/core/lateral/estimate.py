"""Lateral-state estimates shared by the lateral estimators (SI units, REP-103 body axes)."""

from __future__ import annotations

from dataclasses import dataclass

from tire_estimation.core.arrays import F64

#: Source name of the tyre-force Kalman filter (Tuononen 2009).
TYRE_FORCE_SOURCE = "tyre_force_kf"


@dataclass(frozen=True)
class LateralState:
    """Planar velocity state of one point of the body, in body axes.

    The point is the estimator's: ``base_link`` (centre of the rear axle) for
    :class:`LateralEstimate`, the centre of gravity for the linear single-track KF.

    Attributes:
        t_ns: time of the estimate, ns; 0 before the first estimate.
        vx_m_s: forward speed, m/s.
        vy_m_s: lateral velocity of the point, m/s.
        yaw_rate_rad_s: yaw rate r, rad/s (counter-clockwise positive).
        sideslip_rad: atan2(vy, vx), rad.
        covariance: (3, 3) covariance of [vx m/s, vy m/s, r rad/s], SI units squared.
    """

    t_ns: int
    vx_m_s: float
    vy_m_s: float
    yaw_rate_rad_s: float
    sideslip_rad: float
    covariance: F64


@dataclass(frozen=True)
class LateralEstimate(LateralState):
    """Lateral state of ``base_link`` (centre of the rear axle) in base_link axes.

    Attributes (besides those of :class:`LateralState`; vy is vy_cg - lr r):
        axle_lateral_force_n: (2,) [front, rear] axle lateral force of the filter, N.
        linearity: relay state: ``linear``, ``nonlinear`` or ``unknown``.
        source: name of the estimator.
    """

    axle_lateral_force_n: F64
    linearity: str
    source: str = TYRE_FORCE_SOURCE
