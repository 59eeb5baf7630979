"""Baselines of the tyre-stiffness estimator: AUGPF, EKF and KF + RLS, and the grid on its own.

Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on noise-adaptive
particle filtering", IEEE TCST 2018, compare Algorithm 1 (``core.stiffness.mpf``) with a
state-augmented particle filter (AUGPF, Sec. V-VI), a Kalman filter for the lateral dynamics
feeding a linear regression (RLS, Sec. VI-A) and an EKF (Sec. VII). The three filters here use
the single-track model of ``core.stiffness.model`` (eq. 1-12, with ``w = C - C_n``, eq. 7) in
the form of :func:`~tire_estimation.core.stiffness.filter.model`, and run behind Algorithm 1's
own front-end (:class:`BaselineEstimator`, a
:class:`~tire_estimation.core.stiffness.frontend.StiffnessFrontEnd`: the same callbacks, input
checks, activation and replay, returning the same
:class:`~tire_estimation.core.stiffness.frontend.StiffnessEstimate`). Only the filter differs:

* :class:`AugPf` (:class:`AugPfConfig`): bootstrap particle filter on the augmented state
  ``[vX, vY, r, dCx, dCy_f, dCy_r]``; the stiffness deviation is a Gaussian random walk
  (artificial dynamics), the proposal is the prior (eq. 9 + random walk), the weights are the
  Gaussian likelihood of the IMU measurement (eq. 12 with ``R``), systematic resampling. Left
  out w.r.t. the paper's AUGPF: the three extra states of the inverse-Wishart random walk of
  the noise variances (the paper's AUGPF has 9 states, this one 6).
* :class:`AugEkf` (:class:`EkfConfig`): extended Kalman filter on the same 6 states and
  artificial dynamics, Jacobians of ``core.stiffness.model.linearize`` by central differences
  in the vehicle states (the model is affine in ``w``: that block is exact).
* :class:`KfRls` (:class:`RlsConfig`): Kalman filter on ``[vY, r]`` with ``vX`` the measured
  speed (see :class:`RlsConfig`), feeding a recursive least squares with forgetting that
  regresses the measured lateral acceleration and yaw acceleration on the slip angles to get
  ``[Cy_f, Cy_r]``; ``Cx`` is not estimated.

:class:`BaselineEstimator` also runs the point-mass filter of ``core.stiffness.grid``
(:class:`~tire_estimation.core.stiffness.grid.GridConfig`) on its own.

With ``friction_coefficient`` mu > 0 all three use the friction-limited lateral tyre of
Algorithm 1 (peak at the friction limit): ``Fy = mu Fz tanh(C alpha / (mu Fz))`` per axle,
i.e. ``C phi(alpha)`` with ``alpha_s = mu Fz / C`` at the method's own stiffness (per particle in
AUGPF, the estimate in the EKF and the RLS), in the shape Algorithm 1 is given (``tyre_shape``:
the tanh, or the Magic Formula of ``stiffness_model.lateral_slip_function``); the model is then no
longer affine in ``w``, and the EKF takes its ``w`` Jacobian by central differences too.

None of them estimates the IMU biases (the paper's simulation, Sec. VI-A, is bias-free):
compare them on bias-free sensors. The reported ``stiffness_std`` is the posterior std of the
stiffness estimate (particle spread, ``sqrt(diag P)``), not the std of the stiffness noise
``w`` that Algorithm 1 reports (eq. 27b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

import numpy as np

from tire_estimation.core import resampling
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness.filter import (
    JACOBIAN_STEP,
    BaselineConfig,
    FilterEstimate,
    Measurement,
    StiffnessFilter,
    friction_saturation,
    model,
)
from tire_estimation.core.stiffness.frontend import StiffnessFrontEnd
from tire_estimation.core.stiffness.grid import GridConfig, GridEkf
from tire_estimation.core.stiffness.model import (
    WHEEL_SPEED_NOISE_STD_M_S,
    SingleTrackParams,
    linearize,
    measurement_cov,
    stiffness_bounds,
)
from tire_estimation.core.validation import (
    Flag,
    NonNegative,
    Positive,
    in_range,
    int_in_range,
    one_of,
)
from tire_estimation.core.vehicle import VehicleParams

#: Central-difference steps in ``w`` (friction-limited tyre only), fraction of ``C_n``.
W_JACOBIAN_STEP_FRACTION = 1e-4
_LOG_2PI = math.log(2.0 * math.pi)


# ---------------------------------------------------------------------------- configuration
#: suffixes of the state-noise fields ``{prefix}_...`` of vX, vY and r
_STATE_NOISES = ("vx_m_s_sqrt_s", "vy_m_s_sqrt_s", "yaw_rate_rad_s_sqrt_s")


#: the std of the stiffness random walk: within [0, 5] of nominal per sqrt(s)
WalkFraction = Annotated[float, in_range(0.0, 5.0)]


def _state_noise(config: BaselineConfig, prefix: str) -> F64:
    """The state noises ``{prefix}_...`` (suffixes :data:`_STATE_NOISES`) of ``config``, (3,) =
    [vX, vY, r], per sqrt(s)."""
    return np.array([getattr(config, f"{prefix}_{state}") for state in _STATE_NOISES])


@dataclass(frozen=True)
class AugPfConfig(BaselineConfig):
    """AUGPF: bootstrap particle filter on ``[vX, vY, r, dCx, dCy_f, dCy_r]``.

    Attributes:
        n_particles: number of particles N, 1 (default 200).
        resample_threshold: systematic resampling when N_eff <= threshold * N, 1 (0.5).
        stiffness_walk_std_fraction_sqrt_s: std of the random walk of every stiffness state
            (artificial dynamics), fraction of nominal per sqrt(s), 1/sqrt(s) (default 0.2:
            the paper's 2 % per step (Sec. VI-A) read as per 10 ms IMU step; 0.01-0.1
            collapsed onto wrong stiffness and diverged on stiffness_step seeds 0-2).
        state_jitter_vx_m_s_sqrt_s: process noise of vX, m/s/sqrt(s) (0.05, as Algorithm 1).
        state_jitter_vy_m_s_sqrt_s: process noise of vY, m/s/sqrt(s) (0.02).
        state_jitter_yaw_rate_rad_s_sqrt_s: process noise of the yaw rate, rad/s/sqrt(s)
            (0.002).
    """

    n_particles: Annotated[int, int_in_range(1, 1_000_000)] = 200
    resample_threshold: Annotated[float, in_range(0.0, 1.0)] = 0.5
    stiffness_walk_std_fraction_sqrt_s: WalkFraction = 0.2
    state_jitter_vx_m_s_sqrt_s: NonNegative = 0.05
    state_jitter_vy_m_s_sqrt_s: NonNegative = 0.02
    state_jitter_yaw_rate_rad_s_sqrt_s: NonNegative = 0.002


@dataclass(frozen=True)
class EkfConfig(BaselineConfig):
    """EKF on ``[vX, vY, r, dCx, dCy_f, dCy_r]``.

    Attributes:
        stiffness_walk_std_fraction_sqrt_s: std of the stiffness random walk (Q), fraction of
            nominal per sqrt(s), 1/sqrt(s) (default 0.02, tuned on stiffness_step seeds 0-2).
        process_vx_m_s_sqrt_s: process noise of vX (Q), m/s/sqrt(s) (default 0.05).
        process_vy_m_s_sqrt_s: process noise of vY (Q), m/s/sqrt(s) (default 0.02).
        process_yaw_rate_rad_s_sqrt_s: process noise of the yaw rate (Q), rad/s/sqrt(s)
            (default 0.002).
    """

    stiffness_walk_std_fraction_sqrt_s: WalkFraction = 0.02
    process_vx_m_s_sqrt_s: Positive = 0.05
    process_vy_m_s_sqrt_s: Positive = 0.02
    process_yaw_rate_rad_s_sqrt_s: Positive = 0.002


@dataclass(frozen=True)
class RlsConfig(BaselineConfig):
    """Kalman filter on ``[vY, r]`` feeding a recursive least squares of ``[Cy_f, Cy_r]``.

    Attributes:
        forgetting: RLS forgetting factor per IMU step, 1 (default 0.99: memory ~1 s at
            100 Hz; 0.998 locked onto ~20 % of the true stiffness for ~30 s on
            stiffness_step seed 0).
        kf_stiffness: cornering stiffness of the Kalman filter's model: ``estimate`` (the
            current RLS estimate, starting at the initial guess) or ``nominal`` (the vehicle's
            nominal values), default ``estimate``.
        kf_measures_accel: the Kalman filter also measures the lateral acceleration (else only
            the yaw rate), default False.
        process_vy_m_s_sqrt_s: process noise of vY (Q), m/s/sqrt(s) (default 0.02).
        process_yaw_rate_rad_s_sqrt_s: process noise of the yaw rate (Q), rad/s/sqrt(s)
            (default 0.002).
    """

    forgetting: Annotated[float, in_range(0.5, 1.0)] = 0.99
    kf_stiffness: Annotated[str, one_of(("estimate", "nominal"))] = "estimate"
    kf_measures_accel: Flag = False
    process_vy_m_s_sqrt_s: Positive = 0.02
    process_yaw_rate_rad_s_sqrt_s: Positive = 0.002


# ---------------------------------------------------------------------------- model helpers
def model_jacobian(
    x: F64, w: F64, delta_rad: float, wheel_speed_m_s: tuple[float, float], p: SingleTrackParams
) -> tuple[F64, F64, F64, F64, F64, F64]:
    """:func:`model` at one state and its Jacobians in ``x`` and ``w`` by central differences.

    ``x`` (3,), ``w`` (3,) -> ``rate`` (3,), ``y_hat`` (3,), ``d rate / dx`` (3, 3),
    ``d y_hat / dx`` (3, 3), ``d rate / dw`` (3, 3) and ``d y_hat / dw`` (3, 3). With the
    linear tyre the model is affine in ``w`` (eq. 9 and 12) and the ``w`` Jacobians are its
    exact ``a`` and ``d``: one vectorized call on 7 rows. With the friction-limited tyre they
    are central differences too (13 rows, steps ``W_JACOBIAN_STEP_FRACTION`` of ``C_n``).
    """
    eye = np.diag(JACOBIAN_STEP)
    friction = friction_saturation(p, w[None, :]) is not None
    xs = np.vstack([x[None, :], x[None, :] + eye, x[None, :] - eye])
    ws = np.broadcast_to(w, xs.shape)
    if friction:
        hw = np.diag(W_JACOBIAN_STEP_FRACTION * np.asarray(p.nominal, dtype=float))
        xs = np.vstack([xs, np.broadcast_to(x, (6, 3))])
        ws = np.vstack([ws, w[None, :] + hw, w[None, :] - hw])
    rate, y_hat, a, d = model(xs, ws, delta_rad, wheel_speed_m_s, p)
    # central differences: column j = (f(x + h_j e_j) - f(x - h_j e_j)) / (2 h_j)
    d_rate = ((rate[1:4] - rate[4:7]) / (2.0 * JACOBIAN_STEP[:, None])).T
    d_meas = ((y_hat[1:4] - y_hat[4:7]) / (2.0 * JACOBIAN_STEP[:, None])).T
    if not friction:
        return rate[0], y_hat[0], d_rate, d_meas, a[0], d[0]
    step_w = 2.0 * W_JACOBIAN_STEP_FRACTION * np.asarray(p.nominal, dtype=float)
    # d/dw of Fy = mu Fz tanh(C alpha / (mu Fz)): central differences in w as well
    d_rate_w = ((rate[7:10] - rate[10:13]) / step_w[:, None]).T
    d_meas_w = ((y_hat[7:10] - y_hat[10:13]) / step_w[:, None]).T
    return rate[0], y_hat[0], d_rate, d_meas, d_rate_w, d_meas_w


def gaussian_logpdf(e: F64, cov: F64) -> F64:
    """Log N(e; 0, cov) per row: ``e`` (N, m), ``cov`` (N, m, m) -> (N,)."""
    chol = np.linalg.cholesky(cov)
    z = np.linalg.solve(chol, e[..., None])[..., 0]
    log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * (np.sum(z * z, axis=-1) + log_det + e.shape[-1] * _LOG_2PI)


# ---------------------------------------------------------------------------- AUGPF
class AugPf(StiffnessFilter):
    """Bootstrap particle filter on ``[vX, vY, r, w]``, vectorized over particles.

    Args:
        config: :class:`AugPfConfig`.
        params: single-track parameters (nominal stiffness C_n, geometry).
        rng: generator of every random draw.
    """

    def __init__(
        self, config: AugPfConfig, params: SingleTrackParams, rng: np.random.Generator
    ) -> None:
        self._set_model(config, params)
        self.rng = rng
        self.n = config.n_particles
        self.jitter = _state_noise(config, "state_jitter")
        self.walk = config.stiffness_walk_std_fraction_sqrt_s * self.nominal
        self.initialized = False
        self.x = np.zeros((self.n, 3))
        self.w = np.zeros((self.n, 3))
        self.rate = np.zeros((self.n, 3))
        self.log_w = np.full(self.n, -math.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.n_eff = float(self.n)
        self.resample_count = 0

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """x ~ N(x0, diag(x0_std^2)), C ~ N(f0 C_n, (s0 C_n)^2) per component, q = 1/N."""
        c = self.config
        self.x = x0[None, :] + self.rng.standard_normal((self.n, 3)) * x0_std[None, :]
        mean0 = (c.initial_stiffness_factor - 1.0) * self.nominal
        std0 = c.initial_stiffness_std_fraction * self.nominal
        self.w = np.clip(
            mean0[None, :] + self.rng.standard_normal((self.n, 3)) * std0[None, :],
            self.lower,
            self.upper,
        )
        self.rate = np.zeros((self.n, 3))
        self.log_w = np.full(self.n, -math.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.n_eff = float(self.n)
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """Sample the prior (bootstrap proposal): eq. (9) plus the stiffness random walk."""
        # eq. (9) x_{k+1} = x_k + Ts (rate_n(x_k) + a(x_k) w_k), rate stored at update()
        self.x += dt_s * self.rate
        self.x += self.rng.standard_normal((self.n, 3)) * (self.jitter * math.sqrt(dt_s))
        self.x[:, 0] = np.maximum(self.x[:, 0], 0.0)
        if learn:
            step = self.walk * math.sqrt(dt_s)
            if not learn_cx:
                step = step * np.array([0.0, 1.0, 1.0])
            # artificial dynamics (AUGPF): w_{k+1} = w_k + v_k, v_k ~ N(0, diag(step^2))
            self.w += self.rng.standard_normal((self.n, 3)) * step
            np.clip(self.w, self.lower, self.upper, out=self.w)

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """Weights from the Gaussian likelihood of ``y`` (eq. 12), resampling, next rate."""
        if meas.vx_measured:
            self.x[:, 0] = meas.speed_m_s
        p = self.params
        rate, y_hat, _, _ = model(self.x, self.w, meas.delta_rad, meas.wheel_speed_m_s, p)
        cov = measurement_cov(
            self.r_cov,
            self.x,
            meas.delta_rad,
            meas.wheel_speed_m_s,
            p,
            self.nominal[0] + self.w[:, 0],
        )
        # eq. (12): q_k ∝ q_{k-1} N(y; h(x) + d(x) w, R)  (bootstrap: proposal = prior)
        self.log_w += gaussian_logpdf(meas.y[None, :] - y_hat, cov)
        self.weights, _ = resampling.normalize_log_weights(self.log_w)
        self.n_eff = resampling.ess(self.weights)
        self.rate = rate
        if self.n_eff <= self.config.resample_threshold * self.n:
            idx = resampling.systematic(self.weights, self.rng)
            self.x = self.x[idx]
            self.w = self.w[idx]
            self.rate = self.rate[idx]
            self.weights = np.full(self.n, 1.0 / self.n)
            self.resample_count += 1
        self.log_w = resampling.log_of_weights(self.weights)

    def estimate(self) -> FilterEstimate:
        """Weighted means and covariances of the particles."""
        q = self.weights
        wm = q @ self.w
        dw = self.w - wm
        xm = q @ self.x
        dx = self.x - xm
        return FilterEstimate(
            stiffness=self.nominal + wm,
            stiffness_std=np.sqrt(np.maximum(q @ (dw * dw), 0.0)),
            state=xm,
            state_cov=np.einsum("n,ni,nj->ij", q, dx, dx),
            n_eff=float(self.n_eff),
        )


# ---------------------------------------------------------------------------- EKF
class AugEkf(StiffnessFilter):
    """Extended Kalman filter on ``z = [vX, vY, r, w]`` (6,).

    Args:
        config: :class:`EkfConfig`.
        params: single-track parameters.
    """

    def __init__(self, config: EkfConfig, params: SingleTrackParams) -> None:
        self._set_model(config, params)
        self.q_state = _state_noise(config, "process")
        self.q_walk = config.stiffness_walk_std_fraction_sqrt_s * self.nominal
        self.initialized = False
        self.z = np.zeros(6)
        self.p = np.eye(6)
        self._inputs: tuple[float, tuple[float, float]] | None = None

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """z0 = [x0, (f0 - 1) C_n], P0 = diag(x0_std^2, (s0 C_n)^2)."""
        c = self.config
        self.z = np.concatenate([x0, (c.initial_stiffness_factor - 1.0) * self.nominal])
        std0 = c.initial_stiffness_std_fraction * self.nominal
        self.p = np.diag(np.concatenate([x0_std, std0]) ** 2)
        self._inputs = None
        self.initialized = True

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """EKF time update with the inputs of the last update."""
        if self._inputs is None:
            return
        delta, ws = self._inputs
        x, w = self.z[:3], self.z[3:]
        rate, _, d_rate, _, a, _ = model_jacobian(x, w, delta, ws, self.params)
        # eq. (9) x_{k+1} = x_k + Ts (rate_n(x_k) + a(x_k) w_k); w_{k+1} = w_k + v_k
        self.z[:3] = x + dt_s * rate
        self.z[0] = max(self.z[0], 0.0)
        # F = d z_{k+1} / d z_k = [[I + Ts d rate/dx, Ts a], [0, I]]
        f = np.eye(6)
        f[:3, :3] += dt_s * d_rate
        f[:3, 3:] = dt_s * a
        walk = self.q_walk.copy() if learn else np.zeros(3)
        if not learn_cx:
            walk[0] = 0.0
        q = np.diag(np.concatenate([self.q_state, walk]) ** 2 * dt_s)
        # P_{k+1|k} = F P F^T + Q
        self.p = f @ self.p @ f.T + q

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """EKF measurement update (Joseph form); the stiffness rows of K are zero when frozen."""
        if meas.vx_measured:
            self.z[0] = meas.speed_m_s
            self.p[0, :] = 0.0
            self.p[:, 0] = 0.0
            self.p[0, 0] = WHEEL_SPEED_NOISE_STD_M_S**2 + 1e-6
        x, w = self.z[:3], self.z[3:]
        _, y_hat, _, d_meas, _, d = model_jacobian(
            x, w, meas.delta_rad, meas.wheel_speed_m_s, self.params
        )
        # eq. (12) linearized: H = [d(h + d w)/dx, d]
        h = np.hstack([d_meas, d])
        r = measurement_cov(
            self.r_cov,
            x[None, :],
            meas.delta_rad,
            meas.wheel_speed_m_s,
            self.params,
            np.array([self.nominal[0] + w[0]]),
        )[0]
        # S = H P H^T + R, K = P H^T S^-1
        s = h @ self.p @ h.T + r
        k = np.linalg.solve(s, h @ self.p).T
        if not learn:
            k[3:, :] = 0.0
        elif not learn_cx:
            k[3, :] = 0.0
        # z_{k|k} = z_{k|k-1} + K (y - y_hat)
        self.z = self.z + k @ (meas.y - y_hat)
        self.z[3:] = np.clip(self.z[3:], self.lower, self.upper)
        # Joseph form P = (I - K H) P (I - K H)^T + K R K^T (valid for the frozen-row gain)
        ikh = np.eye(6) - k @ h
        self.p = ikh @ self.p @ ikh.T + k @ r @ k.T
        self.p = 0.5 * (self.p + self.p.T)
        self._inputs = (meas.delta_rad, meas.wheel_speed_m_s)

    def estimate(self) -> FilterEstimate:
        """Mean and covariance of the EKF."""
        return FilterEstimate(
            stiffness=self.nominal + self.z[3:],
            stiffness_std=np.sqrt(np.maximum(np.diag(self.p)[3:], 0.0)),
            state=self.z[:3].copy(),
            state_cov=self.p[:3, :3].copy(),
            n_eff=float("nan"),
        )


# ---------------------------------------------------------------------------- KF + RLS
class KfRls(StiffnessFilter):
    """Kalman filter on ``[vY, r]`` (``vX`` measured) feeding an RLS of ``[Cy_f, Cy_r]``.

    Regression (eq. 1b-c with eq. 2 and 4, linear in ``theta = [Cy_f, Cy_r]``), two rows per
    IMU step, using the slip angles of the Kalman filter's posterior ``[vY, r]``:

    * lateral specific force at the IMU (no differentiation needed):
      ``ay_imu + r^2 p_y - d_{y,x} Cx = d_{y,f} Cy_f + d_{y,r} Cy_r``, ``d`` of eq. (12);
    * yaw acceleration from the gyro by a central difference one step late,
      ``(r_{k+1} - r_{k-1}) / (t_{k+1} - t_{k-1}) - a_{r,x} Cx = a_{r,f} Cy_f + a_{r,r} Cy_r``
      (rows of ``a``, eq. 1c, at step ``k``).

    The outputs are weighted by their noise variances (``sigma_a^2`` and ``2 sigma_g^2 /
    (2 Ts)^2``): the RLS is the Kalman filter of a constant ``theta`` with forgetting. The
    slip angles are regressors, so their error (from the KF) is not modelled (errors in
    variables). Cx stays at the initial guess (the paper's RLS neither shows Cx).

    Args:
        config: :class:`RlsConfig`.
        params: single-track parameters.
    """

    def __init__(self, config: RlsConfig, params: SingleTrackParams) -> None:
        self.config = config
        self.params = params
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower, self.upper = stiffness_bounds(self.nominal)
        self.q_state = np.array(
            [config.process_vy_m_s_sqrt_s, config.process_yaw_rate_rad_s_sqrt_s]
        )
        self.initialized = False
        self.vx = 0.0
        self.xl = np.zeros(2)
        self.p = np.eye(2)
        self.theta = np.zeros(2)
        self.p_theta = np.eye(2)
        self._inputs: tuple[float, tuple[float, float]] | None = None
        self._t_s = 0.0
        self._hist: list[tuple[float, float, F64, bool]] = []

    def _c_kf(self) -> F64:
        """Stiffness deviation ``w`` used by the Kalman filter's model."""
        if self.config.kf_stiffness == "nominal":
            return np.zeros(3)
        w0 = (self.config.initial_stiffness_factor - 1.0) * self.nominal[0]
        return np.array([w0, self.theta[0] - self.nominal[1], self.theta[1] - self.nominal[2]])

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """KF at ``x0[1:]``, RLS at the initial guess with P = diag((s0 C_n)^2)."""
        c = self.config
        self.vx = float(x0[0])
        self.xl = x0[1:].astype(float).copy()
        self.p = np.diag(x0_std[1:] ** 2)
        self.theta = c.initial_stiffness_factor * self.nominal[1:]
        self.p_theta = np.diag((c.initial_stiffness_std_fraction * self.nominal[1:]) ** 2)
        self._inputs = None
        self._t_s = 0.0
        self._hist = []
        self.initialized = True

    def _x3(self) -> F64:
        return np.array([self.vx, self.xl[0], self.xl[1]])

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """KF time update of ``[vY, r]`` (eq. 9, rows 2-3) with the last inputs."""
        self._t_s += dt_s
        if self._inputs is None:
            return
        delta, ws = self._inputs
        rate, _, d_rate, _, _, _ = model_jacobian(self._x3(), self._c_kf(), delta, ws, self.params)
        # eq. (9) rows vY, r: x_{k+1} = x_k + Ts rate(x_k)
        self.xl = self.xl + dt_s * rate[1:]
        f = np.eye(2) + dt_s * d_rate[1:, 1:]
        # P = F P F^T + Q
        self.p = f @ self.p @ f.T + np.diag(self.q_state**2 * dt_s)

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """KF measurement update, then one RLS step (rows as in the class docstring)."""
        self.vx = meas.speed_m_s
        c = self.config
        p = self.params
        w_kf = self._c_kf()
        _, y_hat, _, d_meas, _, _ = model_jacobian(
            self._x3(), w_kf, meas.delta_rad, meas.wheel_speed_m_s, p
        )
        rows = [1, 2] if c.kf_measures_accel else [2]
        h = d_meas[np.ix_(rows, [1, 2])]
        r = np.diag([c.accel_noise_std_m_s2**2, c.gyro_noise_std_rad_s**2])
        r = r[-len(rows) :, -len(rows) :]
        # KF: S = H P H^T + R, K = P H^T S^-1, x += K (y - y_hat), P = (I - K H) P
        s = h @ self.p @ h.T + r
        k = np.linalg.solve(s, h @ self.p).T
        self.xl = self.xl + k @ (meas.y[rows] - y_hat[rows])
        ikh = np.eye(2) - k @ h
        self.p = ikh @ self.p @ ikh.T + k @ r @ k.T
        self._inputs = (meas.delta_rad, meas.wheel_speed_m_s)
        # regressors at the KF posterior (a and d of eq. 9 and 12 do not depend on w; with the
        # friction-limited tyre they are taken at alpha_s = mu Fz / theta, so the regression
        # model is exact at the current estimate)
        w_theta = np.concatenate([[0.0], self.theta - self.nominal[1:]])[None, :]
        lin = linearize(
            self._x3()[None, :],
            meas.delta_rad,
            meas.wheel_speed_m_s,
            p,
            friction_saturation(p, w_theta),
        )
        a, d = lin.a[0], lin.d[0]
        cx0 = c.initial_stiffness_factor * self.nominal[0]
        gyro = float(meas.y[2])
        hist = self._hist
        self._hist = [*hist[-1:], (self._t_s, gyro, a[2].copy(), learn)]
        if not learn:
            return
        # eq. (12) ay row at the IMU (h = lever (a C + a0) - r^2 p; a0_y = 0):
        # ay + r^2 p_y - d_yx Cx = [d_yf, d_yr] theta
        phi_rows = [d[1, 1:]]
        out = [meas.y[1] + self.xl[1] ** 2 * p.imu_y_m - d[1, 0] * cx0]
        noise = [c.accel_noise_std_m_s2**2]
        if len(hist) == 2 and hist[1][3]:
            t_pp, g_pp = hist[0][0], hist[0][1]
            a_r = hist[1][2]
            span = self._t_s - t_pp
            if span > 0.0:
                # eq. (1c) at step k-1: (r_k - r_{k-2}) / (t_k - t_{k-2}) - a_rx Cx = a_r theta
                phi_rows.append(a_r[1:])
                out.append((gyro - g_pp) / span - a_r[0] * cx0)
                noise.append(2.0 * c.gyro_noise_std_rad_s**2 / span**2)
        phi = np.array(phi_rows)
        lam = c.forgetting
        # RLS with forgetting: K = P phi^T (lam W + phi P phi^T)^-1, W = output noise cov
        s_t = lam * np.diag(noise) + phi @ self.p_theta @ phi.T
        k_t = np.linalg.solve(s_t, phi @ self.p_theta).T
        # theta += K (out - phi theta); P = (P - K phi P) / lam
        self.theta = self.theta + k_t @ (np.array(out) - phi @ self.theta)
        np.clip(
            self.theta,
            self.nominal[1:] + self.lower[1:],
            self.nominal[1:] + self.upper[1:],
            out=self.theta,
        )
        self.p_theta = (self.p_theta - k_t @ phi @ self.p_theta) / lam
        self.p_theta = 0.5 * (self.p_theta + self.p_theta.T)

    def estimate(self) -> FilterEstimate:
        """KF state and RLS parameters (Cx: the initial guess with the prior std)."""
        c = self.config
        cov = np.zeros((3, 3))
        cov[0, 0] = WHEEL_SPEED_NOISE_STD_M_S**2
        cov[1:, 1:] = self.p
        return FilterEstimate(
            stiffness=np.concatenate([[c.initial_stiffness_factor * self.nominal[0]], self.theta]),
            stiffness_std=np.concatenate(
                [
                    [c.initial_stiffness_std_fraction * self.nominal[0]],
                    np.sqrt(np.maximum(np.diag(self.p_theta), 0.0)),
                ]
            ),
            state=self._x3(),
            state_cov=cov,
            n_eff=float("nan"),
        )


# ---------------------------------------------------------------------------- front-end
class BaselineEstimator(StiffnessFrontEnd[StiffnessFilter]):
    """A baseline filter behind Algorithm 1's front-end; the filter follows the type of
    ``config``: :class:`AugPf` (:class:`AugPfConfig`), :class:`AugEkf` (:class:`EkfConfig`),
    :class:`KfRls` (:class:`RlsConfig`) or the point-mass filter
    :class:`~tire_estimation.core.stiffness.grid.GridEkf`
    (:class:`~tire_estimation.core.stiffness.grid.GridConfig`).

    Args:
        config: the filter's configuration.
        vehicle: geometry, nominal stiffness and drive.
        rng: random generator of every draw (only the AUGPF draws; default seed 0).
    """

    config: BaselineConfig

    def __init__(
        self,
        config: BaselineConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator | None = None,
    ) -> None:
        if not isinstance(config, (AugPfConfig, EkfConfig, RlsConfig, GridConfig)):
            raise TypeError(f"no baseline filter for {type(config).__name__}")
        super().__init__(config, vehicle, rng if rng is not None else np.random.default_rng(0))

    def make_filter(self) -> StiffnessFilter:
        """A fresh filter of the configuration's type."""
        c = self.config
        if isinstance(c, AugPfConfig):
            return AugPf(c, self.params, self.rng)
        if isinstance(c, EkfConfig):
            return AugEkf(c, self.params)
        if isinstance(c, RlsConfig):
            return KfRls(c, self.params)
        assert isinstance(c, GridConfig)
        return GridEkf(c, self.params)


__all__ = [
    "W_JACOBIAN_STEP_FRACTION",
    "AugEkf",
    "AugPf",
    "AugPfConfig",
    "BaselineEstimator",
    "EkfConfig",
    "KfRls",
    "RlsConfig",
    "gaussian_logpdf",
    "model_jacobian",
]
