"""NumPy reference of Algorithm 1's compiled IMU step (Berntorp & Di Cairano, IEEE TCST 2018).

:class:`NumpyMpf` is :class:`~tire_estimation.core.stiffness.mpf.StiffnessMpf` with the steps
that the production filter runs in the compiled kernels (``core.stiffness.kernels``) written as
vectorized NumPy over the particles with the functions of ``core.stiffness.model``,
``core.stiffness.student_t``, ``core.niw`` and ``core.resampling``, and the same random
numbers (:func:`draws`, in the kernels' order): the same filter, equal to rounding
(test_kernels.py).
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import kernel_random as kr
from tire_estimation.core import niw, resampling
from tire_estimation.core.stiffness import mpf as stiffness_mpf
from tire_estimation.core.stiffness.mat3 import aos, mm, mm_bt, soa
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
    niw_mean_gains,
    student_t_draw,
    yaw_rate_nis,
)

F64 = NDArray[np.float64]


@numba.njit(cache=True)
def draws(
    state: NDArray[np.uint64], n: int, gamma_shape: float, resample: bool
) -> tuple[float, F64, F64]:
    """The variates of ``kernels.update`` in its order: a uniform (if it resamples), then per
    particle three normals and one ``Gamma(gamma_shape)``."""
    st = kr.load(state)
    u0 = 0.0
    if resample:
        u0, st = kr.uniform(st)
    z = np.empty((n, 3))
    g = np.empty(n)
    for i in range(n):
        z[i, 0], st = kr.normal(st)
        z[i, 1], st = kr.normal(st)
        z[i, 2], st = kr.normal(st)
        g[i], st = kr.gamma(st, gamma_shape)
    return u0, z, g


def jitter_normals(rng: np.random.Generator, n: int) -> F64:
    """The normals (N, 3) of ``kernels.predict``'s jitter."""
    out = np.empty(3 * n)
    kr.fill_normal(kr.kernel_state(rng), out)
    return out.reshape(n, 3)


class NumpyMpf(StiffnessMpf):
    """:class:`StiffnessMpf` with its compiled steps in NumPy (``state_proposal`` = ``prior``)."""

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        jitter = np.where(self._drawn_in_update, 0.0, self.jitter)
        # eq. (9) x_{k+1} = f + g w_k with the stored rate = rate_n + a w_k, jitter (iii)
        self.x += dt_s * self.rate
        if np.any(jitter > 0.0):
            self.x += jitter_normals(self.rng, self.n) * (jitter * np.sqrt(dt_s))
        self.x[:, 0] = np.maximum(self.x[:, 0], 0.0)
        self._before_learning = None
        if learn:
            if learn_cx is False:
                self._before_learning = self.stats.copy()
            # eq. (20) gamma/lambda, mu, lambda nu, lambda Lambda
            niw.time_update(self.stats, self.config.forgetting)
        # eq. (29) P_{k+1} = P_k + Q Ts
        self.p_bias += self.q_rate * dt_s
        self._dt_s = dt_s

    def _update_compiled(
        self,
        y: F64,
        delta_rad: float,
        wheel_speed_m_s: tuple[float, float],
        learn: bool,
        vx_m_s: float | None,
        freeze_cx: bool,
    ) -> None:
        before = self._before_learning if freeze_cx else None
        if freeze_cx and before is None:
            before = self.stats.copy()
        self._before_learning = None
        lin, y, r_cov = self._linearize(y, delta_rad, wheel_speed_m_s, vx_m_s)
        # e_bar = y - h - b_{k|k-1} (eq. 12)
        e_bar = y[None, :] - lin.h - self.b
        lp = likelihood_params(self.stats, lin.d, r_cov, self.p_bias)
        self._track_yaw_rate_nis(yaw_rate_nis(e_bar, lp, self.weights))
        # Algorithm 1 line 3: eq. (36)
        maha = mahalanobis(e_bar - lp.loc, lp.shape_inv)
        self.log_w = self.log_w + niw.student_t_log_density(maha, lp.logdet, lp.dof, NE)
        # line 6-7: normalize, N_eff
        self.weights, log_pred = resampling.normalize_log_weights(self.log_w)
        self._add_evidence(log_pred)
        self.n_eff = resampling.ess(self.weights)
        beta = 0.0
        if learn and self.config.niw_update != "sampled":
            comps = self._learned_components(before is not None)
            beta = float(
                self.weights @ information_fraction(lp.w_shape, lin.d, lp.shape_inv, comps)
            )
        # the variates of this step (kernels.update's order)
        resample = self.n_eff <= stiffness_mpf.RESAMPLE_THRESHOLD * self.n
        dof_c = float(lp.dof) + NE
        u0, z, g = draws(kr.kernel_state(self.rng), self.n, 0.5 * dof_c, resample)
        # line 8-10: systematic resampling and copy of the statistics
        sigma_noise = self._bias_noise(r_cov)
        if resample:
            idx = resampling._inverse_cdf(self.weights, (np.arange(self.n) + u0) / self.n)
            self.weights = np.full(self.n, 1.0 / self.n)
            self.resample_count += 1
            self._take(idx)
            if before is not None:
                before.take(idx)
            lin = type(lin)(rate=lin.rate[idx], a=lin.a[idx], h=lin.h[idx], d=lin.d[idx])
            e_bar, lp, maha = e_bar[idx], lp.take(idx), maha[idx]
            sigma_noise = sigma_noise[idx]
        self.log_w = resampling.log_of_weights(self.weights)
        # line 17: w_k from the conditional predictive (39)-(41); Sec. V projection
        cp = conditional_predictive(self.stats, lin.d, e_bar, lp, maha, NE)
        w = np.clip(student_t_draw(cp, z, 2.0 * g), self.lower, self.upper)
        if learn:
            if self.config.niw_update == "sampled":
                niw.measurement_update(self.stats, w)
            else:
                g_loc, g_w, g_new = niw_mean_gains(
                    float(self.stats.gamma), beta, self.config.niw_update
                )
                self.information_share = beta
                niw.measurement_update_split(
                    self.stats, w, cp.loc, g_loc, g_w, min(g_new, self._gamma0)
                )
            np.clip(self.stats.mean, self.lower, self.upper, out=self.stats.mean)
            if before is not None:
                freeze_component(self.stats, before, 0)
        # line 15: eq. (30) with mu_{k|k} and Sigma_{k|k} = Lambda / (nu - 4)
        sigma = self.stats.scale / (float(self.stats.dof) - NW - 1.0)
        d_s = soa(lin.d)
        extra = aos(mm_bt(mm(d_s, soa(sigma)), d_s))
        resid = e_bar - np.einsum("nij,nj->ni", lin.d, self.stats.mean)
        self.bias_updated = self.bias_gate_open(learn)
        if self.bias_updated:
            bias_update(self.b, self.p_bias, resid, extra, sigma_noise, lp.dof)
        # line 18 (first half): derivative for eq. (9)
        self.rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w)
