"""Gauss-Markov GNSS position error (beyond the paper): its size and, for the MPF, its
marginalization (per-particle Kalman filters with one shared covariance)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.radius import kernels as radius_kernels
from tire_estimation.core.radius.model import gnss_bias_var, gnss_white_cov

if TYPE_CHECKING:
    from tire_estimation.core.radius.mpf_outcomes import FixPrediction


class GnssErrorSize:
    """Size of the Gauss-Markov GNSS error: a fixed stationary std, or a share of each fix's
    covariance (shared by :class:`~.mpf.RadiusMPF` and :class:`~.aug_kf.AugKf`)."""

    bias_var: float
    bias_fraction: float
    bias_tau_s: float

    def _bias_size(self, std_m: float, time_constant_s: float, fraction: float) -> bool:
        """Set the error's size from the configuration; return whether the model is on."""
        self.bias_var = float(std_m) ** 2
        self.bias_fraction = 0.0 if self.bias_var > 0.0 else float(fraction)
        self.bias_tau_s = float(time_constant_s)
        return self.bias_var > 0.0 or self.bias_fraction > 0.0

    def observe_fix_cov(self, r_m2: F64) -> None:
        """Take the Gauss-Markov error's variance from a fix's (2, 2) covariance when it is
        configured as a share of it (``sigma_b^2 = f lambda_min(R)``, :func:`gnss_bias_var`);
        called for every fix before :meth:`init_pose` or :meth:`predict_fix`. The new variance
        sets the stationary level of the time update that follows (a receiver whose reported
        accuracy changes moves the modelled error's level with it)."""
        if self.bias_fraction > 0.0:
            self.bias_var = gnss_bias_var(r_m2, self.bias_fraction)


class MarginalGnssBias(GnssErrorSize):
    """The Gauss-Markov GNSS error of the MPF, marginalized: per-particle means ``_bias``
    (2, N) and one covariance ``_bias_p`` (2, 2) shared by all particles (same linear model and
    ``R`` for all)."""

    D = 2
    bias_on: bool
    bias_dt_s: float
    _bias: F64
    _bias_p: F64

    def _bias_init(self, n: int, std_m: float, time_constant_s: float, fraction: float) -> None:
        #: the GNSS error model is on (a fixed size, or a share of each fix's covariance)
        self.bias_on = self._bias_size(std_m, time_constant_s, fraction)
        self.bias_dt_s = 0.0
        self._bias = np.zeros((self.D, n))
        self._bias_p = np.eye(self.D) * self.bias_var

    def _bias_restart(self) -> None:
        """At a pose initialization: the fix the pose was initialized from holds the current
        GNSS error."""
        self._bias[:] = 0.0
        self._bias_p = np.eye(self.D) * self.bias_var
        self.bias_dt_s = 0.0

    def _bias_phi(self) -> float:
        """``phi = exp(-dt / tau)`` over the time since the last fix (and restart the clock)."""
        dt = self.bias_dt_s
        self.bias_dt_s = 0.0
        return math.exp(-dt / self.bias_tau_s) if dt > 0.0 else 1.0

    def _bias_predict(self, phi: float, r_m2: F64) -> F64:
        """GNSS fix model with a first-order Gauss-Markov error ``b`` (beyond the paper):
        ``y = h(x) + b + v``, ``b_k = phi b_{k-1} + u``, ``phi = exp(-dt / tau)``,
        ``u ~ N(0, sigma_b^2 (1 - phi^2) I)``, ``v ~ N(0, R_w)``. ``b`` enters linearly with the
        same ``H = I`` and ``R_w`` for every particle, so it is marginalized with one Kalman
        filter per particle whose covariance ``P`` is shared (Schoen, Gustafsson & Nordlund,
        IEEE TSP 2005, the marginalized PF with a linear substructure). The fix covariance is
        taken as the total error: ``R_w = R - c I``, ``c = min(sigma_b^2, 0.9 lambda_min(R))``.

        The means' time update ``b_i = phi b_i`` and ``h_i + b_i`` run in
        :func:`radius_kernels.fix_predict`; here the shared covariance's time update
        ``P = phi^2 P + sigma_b^2 (1 - phi^2) I``. Returns ``P + R_w`` (2, 2), the covariance of
        each particle's likelihood.
        """
        p = self._bias_p
        q = self.bias_var * (1.0 - phi * phi)
        phi2 = phi * phi
        p00 = phi2 * float(p[0, 0]) + q
        p01 = phi2 * float(p[0, 1])
        p11 = phi2 * float(p[1, 1]) + q
        self._bias_p = np.array([[p00, p01], [p01, p11]])
        r_white = gnss_white_cov(r_m2, self.bias_var)
        return self._bias_p + r_white

    def _bias_update(self, y_m: F64, pred: FixPrediction) -> None:
        """Measurement update of every particle's bias filter (before any resampling):
        ``K = P S^-1``, ``b_i += K (y - h_i - b_i)``, ``P = P - K P``, ``S = P + R_w``
        (closed-form 2x2 inverse; the means in :func:`radius_kernels.bias_correct`)."""
        if not self.bias_on or pred.likelihood_cov_m2 is None:
            return
        p = self._bias_p
        sm = pred.likelihood_cov_m2
        s00, s01, s11 = float(sm[0, 0]), float(sm[0, 1]), float(sm[1, 1])
        det = s00 * s11 - s01 * s01
        i00, i01, i11 = s11 / det, -s01 / det, s00 / det
        p00, p01, p11 = float(p[0, 0]), float(p[0, 1]), float(p[1, 1])
        # K = P S^-1 (P and S symmetric; K in general not)
        k00 = p00 * i00 + p01 * i01
        k01 = p00 * i01 + p01 * i11
        k10 = p01 * i00 + p11 * i01
        k11 = p01 * i01 + p11 * i11
        radius_kernels.bias_correct(
            self._bias, pred.h, float(y_m[0]), float(y_m[1]), k00, k01, k10, k11
        )
        # P = P - K P (= P - P S^-1 P, symmetric)
        n00 = p00 - (k00 * p00 + k01 * p01)
        n01 = p01 - (k00 * p01 + k01 * p11)
        n11 = p11 - (k10 * p01 + k11 * p11)
        self._bias_p = np.array([[n00, n01], [n01, n11]])

    def _bias_anchor(self, s_inv: F64, innovation_m: F64) -> None:
        """The bias filters take their share of the mean innovation of an anchoring (pose and
        bias uncorrelated): ``b += P S^-1 innovation``, ``P -= P S^-1 P``."""
        p = self._bias_p
        self._bias += (p @ s_inv @ innovation_m)[:, None]
        self._bias_p = p - p @ s_inv @ p
