"""Marginalized particle filter (MPF) for the rear tyre radii (Lundquist et al., T-ITS 2014).

The pose ``[east, north, yaw]`` is carried by ``N`` particles; the radius errors are the process
noise ``w ~ N(mu, Sigma)`` of the motion model (eq. 12) whose unknown ``mu, Sigma`` are
marginalized with per-particle Normal-inverse-Wishart statistics (:mod:`.niw`). One
:meth:`RadiusMPF.predict` per wheel-speed sample performs lines 9-11 and 13 of Table I (NiW time
update, Student-t draw, pose propagation, NiW update); :meth:`RadiusMPF.update` performs lines
12 and 15-16 (GNSS likelihood weights, normalization, resampling).

Performance: predictions are queued and processed in blocks (at the next GNSS fix, estimate or
state access, or after ``block_size`` samples), vectorized over samples and particles: one
draw of ``(mu, Sigma)`` per particle and block from the NiW statistics, Gaussian radius errors
for every sample of the block, the exact unrolled NiW recursion (eq. 23-24) and the pose
propagation (eq. 3) as cumulative sums. See :meth:`RadiusMPF._draw_block` for why this samples
the same law as Table I (exactly without forgetting, and for blocks of one sample).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw
from tire_estimation.core.radius_model import RL, RR, RadiusMotionModel
from tire_estimation.core.resampling import RESAMPLERS, ess, normalize_log_weights
from tire_estimation.core.sampling import standard_normal

_R = TypeVar("_R")

F64 = NDArray[np.float64]

LOG_2PI = math.log(2.0 * math.pi)


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


def _mutates(method: Callable[..., _R]) -> Callable[..., _R]:
    """Count changes of the filter state (``version``) so estimates can be cached."""

    @functools.wraps(method)
    def wrapper(self: RadiusMPF, *args: Any, **kwargs: Any) -> _R:
        self.version += 1
        return method(self, *args, **kwargs)

    return wrapper


class RadiusMPF:
    """MPF over the pose with NiW-marginalized rear radius errors (``d = 2``).

    Args:
        model: the motion model.
        n_particles: ``N``.
        prior_mean_m: prior mean radius errors (2,), m.
        prior_mean_std_m: prior std of the mean radius errors (gamma_0 = (std / noise_std)^2), m.
        prior_noise_std_m: prior sqrt(E[Sigma]) (per wheel), m.
        prior_dof: nu_0 (> 3).
        forgetting_factor: lambda of eq. (24).
        resampler: key of :data:`resampling.RESAMPLERS`.
        resample_threshold: resample when ``N_eff < threshold * N``.
        position_noise_m_sqrt_s: additive pose random walk on east/north (applied at each fix
            with the variance accumulated since the last fix), m/sqrt(s).
        yaw_noise_rad_sqrt_s: same for the heading, rad/sqrt(s).
        mean_random_walk_m_sqrt_s: random walk of each particle's NiW mean, applied with the pose
            noise (beyond the paper), m/sqrt(s).
        kernel_shrinkage: Liu-West shrinkage ``a`` of the NiW means at resampling (beyond the
            paper); 0 disables.
        rng: random generator (all draws).
        block_size: at most this many queued predictions are processed as one block.
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
        resampler: str,
        resample_threshold: float,
        position_noise_m_sqrt_s: float,
        yaw_noise_rad_sqrt_s: float,
        rng: np.random.Generator,
        mean_random_walk_m_sqrt_s: float = 0.0,
        kernel_shrinkage: float = 0.0,
        block_size: int = 64,
    ) -> None:
        self.model = model
        self.n = int(n_particles)
        self.rng = rng
        self.lam = float(forgetting_factor)
        self.resample_fn = RESAMPLERS[resampler]
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

    # ------------------------------------------------------------------ prediction
    @_mutates
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
        self.jitter_dt_s += dt_s
        self._pending.append(
            (
                float(dt_s),
                float(wheel_speed_rad_s[RL]),
                float(wheel_speed_rad_s[RR]),
                1.0 if learn else 0.0,
                math.nan if steer_angle_rad is None else float(steer_angle_rad),
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

        Sigma ~ iW(nu, Lambda) is drawn as the inverse of a Wishart(nu, Lambda^-1) matrix with
        the Bartlett decomposition, ``W = M M^T``, ``M = chol(Lambda^-1) A``, ``A`` lower
        triangular with ``A_11^2 ~ chi2(nu)``, ``A_22^2 ~ chi2(nu - 1)``, ``A_21 ~ N(0, 1)``;
        then ``Sigma = M^-T M^-1`` and ``S = M^-T`` is a square root of Sigma.
        """
        lam, n = self.lam, self.n
        st = self._stats
        rng = self.rng
        # eq. (24a), (24c), (24d): statistics predicted to the first step of the block
        g = float(st.gamma) / lam
        nu = lam * float(st.dof)
        a = self._lam[0, 0]
        b = self._lam[0, 1]
        c = self._lam[1, 1]
        det = a * c - b * b
        det *= lam * lam
        # chol(Lambda^-1) for Lambda = lam [[a, b], [b, c]] (closed form, 2x2):
        # l11 = sqrt(c' / det'), l21 = -b' / sqrt(c' det'), l22 = 1 / sqrt(c')
        sc = np.sqrt(lam * c)
        sdet = np.sqrt(det)
        a11 = np.sqrt(2.0 * rng.standard_gamma(0.5 * nu, n))
        a22 = np.sqrt(2.0 * rng.standard_gamma(0.5 * (nu - 1.0), n))
        z = standard_normal(rng, (2 * k + 3, n))
        # M = chol(Lambda^-1) A; inverse diagonal of M and its off-diagonal term
        inv_m11 = sdet / (sc * a11)
        inv_m22 = sc / a22
        m21 = (lam * b) * a11
        m21 /= -sc * sdet
        m21 += z[0] / sc
        # mu ~ N(mean, gamma Sigma), w_j ~ N(mu, Sigma): w_j = mean + M^-T (sqrt(gamma) z0 + z_j)
        u0 = z[3 : 3 + k]
        u0 += math.sqrt(g) * z[1]
        u1 = z[3 + k :]
        u1 += math.sqrt(g) * z[2]
        d4 = u1 * inv_m22
        d3 = u0 - m21 * d4
        d3 *= inv_m11
        d3 += self._mu[0]
        d4 += self._mu[1]
        return d3, d4

    def _niw_block_update(self, d3: F64, d4: F64) -> None:
        """Eq. (24) + (23) applied to the samples ``(d3, d4)`` ``(k, N)`` in order, exactly.

        gamma and nu are shared scalars, so the gains are scalars: with ``g_j = gamma_{j|j}``
        and ``F_j = prod_{i<j} (1 - g_i)``, the running mean before step ``j`` is
        ``mu_j = F_j mean + sum_{i<j} F_j g_i / F_{i+1} w_i`` (eq. 23b unrolled, a (k+1, k)
        matrix ``B`` applied to the samples), and eq. (24d) + (23d) unroll to
        ``Lambda_k = lambda^k Lambda + sum_j lambda^(k-1-j) c_j e_j e_j^T`` with
        ``e_j = w_j - mu_j`` and ``c_j = 1 / (1 + gamma_{j|j-1})``.
        """
        lam = self.lam
        k = d3.shape[0]
        st = self._stats
        g = float(st.gamma)
        nu = float(st.dof)
        lm = self._lam
        mu = self._mu
        if k == 1:
            # one sample: eq. (24) + (23) directly
            gp = g / lam
            c1 = 1.0 / (1.0 + gp)
            e3 = d3[0] - mu[0]
            e4 = d4[0] - mu[1]
            # eq. (24d) + (23d) Lambda = lambda Lambda + e e^T / (1 + gamma_{k|k-1})
            lm *= lam
            ce3 = c1 * e3
            lm[0, 0] += ce3 * e3
            lm[1, 1] += c1 * e4 * e4
            lm[0, 1] += ce3 * e4
            lm[1, 0] = lm[0, 1]
            # eq. (23a), (23b) mean += gamma_{k|k} e
            g = gp * c1
            mu[0] += g * e3
            mu[1] += g * e4
            st.gamma[...] = g
            # eq. (24c) + (23c)
            st.dof[...] = lam * nu + 1.0
            return
        gain = [0.0] * k
        cj = [0.0] * k
        for j in range(k):
            # eq. (24a) gamma_{j|j-1} = gamma / lambda; eq. (23a) gamma_{j|j} = gp / (1 + gp)
            gp = g / lam
            cj[j] = 1.0 / (1.0 + gp)
            g = gp * cj[j]
            gain[j] = g
            # eq. (24c) + (23c) nu = lambda nu + 1
            nu = lam * nu + 1.0
        gv = np.array(gain)
        f = np.cumprod(np.concatenate(([1.0], 1.0 - gv)))
        # B[j, i] = F_j g_i / F_{i+1} for i < j (rows 0..k: running means before each step and
        # the final mean)
        bmat = np.tril(np.outer(f, gv / f[1:]), -1)
        q = np.array(cj) * lam ** np.arange(k - 1, -1, -1)
        lam_k = lam**k
        run3 = bmat @ d3
        run3 += np.outer(f, mu[0])
        run4 = bmat @ d4
        run4 += np.outer(f, mu[1])
        e3 = d3 - run3[:k]
        e4 = d4 - run4[:k]
        # eq. (24d) + (23d) unrolled
        lm[0, 0] *= lam_k
        lm[0, 0] += q @ (e3 * e3)
        lm[1, 1] *= lam_k
        lm[1, 1] += q @ (e4 * e4)
        lm[0, 1] *= lam_k
        lm[0, 1] += q @ (e3 * e4)
        lm[1, 0] = lm[0, 1]
        mu[0] = run3[k]
        mu[1] = run4[k]
        st.gamma[...] = g
        st.dof[...] = nu

    def _propagate(self, seg: F64, learn: bool) -> None:
        """Propagate the pose over the samples ``seg`` ``(k, 5)`` = dt, w_rl, w_rr, learn,
        steer (NaN = none) with the radius errors drawn for them (or the NiW means)."""
        k = seg.shape[0]
        dt, w3, w4, steer = seg[:, 0], seg[:, 1], seg[:, 2], seg[:, 4]
        r = self.model.nominal_radius_m
        lt = self.model.track_width_m
        if learn:
            # Table I lines 9-11, 13: sample the radius errors and update the NiW statistics
            d3, d4 = self._draw_block(k)
            self._niw_block_update(d3, d4)
        else:
            d3, d4 = self._mu[0][None, :], self._mu[1][None, :]
        a3 = w3[:, None] * d3
        a4 = w4[:, None] * d4
        # eq. (6a)/(7a) v = r (w3 + w4) / 2 + (w3 d3 + w4 d4) / 2; here ds = v dt
        ds = a3 + a4
        ds += (r * (w3 + w4))[:, None]
        ds *= (0.5 * dt)[:, None]
        # eq. (6b)/(7c) yaw_rate = r (w4 - w3) / l_T + (w4 d4 - w3 d3) / l_T; here dt yaw_rate
        dyaw = a4
        dyaw -= a3
        dyaw += (r * (w4 - w3))[:, None]
        dyaw *= (dt / lt)[:, None]
        steer_rows = np.flatnonzero(~np.isnan(steer))
        if steer_rows.size:
            # eq. (31a) low-speed heading from the steer angle: yaw_rate = v tan(delta) / l_b
            dyaw[steer_rows] = (
                ds[steer_rows] * (np.tan(steer[steer_rows]) / self.model.wheelbase_m)[:, None]
            )
        # eq. (3c): heading at the start of each step (zero-order hold), relative to the block
        # start; the block start heading enters through the angle-sum identity below
        rel = np.empty((k, self.n))
        rel[0] = 0.0
        for j in range(1, k):
            np.add(rel[j - 1], dyaw[j - 1], out=rel[j])
        # eq. (3a), (3b) summed over the block: cos/sin of the (small) in-block heading change
        # in float32 (relative error ~1e-7 of a step of a few cm), block start in float64
        c_rel = np.cos(rel, dtype=np.float32)
        s_rel = np.sin(rel, dtype=np.float32)
        fx = np.einsum("kn,kn->n", ds, c_rel)
        fy = np.einsum("kn,kn->n", ds, s_rel)
        c0 = np.cos(self._yaw)
        s0 = np.sin(self._yaw)
        self._east += fx * c0 - fy * s0
        self._north += fx * s0 + fy * c0
        self._yaw += rel[k - 1] + dyaw[k - 1]
        np.multiply(ds[k - 1], 1.0 / dt[k - 1] if dt[k - 1] > 0 else 0.0, out=self._speed)

    # ------------------------------------------------------------------ measurement update
    def _apply_jitter(self) -> None:
        """Additive pose random walk accumulated since the last fix (roughening)."""
        dt = self.jitter_dt_s
        self.jitter_dt_s = 0.0
        if dt <= 0.0 or (self.pos_q == 0.0 and self.yaw_q == 0.0 and self.mean_q == 0.0):
            return
        z = self.rng.standard_normal((3 + self.D, self.n))
        sp = math.sqrt(self.pos_q * dt)
        self._east += sp * z[0]
        self._north += sp * z[1]
        self._yaw += math.sqrt(self.yaw_q * dt) * z[2]
        if self.mean_q > 0.0:
            # artificial dynamics of the NiW mean (beyond the paper): random walk of the
            # per-particle radius-error mean, keeps the radius hypotheses diverse
            self._mu += math.sqrt(self.mean_q * dt) * z[3:]

    @_mutates
    def predict_fix(
        self, y_m: F64, r_m2: F64, lever_arm_m: F64, extrapolate_s: float = 0.0
    ) -> FixPrediction:
        """Predicted antenna positions (eq. 13 with a lever arm) and innovation statistics.

        ``y_m`` (2,) measured east/north; ``r_m2`` (2, 2) its covariance; ``lever_arm_m`` (2,)
        antenna (x, y) in ``base_link``; ``extrapolate_s`` from the pose time to the fix time.
        Applies the accumulated pose noise first.
        """
        self._flush()
        self._apply_jitter()
        c = np.cos(self._yaw)
        s = np.sin(self._yaw)
        ax, ay = float(lever_arm_m[0]), float(lever_arm_m[1])
        h = np.empty((2, self.n))
        # eq. (13) h(x) = [x, y] of the antenna: base_link + R(psi) lever arm (+ extrapolation)
        if extrapolate_s:
            lx = ax + extrapolate_s * self._speed
            h[0] = self._east + lx * c - ay * s
            h[1] = self._north + lx * s + ay * c
        else:
            h[0] = self._east + ax * c - ay * s
            h[1] = self._north + ax * s + ay * c
        w = self.weights
        mean = h @ w
        dev = h - mean[:, None]
        cov = (dev * w) @ dev.T
        s_mat = cov + r_m2
        innov = np.array([float(y_m[0]) - mean[0], float(y_m[1]) - mean[1]])
        # NIS with the closed-form 2x2 inverse
        s00, s01, s11 = float(s_mat[0, 0]), float(s_mat[0, 1]), float(s_mat[1, 1])
        det = s00 * s11 - s01 * s01
        i0, i1 = float(innov[0]), float(innov[1])
        nis = (s11 * i0 * i0 - 2.0 * s01 * i0 * i1 + s00 * i1 * i1) / det if det > 0 else math.inf
        return FixPrediction(h=h, innovation_m=innov, innovation_cov_m2=s_mat, nis=nis)

    @_mutates
    def update(self, y_m: F64, r_m2: F64, pred: FixPrediction) -> float:
        """Weight update with the GNSS likelihood (eq. 18, Table I line 12), normalize (line 15)
        and resample when ``N_eff < threshold N`` (line 16). Returns the log marginal likelihood.

        ``pred.h`` holds the predicted antenna positions ``(2, N)`` of :meth:`predict_fix`.
        """
        self._flush()
        r00, r01, r11 = float(r_m2[0, 0]), float(r_m2[0, 1]), float(r_m2[1, 1])
        det = r00 * r11 - r01 * r01
        d0 = float(y_m[0]) - pred.h[0]
        d1 = float(y_m[1]) - pred.h[1]
        # Mahalanobis distance with the closed-form inverse of R (2x2)
        maha = (r11 * d0 * d0 - 2.0 * r01 * d0 * d1 + r00 * d1 * d1) / det
        # eq. (13c) Gaussian GNSS likelihood p(y_k | x_k^(i))
        loglik = -0.5 * maha - 0.5 * (2 * LOG_2PI + math.log(det))
        with np.errstate(divide="ignore"):
            log_w = np.log(self.weights) + loglik
        # eq. (18) w_k = w_{k-1} p(y_k | x_k), Table I line 15: normalize
        self.weights, log_norm = normalize_log_weights(log_w)
        if ess(self.weights) < self.resample_threshold * self.n:
            self.resample()
        return log_norm

    @_mutates
    def resample(self) -> None:
        """Resample particles and their NiW statistics; uniform weights (Table I line 16)."""
        self._flush()
        w = self.weights
        if self.kernel_a > 0.0:
            mbar = self._mu @ w
            dev = self._mu - mbar[:, None]
            v_cloud = (dev * w) @ dev.T
        idx = self.resample_fn(w, self.rng)
        for a in (self._east, self._north, self._yaw, self._speed):
            a[:] = a[idx]
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
        cov = pred.innovation_cov_m2 - r_m2
        gain = cov @ np.linalg.inv(pred.innovation_cov_m2)
        shift = gain @ pred.innovation_m
        self._east += shift[0]
        self._north += shift[1]

    @_mutates
    def clip_mean(self, upper_m: F64) -> None:
        """Project each particle's NiW mean onto ``mu <= upper_m`` (2,) (non-increasing radii)."""
        self._flush()
        np.minimum(self._mu, np.asarray(upper_m, dtype=float)[:, None], out=self._mu)

    # ------------------------------------------------------------------ estimates
    def estimate(self) -> MpfEstimate:
        """Weighted pose mean/covariance and the NiW MMSE (eq. 30, Table I lines 17-18)."""
        self._flush()
        w = self.weights
        yaw = self._yaw
        yaw_mean = math.atan2(float(np.sin(yaw) @ w), float(np.cos(yaw) @ w))
        x = np.empty((3, self.n))
        x[0] = self._east
        x[1] = self._north
        # headings unwrapped around their circular mean
        np.subtract(yaw, yaw_mean, out=x[2])
        x[2] += math.pi
        np.mod(x[2], 2.0 * math.pi, out=x[2])
        x[2] += yaw_mean - math.pi
        mean = x @ w
        dev = x - mean[:, None]
        cov = (dev * w) @ dev.T
        mean[2] = math.atan2(math.sin(mean[2]), math.cos(mean[2]))
        return MpfEstimate(
            pose=mean,
            pose_cov=0.5 * (cov + cov.T),
            radius=self._radius_mmse(),
            n_eff=ess(w),
            resample_count=self.resample_count,
        )

    def _radius_mmse(self) -> niw.NiwEstimate:
        """:func:`niw.mmse` for the shared-gamma/nu, particle-last 2x2 layout (same values)."""
        w = self.weights
        st = self._stats
        d = self.D
        nu = float(st.dof)
        gam = float(st.gamma)
        mu = self._mu
        # eq. (30a) mu_hat = sum_i w_i mu_i
        mean = mu @ w
        dev = mu - mean[:, None]
        spread = (dev * w) @ dev.T
        lam_w = self._lam.reshape(d * d, self.n) @ w
        lam_w = lam_w.reshape(d, d)
        # E[Sigma | stats_i] = Lambda_i / (nu - d - 1)  (Ozkan et al. eq. 32)
        noise_cov = lam_w / (nu - d - 1.0)
        mean_cov = gam * noise_cov + spread
        # eq. (30b) as printed in the T-ITS paper
        cov30 = lam_w * ((nu - d + 1.0) / (nu - d - 1.0)) + spread
        return niw.NiwEstimate(
            mean=mean,
            mean_cov=0.5 * (mean_cov + mean_cov.T),
            noise_cov=0.5 * (noise_cov + noise_cov.T),
            noise_cov_eq30b=0.5 * (cov30 + cov30.T),
            dof=nu,
        )
