"""NumPy reference of Algorithm 1's compiled IMU step (Berntorp & Di Cairano, IEEE TCST 2018).

:class:`NumpyMpf` is :class:`~tire_estimation.core.stiffness.mpf.StiffnessMpf` with the steps
that the production filter runs in the compiled kernels (``core.stiffness.kernels``) written as
vectorized NumPy over the particles with the functions of ``core.stiffness.student_t`` (lines
8-18 of Algorithm 1 are the production filter's NumPy steps, which the measured proposal
runs too): the same filter and random stream, equal to rounding (test_kernels.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw, resampling
from tire_estimation.core.stiffness.model import Linearized
from tire_estimation.core.stiffness.mpf import StiffnessMpf
from tire_estimation.core.stiffness.student_t import (
    NE,
    likelihood_params,
    mahalanobis,
    yaw_rate_nis,
)

F64 = NDArray[np.float64]


def bias_predict(p_bias: F64, q_cov: F64) -> None:
    """Kalman prediction of the random-walk bias (eq. 29), in place; ``p_bias`` (N, 3, 3)."""
    # eq. (29) b_{k+1|k} = b_{k|k}, P_{k+1} = P_k + Q
    p_bias += q_cov


class NumpyMpf(StiffnessMpf):
    """:class:`StiffnessMpf` with its compiled steps in NumPy (``state_proposal`` = ``prior``)."""

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        jitter = np.where(self._drawn_in_update, 0.0, self.jitter)
        # eq. (9) x_{k+1} = f + g w_k with the stored rate = rate_n + a w_k, jitter (iii)
        self.x += dt_s * self.rate
        if np.any(jitter > 0.0):
            self.x += self.rng.standard_normal((self.n, 3)) * (jitter * np.sqrt(dt_s))
        self.x[:, 0] = np.maximum(self.x[:, 0], 0.0)
        self._before_learning = None
        if learn:
            if learn_cx is False:
                self._before_learning = self.stats.copy()
            # eq. (20) gamma/lambda, mu, lambda nu, lambda Lambda
            niw.time_update(self.stats, self.config.forgetting)
        # eq. (29) P_{k+1} = P_k + Q
        bias_predict(self.p_bias, self.q_rate * dt_s)
        self._dt_s = dt_s

    def _update_compiled(
        self,
        y: F64,
        lin: Linearized,
        r_cov: F64,
        learn: bool,
        freeze_before: niw.NiwStats | None,
    ) -> None:
        # e_bar = y - h - b_{k|k-1} (eq. 12)
        e_bar = y[None, :] - lin.h - self.b
        lp = likelihood_params(self.stats, lin.d, r_cov, self.p_bias)
        self._track_yaw_rate_nis(yaw_rate_nis(e_bar, lp, self.weights))
        # Algorithm 1 line 3: eq. (36)
        maha = mahalanobis(e_bar - lp.loc, lp.shape_inv)
        self.log_w += niw.student_t_log_density(maha, lp.logdet, lp.dof, NE)
        # line 6-7: normalize, N_eff
        self.weights, log_pred = resampling.normalize_log_weights(self.log_w)
        self._add_evidence(log_pred)
        self.n_eff = resampling.ess(self.weights)
        # lines 8-18 are the production filter's NumPy steps (shared with the measured path)
        self._sample_and_learn(lin, e_bar, r_cov, lp, maha, NE, learn, freeze_before)
