"""Baselines of the tyre-stiffness estimator: AUGPF, EKF and KF + RLS.

Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on noise-adaptive
particle filtering", IEEE TCST 2018, compare Algorithm 1 (``core.stiffness_mpf``) with a
state-augmented particle filter (AUGPF, Sec. V-VI), a Kalman filter for the lateral dynamics
feeding a linear regression (RLS, Sec. VI-A) and an EKF (Sec. VII). The three estimators here
use the single-track model of ``core.stiffness_model`` (eq. 1-12, with ``w = C - C_n``, eq. 7)
and one shared sample-by-sample front-end (:class:`BaselineEstimator`: the callbacks, input
checks and activation logic of
:class:`~tire_estimation.core.stiffness_estimator.StiffnessEstimator`, returning the same
:class:`~tire_estimation.core.stiffness_estimator.StiffnessEstimate`). Only the filter differs:

* :class:`AugPfEstimator` (:class:`AugPf`): bootstrap particle filter on the augmented state
  ``[vX, vY, r, dCx, dCy_f, dCy_r]``; the stiffness deviation is a Gaussian random walk
  (artificial dynamics), the proposal is the prior (eq. 9 + random walk), the weights are the
  Gaussian likelihood of the IMU measurement (eq. 12 with ``R``), systematic resampling. Left
  out w.r.t. the paper's AUGPF: the three extra states of the inverse-Wishart random walk of
  the noise variances (the paper's AUGPF has 9 states, this one 6).
* :class:`EkfEstimator` (:class:`AugEkf`): extended Kalman filter on the same 6 states and
  artificial dynamics, Jacobians of ``core.stiffness_model.linearize`` by central differences
  in the vehicle states (the model is affine in ``w``: that block is exact).
* :class:`RlsEstimator` (:class:`KfRls`): Kalman filter on ``[vY, r]`` with ``vX`` the measured
  speed (see :class:`RlsConfig`), feeding a recursive least squares with forgetting that
  regresses the measured lateral acceleration and yaw acceleration on the slip angles to get
  ``[Cy_f, Cy_r]``; ``Cx`` is not estimated.

With ``friction_coefficient`` mu > 0 all three use the friction-limited lateral tyre of
Algorithm 1 (``saturation_peak`` = ``friction``): ``Fy = mu Fz tanh(C alpha / (mu Fz))`` per axle,
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
from dataclasses import dataclass, fields
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import resampling
from tire_estimation.core.activation_replay import ActivationReplay
from tire_estimation.core.stiffness_config import require_tyre_shape
from tire_estimation.core.stiffness_estimator import SlidingWindow, StiffnessEstimate
from tire_estimation.core.stiffness_model import (
    NAMES,
    SingleTrackParams,
    linearize,
    roll_compensate,
    saturation_slip_at,
    wheel_speed_gain,
)
from tire_estimation.core.validation import (
    require_choice,
    require_int_range,
    require_non_negative,
    require_positive,
    require_range,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, InputError

F64 = NDArray[np.float64]
DRIVE_CHOICES = ("vehicle", "front", "rear", "all")
#: Central-difference steps of the numeric Jacobians in [vX m/s, vY m/s, r rad/s].
JACOBIAN_STEP = np.array([1e-3, 1e-3, 1e-4])
#: Central-difference steps in ``w`` (friction-limited tyre only), fraction of ``C_n``.
W_JACOBIAN_STEP_FRACTION = 1e-4
_LOG_2PI = math.log(2.0 * math.pi)

C = TypeVar("C", bound="BaselineConfig")


# ---------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class BaselineConfig:
    """Settings shared by the baselines (names and defaults as ``StiffnessEstimatorConfig``).

    Attributes:
        drive: driven axle whose Cx is estimated: ``vehicle``, ``front``, ``rear`` or ``all``.
        initial_stiffness_factor: initial guess of every stiffness, fraction of nominal, 1
            (default 1.0).
        initial_stiffness_std_fraction: prior std of the stiffness, fraction of nominal, 1
            (default 0.3, paper Sec. VI-A).
        min_stiffness_fraction: lower projection bound, fraction of nominal, 1 (default 0.05).
        max_stiffness_fraction: upper projection bound, fraction of nominal, 1 (default 3.0).
        accel_noise_std_m_s2: accelerometer white-noise std (R of eq. 12), m/s^2 (0.05).
        gyro_noise_std_rad_s: gyro white-noise std (R of eq. 12), rad/s (0.00175).
        wheel_speed_noise_std_m_s: std of the axle-mean ``R_w omega``, carried into ``R``
            through the slip (eq. 2-3) as in Algorithm 1, m/s (0.035).
        initial_vx_std_m_s: initial std of vX around the measured speed, m/s (0.3).
        initial_vy_std_m_s: initial std of vY, m/s (0.3).
        initial_yaw_rate_std_rad_s: initial std of the yaw rate, rad/s (0.0175).
        wheel_radius_m: effective wheel radius, m; 0 = the vehicle's nominal radius (0.0).
        rolling_resistance_n: known constant longitudinal resistance, N (0.0).
        drag_n_s2_m2: known aerodynamic drag coefficient k (F = k vX^2), N s^2/m^2 (0.0).
        roll_gain: c_phi g of Sec. II-A, 1 (0.0).
        friction_coefficient: road friction coefficient mu of Algorithm 1's friction-limited
            lateral tyre ``Fy = mu Fz tanh(C alpha / (mu Fz))`` per axle (static axle load
            ``Fz``), 1; 0 keeps the linear tyre of eq. (2) (0.0).
        tyre_shape: ``tanh`` or ``magic_formula``, as Algorithm 1's (``tanh``).
        magic_formula_shape_c: shape factor C of the ``magic_formula`` tyre, 1 (1.3).
        magic_formula_curvature_e: curvature factor E of the ``magic_formula`` tyre, 1 (0.0).
        min_speed_m_s: below this speed nothing is learned, m/s (5.0).
        activation_window_s: window of the RMS steering angle, s (1.0).
        activation_steer_rad: minimum RMS road-wheel angle to learn (Sec. V), rad (0.003).
        activation_replay_s: when learning starts, rewind the filter to the onset of the
            steering within this time and replay the inputs since with learning on, as
            Algorithm 1's, s (0.0 = off).
        activation_accel_x_window_s: window of the std of the measured ax, s (3.0).
        activation_accel_x_std_m_s2: minimum std of the measured ax to learn Cx, m/s^2 (0.2).
        max_gap_s: a larger gap between IMU samples re-initializes the filter, s (0.5).
        max_input_age_s: wheel speed / steering / velocity older than this are stale, s (0.2).
    """

    drive: str = "vehicle"
    initial_stiffness_factor: float = 1.0
    initial_stiffness_std_fraction: float = 0.3
    min_stiffness_fraction: float = 0.05
    max_stiffness_fraction: float = 3.0
    accel_noise_std_m_s2: float = 0.05
    gyro_noise_std_rad_s: float = 0.00175
    wheel_speed_noise_std_m_s: float = 0.035
    initial_vx_std_m_s: float = 0.3
    initial_vy_std_m_s: float = 0.3
    initial_yaw_rate_std_rad_s: float = 0.0175
    wheel_radius_m: float = 0.0
    rolling_resistance_n: float = 0.0
    drag_n_s2_m2: float = 0.0
    roll_gain: float = 0.0
    friction_coefficient: float = 0.0
    tyre_shape: str = "tanh"
    magic_formula_shape_c: float = 1.3
    magic_formula_curvature_e: float = 0.0
    min_speed_m_s: float = 5.0
    activation_window_s: float = 1.0
    activation_steer_rad: float = 0.003
    activation_replay_s: float = 0.0
    activation_accel_x_window_s: float = 3.0
    activation_accel_x_std_m_s2: float = 0.2
    max_gap_s: float = 0.5
    max_input_age_s: float = 0.2

    def __post_init__(self) -> None:
        require_choice("drive", self.drive, DRIVE_CHOICES)
        require_range("activation_replay_s", self.activation_replay_s, 0.0, 10.0)
        require_range("initial_stiffness_factor", self.initial_stiffness_factor, 0.05, 5.0)
        require_range(
            "initial_stiffness_std_fraction", self.initial_stiffness_std_fraction, 1e-4, 5.0
        )
        require_range("min_stiffness_fraction", self.min_stiffness_fraction, 0.0, 1.0)
        require_range("max_stiffness_fraction", self.max_stiffness_fraction, 1.0, 100.0)
        for name in (
            "accel_noise_std_m_s2",
            "gyro_noise_std_rad_s",
            "min_speed_m_s",
            "activation_window_s",
            "activation_accel_x_window_s",
            "max_gap_s",
            "max_input_age_s",
        ):
            require_positive(name, getattr(self, name))
        for name in (
            "wheel_speed_noise_std_m_s",
            "initial_vx_std_m_s",
            "initial_vy_std_m_s",
            "initial_yaw_rate_std_rad_s",
            "rolling_resistance_n",
            "drag_n_s2_m2",
            "activation_steer_rad",
            "activation_accel_x_std_m_s2",
        ):
            require_non_negative(name, getattr(self, name))
        require_range("wheel_radius_m", self.wheel_radius_m, 0.0, 1.5)
        if 0.0 < self.wheel_radius_m < 0.1:
            raise ConfigError("wheel_radius_m", self.wheel_radius_m, "must be 0 or >= 0.1")
        require_range("roll_gain", self.roll_gain, -0.5, 5.0)
        if self.friction_coefficient != 0.0:
            require_range("friction_coefficient", self.friction_coefficient, 0.1, 5.0)
        require_tyre_shape(self)

    @classmethod
    def sharing(cls: type[C], other: Any, **overrides: Any) -> C:
        """This config with the :class:`BaselineConfig` fields copied from ``other``.

        Every field declared on :class:`BaselineConfig` that ``other`` (a dataclass, e.g. a
        ``StiffnessEstimatorConfig``) also has is copied; the method's own fields (e.g.
        ``RlsConfig.forgetting``, which is not the NiW forgetting of Algorithm 1) keep their
        defaults unless given in ``overrides``. E.g. ``AugPfConfig.sharing(alg1_config,
        n_particles=100)`` initializes a baseline with the values Algorithm 1 uses for the
        variables in common (paper Sec. VI-A).
        """
        names = {f.name for f in fields(BaselineConfig)}
        shared = {f.name: getattr(other, f.name) for f in fields(other) if f.name in names}
        return cls(**{**shared, **overrides})


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

    n_particles: int = 200
    resample_threshold: float = 0.5
    stiffness_walk_std_fraction_sqrt_s: float = 0.2
    state_jitter_vx_m_s_sqrt_s: float = 0.05
    state_jitter_vy_m_s_sqrt_s: float = 0.02
    state_jitter_yaw_rate_rad_s_sqrt_s: float = 0.002

    def __post_init__(self) -> None:
        super().__post_init__()
        require_int_range("n_particles", self.n_particles, 1, 1_000_000)
        require_range("resample_threshold", self.resample_threshold, 0.0, 1.0)
        require_range(
            "stiffness_walk_std_fraction_sqrt_s",
            self.stiffness_walk_std_fraction_sqrt_s,
            0.0,
            5.0,
        )
        for name in (
            "state_jitter_vx_m_s_sqrt_s",
            "state_jitter_vy_m_s_sqrt_s",
            "state_jitter_yaw_rate_rad_s_sqrt_s",
        ):
            require_non_negative(name, getattr(self, name))


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

    stiffness_walk_std_fraction_sqrt_s: float = 0.02
    process_vx_m_s_sqrt_s: float = 0.05
    process_vy_m_s_sqrt_s: float = 0.02
    process_yaw_rate_rad_s_sqrt_s: float = 0.002

    def __post_init__(self) -> None:
        super().__post_init__()
        require_range(
            "stiffness_walk_std_fraction_sqrt_s",
            self.stiffness_walk_std_fraction_sqrt_s,
            0.0,
            5.0,
        )
        for name in (
            "process_vx_m_s_sqrt_s",
            "process_vy_m_s_sqrt_s",
            "process_yaw_rate_rad_s_sqrt_s",
        ):
            require_positive(name, getattr(self, name))


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

    forgetting: float = 0.99
    kf_stiffness: str = "estimate"
    kf_measures_accel: bool = False
    process_vy_m_s_sqrt_s: float = 0.02
    process_yaw_rate_rad_s_sqrt_s: float = 0.002

    def __post_init__(self) -> None:
        super().__post_init__()
        require_range("forgetting", self.forgetting, 0.5, 1.0)
        if self.kf_stiffness not in ("estimate", "nominal"):
            raise ConfigError("kf_stiffness", self.kf_stiffness, "must be 'estimate' or 'nominal'")
        if not isinstance(self.kf_measures_accel, bool):
            raise ConfigError("kf_measures_accel", self.kf_measures_accel, "must be a bool")
        for name in ("process_vy_m_s_sqrt_s", "process_yaw_rate_rad_s_sqrt_s"):
            require_positive(name, getattr(self, name))


# ---------------------------------------------------------------------------- model helpers
@dataclass(frozen=True)
class Measurement:
    """One IMU step as seen by a filter.

    Attributes:
        y: [ax, ay (roll compensated), r] of eq. (12), (3,).
        delta_rad: road-wheel angle, rad.
        wheel_speed_m_s: (front, rear) axle mean ``R_w omega``, m/s.
        speed_m_s: measured speed (undriven axle, or the velocity input), m/s.
        vx_measured: ``speed_m_s`` is a measured vX that replaces the estimate (no wheels).
    """

    y: F64
    delta_rad: float
    wheel_speed_m_s: tuple[float, float]
    speed_m_s: float
    vx_measured: bool


@dataclass(frozen=True)
class FilterEstimate:
    """Point estimate of a baseline filter.

    Attributes:
        stiffness: [Cx, Cy_f, Cy_r], (3,).
        stiffness_std: posterior std of the stiffness estimate, (3,).
        state: [vX, vY, r], (3,).
        state_cov: covariance of the state, (3, 3).
        n_eff: effective sample size (nan for the Kalman filters).
        bias: [b_ax, b_ay, b_r] where the filter estimates the IMU biases, else None.
    """

    stiffness: F64
    stiffness_std: F64
    state: F64
    state_cov: F64
    n_eff: float
    bias: F64 | None = None


def friction_saturation(p: SingleTrackParams, w: F64) -> tuple[F64, F64] | None:
    """Per-row saturation slips ``alpha_s = mu Fz / C`` at ``C = C_n + w``, or None (linear).

    ``w`` (N, 3) -> two (N,) arrays (``stiffness_model.saturation_slip_at``); None where ``p``
    has the linear tyre (``friction_coefficient`` 0).
    """
    if p.saturation_slip_front_rad <= 0.0 and p.saturation_slip_rear_rad <= 0.0:
        return None
    c_n = np.asarray(p.nominal, dtype=float)
    return saturation_slip_at(p, c_n[1] + w[:, 1], c_n[2] + w[:, 2])


def model(
    x: F64, w: F64, delta_rad: float, wheel_speed_m_s: tuple[float, float], p: SingleTrackParams
) -> tuple[F64, F64, F64, F64]:
    """State derivative and measurement mean with stiffness ``C_n + w``, per row.

    ``x`` (N, 3), ``w`` (N, 3) -> ``rate`` (N, 3), ``y_hat`` (N, 3), ``a`` (N, 3, 3) and ``d``
    (N, 3, 3) of :func:`~tire_estimation.core.stiffness_model.linearize`. With the
    friction-limited tyre ``a`` and ``d`` are taken at each row's own ``alpha_s = mu Fz / C``
    (:func:`friction_saturation`), so ``rate`` and ``y_hat`` are the exact model at ``w``
    while ``a`` and ``d`` are secants, not derivatives.
    """
    lin = linearize(x, delta_rad, wheel_speed_m_s, p, friction_saturation(p, w))
    # eq. (9)-(10): dx/dt = rate_n(x) + a(x) w
    rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w)
    # eq. (12): y = h(x) + d(x) w + e
    y_hat = lin.h + np.einsum("nij,nj->ni", lin.d, w)
    return rate, y_hat, lin.a, lin.d


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


def measurement_cov(
    r_cov: F64,
    x: F64,
    delta_rad: float,
    wheel_speed_m_s: tuple[float, float],
    p: SingleTrackParams,
    cx: F64,
    wheel_speed_std_m_s: float,
) -> F64:
    """IMU noise ``R`` (3, 3) plus the wheel-speed noise carried into ``y``, (N, 3, 3).

    As Algorithm 1 (``StiffnessMpf.measurement_cov``): ``R + s^2 sum_axles g g^T`` with ``g``
    from :func:`~tire_estimation.core.stiffness_model.wheel_speed_gain` at Cx = ``cx`` (N,).
    """
    n = x.shape[0]
    out = np.broadcast_to(r_cov, (n, 3, 3)).copy()
    if wheel_speed_std_m_s <= 0.0:
        return out
    g = wheel_speed_gain(x, delta_rad, wheel_speed_m_s, p, cx)
    # eq. (2)-(3): Cov = R + s^2 G^T G
    return out + wheel_speed_std_m_s**2 * np.einsum("nai,naj->nij", g, g)


def gaussian_logpdf(e: F64, cov: F64) -> F64:
    """Log N(e; 0, cov) per row: ``e`` (N, m), ``cov`` (N, m, m) -> (N,)."""
    chol = np.linalg.cholesky(cov)
    z = np.linalg.solve(chol, e[..., None])[..., 0]
    log_det = 2.0 * np.sum(np.log(np.diagonal(chol, axis1=-2, axis2=-1)), axis=-1)
    return -0.5 * (np.sum(z * z, axis=-1) + log_det + e.shape[-1] * _LOG_2PI)


def _stiffness_bounds(config: BaselineConfig, nominal: F64) -> tuple[F64, F64]:
    """Bounds of ``w = C - C_n`` (Sec. V projection)."""
    return (
        config.min_stiffness_fraction * nominal - nominal,
        config.max_stiffness_fraction * nominal - nominal,
    )


def _r_cov(config: BaselineConfig) -> F64:
    return np.diag(
        [
            config.accel_noise_std_m_s2**2,
            config.accel_noise_std_m_s2**2,
            config.gyro_noise_std_rad_s**2,
        ]
    )


class BaselineFilter:
    """Interface of a baseline filter driven by :class:`BaselineEstimator`."""

    initialized: bool = False

    def initialize(self, x0: F64, x0_std: F64) -> None:
        """Start at state ``x0`` (3,) with std ``x0_std`` (3,) and the prior stiffness."""
        raise NotImplementedError

    def predict(self, dt_s: float, learn: bool, learn_cx: bool) -> None:
        """Time update by ``dt_s`` with the inputs of the last :meth:`update`."""
        raise NotImplementedError

    def update(self, meas: Measurement, learn: bool, learn_cx: bool) -> None:
        """Measurement update at one IMU sample."""
        raise NotImplementedError

    def estimate(self) -> FilterEstimate:
        """Current point estimate."""
        raise NotImplementedError


# ---------------------------------------------------------------------------- AUGPF
class AugPf(BaselineFilter):
    """Bootstrap particle filter on ``[vX, vY, r, w]``, vectorized over particles.

    Args:
        config: :class:`AugPfConfig`.
        params: single-track parameters (nominal stiffness C_n, geometry).
        rng: generator of every random draw.
    """

    def __init__(
        self, config: AugPfConfig, params: SingleTrackParams, rng: np.random.Generator
    ) -> None:
        self.config = config
        self.params = params
        self.rng = rng
        self.n = config.n_particles
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower, self.upper = _stiffness_bounds(config, self.nominal)
        self.r_cov = _r_cov(config)
        self.jitter = np.array(
            [
                config.state_jitter_vx_m_s_sqrt_s,
                config.state_jitter_vy_m_s_sqrt_s,
                config.state_jitter_yaw_rate_rad_s_sqrt_s,
            ]
        )
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
            self.config.wheel_speed_noise_std_m_s,
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
class AugEkf(BaselineFilter):
    """Extended Kalman filter on ``z = [vX, vY, r, w]`` (6,).

    Args:
        config: :class:`EkfConfig`.
        params: single-track parameters.
    """

    def __init__(self, config: EkfConfig, params: SingleTrackParams) -> None:
        self.config = config
        self.params = params
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower, self.upper = _stiffness_bounds(config, self.nominal)
        self.r_cov = _r_cov(config)
        self.q_state = np.array(
            [
                config.process_vx_m_s_sqrt_s,
                config.process_vy_m_s_sqrt_s,
                config.process_yaw_rate_rad_s_sqrt_s,
            ]
        )
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
            self.p[0, 0] = self.config.wheel_speed_noise_std_m_s**2 + 1e-6
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
            self.config.wheel_speed_noise_std_m_s,
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
class KfRls(BaselineFilter):
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
        self.lower, self.upper = _stiffness_bounds(config, self.nominal)
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
        cov[0, 0] = c.wheel_speed_noise_std_m_s**2
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
def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def _vector(value: Any, n: int, what: str) -> F64:
    v = np.asarray(value, dtype=float).reshape(-1)
    if v.shape != (n,):
        raise InputError("wrong_length", f"{what}: need {n} values, got {v.shape[0]}")
    if not np.all(np.isfinite(v)):
        raise InputError("nan", f"{what}: non-finite value")
    return v


class BaselineEstimator:
    """Sample-by-sample front-end of a baseline filter (as ``StiffnessEstimator``).

    The IMU drives the filter; the latest wheel speeds (or measured speed) and steering angle
    are its inputs. Activation (Sec. V) as in ``StiffnessEstimator``: the stiffness is learned
    above ``min_speed_m_s`` with an RMS steering angle of at least ``activation_steer_rad``;
    Cx also needs a std of the measured ax of at least ``activation_accel_x_std_m_s2``. Bad
    input never raises: it is dropped and counted in :attr:`stats`. Subclasses build the
    filter in :meth:`make_filter`.

    Args:
        config: a :class:`BaselineConfig` subclass.
        vehicle: geometry, nominal stiffness and drive.
        rng: random generator of every draw (only the AUGPF draws).
    """

    def __init__(
        self,
        config: BaselineConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.config = config
        self.vehicle = vehicle
        self.rng = rng if rng is not None else np.random.default_rng(0)
        drive = vehicle.drive if config.drive == "vehicle" else config.drive
        self.params = SingleTrackParams.from_vehicle(
            vehicle,
            drive=drive,
            wheel_radius_m=config.wheel_radius_m or None,
            rolling_resistance_n=config.rolling_resistance_n,
            drag_n_s2_m2=config.drag_n_s2_m2,
            roll_gain=config.roll_gain,
            friction_coefficient=config.friction_coefficient,
            tyre_shape=config.tyre_shape,
            magic_formula_shape_c=config.magic_formula_shape_c,
            magic_formula_curvature_e=config.magic_formula_curvature_e,
        )
        self.nominal = np.asarray(self.params.nominal, dtype=float)
        self.stats: dict[str, int] = {}
        self.reset()

    def make_filter(self) -> BaselineFilter:
        """The filter of this baseline."""
        raise NotImplementedError

    def reset(self) -> None:
        """Forget everything learned and all inputs."""
        self.filter = self.make_filter()
        self._replay: ActivationReplay[BaselineFilter, tuple[float | None, Measurement, bool]]
        self._replay = ActivationReplay(
            self.config.activation_replay_s, shared=(self.rng, self.config, self.params)
        )
        self._last: dict[str, int | None] = {
            "imu": None,
            "wheel": None,
            "steering": None,
            "velocity": None,
        }
        self._wheel: F64 | None = None
        self._steer = 0.0
        self._vx_meas: float | None = None
        self._steer_window = SlidingWindow(self.config.activation_window_s)
        self._accel_x_window = SlidingWindow(self.config.activation_accel_x_window_s)
        self._active = False
        self._cx_active = False
        self._reason = "not initialized"
        self._t_ns = 0

    @property
    def initialized(self) -> bool:
        """The filter runs (a speed input arrived and the speed was high enough)."""
        return self.filter.initialized

    # ------------------------------------------------------------------ inputs
    def _drop(self, kind: str) -> None:
        self.stats[kind] = self.stats.get(kind, 0) + 1

    def _check_stamp(self, stream: str, t_ns: Any) -> int:
        if not _is_int(t_ns):
            raise InputError("bad_stamp", f"{stream}: stamp must be an integer, got {t_ns!r}")
        last = self._last[stream]
        if last is not None and int(t_ns) <= last:
            kind = "duplicate" if int(t_ns) == last else "out_of_order"
            raise InputError(kind, f"{stream}: stamp {t_ns} not after {last}")
        return int(t_ns)

    def _fresh(self, stream: str, t_ns: int) -> bool:
        last = self._last[stream]
        return last is not None and (t_ns - last) * 1e-9 <= self.config.max_input_age_s

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr), rad/s."""
        try:
            t = self._check_stamp("wheel", t_ns)
            ws = _vector(wheel_speed_rad_s, 4, "wheel speeds")
            if np.any(np.abs(ws) > 1000.0):
                raise InputError("out_of_range", "wheel speed above 1000 rad/s")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._last["wheel"] = t
        self._wheel = ws

    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle delta, rad (positive left)."""
        try:
            t = self._check_stamp("steering", t_ns)
            a = float(_vector(angle_rad, 1, "steering")[0])
            if abs(a) > 1.2:
                raise InputError("out_of_range", f"steering angle {a} rad")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._last["steering"] = t
        self._steer = a

    def on_velocity(self, t_ns: int, vx_m_s: float) -> None:
        """Measured longitudinal speed, m/s (used when there are no wheel speeds)."""
        try:
            t = self._check_stamp("velocity", t_ns)
            v = float(_vector(vx_m_s, 1, "velocity")[0])
            if abs(v) > 150.0:
                raise InputError("out_of_range", f"speed {v} m/s")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._last["velocity"] = t
        self._vx_meas = v

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        """IMU sample in ``base_link`` axes; runs one filter step."""
        try:
            t = self._check_stamp("imu", t_ns)
            gyro = _vector(gyro_rad_s, 3, "gyro")
            acc = _vector(accel_m_s2, 3, "accel")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        last = self._last["imu"]
        self._last["imu"] = t
        self._t_ns = t
        have_wheel = self._wheel is not None and self._fresh("wheel", t)
        have_vel = self._vx_meas is not None and self._fresh("velocity", t)
        if not (have_wheel or have_vel):
            self._reason = "no speed input"
            self._active = self._cx_active = False
            self._drop("no_speed")
            return
        r_w = self.params.wheel_radius_m
        if have_wheel:
            assert self._wheel is not None
            wf = float(0.5 * r_w * (self._wheel[0] + self._wheel[1]))
            wr = float(0.5 * r_w * (self._wheel[2] + self._wheel[3]))
            speed = wr if self.params.drive == "front" else min(wf, wr)
        else:
            assert self._vx_meas is not None
            wf = wr = speed = self._vx_meas
        steer = self._steer if self._fresh("steering", t) else 0.0
        # eq. (12) y = [ax, ay / (1 + c_phi g), r]
        y = np.array([acc[0], roll_compensate(float(acc[1]), self.params.roll_gain), gyro[2]])
        c = self.config
        dt = None if last is None else (t - last) * 1e-9
        if dt is not None and dt > c.max_gap_s:
            self._drop("gap")
            self.filter.initialized = False
        if not self.filter.initialized:
            if speed < 0.5 * c.min_speed_m_s:
                self._reason = "speed below minimum"
                self._active = self._cx_active = False
                return
            x0 = np.array([speed, 0.0, float(gyro[2])])
            std = np.array(
                [c.initial_vx_std_m_s, c.initial_vy_std_m_s, c.initial_yaw_rate_std_rad_s]
            )
            self.filter.initialize(x0, std)
            self._steer_window.reset()
            self._accel_x_window.reset()
            self._replay.clear()
            self._active = False
            dt = None
        was_active = self._active
        # Sec. V activation over sliding windows (as StiffnessEstimator)
        self._steer_window.add(t, steer)
        self._accel_x_window.add(t, float(acc[0]))
        if speed < c.min_speed_m_s:
            self._active, self._reason = False, "speed below minimum"
        elif self._steer_window.rms < c.activation_steer_rad:
            self._active, self._reason = False, "no lateral excitation"
        else:
            self._active, self._reason = True, "excited"
        cx_excited = self._accel_x_window.std >= c.activation_accel_x_std_m_s2
        self._cx_active = self._active and cx_excited
        if self._active and not self._cx_active:
            self._reason = "excited (Cx frozen: no longitudinal excitation)"
        if self._active and not was_active:
            # learn from the onset of the excitation (core/activation_replay, as Algorithm 1)
            threshold = c.activation_steer_rad
            got = self._replay.rewind(excited=lambda step: abs(step[1].delta_rad) >= threshold)
            if got is not None:
                self.filter, steps = got
                for dt_s, past, past_cx in steps:
                    if dt_s is not None:
                        self.filter.predict(dt_s, True, past_cx)
                    self.filter.update(past, True, past_cx)
        if dt is not None:
            self.filter.predict(dt, self._active, self._cx_active)
        meas = Measurement(
            y=y,
            delta_rad=steer,
            wheel_speed_m_s=(wf, wr),
            speed_m_s=speed,
            vx_measured=not have_wheel,
        )
        self.filter.update(meas, self._active, self._cx_active)
        if speed < c.min_speed_m_s:
            # nothing below the minimum speed is ever learned, not even in a replay
            self._replay.clear()
        elif not self._active:
            self._replay.record(t, (dt, meas, cx_excited), self.filter)

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> StiffnessEstimate:
        """Current estimate; biases zero where not estimated, ``n_eff`` nan for the KFs."""
        e = self.filter.estimate()
        vx, vy, r = (float(v) for v in e.state)
        bias = np.zeros(3) if e.bias is None else np.asarray(e.bias, dtype=float)
        return StiffnessEstimate(
            t_ns=self._t_ns,
            names=NAMES,
            stiffness=e.stiffness,
            stiffness_std=e.stiffness_std,
            nominal=self.nominal.copy(),
            active=self._active,
            cx_active=self._cx_active,
            reason=self._reason,
            gyro_bias_rad_s=np.array([0.0, 0.0, bias[2]]),
            accel_bias_m_s2=np.array([bias[0], bias[1], 0.0]),
            n_eff=e.n_eff,
            vx_m_s=vx,
            vy_m_s=vy,
            yaw_rate_rad_s=r,
            sideslip_rad=math.atan2(vy, max(vx, 1e-3)),
            covariance=e.state_cov,
        )


class AugPfEstimator(BaselineEstimator):
    """AUGPF baseline (:class:`AugPf`) behind the shared front-end."""

    config: AugPfConfig

    def __init__(
        self, config: AugPfConfig, vehicle: VehicleParams, rng: np.random.Generator
    ) -> None:
        super().__init__(config, vehicle, rng)

    def make_filter(self) -> BaselineFilter:
        """A fresh :class:`AugPf`."""
        return AugPf(self.config, self.params, self.rng)


class EkfEstimator(BaselineEstimator):
    """EKF baseline (:class:`AugEkf`) behind the shared front-end (deterministic)."""

    config: EkfConfig

    def __init__(
        self,
        config: EkfConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator | None = None,
    ) -> None:
        super().__init__(config, vehicle, rng)

    def make_filter(self) -> BaselineFilter:
        """A fresh :class:`AugEkf`."""
        return AugEkf(self.config, self.params)


class RlsEstimator(BaselineEstimator):
    """KF + RLS baseline (:class:`KfRls`) behind the shared front-end (deterministic)."""

    config: RlsConfig

    def __init__(
        self,
        config: RlsConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator | None = None,
    ) -> None:
        super().__init__(config, vehicle, rng)

    def make_filter(self) -> BaselineFilter:
        """A fresh :class:`KfRls`."""
        return KfRls(self.config, self.params)


__all__ = [
    "AugEkf",
    "AugPf",
    "AugPfConfig",
    "AugPfEstimator",
    "BaselineConfig",
    "BaselineEstimator",
    "BaselineFilter",
    "EkfConfig",
    "EkfEstimator",
    "FilterEstimate",
    "KfRls",
    "Measurement",
    "RlsConfig",
    "RlsEstimator",
]
