"""Lateral vehicle state from measured tyre forces (Tuononen, Sensors 2009, 9, 8761-8775).

A linear Kalman filter on ``x = [vy_cg m/s, r rad/s, Fy_front N, Fy_rear N]``:

* transition (eq. 21): the lateral and yaw equations of motion (eq. 19-20) integrate the axle
  forces; the forces follow a random walk (identity transition, large process noise); the
  forward speed vx is the only time-varying parameter;
* measurement (eq. 22): identity -- vy and r are pseudo-measurements of the linear single-track
  model (eq. 23-28, :mod:`.single_track`), the axle forces come from the
  tyre sensors plus virtual tyre sensors for the wheels without one (eq. 11-15,
  :mod:`~tire_estimation.core.lateral.virtual_tyre`);
* adaptive measurement noise (section 3.5): the axle-force deviation between the single-track
  model and the measurement (eq. 29) drives a relay with hysteresis (Fig. 7) that switches the
  variance of the single-track pseudo-measurements between a low (linear) and a high
  (nonlinear) value.

The filter runs at every tyre-force sample; steering and forward speed (from the wheel speeds
of the undriven axle, "vehicle velocity from the CAN bus" in the paper) are held from their
latest samples, except that the single-track model takes the steer angle as linear between the
samples of consecutive filter steps (first-order hold). Internally vy is that of the centre of
gravity (the paper's); the published :class:`LateralEstimate` is of ``base_link`` (centre of
the rear axle, REP-103 axes) as the ``LateralState`` message requires: vy_base = vy_cg - lr r.

Bad input never raises out of the ``on_*`` methods: the sample is dropped and counted in
:attr:`TyreForceEstimator.stats` by kind.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core.input_checks import stamp_after
from tire_estimation.core.lateral.single_track import SingleTrackModel, SingleTrackParams
from tire_estimation.core.lateral.virtual_tyre import (
    MagicFormulaTyre,
    virtual_force_normalized,
    virtual_load,
)
from tire_estimation.core.validation import (
    require_choice,
    require_non_negative,
    require_positive,
    require_range,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, InputError

F64 = NDArray[np.float64]

GRAVITY_M_S2 = 9.81
VIRTUAL_SENSOR_METHODS = ("inverse_mf", "normalized")
LINEARITY_STATES = ("linear", "nonlinear", "unknown")
SOURCE = "tyre_force_kf"

#: The vehicle of Tuononen 2009, Table 1 (track and CG height are not given: defaults).
TUONONEN_2009_VEHICLE = VehicleParams(
    name="tuononen_2009",
    mass_kg=1603.0,
    wheelbase_m=2.575,
    cg_to_front_axle_m=1.05,
    cg_to_rear_axle_m=1.525,
    yaw_inertia_kg_m2=3156.0,
    cornering_stiffness_front_n_rad=76_614.0,
    cornering_stiffness_rear_n_rad=82_087.0,
)


@dataclass(frozen=True)
class TyreForceKFConfig:
    """Configuration of :class:`TyreForceEstimator` (Tuononen 2009; checked at construction).

    m, Iz, lf, lr and the single-track cornering stiffnesses Cf, Cr come from
    :class:`~tire_estimation.core.vehicle.VehicleParams` (Table 1 values for the paper's car:
    :data:`TUONONEN_2009_VEHICLE`). The paper gives Q (Table 1) but no numbers for R and the
    relay (Fig. 7 and 9 are plots only); those defaults are our tuning for the simulator's
    tyre sensors (150 N noise per wheel) on the ``lane_change`` scenario (seeds 0 and 1).

    Attributes:
        process_noise_vy_m2_s2: Q of vy per filter step, (m/s)^2. Default 0.01 (Table 1).
        process_noise_yaw_rate_rad2_s2: Q of the yaw rate per filter step, (rad/s)^2.
            Default 0.01 (Table 1).
        process_noise_force_n2: Q of each axle lateral force per filter step, N^2.
            Default 1e4 (Table 1).
        force_variance_n2: R of each measured axle lateral force (sensor wheel plus virtual
            wheel), N^2; constant (sensor accuracy does not depend on the driving state).
            Default 9e4 (twice the 150 N sensor noise).
        linear_vy_variance_m2_s2: R of the single-track vy pseudo-measurement while the relay
            says linear, (m/s)^2. Default 1e-3.
        linear_yaw_rate_variance_rad2_s2: R of the single-track yaw rate while linear,
            (rad/s)^2. Default 1e-4.
        nonlinear_vy_variance_m2_s2: R of the single-track vy while nonlinear, (m/s)^2.
            Default 3.
        nonlinear_yaw_rate_variance_rad2_s2: R of the single-track yaw rate while nonlinear,
            (rad/s)^2. Default 0.3 (a yaw rate integrated from noisy forces drifts by
            ~1.3 deg/s per sqrt(s) with 150 N sensors, so the model's yaw rate keeps some
            weight; far larger values make the nonlinear-phase yaw rate worse).
        relay_on_threshold_n: the relay switches to nonlinear when the axle-force deviation
            of eq. (29) exceeds this, N. Default 500.
        relay_off_threshold_n: the relay switches back to linear when the deviation falls
            below this, N (<= on threshold: the hysteresis of Fig. 7). Default 250.
        deviation_filter_time_constant_s: first-order low-pass of the signed per-axle
            differences before eq. (29), s; 0 feeds eq. (29) unfiltered (beyond the paper:
            with 150 N sensors the noise alone gives eq. 29 a ~500 N floor). Default 0.2.
        virtual_sensor_method: ``inverse_mf`` (eq. 11-13) or ``normalized`` (eq. 13-15).
            Default ``inverse_mf``.
        mf_shape_c: Magic Formula shape factor C of the inverse MF, 1 (in (1, 2)). Default 1.3.
        mf_curvature_e: Magic Formula curvature factor E, 1 (< 1). Default -0.5.
        mf_friction_mu: peak friction, D = mu Fz, 1. Default 1.0.
        mf_b_front_1_rad: constant Magic Formula B of the front tyres, 1/rad (the paper's
            similarity assumption). Default None: B is set per load so that B C D equals half
            the vehicle's front cornering stiffness (load-independent tyre stiffness, as the
            simulator's tyres).
        mf_b_rear_1_rad: as ``mf_b_front_1_rad`` for the rear tyres, 1/rad. Default None.
        static_load_fy_threshold_n: the measured Fz of a sensor wheel updates its static load
            (eq. 12) while |Fy| of that wheel is below this, N. Default 300.
        static_load_time_constant_s: time constant of that static-load average, s. Default 5.
        min_speed_m_s: below this forward speed the filter is held at the kinematic state
            and the linearity is ``unknown``, m/s. Default 5.
        max_gap_s: a gap between tyre-force samples longer than this re-initializes the
            filter, s. Default 0.5.
        input_timeout_s: steering / wheel-speed / gyro samples older than this are stale; a
            tyre-force sample without fresh steering and speed is dropped, s. Default 0.5.
        speed_variance_m2_s2: variance reported for vx (wheel speeds, nominal radius),
            (m/s)^2. Default 0.01.
        initial_vy_variance_m2_s2: initial P of vy, (m/s)^2. Default 0.01.
        initial_yaw_rate_variance_rad2_s2: initial P of the yaw rate, (rad/s)^2. Default 1e-3.
        initial_force_variance_n2: initial P of each axle force, N^2. Default 1e6.
        track_yaw_moment: add the yaw moment of the left/right difference of the wheel forces
            along the body x axis (front lateral forces rotated by the steer angle, drive and
            brake forces) as a known input of the yaw equation (beyond the paper, whose eq. 20
            has the axle lateral forces only). Default True.
        use_gyro_yaw_rate: also update with the IMU yaw rate (beyond the paper, where the
            gyro is for validation only). Default False.
        gyro_variance_rad2_s2: R of the gyro yaw rate, (rad/s)^2. Default 1e-4.
    """

    process_noise_vy_m2_s2: float = 0.01
    process_noise_yaw_rate_rad2_s2: float = 0.01
    process_noise_force_n2: float = 1e4
    force_variance_n2: float = 9e4
    linear_vy_variance_m2_s2: float = 1e-3
    linear_yaw_rate_variance_rad2_s2: float = 1e-4
    nonlinear_vy_variance_m2_s2: float = 3.0
    nonlinear_yaw_rate_variance_rad2_s2: float = 0.3
    relay_on_threshold_n: float = 500.0
    relay_off_threshold_n: float = 250.0
    deviation_filter_time_constant_s: float = 0.2
    virtual_sensor_method: str = "inverse_mf"
    mf_shape_c: float = 1.3
    mf_curvature_e: float = -0.5
    mf_friction_mu: float = 1.0
    mf_b_front_1_rad: float | None = None
    mf_b_rear_1_rad: float | None = None
    static_load_fy_threshold_n: float = 300.0
    static_load_time_constant_s: float = 5.0
    min_speed_m_s: float = 5.0
    max_gap_s: float = 0.5
    input_timeout_s: float = 0.5
    speed_variance_m2_s2: float = 0.01
    initial_vy_variance_m2_s2: float = 0.01
    initial_yaw_rate_variance_rad2_s2: float = 1e-3
    initial_force_variance_n2: float = 1e6
    track_yaw_moment: bool = True
    use_gyro_yaw_rate: bool = False
    gyro_variance_rad2_s2: float = 1e-4

    def __post_init__(self) -> None:
        for name in (
            "process_noise_vy_m2_s2",
            "process_noise_yaw_rate_rad2_s2",
            "process_noise_force_n2",
            "force_variance_n2",
            "linear_vy_variance_m2_s2",
            "linear_yaw_rate_variance_rad2_s2",
            "nonlinear_vy_variance_m2_s2",
            "nonlinear_yaw_rate_variance_rad2_s2",
            "speed_variance_m2_s2",
            "initial_vy_variance_m2_s2",
            "initial_yaw_rate_variance_rad2_s2",
            "initial_force_variance_n2",
            "gyro_variance_rad2_s2",
            "static_load_time_constant_s",
            "max_gap_s",
            "input_timeout_s",
        ):
            require_positive(name, getattr(self, name))
            if getattr(self, name) > 1e12:
                raise ConfigError(name, getattr(self, name), "must be <= 1e12")
        require_non_negative("relay_on_threshold_n", self.relay_on_threshold_n)
        require_non_negative("relay_off_threshold_n", self.relay_off_threshold_n)
        if self.relay_off_threshold_n > self.relay_on_threshold_n:
            raise ConfigError(
                "relay_off_threshold_n",
                self.relay_off_threshold_n,
                f"must be <= relay_on_threshold_n = {self.relay_on_threshold_n}",
            )
        require_range(
            "deviation_filter_time_constant_s", self.deviation_filter_time_constant_s, 0.0, 60.0
        )
        require_choice("virtual_sensor_method", self.virtual_sensor_method, VIRTUAL_SENSOR_METHODS)
        require_range("mf_shape_c", self.mf_shape_c, 1.01, 1.99)
        require_range("mf_curvature_e", self.mf_curvature_e, -10.0, 0.99)
        require_range("mf_friction_mu", self.mf_friction_mu, 0.05, 3.0)
        for name in ("mf_b_front_1_rad", "mf_b_rear_1_rad"):
            value = getattr(self, name)
            if value is not None:
                require_range(name, value, 0.1, 1000.0)
        require_non_negative("static_load_fy_threshold_n", self.static_load_fy_threshold_n)
        require_range("min_speed_m_s", self.min_speed_m_s, 0.5, 100.0)
        if not isinstance(self.track_yaw_moment, bool):
            raise ConfigError("track_yaw_moment", self.track_yaw_moment, "must be a bool")
        if not isinstance(self.use_gyro_yaw_rate, bool):
            raise ConfigError("use_gyro_yaw_rate", self.use_gyro_yaw_rate, "must be a bool")

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TyreForceKFConfig:
        """Build from a mapping (e.g. ROS parameters); unknown keys raise ConfigError."""
        if not isinstance(data, Mapping):
            raise ConfigError("tyre_force_kf", data, "must be a mapping")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise ConfigError(unknown[0], data[unknown[0]], "unknown key")
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
            kwargs[key] = value
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping of every field."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class LateralEstimate:
    """Lateral state of ``base_link`` (centre of the rear axle) in base_link axes.

    Attributes:
        t_ns: time of the estimate (stamp of the last tyre-force sample), ns; 0 before the
            first estimate.
        vx_m_s: forward speed, m/s.
        vy_m_s: lateral velocity of base_link, m/s (vy_cg - lr r).
        yaw_rate_rad_s: yaw rate r, rad/s (counter-clockwise positive).
        sideslip_rad: atan2(vy, vx) of base_link, rad.
        covariance: (3, 3) covariance of [vx m/s, vy m/s, r rad/s], SI units squared.
        axle_lateral_force_n: (2,) [front, rear] axle lateral force of the filter, N.
        linearity: relay state: ``linear``, ``nonlinear`` or ``unknown``.
        source: name of the estimator.
    """

    t_ns: int
    vx_m_s: float
    vy_m_s: float
    yaw_rate_rad_s: float
    sideslip_rad: float
    covariance: F64
    axle_lateral_force_n: F64
    linearity: str
    source: str = SOURCE


class HysteresisRelay:
    """Relay with hysteresis (Tuononen 2009, Fig. 7): on above ``on``, off below ``off``.

    Between the thresholds it keeps its state, so a deviation that briefly drops during a lane
    change does not switch the pseudo-measurement variance back to the low value.
    """

    def __init__(self, on_threshold: float, off_threshold: float, state: bool = False) -> None:
        if off_threshold > on_threshold:
            raise ConfigError("relay_off_threshold_n", off_threshold, "must be <= on threshold")
        self.on_threshold = float(on_threshold)
        self.off_threshold = float(off_threshold)
        self.state = bool(state)

    def update(self, value: float) -> bool:
        """Feed one input value; return the new state (True = on = nonlinear)."""
        # Fig. 7: switch on when value > on threshold, off when value < off threshold
        if not self.state and value > self.on_threshold:
            self.state = True
        elif self.state and value < self.off_threshold:
            self.state = False
        return self.state


def axle_force_deviation(single_track_n: F64, measured_n: F64) -> float:
    """Eq. (29): |Fy,f,onetrack - Fy,f,measured| + |Fy,r,onetrack - Fy,r,measured|, N.

    Args:
        single_track_n: (2,) [front, rear] axle forces of the single-track model, N.
        measured_n: (2,) [front, rear] measured (sensor + virtual) axle forces, N.
    """
    d = np.asarray(single_track_n, dtype=float) - np.asarray(measured_n, dtype=float)
    # Tuononen 2009 eq. (29)
    return float(abs(d[0]) + abs(d[1]))


def transition_matrix(
    dt_s: float, vx_m_s: float, mass_kg: float, yaw_inertia_kg_m2: float, lf_m: float, lr_m: float
) -> F64:
    """(4, 4) state transition of eq. (21) for x = [vy, r, Fy_f, Fy_r] over ``dt_s``."""
    ts = dt_s
    # Tuononen 2009 eq. (21): discretized eq. (19)-(20), forces as identity (random walk)
    return np.array(
        [
            [1.0, -ts * vx_m_s, ts / mass_kg, ts / mass_kg],
            [0.0, 1.0, lf_m / yaw_inertia_kg_m2 * ts, -lr_m / yaw_inertia_kg_m2 * ts],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


#: Measurement matrix of eq. (22): every state is measured (vy, r by the single-track model).
MEASUREMENT_MATRIX: F64 = np.eye(4)


class TyreForceKF:
    """The Kalman filter of Tuononen 2009 eq. (1)-(8), (21)-(22) on x = [vy_cg, r, Ff, Fr].

    Args:
        mass_kg, yaw_inertia_kg_m2, lf_m, lr_m: vehicle parameters (Table 1).
        q_diag: (4,) process noise variances per step [(m/s)^2, (rad/s)^2, N^2, N^2].
    """

    def __init__(
        self,
        mass_kg: float,
        yaw_inertia_kg_m2: float,
        lf_m: float,
        lr_m: float,
        q_diag: F64,
    ) -> None:
        self.mass_kg = mass_kg
        self.yaw_inertia_kg_m2 = yaw_inertia_kg_m2
        self.lf_m = lf_m
        self.lr_m = lr_m
        self.q: F64 = np.diag(np.asarray(q_diag, dtype=float))
        self.x: F64 = np.zeros(4)
        self.p: F64 = np.eye(4)

    def reset(self, x0: F64, p0_diag: F64) -> None:
        """Set the state (4,) and a diagonal covariance (4,)."""
        self.x = np.asarray(x0, dtype=float).copy()
        self.p = np.diag(np.asarray(p0_diag, dtype=float))

    def predict(self, dt_s: float, vx_m_s: float, yaw_moment_nm: float = 0.0) -> None:
        """Time update over ``dt_s`` with forward speed ``vx_m_s`` (eq. 1, 5).

        ``yaw_moment_nm``: known extra yaw moment (N m) held over the step (0 in the paper).
        """
        a = transition_matrix(
            dt_s, vx_m_s, self.mass_kg, self.yaw_inertia_kg_m2, self.lf_m, self.lr_m
        )
        # eq. (1): x_k^- = A x_k-1  (+ the known moment input on the yaw rate, beyond eq. 21)
        self.x = a @ self.x
        self.x[1] += dt_s * yaw_moment_nm / self.yaw_inertia_kg_m2
        # a priori covariance: P_k^- = A P A^T + Q
        self.p = a @ self.p @ a.T + self.q

    def update(self, z: F64, h: F64, r_diag: F64) -> None:
        """Measurement update with z (n,), H (n, 4) and diagonal R (n,) (eq. 2, 7, 8)."""
        r = np.diag(np.asarray(r_diag, dtype=float))
        s = h @ self.p @ h.T + r
        # eq. (7): K = P^- H^T (H P^- H^T + R)^-1
        k = np.linalg.solve(s, h @ self.p).T
        # eq. (8): x_k = x_k^- + K (z_k - H x_k^-)
        self.x = self.x + k @ (z - h @ self.x)
        # a posteriori covariance (Joseph form, keeps P symmetric positive definite)
        i_kh = np.eye(4) - k @ h
        self.p = i_kh @ self.p @ i_kh.T + k @ r @ k.T
        self.p = 0.5 * (self.p + self.p.T)


@dataclass
class _Held:
    """Latest sample of an input stream: stamp and value."""

    t_ns: int | None = None
    value: Any = None


def _finite(kind: str, values: F64) -> None:
    if not np.all(np.isfinite(values)):
        raise InputError("nan", f"{kind}: non-finite value in {values!r}")


class TyreForceEstimator:
    """Front-end of the tyre-force Kalman filter: inputs in, :class:`LateralEstimate` out.

    ``stats`` counts dropped samples by kind (``nan``, ``out_of_order``, ``duplicate``,
    ``wrong_length``, ``bad_stamp``, ``bad_value``, ``out_of_range``, ``no_valid_sensor``,
    ``no_steering``, ``no_speed``), filter re-initializations (``gap``, ``diverged``) and
    degraded steps where one axle had no sensor (``axle_unobserved``: that axle's force row is
    left out of the update).

    Args:
        config: filter configuration.
        vehicle: vehicle description (m, Iz, lf, lr, Cf, Cr, track, radius, drive).
    """

    def __init__(self, config: TyreForceKFConfig, vehicle: VehicleParams) -> None:
        if not isinstance(config, TyreForceKFConfig):
            raise ConfigError("config", config, "must be a TyreForceKFConfig")
        if not isinstance(vehicle, VehicleParams):
            raise ConfigError("vehicle", vehicle, "must be a VehicleParams")
        self.config = config
        self.vehicle = vehicle
        c = config
        self.single_track_params = SingleTrackParams.from_vehicle(vehicle)
        self.tyres = (
            MagicFormulaTyre(
                c.mf_shape_c,
                c.mf_curvature_e,
                c.mf_friction_mu,
                vehicle.cornering_stiffness_front_n_rad / 2.0,
                c.mf_b_front_1_rad,
            ),
            MagicFormulaTyre(
                c.mf_shape_c,
                c.mf_curvature_e,
                c.mf_friction_mu,
                vehicle.cornering_stiffness_rear_n_rad / 2.0,
                c.mf_b_rear_1_rad,
            ),
        )
        g, m, wb = GRAVITY_M_S2, vehicle.mass_kg, vehicle.wheelbase_m
        #: Static wheel loads from the vehicle parameters, N, (2,) [front wheel, rear wheel].
        self.nominal_static_load_n = np.array(
            [m * g * vehicle.lr_m / wb / 2.0, m * g * vehicle.lf_m / wb / 2.0]
        )
        self._q_diag = np.array(
            [
                c.process_noise_vy_m2_s2,
                c.process_noise_yaw_rate_rad2_s2,
                c.process_noise_force_n2,
                c.process_noise_force_n2,
            ]
        )
        self.stats: dict[str, int] = {}
        self.reset()

    # ------------------------------------------------------------------ housekeeping
    def reset(self) -> None:
        """Forget the state, the relay and the learned static loads (not ``stats``)."""
        v = self.vehicle
        self.kf = TyreForceKF(v.mass_kg, v.yaw_inertia_kg_m2, v.lf_m, v.lr_m, self._q_diag)
        self.single_track = SingleTrackModel(self.single_track_params, self.config.min_speed_m_s)
        self.relay = HysteresisRelay(
            self.config.relay_on_threshold_n, self.config.relay_off_threshold_n
        )
        #: Static load of each wheel, N, (4,) in the order fl, fr, rl, rr (eq. 12).
        self.static_load_n = np.repeat(self.nominal_static_load_n, 2)
        self._held = {k: _Held() for k in ("forces", "steering", "wheels", "imu")}
        self._speed_m_s: float | None = None
        self._gyro_used_t_ns: int | None = None
        self._t_ns: int | None = None
        self._initialized = False
        self._linearity = "unknown"
        self._deviation_lp_n = np.zeros(2)
        self._moment_nm = 0.0
        self._deviation_n = 0.0
        self._measured_axle_n = np.zeros(2)
        #: Steer angle of the previous filter step (start of the single-track model's step).
        self._st_delta_rad = 0.0

    def _drop(self, kind: str) -> None:
        self.stats[kind] = self.stats.get(kind, 0) + 1

    def _check_stamp(self, stream: str, t_ns: int) -> int:
        return stamp_after(stream, t_ns, self._held[stream].t_ns)

    @staticmethod
    def _vector(kind: str, values: Any, n: int) -> F64:
        arr = np.asarray(values, dtype=float).reshape(-1)
        if arr.shape != (n,):
            raise InputError("wrong_length", f"{kind}: need {n} values, got {arr.size}")
        return arr

    def _fresh(self, stream: str, t_ns: int) -> bool:
        held = self._held[stream]
        if held.t_ns is None:
            return False
        return abs(t_ns - held.t_ns) * 1e-9 <= self.config.input_timeout_s

    # ------------------------------------------------------------------ inputs
    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle delta, rad (positive left)."""
        try:
            t = self._check_stamp("steering", t_ns)
            angle = float(angle_rad)
            _finite("steering", np.array([angle]))
            if abs(angle) > 1.2:
                raise InputError("out_of_range", f"steering angle {angle} rad")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._held["steering"] = _Held(t, angle)

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (4,) rad/s in the order fl, fr, rl, rr: the forward speed vx.

        vx = mean speed of the undriven axle (the rear axle for all-wheel drive) times the
        nominal tyre radius; a front axle is corrected by the steer angle (cos delta).
        """
        try:
            t = self._check_stamp("wheels", t_ns)
            ws = self._vector("wheel speeds", wheel_speed_rad_s, 4)
            _finite("wheel speeds", ws)
            if np.any(np.abs(ws) > 1000.0):
                raise InputError("out_of_range", f"wheel speed above 1000 rad/s: {ws}")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._held["wheels"] = _Held(t, ws)
        radius = self.vehicle.nominal_tire_radius_m
        if self.vehicle.drive == "rear":
            delta = self._held["steering"].value or 0.0
            self._speed_m_s = float(0.5 * (ws[0] + ws[1]) * radius * math.cos(delta))
        else:
            self._speed_m_s = float(0.5 * (ws[2] + ws[3]) * radius)

    def on_imu(
        self, t_ns: int, angular_velocity_rad_s: Any, linear_acceleration_m_s2: Any
    ) -> None:
        """IMU sample in base_link axes: gyro (3,) rad/s, specific force (3,) m/s^2.

        Only the gyro z is used, and only with ``use_gyro_yaw_rate`` (the paper uses the
        IMU for validation only).
        """
        try:
            t = self._check_stamp("imu", t_ns)
            gyro = self._vector("imu gyro", angular_velocity_rad_s, 3)
            acc = self._vector("imu accel", linear_acceleration_m_s2, 3)
            _finite("imu", np.concatenate([gyro, acc]))
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._held["imu"] = _Held(t, float(gyro[2]))

    def on_tire_forces(
        self, t_ns: int, fx_n: Any, fy_n: Any, fz_n: Any, valid: Any
    ) -> LateralEstimate | None:
        """Tyre forces (4,) N per wheel (fl, fr, rl, rr) in the wheel frames; ``valid`` (4,)
        marks wheels with a sensor. Runs one filter step; returns the new estimate, or None
        when the sample was dropped (counted in :attr:`stats`)."""
        try:
            t = self._check_stamp("forces", t_ns)
            fx = self._vector("fx", fx_n, 4)
            fy = self._vector("fy", fy_n, 4)
            fz = self._vector("fz", fz_n, 4)
            ok = np.asarray(valid, dtype=bool).reshape(-1)
            if ok.shape != (4,):
                raise InputError("wrong_length", f"valid: need 4 flags, got {ok.size}")
            if not np.any(ok):
                raise InputError("no_valid_sensor", "no tyre-force sensor is valid")
            _finite("tyre forces", np.concatenate([fx[ok], fy[ok], fz[ok]]))
            if np.any(np.abs(np.concatenate([fx[ok], fy[ok], fz[ok]])) > 1e6):
                raise InputError("out_of_range", "tyre force above 1e6 N")
            if np.any(fz[ok] < 0.0):
                raise InputError("out_of_range", f"negative vertical load {fz}")
            if not self._fresh("steering", t):
                raise InputError("no_steering", "no fresh steering angle")
            if self._speed_m_s is None or not self._fresh("wheels", t):
                raise InputError("no_speed", "no fresh forward speed")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return None
        self._held["forces"] = _Held(t, None)
        self._step(t, fx, fy, fz, ok)
        return self.estimate()

    # ------------------------------------------------------------------ filter step
    def _axle_forces(
        self, dt_s: float, fx: F64, fy: F64, fz: F64, ok: F64, delta: float
    ) -> tuple[F64, F64, float]:
        """Measured (sensor + virtual) axle lateral forces in body axes [front, rear] (N, (2,)),
        which axles are measured ((2,) bool), and the track yaw moment (N m, 0 when an axle is
        not measured or ``track_yaw_moment`` is off)."""
        c = self.config
        out = np.zeros(2)
        have = np.zeros(2, dtype=bool)
        moment = 0.0
        half_track = 0.5 * self.vehicle.track_width_m
        for axle, (i, j) in enumerate(((0, 1), (2, 3))):
            # per-wheel [left, right] forces in the wheel frames
            if ok[i] and ok[j]:
                fy_w = np.array([fy[i], fy[j]])
                fx_w = np.array([fx[i], fx[j]])
            elif ok[i] or ok[j]:
                s, v = (i, j) if ok[i] else (j, i)
                self._learn_static_load(dt_s, s, fy[s], fz[s])
                fz_v = virtual_load(fz[s], self.static_load_n[s], self.static_load_n[v])
                if c.virtual_sensor_method == "inverse_mf":
                    fy_v = self.tyres[axle].virtual_force(fy[s], fz[s], fz_v)
                else:
                    fy_v = virtual_force_normalized(fy[s], fz[s], fz_v)
                fy_w = np.array([fy[s], fy_v]) if s == i else np.array([fy_v, fy[s]])
                # longitudinal force of the virtual wheel: that of its axle partner
                fx_w = np.array([fx[s], fx[s]])
            else:
                continue
            have[axle] = True
            steer = delta if axle == 0 else 0.0
            # wheel frame -> body axes (front wheels steered by delta; beyond the paper)
            fy_body = fy_w * math.cos(steer) + fx_w * math.sin(steer)
            fx_body = fx_w * math.cos(steer) - fy_w * math.sin(steer)
            out[axle] = fy_body.sum()
            # yaw moment of the body-x forces: -y_i Fx_i with y = +half (left), -half (right)
            moment += -half_track * (fx_body[0] - fx_body[1])
        if not (c.track_yaw_moment and np.all(have)):
            moment = 0.0
        return out, have, moment

    def _learn_static_load(self, dt_s: float, i: int, fy: float, fz: float) -> None:
        """Eq. (12) static load: average of Fz,1 recorded while Fy,1 ~ 0."""
        c = self.config
        if abs(fy) < c.static_load_fy_threshold_n and dt_s > 0.0:
            w = min(1.0, dt_s / c.static_load_time_constant_s)
            self.static_load_n[i] += w * (fz - self.static_load_n[i])
            # the virtual partner of the same axle has the same static load (symmetric car)
            self.static_load_n[i ^ 1] = self.static_load_n[i]

    def _initialize(self, t: int, vx: float, delta: float, forces: F64) -> None:
        c = self.config
        self.single_track.reset(vx, delta)
        self._st_delta_rad = delta
        x0 = np.concatenate([self.single_track.x, forces])
        p0 = np.array(
            [
                c.initial_vy_variance_m2_s2,
                c.initial_yaw_rate_variance_rad2_s2,
                c.initial_force_variance_n2,
                c.initial_force_variance_n2,
            ]
        )
        self.kf.reset(x0, p0)
        self._initialized = True
        self._t_ns = t
        self._linearity = "unknown" if vx < c.min_speed_m_s else "linear"
        self.relay.state = False
        self._deviation_lp_n = np.zeros(2)

    def _step(self, t: int, fx: F64, fy: F64, fz: F64, ok: F64) -> None:
        c = self.config
        vx = float(self._speed_m_s or 0.0)
        delta = float(self._held["steering"].value)
        dt = 0.0 if self._t_ns is None else (t - self._t_ns) * 1e-9
        if self._initialized and dt > c.max_gap_s:
            self._drop("gap")
            self._initialized = False
        measured, have, moment = self._axle_forces(dt, fx, fy, fz, ok, delta)
        if not np.all(have):
            self._drop("axle_unobserved")
        self._measured_axle_n = measured
        if not self._initialized or vx < c.min_speed_m_s:
            self._moment_nm = moment
            self._initialize(t, max(vx, 0.0), delta, np.where(have, measured, self.kf.x[2:]))
            return
        self._t_ns = t
        # reference model (eq. 23-28): open-loop vy, r and nominal axle forces; the steer
        # angle is linear between the previous step's sample and this one (first-order hold:
        # holding the newest sample over the step would lead the truth by half a step)
        st = self.single_track.step(dt, vx, delta, self._st_delta_rad)
        self._st_delta_rad = delta
        f_st = self.single_track.axle_forces(vx, delta)
        # linearity (eq. 29) and relay (Fig. 7), on the axles that are measured
        # low-pass of the signed per-axle differences (beyond the paper: removes the bias that
        # the sensor noise gives |.| in eq. 29 before the relay sees it)
        diff = np.where(have, f_st - measured, 0.0)
        tau = c.deviation_filter_time_constant_s
        w = 1.0 if tau <= 0.0 else min(1.0, dt / tau)
        self._deviation_lp_n += w * (diff - self._deviation_lp_n)
        self._deviation_n = axle_force_deviation(self._deviation_lp_n, np.zeros(2))
        nonlinear = self.relay.update(self._deviation_n)
        self._linearity = "nonlinear" if nonlinear else "linear"
        if nonlinear:
            r_st = (c.nonlinear_vy_variance_m2_s2, c.nonlinear_yaw_rate_variance_rad2_s2)
        else:
            r_st = (c.linear_vy_variance_m2_s2, c.linear_yaw_rate_variance_rad2_s2)
        # eq. (21): prediction with the forward speed as the time-varying parameter
        self.kf.predict(dt, vx, self._moment_nm)
        self._moment_nm = moment
        # eq. (22): z = [vy_st, r_st, Ff, Fr] (rows of absent axles removed)
        rows = [0, 1] + [2 + a for a in range(2) if have[a]]
        z = np.concatenate([st, measured[have]])
        r_diag = [r_st[0], r_st[1]] + [c.force_variance_n2] * int(have.sum())
        h = MEASUREMENT_MATRIX[rows]
        gyro = self._held["imu"]
        if (
            c.use_gyro_yaw_rate
            and gyro.t_ns is not None
            and gyro.t_ns != self._gyro_used_t_ns
            and self._fresh("imu", t)
        ):
            self._gyro_used_t_ns = gyro.t_ns
            h = np.vstack([h, MEASUREMENT_MATRIX[1]])
            z = np.append(z, gyro.value)
            r_diag.append(c.gyro_variance_rad2_s2)
        self.kf.update(z, h, np.asarray(r_diag))
        if not np.all(np.isfinite(self.kf.x)) or not np.all(np.isfinite(self.kf.p)):
            self._drop("diverged")
            self._initialize(t, vx, delta, np.where(have, measured, 0.0))

    # ------------------------------------------------------------------ outputs
    @property
    def linearity(self) -> str:
        """Relay state: ``linear``, ``nonlinear`` or ``unknown``."""
        return self._linearity

    @property
    def axle_force_deviation_n(self) -> float:
        """Last eq. (29) deviation after the low-pass (the relay input), N."""
        return self._deviation_n

    @property
    def measured_axle_force_n(self) -> F64:
        """Last measured (sensor + virtual) axle lateral forces [front, rear], N, (2,)."""
        return self._measured_axle_n.copy()

    def _to_base_link(
        self, t_ns: int, vx: float, x2: F64, p2: F64, forces: F64, source: str
    ) -> LateralEstimate:
        lr = self.vehicle.lr_m
        # base_link = CG - lr along x: vy_base = vy_cg - lr r
        jac = np.array([[1.0, -lr], [0.0, 1.0]])
        vy = float(x2[0] - lr * x2[1])
        cov = np.zeros((3, 3))
        cov[0, 0] = self.config.speed_variance_m2_s2
        cov[1:, 1:] = jac @ p2 @ jac.T
        return LateralEstimate(
            t_ns=t_ns,
            vx_m_s=vx,
            vy_m_s=vy,
            yaw_rate_rad_s=float(x2[1]),
            sideslip_rad=math.atan2(vy, vx) if vx > 0.0 else 0.0,
            covariance=cov,
            axle_lateral_force_n=np.asarray(forces, dtype=float).copy(),
            linearity=self._linearity if source == SOURCE else "unknown",
            source=source,
        )

    def estimate(self) -> LateralEstimate:
        """Current estimate (of base_link); zeros and the prior covariance before the first."""
        vx = float(self._speed_m_s or 0.0)
        if not self._initialized:
            c = self.config
            p2 = np.diag([c.initial_vy_variance_m2_s2, c.initial_yaw_rate_variance_rad2_s2])
            return self._to_base_link(0, vx, np.zeros(2), p2, np.zeros(2), SOURCE)
        return self._to_base_link(
            int(self._t_ns or 0), vx, self.kf.x[:2], self.kf.p[:2, :2], self.kf.x[2:], SOURCE
        )

    def single_track_estimate(self) -> LateralEstimate:
        """The open-loop single-track reference model alone (eq. 23-28), for comparison."""
        vx = float(self._speed_m_s or 0.0)
        delta = float(self._held["steering"].value or 0.0)
        forces = (
            self.single_track.axle_forces(vx, delta)
            if self.single_track.initialized
            else np.zeros(2)
        )
        c = self.config
        p2 = np.diag([c.linear_vy_variance_m2_s2, c.linear_yaw_rate_variance_rad2_s2])
        return self._to_base_link(
            int(self._t_ns or 0), vx, self.single_track.x, p2, forces, "single_track"
        )
