"""What the stiffness MPF (Algorithm 1, Berntorp & Di Cairano, IEEE TCST 2018) hands out: its
estimate and the measured proposal's result."""

from __future__ import annotations

from dataclasses import dataclass

from tire_estimation.core.arrays import F64


@dataclass(frozen=True)
class MpfEstimate:
    """Weighted estimates of Algorithm 1 (eq. 27, 42).

    Attributes:
        stiffness: C_n + mu_hat (eq. 7, 27a), (3,).
        stiffness_std: sqrt(diag(Sigma_hat)) of eq. (27b), (3,).
        mean_std: std of the posterior of the mean mu, (3,).
        state: weighted mean [vX, vY, r] (eq. 42), (3,).
        state_cov: weighted covariance of the state, (3, 3).
        bias: weighted mean bias [b_ax, b_ay, b_r], (3,).
        n_eff: effective sample size before the last resampling decision.
    """

    stiffness: F64
    stiffness_std: F64
    mean_std: F64
    state: F64
    state_cov: F64
    bias: F64
    n_eff: float


#: What :meth:`StiffnessMpf._propose_measured` returns: the log proposal weights (N,), the rows
#: of ``y`` weighed with the Student-t, and the weighted gyro NIS.
Measured = tuple[F64, tuple[int, ...], float]
