"""Marginalized particle filter (MPF) for the rear tyre radii (Lundquist et al., T-ITS 2014).

The pose ``[east, north, yaw]`` is carried by ``N`` particles; the radius errors are the process
noise ``w ~ N(mu, Sigma)`` of the motion model (eq. 12) whose unknown ``mu, Sigma`` are
marginalized with per-particle Normal-inverse-Wishart statistics (:mod:`.niw`). One
:meth:`RadiusMPF.predict` per wheel-speed sample performs lines 9-11 and 13 of Table I (NiW time
update, Student-t draw, pose propagation, NiW update); :meth:`RadiusMPF.update` performs lines
12 and 15-16 (GNSS likelihood weights, normalization, resampling).

Performance: the Student-t draws (eq. 27) are exact and drawn in blocks. Because every particle
receives the same sequence of NiW updates, ``gamma`` and ``nu`` are shared scalars whose future
values are known; a block holds, for the next ``B`` updates, standard normals ``(B, d, N)`` and the
per-particle scale ``sqrt(lambda (1 + gamma) / (nu - d + 1) * nu_t / chi2_{nu_t})`` with
``chi2 ~ chi-square(nu_t = nu - d + 1)`` drawn through ``Generator.standard_gamma``.
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

_R = TypeVar("_R")

F64 = NDArray[np.float64]

LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class FixPrediction:
    """Predicted GNSS antenna position of the particle cloud.

    Attributes:
        h: per-particle predicted antenna position (east, north), (N, 2), m.
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
        block_size: number of predictions per block of pre-drawn variates.
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
        self.east = np.zeros(n)
        self.north = np.zeros(n)
        self.yaw = np.zeros(n)
        self.speed = np.zeros(n)
        self.weights = np.full(n, 1.0 / n)
        #: incremented by every method that changes the filter state (see ``_mutates``)
        self.version = 0
        self.resample_count = 0
        self.jitter_dt_s = 0.0
        self._mu = np.empty((d, n))
        self._lam = np.empty((d, d, n))
        self.stats = self._wrap(niw.init_stats(n, *self._prior))
        self._block_z: F64 = np.empty((0, d, n))
        self._block_s: F64 = np.empty((0, n))
        self._block_pos = 0
        # scratch buffers
        self._e = np.empty((d, n))
        self._tmp = np.empty(n)

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
        self.stats = self._wrap(niw.init_stats(self.n, *self._prior))
        self._invalidate_block()

    @_mutates
    def set_stats(self, stats: niw.NiwStats) -> None:
        """Replace the NiW statistics (e.g. restored from a persisted state).

        ``stats`` must have ``N`` particles, ``d = 2`` and shared (0-d) gamma and dof.
        """
        if stats.n != self.n or stats.d != self.D or np.ndim(stats.gamma) or np.ndim(stats.dof):
            raise ValueError("stats must have N particles, d = 2 and shared gamma/dof")
        self.stats = self._wrap(stats)
        self._invalidate_block()

    @_mutates
    def init_pose(self, mean: F64, cov: F64) -> None:
        """Draw the particle poses from ``N(mean, cov)`` (3,), (3, 3); uniform weights."""
        chol = np.linalg.cholesky(np.asarray(cov, dtype=float) + 1e-12 * np.eye(3))
        x = np.asarray(mean, dtype=float) + self.rng.standard_normal((self.n, 3)) @ chol.T
        self.east[:] = x[:, 0]
        self.north[:] = x[:, 1]
        self.yaw[:] = x[:, 2]
        self.speed[:] = 0.0
        self.weights[:] = 1.0 / self.n
        self.jitter_dt_s = 0.0

    # ------------------------------------------------------------------ random blocks
    def _invalidate_block(self) -> None:
        self._block_pos = self._block_z.shape[0]

    def _refill_block(self) -> None:
        """Pre-draw the Student-t variates of the next ``B`` NiW updates (exact, eq. 27)."""
        b, n, d, lam = self.block_size, self.n, self.D, self.lam
        g = float(self.stats.gamma)
        nu = float(self.stats.dof)
        nu_t = np.empty(b)
        factor = np.empty(b)
        for k in range(b):
            # eq. (24a), (24c) predicted gamma and nu of the k-th update ahead
            g_pred = g / lam
            nu_pred = lam * nu
            # eq. (27) dof nu - d + 1; shape (1 + gamma) Lambda / (nu - d + 1), where the
            # predicted Lambda = lambda Lambda (eq. 24d) -> the factor lambda is folded in here
            nu_t[k] = nu_pred - d + 1.0
            factor[k] = lam * (1.0 + g_pred) / nu_t[k]
            # eq. (23a), (23c)
            g = g_pred / (1.0 + g_pred)
            nu = nu_pred + 1.0
        chi2 = 2.0 * self.rng.standard_gamma(np.broadcast_to(0.5 * nu_t[:, None], (b, n)))
        self._block_s = np.sqrt((factor * nu_t)[:, None] / chi2)
        self._block_z = self.rng.standard_normal((b, d, n))
        self._block_pos = 0

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
        Student-t predictive, propagate the pose with them and update the NiW statistics.
        ``learn=False`` (estimation paused): propagate with each particle's mean radius error and
        leave the statistics untouched. ``steer_angle_rad`` selects the low-speed heading model
        (eq. 31a).
        """
        w3 = float(wheel_speed_rad_s[RL])
        w4 = float(wheel_speed_rad_s[RR])
        r = self.model.nominal_radius_m
        lt = self.model.track_width_m
        st = self.stats
        self.jitter_dt_s += dt_s
        if learn:
            if self._block_pos >= self._block_z.shape[0]:
                self._refill_block()
            j = self._block_pos
            self._block_pos += 1
            z = self._block_z[j]
            s = self._block_s[j]
            lam_, mu, e = self._lam, self._mu, self._e
            # Cholesky of the current Lambda (closed form, d = 2); the predictive shape factor
            # and sqrt(nu_t / chi2) are in s -> e = chol(shape) z sqrt(nu_t / chi2)
            l11 = np.sqrt(lam_[0, 0])
            l21 = lam_[1, 0] / l11
            l22 = np.sqrt(np.maximum(lam_[1, 1] - l21 * l21, 0.0))
            zs = z * s
            np.multiply(l11, zs[0], out=e[0])
            np.multiply(l21, zs[0], out=e[1])
            e[1] += l22 * zs[1]
            # eq. (27) w ~ St(mu, (1 + gamma) Lambda / (nu - d + 1), nu - d + 1): w = mu + e
            w = mu + e
            # eq. (24a) gamma_{k|k-1} = gamma / lambda (shared scalar)
            g_pred = float(st.gamma) / self.lam
            c = 1.0 / (1.0 + g_pred)
            # eq. (24d) + (23d): Lambda = lambda Lambda + (w - mu)(w - mu)^T / (1 + gamma_{k|k-1})
            lam_ *= self.lam
            ec = c * e
            lam_[0, 0] += ec[0] * e[0]
            lam_[1, 1] += ec[1] * e[1]
            lam_[0, 1] += ec[0] * e[1]
            lam_[1, 0] = lam_[0, 1]
            # eq. (23a) gamma_{k|k} = gamma_pred / (1 + gamma_pred)
            g_new = g_pred * c
            # eq. (23b) mu = mu + gamma_{k|k} (w - mu)
            mu += g_new * e
            st.gamma[...] = g_new
            # eq. (24c) + (23c) nu = lambda nu + 1
            st.dof[...] = self.lam * float(st.dof) + 1.0
        else:
            w = self._mu
        # eq. (6a)/(7a) v = r (w3 + w4) / 2 + (w3 d3 + w4 d4) / 2 and
        # eq. (6b)/(7c) yaw_rate = r (w4 - w3) / l_T + (w4 d4 - w3 d3) / l_T, as one product
        coef = np.array([[0.5 * w3, 0.5 * w4], [-w3 / lt, w4 / lt]])
        vy = coef @ w
        vy[0] += 0.5 * r * (w3 + w4)
        v = vy[0]
        self.speed[:] = v
        if steer_angle_rad is None:
            vy[1] += r * (w4 - w3) / lt
            yr = vy[1]
        else:
            # eq. (31a) low-speed heading from the steer angle
            yr = self.model.steering_yaw_rate(v, steer_angle_rad)
        # eq. (3a)-(3c) / (7)
        tmp = self._tmp
        np.multiply(v, dt_s, out=tmp)
        self.east += tmp * np.cos(self.yaw)
        self.north += tmp * np.sin(self.yaw)
        self.yaw += dt_s * yr

    # ------------------------------------------------------------------ measurement update
    def _apply_jitter(self) -> None:
        """Additive pose random walk accumulated since the last fix (roughening)."""
        dt = self.jitter_dt_s
        if dt <= 0.0 or (self.pos_q == 0.0 and self.yaw_q == 0.0 and self.mean_q == 0.0):
            self.jitter_dt_s = 0.0
            return
        z = self.rng.standard_normal((3 + self.D, self.n))
        sp = math.sqrt(self.pos_q * dt)
        self.east += sp * z[0]
        self.north += sp * z[1]
        self.yaw += math.sqrt(self.yaw_q * dt) * z[2]
        if self.mean_q > 0.0:
            # artificial dynamics of the NiW mean (beyond the paper): random walk of the
            # per-particle radius-error mean, keeps the radius hypotheses diverse
            self._mu += math.sqrt(self.mean_q * dt) * z[3:]
        self.jitter_dt_s = 0.0

    @_mutates
    def predict_fix(
        self, y_m: F64, r_m2: F64, lever_arm_m: F64, extrapolate_s: float = 0.0
    ) -> FixPrediction:
        """Predicted antenna positions (eq. 13 with a lever arm) and innovation statistics.

        ``y_m`` (2,) measured east/north; ``r_m2`` (2, 2) its covariance; ``lever_arm_m`` (2,)
        antenna (x, y) in ``base_link``; ``extrapolate_s`` from the pose time to the fix time.
        Applies the accumulated pose noise first.
        """
        self._apply_jitter()
        c = np.cos(self.yaw)
        s = np.sin(self.yaw)
        ax, ay = float(lever_arm_m[0]), float(lever_arm_m[1])
        ext = extrapolate_s * self.speed
        h = np.empty((self.n, 2))
        # eq. (13) h(x) = [x, y] of the antenna: base_link + R(psi) lever arm (+ extrapolation)
        h[:, 0] = self.east + (ax + ext) * c - ay * s
        h[:, 1] = self.north + (ax + ext) * s + ay * c
        w = self.weights
        mean = w @ h
        dev = h - mean
        cov = (dev * w[:, None]).T @ dev
        s_mat = cov + r_m2
        innov = np.asarray(y_m, dtype=float) - mean
        nis = float(innov @ np.linalg.solve(s_mat, innov))
        return FixPrediction(h=h, innovation_m=innov, innovation_cov_m2=s_mat, nis=nis)

    @_mutates
    def update(self, y_m: F64, r_m2: F64, pred: FixPrediction) -> float:
        """Weight update with the GNSS likelihood (eq. 18, Table I line 12), normalize (line 15)
        and resample when ``N_eff < threshold N`` (line 16). Returns the log marginal likelihood.
        """
        diff = np.asarray(y_m, dtype=float) - pred.h
        r_inv = np.linalg.inv(r_m2)
        maha = np.einsum("ni,ij,nj->n", diff, r_inv, diff)
        # eq. (13c) Gaussian GNSS likelihood p(y_k | x_k^(i))
        loglik = -0.5 * maha - 0.5 * (2 * LOG_2PI + math.log(np.linalg.det(r_m2)))
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
        w = self.weights
        if self.kernel_a > 0.0:
            mbar = self._mu @ w
            dev = self._mu - mbar[:, None]
            v_cloud = (dev * w) @ dev.T
        idx = self.resample_fn(w, self.rng)
        self.east[:] = self.east[idx]
        self.north[:] = self.north[idx]
        self.yaw[:] = self.yaw[idx]
        self.speed[:] = self.speed[idx]
        self.stats.take(idx)
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
        cov = pred.innovation_cov_m2 - r_m2
        gain = cov @ np.linalg.inv(pred.innovation_cov_m2)
        shift = gain @ pred.innovation_m
        self.east += shift[0]
        self.north += shift[1]

    @_mutates
    def clip_mean(self, upper_m: F64) -> None:
        """Project each particle's NiW mean onto ``mu <= upper_m`` (2,) (non-increasing radii)."""
        np.minimum(self._mu, np.asarray(upper_m, dtype=float)[:, None], out=self._mu)

    # ------------------------------------------------------------------ estimates
    def estimate(self) -> MpfEstimate:
        """Weighted pose mean/covariance and the NiW MMSE (eq. 30, Table I lines 17-18)."""
        w = self.weights
        yaw_mean = math.atan2(float(w @ np.sin(self.yaw)), float(w @ np.cos(self.yaw)))
        x = np.stack(
            [self.east, self.north, np.angle(np.exp(1j * (self.yaw - yaw_mean))) + yaw_mean],
            axis=1,
        )
        mean = w @ x
        dev = x - mean
        cov = (dev * w[:, None]).T @ dev
        mean[2] = math.atan2(math.sin(mean[2]), math.cos(mean[2]))
        return MpfEstimate(
            pose=mean,
            pose_cov=0.5 * (cov + cov.T),
            radius=niw.mmse(self.stats, w),
            n_eff=ess(w),
            resample_count=self.resample_count,
        )
