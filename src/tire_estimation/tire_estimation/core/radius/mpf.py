"""Marginalized particle filter (MPF) for the rear tyre radii (Lundquist et al., T-ITS 2014).

The pose ``[east, north, yaw]`` is carried by ``N`` particles; the radius errors are the process
noise ``w ~ N(mu, Sigma)`` of the motion model (eq. 12) whose unknown ``mu, Sigma`` are
marginalized with per-particle Normal-inverse-Wishart statistics (:mod:`.niw`). One
:meth:`RadiusMPF.predict` per wheel-speed sample performs lines 9-11 and 13 of Table I (NiW time
update, Student-t draw, pose propagation, NiW update); :meth:`RadiusMPF.update` performs lines
12 and 15-16 (GNSS likelihood weights, normalization, resampling).

Performance: predictions are queued and processed in blocks (at the next GNSS fix, estimate or
state access, or after ``block_size`` samples) by the compiled kernel of :mod:`.radius_kernels`:
one draw of ``(mu, Sigma)`` per particle and block from the NiW statistics, Gaussian radius
errors for every sample of the block, the NiW recursion (eq. 23-24) and the pose propagation
(eq. 3), in one pass over the particles. See :meth:`RadiusMPF._draw_block` for why this samples
the same law as Table I (exactly without forgetting, and for blocks of one sample).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from tire_estimation.core import niw
from tire_estimation.core.arrays import F64
from tire_estimation.core.kernel_random import kernel_state
from tire_estimation.core.radius import kernels as radius_kernels
from tire_estimation.core.radius.gnss_bias import MarginalGnssBias
from tire_estimation.core.radius.model import RL, RR, RadiusMotionModel
from tire_estimation.core.radius.mpf_outcomes import FixPrediction, MpfEstimate, VelocityUpdate
from tire_estimation.core.resampling import ess, systematic

_R = TypeVar("_R")


#: prior expected fast radius variation sqrt(E[Sigma]) of the NiW prior (eq. 22c), m: 1 mm,
#: a third of the default prior std of the mean; with the weak :data:`PRIOR_DOF` the learned
#: value soon replaces it
PRIOR_RADIUS_NOISE_STD_M = 0.001

#: prior inverse-Wishart degrees of freedom nu_0 (eq. 22c, > d + 1 = 3): a weak prior, worth a
#: few samples
PRIOR_DOF = 10.0

#: resample when N_eff / N falls below this (Table I line 16)
RESAMPLE_THRESHOLD = 0.5

#: Liu & West (2001) shrinkage ``a`` of the NiW means at each resampling (beyond the paper):
#: keeps the mean and covariance of the cloud of means and refreshes the duplicates with a
#: kernel of ``1 - a^2`` = 4 % of that covariance
KERNEL_SHRINKAGE = 0.98


def _mutates(method: Callable[..., _R]) -> Callable[..., _R]:
    """Count changes of the filter state (``version``) so estimates can be cached."""

    @functools.wraps(method)
    def wrapper(self: RadiusMPF, *args: Any, **kwargs: Any) -> _R:
        self.version += 1
        return method(self, *args, **kwargs)

    return wrapper


class RadiusMPF(MarginalGnssBias):
    """MPF over the pose with NiW-marginalized rear radius errors (``d = 2``).

    Args:
        model: the motion model.
        n_particles: ``N``.
        prior_mean_m: prior mean radius errors (2,), m.
        prior_mean_std_m: prior std of the mean radius errors (gamma_0 = (std / noise_std)^2), m.
        prior_noise_std_m: prior sqrt(E[Sigma]) (per wheel), m.
        prior_dof: nu_0 (> 3).
        forgetting_factor: lambda of eq. (24).
        position_noise_m_sqrt_s: additive pose random walk on east/north (applied at each fix
            with the variance accumulated since the last fix), m/sqrt(s).
        yaw_noise_rad_sqrt_s: same for the heading, rad/sqrt(s).
        mean_random_walk_m_sqrt_s: random walk of each particle's NiW mean, applied with the pose
            noise (beyond the paper), m/sqrt(s).
        kernel_shrinkage: Liu-West shrinkage ``a`` of the NiW means at resampling (beyond the
            paper, :data:`KERNEL_SHRINKAGE`); 0 disables.
        rng: random generator (all draws).
        resample_threshold: resample (systematic) when ``N_eff < threshold * N``.
        block_size: at most this many queued predictions are processed as one block.
        gnss_bias_std_m: stationary std of a Gauss-Markov GNSS position error per axis (beyond
            the paper), m; 0: see ``gnss_bias_fraction``. See :meth:`_bias_predict`.
        gnss_bias_time_constant_s: its correlation time, s.
        gnss_bias_fraction: with ``gnss_bias_std_m`` 0, that error's variance is this share
            of each fix's covariance (:meth:`observe_fix_cov`); both 0 disable the model.
    """

    D = 2

    def __init__(
        self,
        model: RadiusMotionModel,
        n_particles: int,
        prior_mean_m: F64,
        prior_mean_std_m: float,
        prior_noise_std_m: float,
        prior_dof: float,
        forgetting_factor: float,
        position_noise_m_sqrt_s: float,
        yaw_noise_rad_sqrt_s: float,
        rng: np.random.Generator,
        mean_random_walk_m_sqrt_s: float = 0.0,
        kernel_shrinkage: float = 0.0,
        block_size: int = 64,
        gnss_bias_std_m: float = 0.0,
        gnss_bias_time_constant_s: float = 120.0,
        gnss_bias_fraction: float = 0.0,
        resample_threshold: float = RESAMPLE_THRESHOLD,
    ) -> None:
        self.model = model
        self.n = int(n_particles)
        self.rng = rng
        self.lam = float(forgetting_factor)
        self.resample_threshold = float(resample_threshold)
        self.pos_q = float(position_noise_m_sqrt_s) ** 2
        self.yaw_q = float(yaw_noise_rad_sqrt_s) ** 2
        self.mean_q = float(mean_random_walk_m_sqrt_s) ** 2
        self.kernel_a = float(kernel_shrinkage)
        self.block_size = int(block_size)
        d = self.D
        self._prior = (
            np.asarray(prior_mean_m, dtype=float).reshape(d),
            (prior_mean_std_m / prior_noise_std_m) ** 2,
            float(prior_dof),
            np.eye(d) * prior_noise_std_m**2 * (prior_dof - d - 1.0),
        )
        n = self.n
        self._east = np.zeros(n)
        self._north = np.zeros(n)
        self._yaw = np.zeros(n)
        self._speed = np.zeros(n)
        self.weights = np.full(n, 1.0 / n)
        #: incremented by every method that changes the filter state (see ``_mutates``)
        self.version = 0
        self.resample_count = 0
        self.jitter_dt_s = 0.0
        self._mu = np.empty((d, n))
        self._lam = np.empty((d, d, n))
        self._stats = self._wrap(niw.init_stats(n, *self._prior))
        #: queued predictions (dt_s, w_rl, w_rr, learn, steer or NaN), see :meth:`_flush`
        self._pending: list[tuple[float, float, float, float, float]] = []
        # Gauss-Markov GNSS error (beyond the paper), marginalized
        self._bias_init(n, gnss_bias_std_m, gnss_bias_time_constant_s, gnss_bias_fraction)

    # ------------------------------------------------------------------ state access
    # Reading any of these first processes the queued predictions.
    @property
    def east(self) -> F64:
        """Particle east positions of ``base_link`` (N,), m."""
        self._flush()
        return self._east

    @property
    def north(self) -> F64:
        """Particle north positions of ``base_link`` (N,), m."""
        self._flush()
        return self._north

    @property
    def yaw(self) -> F64:
        """Particle headings (N,), rad (ENU, 0 = east, not wrapped)."""
        self._flush()
        return self._yaw

    @property
    def speed(self) -> F64:
        """Particle speeds of the last prediction (N,), m/s."""
        self._flush()
        return self._speed

    @property
    def stats(self) -> niw.NiwStats:
        """Per-particle NiW statistics (views into the filter's buffers)."""
        self._flush()
        return self._stats

    # ------------------------------------------------------------------ initialization
    def _wrap(self, stats: niw.NiwStats) -> niw.NiwStats:
        """Copy ``stats`` into the particle-last buffers and return a view in NiW layout."""
        self._mu[...] = stats.mean.T
        self._lam[...] = stats.scale.transpose(1, 2, 0)
        return niw.NiwStats(
            mean=self._mu.T,
            gamma=np.array(float(stats.gamma)),
            dof=np.array(float(stats.dof)),
            scale=self._lam.transpose(2, 0, 1),
        )

    @_mutates
    def reset_radii(self) -> None:
        """Back to the prior NiW statistics (forget the learned radii)."""
        self._flush()
        self._stats = self._wrap(niw.init_stats(self.n, *self._prior))

    @_mutates
    def scale_radii(self, factor: float) -> float:
        """A gross scale error seen in the GNSS speed (:mod:`.speed_scale`): what was learned
        under it, the left-right split included, is suspect, so the statistics restart from
        the prior centred on the common radius (nominal plus the weighted mean error of both
        wheels) times ``factor``. Returns that radius error, m."""
        self._flush()
        r_n = self.model.nominal_radius_m
        mean = float(np.average(self._mu.mean(axis=0), weights=self.weights))
        common = (r_n + mean) * factor - r_n
        _, gamma, dof, scale = self._prior
        self._stats = self._wrap(
            niw.init_stats(self.n, np.full(self.D, common), gamma, dof, scale)
        )
        return common

    @_mutates
    def set_stats(self, stats: niw.NiwStats) -> None:
        """Replace the NiW statistics (e.g. restored from a persisted state).

        ``stats`` must have ``N`` particles, ``d = 2`` and shared (0-d) gamma and dof.
        """
        if stats.n != self.n or stats.d != self.D or np.ndim(stats.gamma) or np.ndim(stats.dof):
            raise ValueError("stats must have N particles, d = 2 and shared gamma/dof")
        self._flush()
        self._stats = self._wrap(stats)

    @_mutates
    def init_pose(self, mean: F64, cov: F64) -> None:
        """Draw the particle poses from ``N(mean, cov)`` (3,), (3, 3); uniform weights.

        Queued predictions (of the previous pose) are processed first for their effect on the
        radius statistics.
        """
        self._flush()
        chol = np.linalg.cholesky(np.asarray(cov, dtype=float) + 1e-12 * np.eye(3))
        x = np.asarray(mean, dtype=float) + self.rng.standard_normal((self.n, 3)) @ chol.T
        self._east[:] = x[:, 0]
        self._north[:] = x[:, 1]
        self._yaw[:] = x[:, 2]
        self._speed[:] = 0.0
        self.weights[:] = 1.0 / self.n
        self.jitter_dt_s = 0.0
        self._bias_restart()

    # ------------------------------------------------------------------ prediction
    def predict(
        self,
        dt_s: float,
        wheel_speed_rad_s: F64,
        learn: bool = True,
        steer_angle_rad: float | None = None,
    ) -> None:
        """Propagate over ``dt_s`` with the wheel speeds ``(4,)`` of the start of the interval.

        ``learn=True`` (Table I lines 9-11, 13): sample the radius errors from each particle's
        predictive, propagate the pose with them and update the NiW statistics.
        ``learn=False`` (estimation paused): propagate with each particle's mean radius error and
        leave the statistics untouched. ``steer_angle_rad`` selects the low-speed heading model
        (eq. 31a).

        The sample is queued; the queue is processed as one block (see :meth:`_flush`) before
        anything reads the state, so callers always see the propagated filter.
        """
        self.predict_rear(
            float(dt_s),
            float(wheel_speed_rad_s[RL]),
            float(wheel_speed_rad_s[RR]),
            learn,
            None if steer_angle_rad is None else float(steer_angle_rad),
        )

    def predict_rear(
        self,
        dt_s: float,
        rear_left_rad_s: float,
        rear_right_rad_s: float,
        learn: bool = True,
        steer_angle_rad: float | None = None,
    ) -> None:
        """:meth:`predict` with the rear wheel speeds (rad/s) as Python floats (the only wheels
        the model uses; the estimator's per-sample path)."""
        self.version += 1  # as @_mutates does (inline: this runs at every wheel-speed sample)
        self.jitter_dt_s += dt_s
        self.bias_dt_s += dt_s
        self._pending.append(
            (
                dt_s,
                rear_left_rad_s,
                rear_right_rad_s,
                1.0 if learn else 0.0,
                math.nan if steer_angle_rad is None else steer_angle_rad,
            )
        )
        if len(self._pending) >= self.block_size:
            self._flush()

    def _flush(self) -> None:
        """Process the queued predictions, one block per run of equal ``learn`` flags."""
        pend = self._pending
        if not pend:
            return
        self._pending = []
        arr = np.array(pend)
        learn = arr[:, 3] > 0.5
        if learn.all() or not learn.any():
            self._propagate(arr, bool(learn[0]))
            return
        for seg in np.split(arr, np.flatnonzero(np.diff(learn)) + 1):
            self._propagate(seg, bool(seg[0, 3] > 0.5))

    def _draw_block(self, k: int) -> tuple[F64, F64]:
        """Radius errors ``(d_rl, d_rr)``, each ``(k, N)``, of the next ``k`` learning steps.

        Table I line 10 samples each step from the Student-t predictive (eq. 27) of the
        statistics updated with the previous samples. Without forgetting, that sequence has the
        same joint law as: draw ``(mu, Sigma)`` once from the (time-updated, eq. 24) NiW, then
        ``k`` independent ``N(mu, Sigma)`` samples (exchangeability of the conjugate model), which
        is how it is drawn here. With forgetting the predictive of step ``j`` in the block is
        built from statistics discounted by ``lambda^j`` instead; for a block of ``k`` samples
        this changes the weight of the history by a factor ``lambda^k`` (0.998 for 10 samples and
        the default lambda). A block of one sample is exactly eq. (27).

        Sigma ~ iW(nu, Lambda) is drawn with the Bartlett decomposition
        (:func:`radius_kernels.draw_block`). :meth:`_propagate` draws the same way, fused with
        the NiW update and the pose propagation; this method leaves the statistics unchanged.
        """
        st = self._stats
        state = kernel_state(self.rng)
        return radius_kernels.draw_block(
            self._mu, self._lam, self.lam, float(st.gamma), float(st.dof), k, state
        )

    def _niw_block_update(self, d3: F64, d4: F64) -> None:
        """Eq. (24) + (23) applied to the samples ``(d3, d4)`` ``(k, N)`` in order, exactly
        (:func:`radius_kernels.niw_block_update`; :meth:`_propagate` fuses the same steps)."""
        st = self._stats
        g, nu = radius_kernels.niw_block_update(
            self._mu, self._lam, np.ascontiguousarray(d3), np.ascontiguousarray(d4), self.lam,
            float(st.gamma), float(st.dof),
        )  # fmt: skip
        st.gamma[...] = g
        st.dof[...] = nu

    def _propagate(self, seg: F64, learn: bool) -> None:
        """Propagate the pose over the samples ``seg`` ``(k, 5)`` = dt, w_rl, w_rr, learn,
        steer (NaN = none) with the radius errors drawn for them (Table I lines 9-11, 13, with
        the NiW update) or, paused, the NiW means (:func:`radius_kernels.propagate_block`)."""
        st = self._stats
        m = self.model
        seg = np.ascontiguousarray(seg.T)
        g, nu = radius_kernels.propagate_block(
            self._east, self._north, self._yaw, self._speed, self._mu, self._lam,
            seg[0], seg[1], seg[2], seg[4], learn, self.lam, float(st.gamma), float(st.dof),
            m.nominal_radius_m, m.track_width_m, m.wheelbase_m, kernel_state(self.rng),
        )  # fmt: skip
        st.gamma[...] = g
        st.dof[...] = nu

    # ------------------------------------------------------------------ measurement update
    def _jitter_std(self) -> tuple[float, float, float]:
        """Std of the additive pose / NiW-mean random walk accumulated since the last fix
        (roughening; the mean walk is beyond the paper), and restart the accumulation."""
        dt = self.jitter_dt_s
        self.jitter_dt_s = 0.0
        if dt <= 0.0:
            return 0.0, 0.0, 0.0
        return math.sqrt(self.pos_q * dt), math.sqrt(self.yaw_q * dt), math.sqrt(self.mean_q * dt)

    @_mutates
    def predict_fix(
        self, y_m: F64, r_m2: F64, lever_arm_m: F64, extrapolate_s: float = 0.0
    ) -> FixPrediction:
        """Predicted antenna positions (eq. 13 with a lever arm) and innovation statistics.

        ``y_m`` (2,) measured east/north; ``r_m2`` (2, 2) its covariance; ``lever_arm_m`` (2,)
        antenna (x, y) in ``base_link``; ``extrapolate_s`` from the pose time to the fix time.
        Applies the accumulated pose noise first (:func:`radius_kernels.fix_predict`).
        """
        self._flush()
        phi = self._bias_phi() if self.bias_on else 1.0
        h, mean, cov = radius_kernels.fix_predict(
            self._east, self._north, self._yaw, self._speed, self._mu, self.weights,
            *self._jitter_std(), float(lever_arm_m[0]), float(lever_arm_m[1]),
            float(extrapolate_s), kernel_state(self.rng), self._bias, phi, self.bias_on,
        )  # fmt: skip
        lik_cov = self._bias_predict(phi, r_m2) if self.bias_on else r_m2
        s_mat = cov + lik_cov
        i0 = float(y_m[0]) - float(mean[0])
        i1 = float(y_m[1]) - float(mean[1])
        # NIS with the closed-form 2x2 inverse
        s00, s01, s11 = float(s_mat[0, 0]), float(s_mat[0, 1]), float(s_mat[1, 1])
        det = s00 * s11 - s01 * s01
        nis = (s11 * i0 * i0 - 2.0 * s01 * i0 * i1 + s00 * i1 * i1) / det if det > 0 else math.inf
        innov = np.array([i0, i1])
        return FixPrediction(
            h=h, innovation_m=innov, innovation_cov_m2=s_mat, nis=nis, likelihood_cov_m2=lik_cov
        )

    @_mutates
    def update(self, y_m: F64, r_m2: F64, pred: FixPrediction) -> float:
        """Weight update with the GNSS likelihood (eq. 18, Table I line 12), normalize (line 15)
        and resample when ``N_eff < threshold N`` (line 16). Returns the log marginal likelihood.

        ``pred.h`` holds the predicted antenna positions ``(2, N)`` of :meth:`predict_fix`
        (:func:`radius_kernels.fix_reweight`).
        """
        self._flush()
        lik = r_m2 if pred.likelihood_cov_m2 is None else pred.likelihood_cov_m2
        log_norm, n_eff = radius_kernels.fix_reweight(
            self.weights, pred.h, float(y_m[0]), float(y_m[1]),
            float(lik[0, 0]), float(lik[0, 1]), float(lik[1, 1]),
        )  # fmt: skip
        self._bias_update(y_m, pred)
        if n_eff < self.resample_threshold * self.n:
            self.resample()
        return log_norm

    @_mutates
    def update_velocity(
        self,
        v_m_s: F64,
        r_m2_s2: F64,
        lever_arm_m: F64,
        yaw_rate_rad_s: float,
        lateral_std_m_s: float,
        rear_wheel_speed_rad_s: tuple[float, float],
        along_var_m2_s2: float = 0.0,
        gate_nis: float = math.inf,
        heading_offset_rad: float = 0.0,
    ) -> VelocityUpdate:
        """Weight update with a GNSS Doppler velocity (beyond the paper), then normalize and
        resample when ``N_eff < threshold N``.

        ``v_m_s`` (2,) measured east/north velocity of the antenna, ``r_m2_s2`` (2, 2) its
        covariance; ``lever_arm_m`` (2,) antenna (x, y) in ``base_link``; ``yaw_rate_rad_s`` the
        (common) yaw rate for the lever-arm term; ``rear_wheel_speed_rad_s`` (w3, w4) the rear
        wheel speeds at the velocity's time; ``along_var_m2_s2`` extra variance of the speed
        (e.g. from an uncertain latency while accelerating); ``heading_offset_rad`` is added to
        each particle's heading to get the heading at the velocity's time (a velocity that
        describes ``tau`` seconds before the pose: ``-r tau``).

        Model (rigid body; ``base_link`` moves with ``[v, u]`` in its own axes): the antenna
        moves with ``R(psi) [v - r l_y, u + r l_x]``; ``u ~ N(0, sigma_u^2)`` is the lateral
        velocity of the rear axle that the kinematic model sets to zero. The speed is eq. (6a)
        with the particle's radius error drawn from its NiW predictive at the velocity's
        instant and integrated out: ``v ~ N((w3 (r + mu_3) + w4 (r + mu_4)) / 2, p_i)``,
        ``p_i = [w3, w4] Sigma_i [w3, w4]' / 4``, ``Sigma_i = Lambda_i / (nu - d - 1)`` (Ozkan et
        al. eq. 32; the per-sample radius variation is mostly wheel-speed noise, which the true
        speed does not carry, so the velocity weighs the particles' means, not their last draw).
        Each particle's likelihood is ``N(y; h_i, R + sigma_u^2 n_i n_i' + p_i t_i t_i')`` with
        ``t_i = [cos psi_i, sin psi_i]``, ``n_i = [-sin psi_i, cos psi_i]``.

        With ``NIS > gate_nis`` (innovation of the weighted mean against the cloud's spread plus
        the noise) nothing is changed and ``accepted`` is false.
        """
        self._flush()
        w3, w4 = float(rear_wheel_speed_rad_s[0]), float(rear_wheel_speed_rad_s[1])
        v_virt, _ = self.model.virtual_speed_yaw_rate(np.array([0.0, 0.0, w3, w4]))
        # E[Sigma | stats_i] = Lambda_i / (nu - d - 1) (Ozkan et al. eq. 32), times 1/4 of eq. 6a
        k_sigma = 0.25 / (float(self._stats.dof) - self.D - 1.0)
        y0, y1 = float(v_m_s[0]), float(v_m_s[1])
        maha = np.empty(self.n)
        logdet = np.empty(self.n)
        # per particle h_i, S_i = R + q n n' + p t t' and the Mahalanobis distance (compiled)
        m0, m1, s00, s01, s11 = radius_kernels.velocity_predict(
            self._yaw, float(heading_offset_rad), self._mu, self._lam, self.weights,
            float(v_virt), w3, w4, k_sigma, float(along_var_m2_s2), float(yaw_rate_rad_s),
            float(lever_arm_m[0]), float(lever_arm_m[1]), float(lateral_std_m_s) ** 2,
            float(r_m2_s2[0, 0]), float(r_m2_s2[0, 1]), float(r_m2_s2[1, 1]), y0, y1,
            maha, logdet,
        )  # fmt: skip
        # innovation of the cloud: weighted mean and spread of h plus the mean noise
        s_mat = np.array([[s00, s01], [s01, s11]])
        i0 = y0 - m0
        i1 = y1 - m1
        det_s = s00 * s11 - s01 * s01
        nis = (s11 * i0 * i0 - 2.0 * s01 * i0 * i1 + s00 * i1 * i1) / det_s
        innov = np.array([i0, i1])
        if not (det_s > 0.0 and nis <= gate_nis):
            return VelocityUpdate(innov, s_mat, nis, -math.inf, False)
        # w_i <- w_i N(y; h_i, S_i), normalized
        log_norm, n_eff = radius_kernels.loglik_reweight(self.weights, maha, logdet)
        if not math.isfinite(log_norm):
            return VelocityUpdate(innov, s_mat, nis, -math.inf, True)
        if n_eff < self.resample_threshold * self.n:
            self.resample()
        return VelocityUpdate(innov, s_mat, nis, log_norm, True)

    @_mutates
    def resample(self) -> None:
        """Resample particles and their NiW statistics; uniform weights (Table I line 16)."""
        self._flush()
        w = self.weights
        if self.kernel_a > 0.0:
            mbar = self._mu @ w
            dev = self._mu - mbar[:, None]
            v_cloud = (dev * w) @ dev.T
        idx = systematic(w, self.rng)
        for a in (self._east, self._north, self._yaw, self._speed):
            a[:] = a[idx]
        if self.bias_on:
            self._bias[:] = self._bias[:, idx]
        self._stats.take(idx)
        self.weights[:] = 1.0 / self.n
        self.resample_count += 1
        if self.kernel_a > 0.0:
            # Liu & West (2001) kernel shrinkage (beyond the paper): refresh duplicated NiW means
            # while keeping the mean and covariance of the cloud of means
            a = self.kernel_a
            chol = np.linalg.cholesky(v_cloud + 1e-24 * np.eye(self.D))
            z = self.rng.standard_normal((self.D, self.n))
            self._mu *= a
            self._mu += ((1.0 - a) * mbar)[:, None] + math.sqrt(1.0 - a * a) * (chol @ z)

    @_mutates
    def anchor(self, y_m: F64, r_m2: F64, pred: FixPrediction) -> None:
        """Shift the whole cloud by the Kalman correction of its mean, without re-weighting.

        Used while the estimation is paused: keeps the pose tied to GNSS without letting a
        model mismatch (braking slip, low speed) select radius hypotheses.
        """
        self._flush()
        lik = r_m2 if pred.likelihood_cov_m2 is None else pred.likelihood_cov_m2
        s_inv = np.linalg.inv(pred.innovation_cov_m2)
        # the cloud's covariance (innovation covariance minus the likelihood's) sets the gain
        cov = pred.innovation_cov_m2 - lik
        shift = cov @ s_inv @ pred.innovation_m
        self._east += shift[0]
        self._north += shift[1]
        if self.bias_on:
            self._bias_anchor(s_inv, pred.innovation_m)

    def estimate(self) -> MpfEstimate:
        """Weighted pose mean/covariance and the NiW MMSE (eq. 30, Table I lines 17-18)."""
        self._flush()
        return self._moments(self._east, self._north, self._yaw)

    def peek(self) -> MpfEstimate:
        """:meth:`estimate` without processing the queued predictions: the queued samples move
        copies of the poses with each particle's NiW mean radius error (no draw), and the
        filter's state and random stream are untouched, so how often a caller reads the
        estimate does not change what the filter does."""
        if not self._pending:
            return self._moments(self._east, self._north, self._yaw)
        east, north, yaw = self._east.copy(), self._north.copy(), self._yaw.copy()
        seg = np.ascontiguousarray(np.array(self._pending).T)
        m = self.model
        st = self._stats
        radius_kernels.propagate_block(
            east, north, yaw, self._speed.copy(), self._mu, self._lam,
            seg[0], seg[1], seg[2], seg[4], False, self.lam, float(st.gamma), float(st.dof),
            m.nominal_radius_m, m.track_width_m, m.wheelbase_m, np.ones(4, dtype=np.uint64),
        )  # fmt: skip
        return self._moments(east, north, yaw)

    def _moments(self, east: F64, north: F64, yaw: F64) -> MpfEstimate:
        pose, pose_cov, mean, spread, lam_w = radius_kernels.moments(
            east, north, yaw, self._mu, self._lam, self.weights
        )
        return MpfEstimate(
            pose=pose,
            pose_cov=pose_cov,
            radius=self._radius_mmse(mean, spread, lam_w),
            n_eff=ess(self.weights),
            resample_count=self.resample_count,
        )

    def _radius_mmse(self, mean: F64, spread: F64, lam_w: F64) -> niw.NiwEstimate:
        """:func:`niw.mmse` for the shared-gamma/nu, particle-last 2x2 layout (same values).

        ``mean`` (2,) = eq. (30a) ``sum_i w_i mu_i``; ``spread`` (2, 2) the weighted covariance
        of the ``mu_i``; ``lam_w`` (2, 2) = ``sum_i w_i Lambda_i``.
        """
        st = self._stats
        d = self.D
        nu = float(st.dof)
        gam = float(st.gamma)
        # E[Sigma | stats_i] = Lambda_i / (nu - d - 1)  (Ozkan et al. eq. 32)
        noise_cov = lam_w / (nu - d - 1.0)
        mean_cov = gam * noise_cov + spread
        # eq. (30b) as printed in the T-ITS paper
        cov30 = lam_w * ((nu - d + 1.0) / (nu - d - 1.0)) + spread
        return niw.NiwEstimate(
            mean=mean,
            mean_cov=mean_cov,
            noise_cov=noise_cov,
            noise_cov_eq30b=cov30,
            dof=nu,
        )
