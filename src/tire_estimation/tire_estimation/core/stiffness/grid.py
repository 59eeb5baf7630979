"""Point-mass filter on the cornering stiffnesses with an EKF on the vehicle state per cell.

A method beside Algorithm 1 (Berntorp & Di Cairano, IEEE TCST 2018) and its baselines
(``evaluation.stiffness_baselines``), not in the paper. Algorithm 1 samples the vehicle state and
marginalizes the stiffness (Normal-inverse-Wishart statistics of ``w`` per particle); this filter
does it the other way round. The stiffness is a parameter, constant over a step, gridded over
``(Cy_f, Cy_r)``; given a cell's stiffness the single-track model (eq. 1-12, the same
:func:`.stiffness_filter.model`) is a smooth system in ``[vX, vY, r]``, and an extended Kalman
filter per cell carries that state and the cell's predictive density of every IMU sample. The
cell weights are the posterior of the stiffness (Bayes' rule on the grid: point-mass filter,
Bucy & Senne 1971), the per-cell EKF the Rao-Blackwellized part (a bank of Kalman filters, as in
multiple-model adaptive estimation, Magill 1965).

Why: on the snow sine drives the friction-limited tyre explains nearly the same lateral
acceleration and yaw rate with a larger stiffness at smaller slip angles, so the common scale of
the two stiffnesses is weakly observable and Algorithm 1's statistics narrow on it early
(docs/stiffness_limits.md, "What limits Algorithm 1 on snow"); an EKF on the augmented state
diverges from a start at 150 % (the model is far from linear in the stiffness over the prior).
On a grid the stiffness enters the model exactly; only the state, which the IMU pins within
millimetres per second, is linearized.

The grid follows the posterior. It starts as ``grid_points`` x ``grid_points`` cells over the
prior (``initial_stiffness_factor`` +- ``grid_span_sigma`` ``initial_stiffness_std_fraction``
of nominal, cells outside the projection bounds weightless). When the posterior's std along
its narrowest principal axis falls below ``regrid_min_cells`` cell spacings, or more than
``regrid_edge_mass`` of it lies on the grid's boundary ring, a new grid of the same size is laid
along the posterior's principal axes over +- ``grid_span_sigma`` std around its mean; each new
cell takes the EKF of the nearest old cell and the weight of the Gaussian with the posterior's
mean and covariance. ``forgetting`` lambda flattens the log-weights at every learning step
(``log q <- lambda log q``), so that the posterior keeps a memory of about ``1 / (1 - lambda)``
steps. That is not enough to follow an abrupt change of the road: on ``stiffness_step`` the
estimate stays at the stiffness from before the 50 % drop (docs/results.md section 6,
"The grid learns first").

IMU biases: with a non-zero ``accel_bias_std_m_s2`` or ``gyro_bias_std_rad_s`` (Algorithm 1's
values, eq. 11-12; zero when its ``imu_bias_states`` is false) each cell's EKF carries ``[b_ax,
b_ay, b_r]`` as random-walk states beside the vehicle state; they enter the measurement
additively, so given the cell they are linear, as in Algorithm 1's per-particle bias Kalman
filters (eq. 29-30).

Left out: ``Cx`` is not estimated (held at the prior: the sine drives do not excite it, and
Algorithm 1 freezes it there as well). In the estimator node it runs only as the first learner
of ``first_learning: grid``, which hands its posterior to Algorithm 1
(:class:`~.stiffness_estimator.StiffnessEstimator`); on its own it runs behind the same
front-end (:class:`~.stiffness_frontend.StiffnessFrontEnd`) in the evaluations
(``evaluation.stiffness_baselines.BaselineEstimator``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any, ClassVar

import numpy as np

from tire_estimation.core import resampling
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.filter import (
    JACOBIAN_STEP,
    BaselineConfig,
    FilterEstimate,
    Measurement,
    StiffnessFilter,
    model,
)
from tire_estimation.core.stiffness.model import (
    WHEEL_SPEED_NOISE_STD_M_S,
    SingleTrackParams,
    measurement_cov,
)
from tire_estimation.core.validation import (
    Fraction,
    NonNegative,
    Positive,
    in_range,
    int_in_range,
)

_LOG_2PI = math.log(2.0 * math.pi)


@dataclass(frozen=True)
class GridConfig(BaselineConfig):
    """Point-mass filter on ``(Cy_f, Cy_r)`` with an EKF on ``[vX, vY, r]`` per cell.

    Attributes:
        grid_points: cells per axis G (G x G cells), 1 (default 25).
        grid_span_sigma: half-width of the grid in posterior (initially prior) std along each
            principal axis, 1 (default 4.0).
        regrid_min_cells: a new grid is laid when the posterior std along its narrowest
            principal axis is below this many cell spacings, 1 (default 1.5).
        regrid_edge_mass: ... or when more than this share of the posterior lies on the grid's
            boundary ring, 1 (default 1e-3).
        forgetting: exponent lambda of the log-weights per learning step (1 = a constant
            stiffness, no forgetting), 1 (default 0.999: a memory of about 1000 IMU steps).
        state_jitter_vx_m_s_sqrt_s: process noise of vX in each EKF, m/s/sqrt(s) (default
            0.015, Algorithm 1's state jitter).
        state_jitter_vy_m_s_sqrt_s: process noise of vY, m/s/sqrt(s) (default 0.006).
        state_jitter_yaw_rate_rad_s_sqrt_s: process noise of the yaw rate, rad/s/sqrt(s)
            (default 0.0006).
        accel_bias_std_m_s2: prior std of the accelerometer biases b_ax, b_ay (eq. 11), m/s^2
            (default 0.1, as Algorithm 1); 0 with ``gyro_bias_std_rad_s`` 0: no bias states.
        gyro_bias_std_rad_s: prior std of the gyro bias b_r, rad/s (default 0.005).
        accel_bias_walk_m_s2_sqrt_s: random walk of the accelerometer biases, m/s^2/sqrt(s)
            (default 0.0005).
        gyro_bias_walk_rad_s_sqrt_s: random walk of the gyro bias, rad/s/sqrt(s) (default
            0.0001).
        learn_hold_s: the weights are not updated within this time of the initialization,
            while the EKFs' state converges from its prior (a start in a turn would otherwise
            be taken as stiffness), s (default 2.0).
        fit_window_s: time constant of :attr:`GridEkf.nis_mean`, the exponential mean of the
            weighted normalized innovation squared (a diagnostic: about 3 while the model fits
            the data), s (default 1.0).
    """

    #: the bias fields, zero when Algorithm 1's configuration has no bias states
    #: (``imu_bias_states`` false)
    BIAS_FIELDS: ClassVar[tuple[str, ...]] = (
        "accel_bias_std_m_s2",
        "gyro_bias_std_rad_s",
        "accel_bias_walk_m_s2_sqrt_s",
        "gyro_bias_walk_rad_s_sqrt_s",
    )

    grid_points: Annotated[int, int_in_range(5, 201)] = 25
    grid_span_sigma: Annotated[float, in_range(1.0, 20.0)] = 4.0
    regrid_min_cells: Annotated[float, in_range(0.1, 100.0)] = 1.5
    regrid_edge_mass: Fraction = 1e-3
    forgetting: Annotated[float, in_range(0.5, 1.0)] = 0.999
    state_jitter_vx_m_s_sqrt_s: NonNegative = 0.015
    state_jitter_vy_m_s_sqrt_s: NonNegative = 0.006
    state_jitter_yaw_rate_rad_s_sqrt_s: NonNegative = 0.0006
    accel_bias_std_m_s2: NonNegative = 0.1
    gyro_bias_std_rad_s: NonNegative = 0.005
    accel_bias_walk_m_s2_sqrt_s: NonNegative = 0.0005
    gyro_bias_walk_rad_s_sqrt_s: NonNegative = 0.0001
    learn_hold_s: Annotated[float, in_range(0.0, 600.0)] = 2.0
    fit_window_s: Positive = 1.0

    @classmethod
    def sharing(cls, other: Any, **overrides: Any) -> GridConfig:
        """:meth:`BaselineConfig.sharing`, without bias states where ``other`` has
        ``imu_bias_states`` false."""
        extra: dict[str, float] = {}
        if not getattr(other, "imu_bias_states", True):
            extra = dict.fromkeys(cls.BIAS_FIELDS, 0.0)
        return super().sharing(other, **{**extra, **overrides})

    @property
    def estimates_bias(self) -> bool:
        """The EKFs carry the IMU biases (a non-zero prior std)."""
        return self.accel_bias_std_m_s2 > 0.0 or self.gyro_bias_std_rad_s > 0.0


def lattice(points: int) -> F64:
    """Unit lattice ``u`` (G^2, 2) over [-1, 1]^2, row-major (axis 0 slow)."""
    g = np.linspace(-1.0, 1.0, points)
    u0, u1 = np.meshgrid(g, g, indexing="ij")
    return np.column_stack([u0.ravel(), u1.ravel()])


def gaussian_fit(cells: F64, q: F64) -> tuple[F64, F64]:
    """Weighted mean (2,) and covariance (2, 2) of the cells (K, 2) with weights ``q`` (K,)."""
    m = q @ cells
    dev = cells - m
    return m, np.einsum("k,ki,kj->ij", q, dev, dev)


def posterior(f: GridEkf) -> tuple[F64, F64]:
    """Mean (2,) and covariance (2, 2) of ``(dCy_f, dCy_r)`` (deviation from nominal, N/rad)
    on the grid of ``f``."""
    return gaussian_fit(f.w[:, 1:], f.q)


def principal_axes(cov: F64, floor: F64) -> F64:
    """``L`` (2, 2) with ``L L^T = cov``, columns along the principal axes; each std at least
    ``floor`` (2,) projected on its axis (a grid never narrower than that)."""
    s2, u = np.linalg.eigh(0.5 * (cov + cov.T))
    # the floor of each axis: the floor ellipse's std along it
    floor2 = (u * u).T @ (floor * floor)
    s = np.sqrt(np.maximum(s2, floor2))
    return u * s[None, :]


class GridEkf(StiffnessFilter):
    """Point-mass filter on ``(Cy_f, Cy_r)``, one EKF on ``[vX, vY, r]`` per cell, vectorized.

    Args:
        config: :class:`GridConfig`.
        params: single-track parameters (nominal stiffness, geometry, tyre).
    """

    def __init__(self, config: GridConfig, params: SingleTrackParams) -> None:
        self._set_model(config, params)
        c = config
        jitter = [
            c.state_jitter_vx_m_s_sqrt_s,
            c.state_jitter_vy_m_s_sqrt_s,
            c.state_jitter_yaw_rate_rad_s_sqrt_s,
        ]
        #: EKF state [vX, vY, r] or, with the biases, [vX, vY, r, b_ax, b_ay, b_r]
        self.nx = 6 if c.estimates_bias else 3
        walk = [c.accel_bias_walk_m_s2_sqrt_s] * 2 + [c.gyro_bias_walk_rad_s_sqrt_s]
        #: process noise per second, diag Q / Ts (eq. 9 jitter and eq. 29 bias walk)
        self.q_rate = np.array(jitter + (walk if self.nx == 6 else [])) ** 2
        self.bias_var0 = np.array([c.accel_bias_std_m_s2] * 2 + [c.gyro_bias_std_rad_s]) ** 2
        self.u = lattice(config.grid_points)
        self.k = self.u.shape[0]
        #: the cells on the lattice's boundary ring (``regrid_edge_mass``)
        self._rim = np.any(np.abs(self.u) >= 1.0 - 1e-12, axis=1)
        #: the smallest posterior std a grid is laid for, N/rad (1e-4 of nominal)
        self.floor = 1e-4 * self.nominal[1:]
        self.initialized = False
        self.regrid_count = 0
        #: exponential mean of the weighted NIS (``fit_window_s``), 1
        self.nis_mean = 3.0
        #: time the weights have learned since the initialization, s
        self.learned_s = 0.0
        #: time since the initialization, s (``learn_hold_s``)
        self.since_start_s = 0.0
        self._dt_s = 0.0
        self.centre = np.zeros(2)
        self.axes = np.eye(2)
        self.w = np.zeros((self.k, 3))
        self.x = np.zeros((self.k, self.nx))
        self.p = np.zeros((self.k, self.nx, self.nx))
        self.log_q = np.zeros(self.k)
        self.q = np.full(self.k, 1.0 / self.k)
        self._rate: F64 | None = None
        self._jac: F64 | None = None

    # ------------------------------------------------------------------ grid
    def _cells(self, centre: F64, axes: F64) -> tuple[F64, F64]:
        """Stiffness deviations ``w`` (K, 3) of the grid ``centre + axes u`` and a log-weight
        offset (K,) that is -inf outside the projection bounds."""
        c = centre[None, :] + self.u @ axes.T
        w = np.empty((self.k, 3))
        w[:, 0] = (self.config.initial_stiffness_factor - 1.0) * self.nominal[0]
        w[:, 1:] = c
        inside = np.all((c >= self.lower[1:]) & (c <= self.upper[1:]), axis=1)
        return w, np.where(inside, 0.0, -np.inf)

    def _spacing_in_std(self, cov: F64) -> float:
        """Posterior std along its narrowest principal axis, in cell spacings of this grid."""
        h = 2.0 / (self.config.grid_points - 1)
        # the posterior covariance in lattice units: A^-1 V A^-T
        a_inv = np.linalg.inv(self.axes)
        cov_u = a_inv @ cov @ a_inv.T
        return float(np.sqrt(max(np.linalg.eigvalsh(0.5 * (cov_u + cov_u.T))[0], 0.0)) / h)

    def _edge_mass(self) -> float:
        return float(self.q[self._rim].sum())

    def regrid(self) -> None:
        """Lay a new grid along the posterior's principal axes (see the module doc)."""
        c = self.config
        cells = self.w[:, 1:]
        m, cov = gaussian_fit(cells, self.q)
        axes = c.grid_span_sigma * principal_axes(cov, self.floor)
        w_new, outside = self._cells(m, axes)
        # nearest old cell: lattice coordinates in the old grid, rounded to its points
        h = 2.0 / (c.grid_points - 1)
        u_old = (w_new[:, 1:] - self.centre) @ np.linalg.inv(self.axes).T
        idx = np.clip(np.rint((u_old + 1.0) / h), 0, c.grid_points - 1).astype(np.intp)
        nearest = idx[:, 0] * c.grid_points + idx[:, 1]
        dev = w_new[:, 1:] - m
        cov_inv = np.linalg.inv(axes @ axes.T / c.grid_span_sigma**2)
        # Gaussian N(m, V) of the posterior at the new cells
        self.log_q = -0.5 * np.einsum("ki,ij,kj->k", dev, cov_inv, dev) + outside
        self.x = self.x[nearest]
        self.p = self.p[nearest]
        if self._rate is not None and self._jac is not None:
            self._rate = self._rate[nearest]
            self._jac = self._jac[nearest]
        self.w = w_new
        self.centre, self.axes = m, axes
        self.q, _ = resampling.normalize_log_weights(self.log_q)
        self.regrid_count += 1

    # ------------------------------------------------------------------ filter
    def initialize(self, x0: F64, x0_std: F64) -> None:
        """Grid over the prior, every cell's EKF at ``x0`` with ``diag(x0_std^2)`` (biases at 0
        with their prior variance)."""
        c = self.config
        std0 = c.initial_stiffness_std_fraction * self.nominal[1:]
        self.centre = (c.initial_stiffness_factor - 1.0) * self.nominal[1:]
        self.axes = np.diag(c.grid_span_sigma * std0)
        self.w, outside = self._cells(self.centre, self.axes)
        # the prior N(f0 C_n, (s0 C_n)^2) per cornering stiffness
        z = (self.w[:, 1:] - self.centre) / std0
        self.log_q = -0.5 * np.sum(z * z, axis=1) + outside
        self.q, _ = resampling.normalize_log_weights(self.log_q)
        var0 = np.asarray(x0_std, dtype=float) ** 2
        if self.nx == 6:
            x0 = np.concatenate([x0, np.zeros(3)])
            var0 = np.concatenate([var0, self.bias_var0])
        self.x = np.tile(x0, (self.k, 1))
        self.p = np.tile(np.diag(var0), (self.k, 1, 1))
        self._rate = self._jac = None
        self.nis_mean = 3.0
        self.since_start_s = 0.0
        self.learned_s = 0.0
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """EKF time update of every cell with the inputs of the last update (eq. 9)."""
        if self._rate is None or self._jac is None:
            return
        # eq. (9) x_{k+1} = x_k + Ts f(x_k, C), F = I + Ts df/dx; eq. (29) b_{k+1} = b_k
        self.x[:, :3] += dt_s * self._rate
        self.x[:, 0] = np.maximum(self.x[:, 0], 0.0)
        f = np.tile(np.eye(self.nx), (self.k, 1, 1))
        f[:, :3, :3] += dt_s * self._jac
        # P_{k+1|k} = F P F^T + Q Ts
        self.p = f @ self.p @ np.transpose(f, (0, 2, 1)) + np.diag(self.q_rate * dt_s)
        self.since_start_s += dt_s
        self._dt_s = dt_s

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """EKF update of every cell; with ``learn`` the cell weights take its predictive
        density of ``y`` (Bayes on the grid); the next step's derivative and Jacobian."""
        if meas.vx_measured:
            self.x[:, 0] = meas.speed_m_s
            self.p[:, 0, :] = 0.0
            self.p[:, :, 0] = 0.0
            self.p[:, 0, 0] = WHEEL_SPEED_NOISE_STD_M_S**2 + 1e-6
        k = self.k
        eye = np.diag(JACOBIAN_STEP)
        xv = self.x[:, :3]
        xs = np.concatenate([xv] + [xv + eye[j] for j in range(3)])
        xs = np.concatenate([xs] + [xv - eye[j] for j in range(3)])
        rate, y_hat, _, _ = model(
            xs, np.tile(self.w, (7, 1)), meas.delta_rad, meas.wheel_speed_m_s, self.params
        )
        rate = rate.reshape(7, k, 3)
        y_hat = y_hat.reshape(7, k, 3)
        # central differences: column j = (g(x + h_j e_j) - g(x - h_j e_j)) / (2 h_j)
        two_h = 2.0 * JACOBIAN_STEP
        h_jac = np.zeros((k, 3, self.nx))
        for j in range(3):
            h_jac[:, :, j] = (y_hat[1 + j] - y_hat[4 + j]) / two_h[j]
        f_jac = np.stack([(rate[1 + j] - rate[4 + j]) / two_h[j] for j in range(3)], axis=-1)
        y_pred = y_hat[0]
        if self.nx == 6:
            # eq. (12) y = h(x) + b + e: the bias enters with the identity
            h_jac[:, :, 3:] = np.eye(3)
            y_pred = y_pred + self.x[:, 3:]
        r = measurement_cov(
            self.r_cov,
            xv,
            meas.delta_rad,
            meas.wheel_speed_m_s,
            self.params,
            self.nominal[0] + self.w[:, 0],
        )
        # eq. (12) linearized per cell: S = H P H^T + R, K = P H^T S^-1
        ph_t = self.p @ np.transpose(h_jac, (0, 2, 1))
        s = h_jac @ ph_t + r
        chol = np.linalg.cholesky(s)
        nu = meas.y[None, :] - y_pred
        z = np.linalg.solve(chol, nu[..., None])[..., 0]
        nis = np.sum(z * z, axis=-1)
        a = min(1.0, self._dt_s / self.config.fit_window_s)
        self.nis_mean += a * (float(self.q @ nis) - self.nis_mean)
        learn = learn and self.since_start_s >= self.config.learn_hold_s
        if learn:
            # predictive density N(y; y_hat, S) of each cell: the likelihood of its stiffness
            log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
            log_lik = -0.5 * (nis + log_det + 3.0 * _LOG_2PI)
            # forgetting: log q <- lambda log q (relative to the best cell), then Bayes
            finite = np.isfinite(self.log_q)
            top = np.max(self.log_q[finite])
            self.log_q = np.where(
                finite, self.config.forgetting * (self.log_q - top) + log_lik, -np.inf
            )
            self.q, _ = resampling.normalize_log_weights(self.log_q)
            self.learned_s += self._dt_s
        gain = np.transpose(np.linalg.solve(s, np.transpose(ph_t, (0, 2, 1))), (0, 2, 1))
        dx = np.einsum("kij,kj->ki", gain, nu)
        self.x += dx
        # Joseph form P = (I - K H) P (I - K H)^T + K R K^T
        ikh = np.eye(self.nx)[None, :, :] - gain @ h_jac
        self.p = ikh @ self.p @ np.transpose(ikh, (0, 2, 1))
        self.p += gain @ r @ np.transpose(gain, (0, 2, 1))
        self.p = 0.5 * (self.p + np.transpose(self.p, (0, 2, 1)))
        # derivative at the updated state to first order: f(x + dx) = f(x) + F dx
        self._rate = rate[0] + np.einsum("kij,kj->ki", f_jac, dx[:, :3])
        self._jac = f_jac
        if learn:
            c = self.config
            _, cov = gaussian_fit(self.w[:, 1:], self.q)
            if (
                self._spacing_in_std(cov) < c.regrid_min_cells
                or self._edge_mass() > c.regrid_edge_mass
            ):
                self.regrid()

    def estimate(self) -> FilterEstimate:
        """Posterior mean and std of the stiffness (Cx: the prior), mixture mean and
        covariance of the state, mixture mean of the biases."""
        q = self.q
        m, cov = gaussian_fit(self.w[:, 1:], q)
        std = np.empty(3)
        std[0] = self.config.initial_stiffness_std_fraction * self.nominal[0]
        std[1:] = np.sqrt(np.maximum(np.diag(cov), 0.0))
        xm = q @ self.x
        dx = self.x - xm
        cov = np.einsum("k,kij->ij", q, self.p) + np.einsum("k,ki,kj->ij", q, dx, dx)
        return FilterEstimate(
            stiffness=self.nominal + np.concatenate([[self.w[0, 0]], m]),
            stiffness_std=std,
            state=xm[:3],
            state_cov=cov[:3, :3],
            n_eff=resampling.ess(q),
            bias=xm[3:] if self.nx == 6 else None,
        )


__all__ = [
    "GridConfig",
    "GridEkf",
    "gaussian_fit",
    "lattice",
    "posterior",
    "principal_axes",
]
