"""Outcomes of the radius MPF's updates and its estimate (:mod:`.mpf`)."""

from __future__ import annotations

from dataclasses import dataclass

from tire_estimation.core import niw
from tire_estimation.core.arrays import F64


@dataclass(frozen=True)
class FixPrediction:
    """Predicted GNSS antenna position of the particle cloud.

    Attributes:
        h: per-particle predicted antenna position (east, north), (2, N), m.
        innovation_m: measurement minus the weighted mean prediction, (2,), m.
        innovation_cov_m2: weighted cloud covariance of ``h`` plus ``R``, (2, 2), m^2.
        nis: normalized innovation squared, ``innovation' S^-1 innovation``.
    """

    h: F64
    innovation_m: F64
    innovation_cov_m2: F64
    nis: float
    #: covariance each particle's likelihood uses: ``R``, or with the GNSS bias ``P_b + R_w``
    likelihood_cov_m2: F64 | None = None


@dataclass(frozen=True)
class VelocityUpdate:
    """Outcome of a GNSS velocity update (:meth:`RadiusMPF.update_velocity`).

    Attributes:
        innovation_m_s: measured minus the weighted mean predicted velocity (east, north), m/s.
        innovation_cov_m2_s2: cloud spread of the prediction plus the noise (2, 2), m^2/s^2.
        nis: normalized innovation squared.
        log_likelihood: log of the weighted mean likelihood (``-inf`` when not applied).
        accepted: the weights were updated (false: gated out).
    """

    innovation_m_s: F64
    innovation_cov_m2_s2: F64
    nis: float
    log_likelihood: float
    accepted: bool


@dataclass(frozen=True)
class MpfEstimate:
    """Weighted summary of the MPF.

    Attributes:
        pose: ``[east_m, north_m, yaw_rad]`` weighted mean (circular mean for the yaw), (3,).
        pose_cov: covariance of the pose, (3, 3).
        radius: MMSE of the NiW statistics (eq. 30), see :class:`niw.NiwEstimate`.
        n_eff: effective sample size.
        resample_count: resamplings since construction.
    """

    pose: F64
    pose_cov: F64
    radius: niw.NiwEstimate
    n_eff: float
    resample_count: int
