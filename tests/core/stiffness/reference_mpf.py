"""NumPy reference of Algorithm 1's compiled IMU step (Berntorp & Di Cairano, IEEE TCST 2018).

:class:`NumpyMpf` is :class:`~tire_estimation.core.stiffness.mpf.StiffnessMpf` with the steps
that the production filter runs in the compiled kernels (``core.stiffness.kernels``) written as
vectorized NumPy over the particles with the functions of ``core.stiffness.student_t``: the
same filter and random stream, equal to rounding (test_kernels.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw, resampling
from tire_estimation.core.stiffness import mat3
from tire_estimation.core.stiffness.model import Linearized
from tire_estimation.core.stiffness.mpf import StiffnessMpf
from tire_estimation.core.stiffness.student_t import (
    NE,
    NW,
    bias_update,
    conditional_predictive,
    freeze_component,
    information_fraction,
    likelihood_params,
    mahalanobis,
    sample_student_t,
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
        freeze_cx = freeze_before is not None
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
        if not np.all(np.isfinite(self.weights)):
            self.weights = np.full(self.n, 1.0 / self.n)
        beta = 0.0
        if learn and self.config.niw_update != "sampled":
            comps = self._learned_components(freeze_cx)
            beta = float(
                self.weights @ information_fraction(lp.w_shape, lin.d, lp.shape_inv, comps)
            )
        # line 8-10: resample and copy the statistics
        idx = self._resample_if_needed()
        if idx is not None:
            self._take(idx)
            if freeze_before is not None:
                freeze_before.take(idx)
            lin = Linearized(rate=lin.rate[idx], a=lin.a[idx], h=lin.h[idx], d=lin.d[idx])
            e_bar, r_cov, lp, maha = e_bar[idx], r_cov[idx], lp.take(idx), maha[idx]
        # line 17: sample w_k from the conditional predictive (39)-(41); Sec. V projection
        cp = conditional_predictive(self.stats, lin.d, e_bar, lp, maha, NE)
        w = np.clip(sample_student_t(cp, self.rng), self.lower, self.upper)
        if learn:
            if self.config.niw_update == "sampled":
                # line 4: eq. (19) with w_bar = w_k (Remark 3)
                niw.measurement_update(self.stats, w)
            else:
                g_loc, g_w, g_new = self._niw_gains(float(self.stats.gamma), beta)
                niw.measurement_update_split(self.stats, w, cp.loc, g_loc, g_w, g_new)
            np.clip(self.stats.mean, self.lower, self.upper, out=self.stats.mean)
            if freeze_before is not None:
                freeze_component(self.stats, freeze_before, 0)
        # line 15: eq. (30) with mu_{k|k} and Sigma_{k|k} = Lambda / (nu - 4)
        sigma = self.stats.scale / (np.asarray(self.stats.dof) - NW - 1.0)
        d_s = mat3.soa(lin.d)
        extra = mat3.aos(mat3.mm_bt(mat3.mm(d_s, mat3.soa(sigma)), d_s))
        resid = e_bar - np.einsum("nij,nj->ni", lin.d, self.stats.mean)
        self.bias_updated = self.bias_gate_open(learn)
        if self.bias_updated:
            bias_update(self.b, self.p_bias, resid, extra, self._bias_noise(r_cov), lp.dof)
        # line 18 (first half): derivative for eq. (9)
        self.rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w)
