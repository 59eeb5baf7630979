"""Configuration of the tyre-stiffness estimator (Berntorp & Di Cairano, IEEE TCST 2018)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from tire_estimation.core.stiffness.model import TYRE_SHAPES
from tire_estimation.core.validation import (
    require_choice,
    require_int_range,
    require_non_negative,
    require_positive,
    require_range,
)
from tire_estimation.errors import ConfigError

DRIVE_CHOICES = ("vehicle", "front", "rear", "all")
SPEED_MODELS = ("input", "kinematic")
RESAMPLERS = ("systematic", "stratified", "multinomial", "residual")
STATE_PROPOSALS = ("prior", "measured")
NIW_UPDATES = ("sampled", "tempered", "rao_blackwellized")
SATURATION_PEAKS = ("scaled", "friction")
INACTIVE_STATISTICS = ("particles", "held")
INACTIVE_PROPAGATIONS = ("draw", "mean")
FIRST_LEARNING = ("mpf", "grid")


def require_tyre_shape(config: Any) -> None:
    """Check ``tyre_shape`` and the Magic Formula factors of ``config`` (ConfigError)."""
    require_choice("tyre_shape", config.tyre_shape, TYRE_SHAPES)
    require_range("magic_formula_shape_c", config.magic_formula_shape_c, 1.0, 1.9)
    require_range("magic_formula_curvature_e", config.magic_formula_curvature_e, -5.0, 0.99)


@dataclass(frozen=True)
class StiffnessEstimatorConfig:
    """Tuning of the stiffness MPF (Algorithm 1) and its front-end; checked at construction.

    Attributes:
        n_particles: number of particles N, 1 (default 200).
        forgetting: NiW forgetting factor lambda of eq. (20) per IMU step, 1 (default 0.99).
        resample_threshold: resample when N_eff <= threshold * N (Algorithm 1 line 8), 1
            (default 0.5).
        resampler: ``systematic``, ``stratified``, ``multinomial`` or ``residual`` (default
            ``systematic``).
        drive: driven axle whose longitudinal stiffness is estimated: ``vehicle`` (take
            ``VehicleParams.drive``), ``front``, ``rear`` or ``all`` (default ``vehicle``).
        initial_stiffness_factor: initial guess of every stiffness as a fraction of nominal, 1
            (default 1.0).
        initial_stiffness_std_fraction: prior std of the stiffness mean as a fraction of the
            nominal value, 1 (default 0.3, paper Sec. VI-A).
        stiffness_noise_std_fraction: prior std of the stiffness process noise w (square root of
            E[Sigma]) as a fraction of nominal, 1 (default 0.03). Smaller values make the
            likelihood sharper along the weakly observed joint scale of the cornering
            stiffnesses: 0.01 settles faster on a uniform surface with a bias-free IMU, but
            leaves IMU-bias errors less room and ran away more often with them
            (docs/results.md section 6).
        prior_dof: prior inverse-Wishart degrees of freedom nu_0 (> 4), 1 (default 10.0).
        min_stiffness_fraction: lower projection bound of every stiffness, fraction of nominal,
            1 (default 0.05; Sec. V).
        max_stiffness_fraction: upper projection bound, fraction of nominal, 1 (default 3.0).
        accel_noise_std_m_s2: accelerometer white-noise std (R), m/s^2 (default 0.05).
        gyro_noise_std_rad_s: gyro white-noise std (R), rad/s (default 0.00175).
        wheel_speed_noise_std_m_s: std of the axle-mean wheel speed ``R_w omega`` (ABS edge
            timing); carried into ``y`` through the slip (eq. 2-3) it is added to R, m/s
            (default 0.035, the simulator's 48-tooth sensor).
        accel_bias_std_m_s2: initial accelerometer bias std (P_0), m/s^2 (default 0.1).
        gyro_bias_std_rad_s: initial gyro bias std (P_0), rad/s (default 0.005).
        accel_bias_walk_m_s2_sqrt_s: accelerometer bias random walk (Q, eq. 11), m/s^2/sqrt(s)
            (default 0.0005).
        gyro_bias_walk_rad_s_sqrt_s: gyro bias random walk (Q, eq. 11), rad/s/sqrt(s) (default
            0.0001).
        bias_gate_sigma: while the stiffness is learned, the bias update (eq. 30) runs only
            when the RMS of the normalized yaw-rate innovations (weighted over particles,
            exponential mean over ``bias_gate_window_s``) is at most this, 1 (default 3.0). On
            straight driving it always runs; after initialization the gate starts closed.
        bias_gate_window_s: time constant of that mean, s (default 1.0).
        bias_hold_s: the bias update (eq. 30) does not run for this long after the filter is
            (re)initialized, whether the stiffness is learned or not, s (default 0.0). The
            per-particle bias filters would take the initial transient of the lateral state
            (P_0) and of the stiffness (prior) as bias, which the gate above then keeps; a hold
            did not reduce the run-aways on ``stiffness_step`` reliably (4, 7, 12 s: 11, 4, 10
            of 40 against 8; docs/results.md, "IMU biases on `stiffness_step`").
        bias_average_s: time constant tau of the bias update: eq. (30) adds ``(tau / Ts) P`` to
            its measurement noise (``Ts`` the IMU period), which caps its gain at ``Ts / (tau +
            Ts)``, so the bias follows the residuals as an average over about tau instead of
            taking a transient of the particle's trajectory within a few steps while ``P`` is
            still near ``P_0``; 0 is eq. (30) as printed, s (default 2.0; on ``stiffness_step``
            with IMU biases 1 of 40 drives ran away at each of three filter seeds, against 8, 5
            and 9 with 0; docs/results.md section 6).
        initial_vx_std_m_s: initial std of vX around the measured speed, m/s (default 0.3).
        initial_vy_std_m_s: initial std of vY, m/s (default 0.3).
        initial_yaw_rate_std_rad_s: initial std of the yaw rate, rad/s (default 0.0175).
        state_jitter_vx_m_s_sqrt_s: extra random walk on vX (particle diversity), m/s/sqrt(s)
            (default 0.015). Not in the model the likelihood assumes: larger values bias the
            learned cornering stiffness upwards, more so with more particles (docs/results.md
            section 6); without any, one of five simulated drives with IMU biases diverged.
        state_jitter_vy_m_s_sqrt_s: extra random walk on vY, m/s/sqrt(s) (default 0.006).
        state_jitter_yaw_rate_rad_s_sqrt_s: extra random walk on the yaw rate, rad/s/sqrt(s)
            (default 0.0006).
        state_proposal: how the random walk (``state_jitter_*``) of the states that are measured
            directly is drawn (not in the paper): ``prior`` from its own distribution, the
            particles then only weighed by the measurement (Algorithm 1); ``measured`` from the
            locally optimal proposal given the measurement, for the yaw rate (gyro) and, with
            ``measured_speed_model`` = ``kinematic``, vX (measured speed); those rows are then
            weighed with their Gaussian predictive and the other rows with their Student-t
            marginal (``core/stiffness/proposal.py``) (default ``prior``).
        niw_update: how a step's draw of ``w`` updates the mean ``mu`` and ``gamma`` of the NiW
            statistics while the stiffness is learned (not in the paper;
            ``stiffness_mpf.niw_mean_gains``): ``sampled`` is eq. (19) with ``w_bar = w_k``
            (Remark 3); ``tempered`` counts the draw as the fraction ``alpha = beta / (1 + gamma
            (1 - beta))`` of an observation, ``beta`` the share of the predictive variance of
            ``w`` that this measurement explains (mean over the particles and the learned
            components); ``rao_blackwellized`` moves the mean to the conditional mean of ``w``
            given the measurement (eq. 41) and commits only the share ``beta`` of the draw's
            deviation from it, ``gamma`` keeping the rest of the posterior variance of ``mu``.
            ``Lambda`` and ``nu`` follow eq. (19) in every mode (default ``sampled``).
        rejuvenation_bandwidth: Liu & West (2001) kernel shrinkage of the NiW means after each
            resampling while the stiffness is learned: ``mu_i <- a mu_i + (1 - a) mu_bar + h
            N(0, V)``, ``a = sqrt(1 - h^2)``, ``mu_bar`` and ``V`` the mean and covariance of the
            resampled means (learned components only); keeps those two moments, 1; 0 switches it
            off (default 0.0).
        propagation_draw_share: share ``h`` of the draw's deviation from its conditional mean
            that drives the state (not in the paper): eq. (9) propagates each particle with
            ``loc + h (w_k - loc)``, ``loc`` the conditional mean of eq. (41); 1 is eq. (9) as
            printed (the draw ``w_k``), 0 the conditional mean. The NiW update (19) takes the
            draw in any case. Below 1 the per-step stiffness noise ``Sigma`` diffuses the lateral
            state by only ``h^2`` of its variance, so the state keeps more of the information
            that fixes the common scale of the two cornering stiffnesses. Experimental: it
            also takes away the state diversity that lets the gyro pull a drifting lateral
            state back (with 0.5, 1-2 of 50 snow drives per start ran off, drive 8 before the
            excitation; docs/results.md section 6), 1 (default 1.0).
        inactive_statistics: what the particles' NiW statistics do while the stiffness is not
            learned (activation, Sec. V; not in the paper): ``particles`` keeps them per particle,
            so weighting and resampling the particles (which goes on for the lateral state)
            still moves the weighted estimate (27) although nothing is learned; ``held``
            replaces them at the end of each learning phase by their weighted moment match,
            shared by all particles (``niw.collapse``: same mean and expected noise covariance,
            the spread of the means folded into ``gamma``), so the estimate stays where the
            learning left it until the next excitation, as the paper runs Algorithm 1 only while
            the stiffness is observable (Sec. V) (default ``held``; on ``snow_sine`` 4 of 100
            runs end above 3 % against 12 with ``particles``, docs/results.md section 6).
        inactive_propagation: what drives the state (eq. 9) while the stiffness is not learned
            (not in the paper): ``draw`` is eq. (9) as printed, the draw ``w_k`` of the
            conditional predictive (39)-(41); ``mean`` is each particle's NiW mean ``mu``, the
            stiffness the filter holds. Without learning the draw is a fresh sample of the whole
            predictive ``(1 + gamma) Sigma`` at every step, and its conditional mean explains
            each lateral-acceleration residual by a stiffness change (the gain is large when
            ``gamma`` is): this diffuses the lateral state and, driven by that conditional
            mean alone (``propagation_draw_share`` 0), lets vY and the yaw rate drift off
            together. Experimental: ``mean`` keeps the lateral state tight before the
            excitation, which helps the runs that start above the true stiffness and hurts
            those that start below it (snow, 100 runs: 9 end above 3 % against 4 with
            ``draw``; docs/results.md section 6) (default ``draw``).
        first_learning: what learns the stiffness from the prior (not in the paper): ``mpf`` is
            Algorithm 1 from the start; ``grid`` runs the point-mass filter with an EKF per
            cell (:mod:`~tire_estimation.core.stiffness.grid`, its defaults, the settings of
            the same names shared) beside it until it has learned ``grid_handover_s``, hands its
            posterior (mean and covariance of Cy_f, Cy_r) to Algorithm 1 as the NiW statistics,
            which then go on learning and follow later changes, and publishes its cornering
            stiffness until ``grid_publish_s`` or until its NIS gate
            (``grid_handover_max_nis``) trips; once per initialization or reset
            (docs/results.md section 6) (default ``mpf``).
        grid_handover_s: learning time of the grid before the hand-over, s (default 2.0).
        grid_handover_max_nis: the hand-over happens, and the grid stays published after it
            (``grid_publish_s``), only while the grid's normalized innovation squared (its
            exponential mean ``nis_mean``, 3 measurements: about 3 when its model fits the data)
            is at most this, checked from ``grid_handover_s`` on; above it the grid is dropped
            (its posterior would be confident and wrong: Revs 250 LM, 68 against 3.0-4.9 on the
            simulated sine drives) and Algorithm 1, which has learned beside it from the same
            samples, goes on with its own statistics, exactly as ``mpf``, 1 (default 10.0).
        grid_publish_s: learning time of the grid up to which its cornering stiffness is
            published, s: after the hand-over the grid keeps learning beside Algorithm 1 and is
            published until it has learned this long, or until its mean NIS rises above
            ``grid_handover_max_nis`` (the stiffness changed, or the model stopped fitting);
            then it is dropped and Algorithm 1's estimate is published. Up to
            ``grid_handover_s``: dropped at the hand-over (default 30.0; docs/results.md
            section 6).
        wheel_radius_m: effective wheel radius R_w of eq. (3), m; 0 uses the vehicle's nominal
            radius (default 0.0).
        rolling_resistance_n: known constant longitudinal resistance, N (default 0.0, the
            paper's Assumption 4).
        drag_n_s2_m2: known aerodynamic drag coefficient k (F = k vX^2), N s^2/m^2 (default 0.0).
        roll_gain: c_phi g of Sec. II-A; measured ay is divided by 1 + roll_gain, 1 (default
            0.0).
        friction_coefficient: road friction coefficient mu of the saturating lateral tyre
            ``Fy = C alpha_s tanh(alpha / alpha_s)`` per axle, or the curve of ``tyre_shape``
            (static axle load Fz, ``alpha_s`` by ``saturation_peak``): the axle force levels off
            near ``mu Fz`` instead of growing linearly with the slip angle, 1; 0 keeps the
            paper's linear tyre (eq. 2) (default 0.0). Where the car drives at the limit, the
            peak |ay| / g it reaches; otherwise the road's value. If unsure, err high: too low
            a value biases the learned stiffness up more than too high a value biases it down
            (docs/results.md section 6).
        saturation_peak: what sets the peak force of the saturating tyre (with
            ``friction_coefficient`` > 0): ``scaled``: ``alpha_s = mu Fz / C_n`` is fixed, so the
            peak ``C alpha_s`` scales with the learned ``C / C_n``; ``friction``: the peak is the
            friction limit ``mu Fz``, i.e. ``alpha_s = mu Fz / C`` with ``C`` each particle's
            current stiffness mean (nominal + NiW mean; the force stays affine in the step's
            ``w``; ``stiffness_model.saturation_slip_at``) (default ``friction``).
        tyre_shape: shape of the saturating tyre (with ``friction_coefficient`` > 0): ``tanh``
            (``Fy = C alpha_s tanh(alpha / alpha_s)``, no shape to know) or ``magic_formula``
            (Pacejka's ``D sin(C atan(B alpha - E (B alpha - atan(B alpha))))`` with ``D = C_y
            alpha_s`` and ``B C D = C_y``: the same stiffness and peak, the curve of a known
            tyre; ``stiffness_model.lateral_slip_function``) (default ``tanh``).
        magic_formula_shape_c: shape factor C of the ``magic_formula`` tyre, within [1, 1.9],
            1 (default 1.3, a typical lateral value).
        magic_formula_curvature_e: curvature factor E of the ``magic_formula`` tyre, within
            [-5, 0.99], 1 (default 0.0).
        cornering_stiffness_front_n_rad: nominal front-axle cornering stiffness C_n (eq. 7),
            N/rad; 0 takes the vehicle's (default 0.0).
        cornering_stiffness_rear_n_rad: nominal rear-axle cornering stiffness, N/rad; 0 takes
            the vehicle's (default 0.0).
        measured_speed_model: use of a measured speed (``/vehicle/velocity``, no wheel speeds):
            ``input`` replaces the particles' vX by it and models zero wheel slip, so the
            longitudinal tyre force is taken as 0 in the ax row; ``kinematic`` leaves the
            (unknown) longitudinal force out: the measured ax drives vX (dvX/dt = ax + vY r) and
            the speed is measured with ``speed_noise_std_m_s``, which makes vY observable
            through vY r in turns (default ``kinematic``). The ax bias is not estimated then.
        speed_noise_std_m_s: std of the measured speed in the ``kinematic`` model, m/s (default
            0.02, an RTK-aided INS).
        min_speed_m_s: below this speed the stiffness statistics are frozen, m/s (default 5.0).
        activation_window_s: length of the sliding (box) window of the excitation measures, s
            (default 1.0). Learning stops at most one window after the excitation ends.
        activation_steer_rad: minimum RMS road-wheel angle over the window to learn the
            stiffness (Sec. V: lateral excitation), rad (default 0.003).
        activation_replay_s: when learning starts, the filter goes back to a copy of itself
            taken before the first sample of the last ``activation_replay_s`` with a steering
            angle of at least ``activation_steer_rad``, and runs the inputs since again with
            learning on, so it learns from the onset of the excitation that the window measure
            sees only later; not in the paper (:mod:`.activation_replay`;
            experimental, docs/results.md section 6), s (default 0 = off; at most 10).
        activation_restart_s: this long after learning first starts (after the initialization
            or a reset), the filter goes back to a copy of itself taken when learning started,
            moves the prior mean of the stiffness statistics to the estimate learned so far
            (the prior's width, ``initial_stiffness_std_fraction``, is kept), and runs the steps
            since again: the estimate then no longer carries the initial guess
            (empirical-Bayes recentring; not in the paper), s (default 0 = off; at most 10).
        activation_accel_x_window_s: length of the sliding window of the longitudinal
            excitation measure, s (default 3.0).
        activation_accel_x_std_m_s2: minimum standard deviation of the measured longitudinal
            acceleration over its window to learn Cx (Sec. II-B: the wheel slip must vary, else
            Cx is confounded with the accelerometer bias and the resistances); otherwise the Cx
            statistics are frozen, m/s^2 (default 0.2).
        max_gap_s: a larger gap between IMU samples re-initializes the filter, s (default 0.5).
        max_input_age_s: wheel speed / steering / velocity older than this are stale, s
            (default 0.2).
    """

    n_particles: int = 200
    forgetting: float = 0.99
    resample_threshold: float = 0.5
    resampler: str = "systematic"
    drive: str = "vehicle"
    initial_stiffness_factor: float = 1.0
    initial_stiffness_std_fraction: float = 0.3
    stiffness_noise_std_fraction: float = 0.03
    prior_dof: float = 10.0
    min_stiffness_fraction: float = 0.05
    max_stiffness_fraction: float = 3.0
    accel_noise_std_m_s2: float = 0.05
    gyro_noise_std_rad_s: float = 0.00175
    wheel_speed_noise_std_m_s: float = 0.035
    accel_bias_std_m_s2: float = 0.1
    gyro_bias_std_rad_s: float = 0.005
    accel_bias_walk_m_s2_sqrt_s: float = 0.0005
    gyro_bias_walk_rad_s_sqrt_s: float = 0.0001
    bias_gate_sigma: float = 3.0
    bias_gate_window_s: float = 1.0
    bias_hold_s: float = 0.0
    bias_average_s: float = 2.0
    initial_vx_std_m_s: float = 0.3
    initial_vy_std_m_s: float = 0.3
    initial_yaw_rate_std_rad_s: float = 0.0175
    state_jitter_vx_m_s_sqrt_s: float = 0.015
    state_jitter_vy_m_s_sqrt_s: float = 0.006
    state_jitter_yaw_rate_rad_s_sqrt_s: float = 0.0006
    state_proposal: str = "prior"
    niw_update: str = "sampled"
    rejuvenation_bandwidth: float = 0.0
    propagation_draw_share: float = 1.0
    inactive_statistics: str = "held"
    inactive_propagation: str = "draw"
    first_learning: str = "mpf"
    grid_handover_s: float = 2.0
    grid_handover_max_nis: float = 10.0
    grid_publish_s: float = 30.0
    wheel_radius_m: float = 0.0
    rolling_resistance_n: float = 0.0
    drag_n_s2_m2: float = 0.0
    roll_gain: float = 0.0
    friction_coefficient: float = 0.0
    saturation_peak: str = "friction"
    tyre_shape: str = "tanh"
    magic_formula_shape_c: float = 1.3
    magic_formula_curvature_e: float = 0.0
    cornering_stiffness_front_n_rad: float = 0.0
    cornering_stiffness_rear_n_rad: float = 0.0
    measured_speed_model: str = "kinematic"
    speed_noise_std_m_s: float = 0.02
    min_speed_m_s: float = 5.0
    activation_window_s: float = 1.0
    activation_steer_rad: float = 0.003
    activation_replay_s: float = 0.0
    activation_restart_s: float = 0.0
    activation_accel_x_window_s: float = 3.0
    activation_accel_x_std_m_s2: float = 0.2
    max_gap_s: float = 0.5
    max_input_age_s: float = 0.2

    def __post_init__(self) -> None:
        require_int_range("n_particles", self.n_particles, 1, 1_000_000)
        require_range("activation_replay_s", self.activation_replay_s, 0.0, 10.0)
        require_range("activation_restart_s", self.activation_restart_s, 0.0, 10.0)
        require_range("forgetting", self.forgetting, 0.5, 1.0)
        require_range("resample_threshold", self.resample_threshold, 0.0, 1.0)
        require_choice("resampler", self.resampler, RESAMPLERS)
        require_choice("measured_speed_model", self.measured_speed_model, SPEED_MODELS)
        require_choice("state_proposal", self.state_proposal, STATE_PROPOSALS)
        require_choice("niw_update", self.niw_update, NIW_UPDATES)
        require_choice("saturation_peak", self.saturation_peak, SATURATION_PEAKS)
        require_range("rejuvenation_bandwidth", self.rejuvenation_bandwidth, 0.0, 0.99)
        require_range("propagation_draw_share", self.propagation_draw_share, 0.0, 1.0)
        require_choice("inactive_statistics", self.inactive_statistics, INACTIVE_STATISTICS)
        require_choice("inactive_propagation", self.inactive_propagation, INACTIVE_PROPAGATIONS)
        require_choice("first_learning", self.first_learning, FIRST_LEARNING)
        require_range("grid_handover_s", self.grid_handover_s, 0.01, 600.0)
        require_range("grid_handover_max_nis", self.grid_handover_max_nis, 1.0, 1e9)
        require_range("grid_publish_s", self.grid_publish_s, 0.0, 1e6)
        require_choice("drive", self.drive, DRIVE_CHOICES)
        require_range("initial_stiffness_factor", self.initial_stiffness_factor, 0.05, 5.0)
        require_range(
            "initial_stiffness_std_fraction", self.initial_stiffness_std_fraction, 1e-4, 5.0
        )
        require_range("stiffness_noise_std_fraction", self.stiffness_noise_std_fraction, 1e-5, 5.0)
        require_range("prior_dof", self.prior_dof, 4.5, 1e6)
        require_range("min_stiffness_fraction", self.min_stiffness_fraction, 0.0, 1.0)
        require_range("max_stiffness_fraction", self.max_stiffness_fraction, 1.0, 100.0)
        for name in (
            "accel_noise_std_m_s2",
            "gyro_noise_std_rad_s",
            "bias_gate_sigma",
            "bias_gate_window_s",
            "speed_noise_std_m_s",
            "min_speed_m_s",
            "activation_window_s",
            "activation_accel_x_window_s",
            "max_gap_s",
            "max_input_age_s",
        ):
            require_positive(name, getattr(self, name))
        for name in (
            "wheel_speed_noise_std_m_s",
            "accel_bias_std_m_s2",
            "gyro_bias_std_rad_s",
            "accel_bias_walk_m_s2_sqrt_s",
            "gyro_bias_walk_rad_s_sqrt_s",
            "bias_hold_s",
            "bias_average_s",
            "initial_vx_std_m_s",
            "initial_vy_std_m_s",
            "initial_yaw_rate_std_rad_s",
            "state_jitter_vx_m_s_sqrt_s",
            "state_jitter_vy_m_s_sqrt_s",
            "state_jitter_yaw_rate_rad_s_sqrt_s",
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
        for name in ("cornering_stiffness_front_n_rad", "cornering_stiffness_rear_n_rad"):
            require_range(name, getattr(self, name), 0.0, 1e7)
