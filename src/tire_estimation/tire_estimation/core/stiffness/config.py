"""Configuration of the tyre-stiffness estimator (Berntorp & Di Cairano, IEEE TCST 2018)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Annotated, Any, TypeVar

from tire_estimation.core.stiffness.model import TYRE_SHAPES, CurvatureFactor, ShapeFactor
from tire_estimation.core.validation import (
    Checked,
    NonNegative,
    Positive,
    in_range,
    int_in_range,
    one_of,
    require_range,
)

STATE_PROPOSALS = ("prior", "measured")
NIW_UPDATES = ("sampled", "rao_blackwellized")
FIRST_LEARNING = ("mpf", "grid")
C = TypeVar("C", bound="BaselineConfig")


@dataclass(frozen=True)
class BaselineConfig(Checked):
    """Settings every stiffness filter shares: Algorithm 1's (:class:`StiffnessEstimatorConfig`
    extends them) and those of the filters it is compared with (``core.stiffness.grid``,
    ``evaluation.stiffness_baselines``); ranges as in :class:`StiffnessEstimatorConfig`.

    Attributes:
        initial_stiffness_factor: initial guess of every stiffness, fraction of nominal, 1
            (default 1.0).
        initial_stiffness_std_fraction: prior std of the stiffness, fraction of nominal, 1
            (default 0.3, paper Sec. VI-A).
        accel_noise_std_m_s2: accelerometer white-noise std (R of eq. 12), m/s^2 (0.05).
        gyro_noise_std_rad_s: gyro white-noise std (R of eq. 12), rad/s (0.00175).
        initial_vy_std_m_s: initial std of vY, m/s (0.3).
        rolling_resistance_n: known constant longitudinal resistance, N (0.0).
        drag_n_s2_m2: known aerodynamic drag coefficient k (F = k vX^2), N s^2/m^2 (0.0).
        friction_coefficient: road friction coefficient mu of Algorithm 1's friction-limited
            lateral tyre ``Fy = mu Fz tanh(C alpha / (mu Fz))`` per axle (static axle load
            ``Fz``), 1; 0 keeps the linear tyre of eq. (2) (0.0).
        tyre_shape: ``tanh`` or ``magic_formula``, as Algorithm 1's (``tanh``).
        magic_formula_shape_c: shape factor C of the ``magic_formula`` tyre, 1 (1.3).
        magic_formula_curvature_e: curvature factor E of the ``magic_formula`` tyre, 1 (0.0).
        cornering_stiffness_front_n_rad: nominal front cornering stiffness, N/rad; 0 = the
            vehicle's (0.0).
        cornering_stiffness_rear_n_rad: nominal rear cornering stiffness, N/rad; 0 = the
            vehicle's (0.0).
    """

    initial_stiffness_factor: Annotated[float, in_range(0.05, 5.0)] = 1.0
    initial_stiffness_std_fraction: Annotated[float, in_range(1e-4, 5.0)] = 0.3
    accel_noise_std_m_s2: Positive = 0.05
    gyro_noise_std_rad_s: Positive = 0.00175
    initial_vy_std_m_s: NonNegative = 0.3
    rolling_resistance_n: NonNegative = 0.0
    drag_n_s2_m2: NonNegative = 0.0
    friction_coefficient: float = 0.0
    tyre_shape: Annotated[str, one_of(TYRE_SHAPES)] = "tanh"
    magic_formula_shape_c: ShapeFactor = 1.3
    magic_formula_curvature_e: CurvatureFactor = 0.0
    cornering_stiffness_front_n_rad: Annotated[float, in_range(0.0, 1e7)] = 0.0
    cornering_stiffness_rear_n_rad: Annotated[float, in_range(0.0, 1e7)] = 0.0

    def check(self) -> None:
        if self.friction_coefficient != 0.0:
            require_range("friction_coefficient", self.friction_coefficient, 0.1, 5.0)

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
class StiffnessEstimatorConfig(BaselineConfig):
    """Tuning of the stiffness MPF (Algorithm 1) and its front-end; checked at construction.

    The tuning constants nobody sets live next to the equations they serve
    (``core.stiffness.mpf``, ``core.stiffness.model``, ``core.stiffness.frontend``).

    Attributes:
        n_particles: number of particles N, 1, within [1, 1e6] (default 200).
        forgetting: NiW forgetting factor lambda of eq. (20) per IMU step, 1, within [0.5, 1]
            (default 0.99).
        initial_stiffness_factor: initial guess of every stiffness as a fraction of nominal, 1,
            within [0.05, 5] (default 1.0).
        initial_stiffness_std_fraction: prior std of the stiffness mean as a fraction of the
            nominal value, 1, within [1e-4, 5] (default 0.3, paper Sec. VI-A).
        stiffness_noise_std_fraction: prior std of the stiffness process noise w (square root of
            E[Sigma]) as a fraction of nominal, 1, within [1e-5, 5] (default 0.03; 0.01 settles
            faster on a uniform surface with a bias-free IMU, but runs away more often with IMU
            biases).
        accel_noise_std_m_s2: accelerometer white-noise std (R of eq. 12), m/s^2, > 0 (default
            0.05).
        gyro_noise_std_rad_s: gyro white-noise std (R of eq. 12), rad/s, > 0 (default 0.00175).
        imu_bias_states: estimate the IMU biases with the per-particle Kalman filters of eq.
            (29)-(30) (prior and random walk: ``core.stiffness.mpf.ACCEL_BIAS_STD_M_S2`` ...);
            false for bias-compensated IMU outputs (an INS), bool (default true).
        initial_vy_std_m_s: initial std of vY around 0, m/s, >= 0 (default 0.3).
        state_jitter_vx_m_s_sqrt_s: random walk on vX (particle diversity, not in the model the
            likelihood assumes), m/s/sqrt(s), >= 0 (default 0.015).
        state_proposal: how the random walk of the directly measured states is drawn (not in the
            paper): ``prior`` from its own distribution (Algorithm 1); ``measured`` from the
            locally optimal proposal given the gyro and the measured speed
            (``core/stiffness/proposal.py``) (default ``prior``).
        niw_update: how a step's draw of ``w`` updates the NiW mean and ``gamma`` while the
            stiffness is learned (not in the paper; ``core.stiffness.student_t.niw_mean_gains``):
            ``sampled`` is eq. (19) with ``w_bar = w_k`` (Remark 3); ``rao_blackwellized`` moves
            the mean to the conditional mean of ``w`` (eq. 41) and commits only the share of
            the draw's deviation the measurement explains (default ``sampled``).
        first_learning: what learns the stiffness from the prior (not in the paper): ``mpf`` is
            Algorithm 1 from the start; ``grid`` runs the point-mass filter with an EKF per
            cell (:mod:`~tire_estimation.core.stiffness.grid`) beside it, hands its posterior
            to Algorithm 1 after ``grid_handover_s`` and publishes it until ``grid_publish_s``
            while its mean NIS stays at most ``core.stiffness.estimator.GRID_MAX_NIS``
            (default ``mpf``).
        grid_handover_s: learning time of the grid before the hand-over, s, within [0.01, 600]
            (default 2.0).
        grid_publish_s: learning time of the grid up to which its cornering stiffness is
            published, s, within [0, 1e6] (default 30.0).
        rolling_resistance_n: known constant longitudinal resistance, N, >= 0 (default 0.0,
            the paper's Assumption 4).
        drag_n_s2_m2: known aerodynamic drag coefficient k (F = k vX^2), N s^2/m^2, >= 0
            (default 0.0).
        friction_coefficient: road friction coefficient mu of the saturating lateral tyre
            (peak ``mu Fz`` at the static axle load, ``alpha_s = mu Fz / C`` at each particle's
            stiffness), 1, 0 or within [0.1, 5]; 0 keeps the linear tyre of eq. (2) (default
            0.0). If unsure, err high.
        tyre_shape: shape of the saturating tyre: ``tanh`` or ``magic_formula`` (Pacejka's,
            scaled to the same stiffness and peak) (default ``tanh``).
        magic_formula_shape_c: shape factor C of the ``magic_formula`` tyre, 1, within
            [1, 1.9] (default 1.3).
        magic_formula_curvature_e: curvature factor E of the ``magic_formula`` tyre, 1, within
            [-5, 0.99] (default 0.0).
        cornering_stiffness_front_n_rad: nominal front-axle cornering stiffness C_n (eq. 7),
            N/rad, within [0, 1e7]; 0 takes the vehicle's (default 0.0).
        cornering_stiffness_rear_n_rad: nominal rear-axle cornering stiffness, N/rad, within
            [0, 1e7]; 0 takes the vehicle's (default 0.0).
        speed_noise_std_m_s: std of a measured speed (``/vehicle/velocity``, no wheel speeds;
            it is then measurement row 0 and the measured ax drives vX), m/s, > 0 (default
            0.02, an RTK-aided INS).
    """

    n_particles: Annotated[int, int_in_range(1, 1_000_000)] = 200
    forgetting: Annotated[float, in_range(0.5, 1.0)] = 0.99
    stiffness_noise_std_fraction: Annotated[float, in_range(1e-5, 5.0)] = 0.03
    imu_bias_states: bool = True
    state_jitter_vx_m_s_sqrt_s: NonNegative = 0.015
    state_proposal: Annotated[str, one_of(STATE_PROPOSALS)] = "prior"
    niw_update: Annotated[str, one_of(NIW_UPDATES)] = "sampled"
    first_learning: Annotated[str, one_of(FIRST_LEARNING)] = "mpf"
    grid_handover_s: Annotated[float, in_range(0.01, 600.0)] = 2.0
    grid_publish_s: Annotated[float, in_range(0.0, 1e6)] = 30.0
    speed_noise_std_m_s: Positive = 0.02
