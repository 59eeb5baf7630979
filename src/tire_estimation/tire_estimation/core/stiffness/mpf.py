"""Noise-adaptive marginalized particle filter with dependent noise and IMU bias.

Algorithm 1 of Berntorp & Di Cairano, "Tire-stiffness and vehicle-state estimation based on
noise-adaptive particle filtering", IEEE TCST 2018 (eq. 19-20, 27, 29-30, 35-36, 39-41).

Per particle ``i`` (all arrays vectorized over ``N`` particles):

* state ``x`` (N, 3) = [vX, vY at the CG, yaw rate] (sampled),
* NiW statistics of the stiffness deviation ``w`` = [dCx, dCy_f, dCy_r] (eq. 8), d = 3
  (``core.niw``),
* IMU bias ``b`` (N, 3) = [b_ax, b_ay, b_r] with covariance ``P`` (N, 3, 3) (Kalman, eq. 29-30).

Step order at IMU sample ``k`` (after :meth:`StiffnessMpf.predict` to time k, which applies (9),
(20) and (29)): weights (36) -> normalize, N_eff, resample (lines 6-10) -> sample ``w_k`` from
the conditional predictive (39)-(41) -> NiW update (19) -> bias update (30) -> estimates (27,
42) -> store the state derivative for the prediction (9) of the next step.

Documented deviations from the printed paper: (i) eq. (40) is implemented as the conditional of
the joint Student-t of Approximation 1 per eq. (41) (dof ``nu~ + n_e``, gain ``L11 d^T L22^-1``);
(ii) eq. (30) uses ``P - K S K^T`` (the printed ``K S^-1 K^T`` is dimensionally a typo); (iii) a
small random walk ("jitter") on the states keeps particle diversity when Sigma becomes small;
(iv) ``R`` is augmented by the wheel-speed noise that the slip (eq. 3) carries into ``y``; (v)
the bias update (30) treats the total noise as the Student-t of Approximation 1 and, while the
stiffness is learned, runs only while the particles' yaw rate plus bias agrees with the gyro
(the gyro row of ``d`` is zero, so otherwise the bias filters absorb every yaw-rate model error
and the gyro no longer constrains the yaw rate); (vi) without longitudinal excitation the Cx
part of the statistics is frozen (``student_t.freeze_component``); (vii) with a measured speed
and no wheel speeds the measured ax drives vX (``dvX/dt = ax + vY r``) and the speed replaces ax
as measurement row 0 (``model.kinematic_speed_row``), the ax bias not estimated; (viii) optional
saturating lateral tyre ``Fy = C alpha_s phi(alpha / alpha_s)`` (``friction_coefficient``,
``tyre_shape``) with the peak at the friction limit, ``alpha_s = mu Fz / C`` at each particle's
stiffness mean; (ix) optional (``niw_update`` = ``rao_blackwellized``): the NiW mean and
``gamma`` updated with the measurement's information share of the draw of ``w``
(``student_t.niw_mean_gains``), against the collapse of the particles onto a jointly scaled
stiffness pair at activation; (x) the bias update (30) adds ``(tau / Ts) P`` to its noise, which
caps its gain at ``Ts / (tau + Ts)``, so that the bias is an average over about tau instead of
the particle's own start-up transient; (xi) when a learning phase ends the statistics of all
particles are replaced by their weighted moment match (``niw.collapse``), so that weighting and
resampling for the lateral state do not move the stiffness estimate while nothing is learned
(the paper runs Algorithm 1 only while the stiffness is observable, Sec. V).

The IMU step runs in two compiled kernels of :mod:`.kernels` (the model, the likelihood, the
resampling and the per-particle updates included); with ``state_proposal`` = ``measured``
(:mod:`.proposal`) the measurement part runs the NumPy functions of :mod:`.model` and
:mod:`.student_t`.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw, resampling
from tire_estimation.core.arrays import F64
from tire_estimation.core.stiffness import kernels as stiffness_kernels
from tire_estimation.core.stiffness import mat3
from tire_estimation.core.stiffness.config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness.model import (
    WHEEL_SPEED_NOISE_STD_M_S,
    Linearized,
    SingleTrackParams,
    kinematic_speed_row,
    linearize,
    measurement_cov,
    saturation_slip_at,
    stiffness_bounds,
)
from tire_estimation.core.stiffness.mpf_outcomes import Measured, MpfEstimate
from tire_estimation.core.stiffness.proposal import (
    marginal_maha_logdet,
    measured_state_proposal,
)
from tire_estimation.core.stiffness.student_t import (
    NE,
    NW,
    LikelihoodParams,
    bias_update,
    conditional_predictive,
    freeze_component,
    information_fraction,
    likelihood_params,
    niw_mean_gains,
    sample_student_t,
)

#: Algorithm 1 lines 8-10: resample (systematic) when N_eff <= this share of N (the usual
#: choice; Doucet & Johansen 2009).
RESAMPLE_THRESHOLD = 0.5
#: Prior inverse-Wishart degrees of freedom nu_0 (> d + 1 = 4 for a finite E[Sigma], eq. 27b):
#: a weak prior on the noise covariance, about six observations' worth.
PRIOR_DOF = 10.0
#: Random walk of vY and of the yaw rate per sqrt(s) (deviation iii), 0.3x the values at which
#: the jitter, which the likelihood does not model, biased the cornering stiffness upwards.
STATE_JITTER_VY_M_S_SQRT_S = 0.006
STATE_JITTER_YAW_RATE_RAD_S_SQRT_S = 0.0006
#: Initial bias std (P_0 of eq. 29-30) and bias random walk per sqrt(s) (Q, eq. 11) of a
#: consumer MEMS IMU (the simulator's bias model) with ``imu_bias_states``; zero without.
ACCEL_BIAS_STD_M_S2 = 0.1
GYRO_BIAS_STD_RAD_S = 0.005
ACCEL_BIAS_WALK_M_S2_SQRT_S = 0.0005
GYRO_BIAS_WALK_RAD_S_SQRT_S = 0.0001
#: Deviation (v): while the stiffness is learned the bias update (30) runs only when the RMS of
#: the normalized yaw-rate innovations is at most this (a 3-sigma gate), 1 ...
BIAS_GATE_SIGMA = 3.0
#: ... averaged exponentially over this time constant, s.
BIAS_GATE_WINDOW_S = 1.0
#: Deviation (x): time constant tau of the bias update, s (``stiffness_step`` with IMU biases:
#: 1 of 40 drives ran away per filter seed with 2 s, 5-9 with eq. (30) as printed, tau = 0).
BIAS_AVERAGE_S = 2.0


#: components of ``w`` learned (the moment match of deviation xi): all, or all but a frozen Cx
_ALL_COMPONENTS = np.arange(NW)
_WITHOUT_CX = np.arange(1, NW)


def imu_bias_covariances(config: StiffnessEstimatorConfig) -> tuple[F64, F64]:
    """``P_0`` (eq. 29-30) and ``Q`` per second (eq. 11) of the bias states, (3, 3) each; zero
    without ``imu_bias_states``."""
    on = 1.0 if config.imu_bias_states else 0.0
    a0, g0 = on * ACCEL_BIAS_STD_M_S2, on * GYRO_BIAS_STD_RAD_S
    aw, gw = on * ACCEL_BIAS_WALK_M_S2_SQRT_S, on * GYRO_BIAS_WALK_RAD_S_SQRT_S
    return np.diag([a0**2, a0**2, g0**2]), np.diag([aw**2, aw**2, gw**2])


class StiffnessMpf:
    """Algorithm 1, vectorized over particles.

    Args:
        config: tuning (see :class:`StiffnessEstimatorConfig`).
        params: single-track parameters (nominal stiffness, geometry).
        rng: random generator for every draw.
    """

    def __init__(
        self,
        config: StiffnessEstimatorConfig,
        params: SingleTrackParams,
        rng: np.random.Generator,
    ) -> None:
        self.config = config
        self.params = params
        self.rng = rng
        self.n = config.n_particles
        c = config
        self.nominal = np.asarray(params.nominal, dtype=float)
        self.lower, self.upper = stiffness_bounds(self.nominal)
        # float arrays: integer config values (0 from YAML / ROS) must not make them int
        self.r_cov = np.diag(
            np.array(
                [c.accel_noise_std_m_s2**2, c.accel_noise_std_m_s2**2, c.gyro_noise_std_rad_s**2],
                dtype=float,
            )
        )
        self.p0_bias, self.q_rate = imu_bias_covariances(c)
        self.jitter = np.array(
            [
                c.state_jitter_vx_m_s_sqrt_s,
                STATE_JITTER_VY_M_S_SQRT_S,
                STATE_JITTER_YAW_RATE_RAD_S_SQRT_S,
            ]
        )
        #: state_proposal = measured (core/stiffness/proposal.py): the random walk of the
        #: yaw rate and, with a measured speed, of vX is drawn in update() given the gyro /
        #: speed; ``_drawn_in_update`` marks those states
        self.measured_proposal = c.state_proposal == "measured"
        self._drawn_in_update = np.array([False, False, self.measured_proposal])
        self._resample = resampling.systematic
        self.initialized = False
        self.x = np.zeros((self.n, 3))
        self.rate = np.zeros((self.n, 3))
        self.b = np.zeros((self.n, 3))
        self.p_bias = np.zeros((self.n, 3, 3))
        self.log_w = np.full(self.n, -np.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.stats = self.prior_stats()
        #: prior gamma_0: the cap of gamma with ``niw_update`` = ``rao_blackwellized``
        #: (forgetting must not make the mean less certain than the prior)
        self._gamma0 = float(self.stats.gamma)
        #: ``niw_update``: weighted share of the predictive variance of w explained by the last
        #: learning step's measurement (``student_t.information_fraction``), 1
        self.information_share = 0.0
        self.n_eff = float(self.n)
        self.resample_count = 0
        #: sum over updates of log p(y_k | y_1:k-1) (nats) and the number of terms: the log
        #: marginal likelihood of the measurements under this configuration (model selection
        #: without ground truth)
        self.log_evidence = 0.0
        self.evidence_steps = 0
        self.yaw_rate_nis = 0.0
        self.yaw_rate_nis_mean = 0.0
        self.bias_updated = False
        self._dt_s = 0.0
        self._step_dt_s = 0.0
        self._before_learning: niw.NiwStats | None = None
        #: deviation (xi): whether the last update learned, and which components
        self._learned_last_step = False
        self._last_learned_components = _ALL_COMPONENTS
        # the compiled step (kernels.update): model constants, scratch, the ancestors, and
        # Lambda_00 before eq. (20) for the Cx freeze (kernels.predict) with its nu
        self._constants = stiffness_kernels.model_constants(
            params, np.diag(self.r_cov), WHEEL_SPEED_NOISE_STD_M_S, c.speed_noise_std_m_s**2,
            self.lower, self.upper,
        )  # fmt: skip
        self._work = np.empty(stiffness_kernels.scratch_size(self.n))
        self._work2 = np.empty(stiffness_kernels.scratch_size(self.n))
        self._ancestors = np.empty(self.n, dtype=np.intp)
        self._scale00_before = np.empty(self.n)
        self._no_scale00 = np.empty(0)
        self._freeze_dof: float | None = None
        self._niw_mode = (
            stiffness_kernels.NIW_SAMPLED
            if c.niw_update == "sampled"
            else stiffness_kernels.NIW_RAO_BLACKWELLIZED
        )

    def prior_stats(self) -> niw.NiwStats:
        """Prior NiW statistics: mean at the initial guess, E[Sigma] and gamma from config."""
        c = self.config
        mean0 = (c.initial_stiffness_factor - 1.0) * self.nominal
        noise_var = (c.stiffness_noise_std_fraction * self.nominal) ** 2
        scale0 = np.diag(noise_var) * (PRIOR_DOF - NW - 1.0)
        gamma0 = (c.initial_stiffness_std_fraction / c.stiffness_noise_std_fraction) ** 2
        return niw.init_stats(self.n, mean0, gamma0, PRIOR_DOF, scale0)

    def initialize(self, x0: F64, x0_std: F64, bias0: F64 | None = None) -> None:
        """Algorithm 1 'Initialize': x ~ N(x0, diag(x0_std^2)), b ~ N(bias0, P0), q = 1/N."""
        self.x = x0[None, :] + self.rng.standard_normal((self.n, 3)) * x0_std[None, :]
        self.rate = np.zeros((self.n, 3))
        self.b = np.tile(np.zeros(3) if bias0 is None else bias0, (self.n, 1))
        self.p_bias = np.tile(self.p0_bias, (self.n, 1, 1))
        self.log_w = np.full(self.n, -np.log(self.n))
        self.weights = np.full(self.n, 1.0 / self.n)
        self.initialized = True
        # the gate of the bias update starts closed: the yaw rate must first prove consistent
        self.yaw_rate_nis_mean = 4.0 * BIAS_GATE_SIGMA**2

    def predict(self, dt_s: float, learn: bool, learn_cx: bool | None = None) -> None:
        """Time update to the next IMU sample: eq. (9) state, (20) NiW, (29) bias.

        ``learn`` applies (20); ``learn_cx`` False (default ``learn``) keeps the statistics
        before (20) for the Cx freeze of the following :meth:`update`.
        """
        st = self.stats
        self._before_learning = None
        self._freeze_dof = None
        keep = self._no_scale00
        if learn and learn_cx is False:
            if self.measured_proposal:
                self._before_learning = st.copy()
            else:
                # kernels.predict keeps Lambda_00 before eq. (20) (eq. 20 keeps the mean)
                keep = self._scale00_before
                self._freeze_dof = float(st.dof)
        # jitter (iii) of the states whose random walk update() does not draw
        jitter = (
            np.where(self._drawn_in_update, 0.0, self.jitter)
            if self.measured_proposal
            else self.jitter
        )
        # eq. (9) with the stored rate, jitter (iii), vX >= 0, eq. (29) P += Q Ts and, learning,
        # eq. (20) gamma/lambda, mu, lambda nu, lambda Lambda
        stiffness_kernels.predict(
            self.x, self.rate, self.p_bias, self.q_rate, dt_s, jitter,
            self.rng.bit_generator.random_raw(4), st.scale, st.gamma, st.dof, learn,
            self.config.forgetting, keep,
        )  # fmt: skip
        self._dt_s = dt_s

    def bias_gate_open(self, learn: bool) -> bool:
        """Whether the bias update (30) runs at this step (deviation v): always on straight
        driving (``learn`` False) and, while the stiffness is learned, when the exponential
        mean of the yaw-rate NIS is at most :data:`BIAS_GATE_SIGMA` squared."""
        return (not learn) or self.yaw_rate_nis_mean <= BIAS_GATE_SIGMA**2

    def update(
        self,
        y: F64,
        delta_rad: float,
        wheel_speed_m_s: tuple[float, float],
        learn: bool,
        vx_m_s: float | None = None,
        learn_cx: bool | None = None,
    ) -> None:
        """Measurement part of Algorithm 1 at one IMU sample ``y`` (3,) = [ax, ay, r].

        ``learn`` enables the NiW update (19) (activation, Sec. V); ``learn_cx`` (default
        ``learn``) False keeps the Cx part of the statistics as it was before this step's (20)
        and (19) (no longitudinal excitation, see ``student_t.freeze_component``). ``vx_m_s``
        (optional) is a measured speed (no wheel speeds): the measured ax drives vX and the
        speed is the measurement row 0 (:func:`kinematic_speed_row`, deviation vii).
        """
        # IMU period of this step (the bias update's gain cap, deviation x)
        self._step_dt_s = self._dt_s
        freeze_cx = learn and learn_cx is False
        self._hold_statistics(learn, freeze_cx)
        if not self.measured_proposal:
            self._update_compiled(y, delta_rad, wheel_speed_m_s, learn, vx_m_s, freeze_cx)
            return
        before = self._before_learning
        if freeze_cx and before is None:
            before = self.stats.copy()
        self._before_learning = None
        measured = self._propose_measured(y, vx_m_s)
        lin, y, r_cov = self._linearize(y, delta_rad, wheel_speed_m_s, vx_m_s)
        self._update_measured(y, lin, r_cov, learn, before if freeze_cx else None, measured)

    def _propose_measured(self, y: F64, vx_m_s: float | None) -> Measured:
        """``state_proposal`` = ``measured``: draw the random walk of the yaw rate (gyro) and,
        with a measured speed, of vX given their measurement
        (:func:`~.proposal.measured_state_proposal`)."""
        self._drawn_in_update[0] = vx_m_s is not None
        # (row, measurement, offset, its variance, noise variance) per measured state
        rows = [(2, float(y[2]), self.b[:, 2], self.p_bias[:, 2, 2], float(self.r_cov[2, 2]))]
        if vx_m_s is not None:
            rows.append((0, float(vx_m_s), 0.0, 0.0, self.config.speed_noise_std_m_s**2))
        log_w = np.zeros(self.n)
        gyro_nis = 0.0
        for j, y_j, b_j, p_j, r_j in rows:
            prop = measured_state_proposal(
                self.x[:, j], y_j, b_j, p_j, r_j, self.jitter[j] ** 2 * self._dt_s, self.rng
            )
            self.x[:, j] = prop.state
            log_w += prop.log_weight
            if j == 2:
                gyro_nis = float(self.weights @ prop.nis)
        drawn = {row[0] for row in rows}
        return log_w, tuple(i for i in range(NE) if i not in drawn), gyro_nis

    def _linearize(
        self, y: F64, delta_rad: float, wheel_speed_m_s: tuple[float, float], vx_m_s: float | None
    ) -> tuple[Linearized, F64, F64]:
        """Eq. (9)-(12) at the particles, the measurement and its noise covariance (N, 3, 3);
        with a measured speed row 0 is the speed (deviation vii)."""
        sat = self._saturation_slips()
        if vx_m_s is None:
            lin = linearize(self.x, delta_rad, wheel_speed_m_s, self.params, sat)
            return lin, y, self.measurement_cov(delta_rad, wheel_speed_m_s)
        # slip 0 (wheel speed = each particle's vX): the longitudinal force is unknown
        vx_p = self.x[:, 0]
        lin = kinematic_speed_row(
            linearize(self.x, delta_rad, (vx_p, vx_p), self.params, sat), self.x, y[0], self.params
        )
        # the ax bias is not a measurement offset of the speed row: not estimated
        self.b[:, 0] = 0.0
        self.p_bias[:, 0, :] = 0.0
        self.p_bias[:, :, 0] = 0.0
        r_cov = np.tile(self.r_cov, (self.n, 1, 1))
        r_cov[:, 0, 0] = self.config.speed_noise_std_m_s**2
        return lin, np.array([vx_m_s, y[1], y[2]]), r_cov

    def _track_yaw_rate_nis(self, nis: float) -> None:
        """Deviation (v): the exponential mean of the yaw-rate NIS (:data:`BIAS_GATE_WINDOW_S`)."""
        self.yaw_rate_nis = nis
        a = min(1.0, self._dt_s / BIAS_GATE_WINDOW_S)
        self.yaw_rate_nis_mean += a * (self.yaw_rate_nis - self.yaw_rate_nis_mean)
        self._dt_s = 0.0

    def _add_evidence(self, log_pred: float) -> None:
        """The predictive density p(y_k | y_1:k-1) (model evidence increment)."""
        if math.isfinite(log_pred):
            self.log_evidence += log_pred
            self.evidence_steps += 1

    def _resample_if_needed(self) -> NDArray[np.intp] | None:
        """Algorithm 1 lines 8-10: the ancestors (weights reset), or None without resampling."""
        idx = None
        if self.n_eff <= RESAMPLE_THRESHOLD * self.n:
            idx = self._resample(self.weights, self.rng)
            self.weights = np.full(self.n, 1.0 / self.n)
            self.resample_count += 1
        self.log_w = resampling.log_of_weights(self.weights)
        return idx

    def _niw_gains(self, gamma: float, beta: float) -> tuple[float, float, float]:
        """``niw_mean_gains`` of ``rao_blackwellized``, ``gamma`` capped at the prior's."""
        g_loc, g_w, g_new = niw_mean_gains(gamma, beta, self.config.niw_update)
        self.information_share = beta
        return g_loc, g_w, min(g_new, self._gamma0)

    def _update_compiled(
        self,
        y: F64,
        delta_rad: float,
        wheel_speed_m_s: tuple[float, float],
        learn: bool,
        vx_m_s: float | None,
        freeze_cx: bool,
    ) -> None:
        """The measurement part of :meth:`update` in one compiled call (:func:`.kernels.update`):
        eq. (1)-(12) at the particles, eq. (35)-(36), lines 6-10, eq. (39)-(41), (19), (30) and
        the derivative of eq. (9). Shared ``gamma`` and ``nu`` (``niw.init_stats(shared=True)``).
        """
        st = self.stats
        freeze_ratio = 0.0
        if freeze_cx:
            nu = float(st.dof)
            nu_before = self._freeze_dof
            if nu_before is None:
                # no eq. (20) since the statistics to keep: they are the present ones
                self._scale00_before[:] = st.scale[:, 0, 0]
                nu_before = nu
            # freeze_component: E[Sigma_00] = Lambda_00 / (nu - 4) (eq. 27b) unchanged
            freeze_ratio = (((nu + 1.0) - NW) - 1.0) / ((nu_before - NW) - 1.0)
        self._freeze_dof = None
        # deviation (x): R_b = R + (tau / Ts) P  ->  K = P (P + R_b)^-1 <= Ts / (tau + Ts)
        step_dt = self._step_dt_s
        bias_fac = BIAS_AVERAGE_S / step_dt if step_dt > 0.0 else 0.0
        log_pred, n_eff, resampled, beta, bias_on, nis, nis_mean = stiffness_kernels.update(
            self.x, self.b, self.p_bias, self.rate, st.mean, st.scale, st.gamma, st.dof,
            self.weights, self.log_w, self._work, self._work2, self._ancestors, self._constants, y,
            math.cos(delta_rad), math.sin(delta_rad), delta_rad, wheel_speed_m_s[0],
            wheel_speed_m_s[1], math.nan if vx_m_s is None else vx_m_s, learn, freeze_ratio,
            self._scale00_before, self._niw_mode, self._gamma0, self.yaw_rate_nis_mean,
            min(1.0, self._dt_s / BIAS_GATE_WINDOW_S), BIAS_GATE_SIGMA**2, bias_fac,
            RESAMPLE_THRESHOLD, self.rng.bit_generator.random_raw(4),
        )  # fmt: skip
        # deviation (v): the yaw-rate NIS and its exponential mean (BIAS_GATE_WINDOW_S)
        self.yaw_rate_nis = nis
        self.yaw_rate_nis_mean = nis_mean
        self._dt_s = 0.0
        self._add_evidence(log_pred)
        self.n_eff = n_eff
        self.resample_count += resampled
        self.bias_updated = bias_on
        if learn and self._niw_mode == stiffness_kernels.NIW_RAO_BLACKWELLIZED:
            self.information_share = beta

    def _update_measured(
        self,
        y: F64,
        lin: Linearized,
        r_cov: F64,
        learn: bool,
        freeze_before: niw.NiwStats | None,
        measured: Measured,
    ) -> None:
        """The measurement part of :meth:`update` with ``state_proposal`` = ``measured``: the
        same steps as :meth:`_update_compiled`, the rows drawn given their measurement weighed
        by the proposal's predictive (``measured``), the others by their Student-t marginal."""
        log_w_measured, rows, gyro_nis = measured
        # e_bar = y - h - b_{k|k-1} (eq. 12)
        e_bar = y[None, :] - lin.h - self.b
        lp = likelihood_params(self.stats, lin.d, r_cov, self.p_bias)
        self._track_yaw_rate_nis(gyro_nis)
        # Algorithm 1 line 3, eq. (36) with the proposal: q_k = q_{k-1} prod_j N(nu_j; 0, S_j)
        # St(other rows)
        n_meas = len(rows)
        maha, logdet = marginal_maha_logdet(e_bar - lp.loc, lp.shape, rows)
        self.log_w += log_w_measured + niw.student_t_log_density(maha, logdet, lp.dof, n_meas)
        # line 6-7: normalize, N_eff
        self.weights, log_pred = resampling.normalize_log_weights(self.log_w)
        self._add_evidence(log_pred)
        self.n_eff = resampling.ess(self.weights)
        self._sample_and_learn(lin, e_bar, r_cov, lp, maha, n_meas, learn, freeze_before)

    def _sample_and_learn(
        self,
        lin: Linearized,
        e_bar: F64,
        r_cov: F64,
        lp: LikelihoodParams,
        maha: F64,
        n_meas: int,
        learn: bool,
        freeze_before: niw.NiwStats | None,
    ) -> None:
        """Algorithm 1 after the weights are normalized: resample, draw ``w_k``, update the NiW
        statistics and the IMU bias, store the derivative (lines 8-18). ``n_meas`` is the
        number of measured rows the Student-t marginal was taken over."""
        if not np.all(np.isfinite(self.weights)):
            self.weights = np.full(self.n, 1.0 / self.n)
        beta = 0.0
        if learn and self.config.niw_update != "sampled":
            # the share of the predictive variance of w this measurement explains, weighted
            # with the normalized weights before resampling
            comps = self._learned_components(freeze_before is not None)
            beta = float(
                self.weights @ information_fraction(lp.w_shape, lin.d, lp.shape_inv, comps)
            )
        # line 8-10: resample and copy the statistics
        idx = self._resample_if_needed()
        if idx is not None:
            self._take(idx)
            if freeze_before is not None:
                # the statistics the Cx freeze restores follow their particles
                freeze_before.take(idx)
            lin = Linearized(rate=lin.rate[idx], a=lin.a[idx], h=lin.h[idx], d=lin.d[idx])
            e_bar, r_cov, lp, maha = e_bar[idx], r_cov[idx], lp.take(idx), maha[idx]
        # line 17: sample w_k from the conditional predictive (39)-(41); Sec. V projection
        cp = conditional_predictive(self.stats, lin.d, e_bar, lp, maha, n_meas)
        w = np.clip(sample_student_t(cp, self.rng), self.lower, self.upper)
        if learn:
            if self.config.niw_update == "sampled":
                # line 4: eq. (19) with w_bar = w_k (Remark 3)
                niw.measurement_update(self.stats, w)
            else:
                # eq. (19) for Lambda and nu, the mean and gamma by niw_mean_gains
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
        # line 18 (first half): derivative for eq. (9), applied in predict()
        self.rate = lin.rate + np.einsum("nij,nj->ni", lin.a, w)

    def _hold_statistics(self, learn: bool, freeze_cx: bool) -> None:
        """Deviation (xi): at the first step without learning after a learning phase, every
        particle takes the weighted moment match of the statistics (:func:`niw.collapse`; the
        learned components set ``gamma``): the estimate (27) stays at its last learned value."""
        if learn:
            self._last_learned_components = _WITHOUT_CX if freeze_cx else _ALL_COMPONENTS
        elif self._learned_last_step:
            niw.collapse(self.stats, self.weights, self._last_learned_components)
        self._learned_last_step = learn

    def _bias_noise(self, r_cov: F64) -> F64:
        """Measurement noise of the bias update (eq. 30), (N, 3, 3): ``R`` (with the
        wheel-speed term) plus ``(tau / Ts) P`` (deviation x, tau = :data:`BIAS_AVERAGE_S`),
        which caps the Kalman gain at ``Ts / (tau + Ts)``."""
        if self._step_dt_s <= 0.0:
            return r_cov
        # deviation (x): R_b = R + (tau / Ts) P  ->  K = P (P + R_b)^-1 <= Ts / (tau + Ts)
        return r_cov + (BIAS_AVERAGE_S / self._step_dt_s) * self.p_bias

    def _saturation_slips(self) -> tuple[F64, F64] | None:
        """Per-particle saturation slips of the friction-limited tyre, else None (linear).

        ``alpha_s = mu Fz / C`` at each particle's stiffness mean ``C_n + mu_i`` (eq. 7, 27a
        per particle) before this step's draw, so the step stays affine in ``w``.
        """
        p = self.params
        if p.saturation_slip_front_rad <= 0.0 and p.saturation_slip_rear_rad <= 0.0:
            return None
        c = self.nominal[None, :] + self.stats.mean
        return saturation_slip_at(p, c[:, 1], c[:, 2])

    def _learned_components(self, freeze_cx: bool) -> F64:
        """1 for each component of ``w`` learned in this step, 0 for a frozen Cx, (3,)."""
        return np.array([0.0 if freeze_cx else 1.0, 1.0, 1.0])

    def measurement_cov(self, delta_rad: float, wheel_speed_m_s: tuple[float, float]) -> F64:
        """Measurement-noise covariance of ``y`` per particle, (N, 3, 3) (deviation iv):
        :func:`~.model.measurement_cov` at each particle's mean Cx (nominal + mu, eq. 7)."""
        cx = self.nominal[0] + self.stats.mean[:, 0]
        return measurement_cov(self.r_cov, self.x, delta_rad, wheel_speed_m_s, self.params, cx)

    def _take(self, idx: NDArray[np.intp]) -> None:
        self.x = self.x[idx]
        self.b = self.b[idx]
        self.p_bias = self.p_bias[idx]
        self.rate = self.rate[idx]
        self.stats.take(idx)

    def estimate_vector(self) -> F64:
        """The estimates of :meth:`estimate` as one vector (24,): stiffness, its std, the std of
        the mean, the state, its covariance (row-major), the bias (:func:`.kernels.estimate`)."""
        st = self.stats
        out = np.empty(24)
        stiffness_kernels.estimate(
            self.weights, st.mean, st.scale, self.x, self.b, float(st.gamma), float(st.dof),
            self.nominal, out,
        )  # fmt: skip
        return out

    def estimate(self) -> MpfEstimate:
        """Estimates (27) of the stiffness and (42) of the state (:func:`.kernels.estimate`)."""
        out = self.estimate_vector()
        return MpfEstimate(
            # eq. (27a) C_n + sum q_i mu_i; eq. (27b) Sigma_hat = sum q_i (Lambda_i / (nu - 4) +
            # dev dev^T); eq. (42) weighted mean of the state
            stiffness=out[0:3],
            stiffness_std=out[3:6],
            mean_std=out[6:9],
            state=out[9:12],
            state_cov=out[12:21].reshape(3, 3),
            bias=out[21:24],
            n_eff=float(self.n_eff),
        )
