"""Lateral vehicle state from measured tyre forces (Tuononen, Sensors 2009, 9, 8761-8775).

A linear Kalman filter on ``x = [vy_cg m/s, r rad/s, Fy_front N, Fy_rear N]``:

* transition (eq. 21): the lateral and yaw equations of motion (eq. 19-20) integrate the axle
  forces; the forces follow a random walk (identity transition, large process noise); the
  forward speed vx is the only time-varying parameter;
* measurement (eq. 22): identity -- vy and r are pseudo-measurements of the linear single-track
  model (eq. 23-28, :mod:`.single_track`), the axle forces come from the
  tyre sensors plus virtual tyre sensors for the wheels without one (inverse Magic Formula,
  eq. 11-13, :mod:`~tire_estimation.core.lateral.virtual_tyre`);
* adaptive measurement noise (section 3.5): the axle-force deviation between the single-track
  model and the measurement (eq. 29) drives a relay with hysteresis (Fig. 7) that switches the
  variance of the single-track pseudo-measurements between a low (linear) and a high
  (nonlinear) value (:mod:`.tyre_force_filter`).

Beyond the paper, the front lateral forces are rotated into body axes by the steer angle, and
the yaw moment of the left/right difference of the body-x wheel forces (front lateral forces
rotated by the steer angle, drive and brake forces) is a known input of the yaw equation when
both axles are measured (the paper's eq. 20 has the axle lateral forces only).

The filter runs at every tyre-force sample; steering and forward speed (from the wheel speeds
of the undriven axle, "vehicle velocity from the CAN bus" in the paper) are held from their
latest samples, except that the single-track model takes the steer angle as linear between the
samples of consecutive filter steps (first-order hold). Internally vy is that of the centre of
gravity (the paper's); the published :class:`LateralEstimate` is of ``base_link`` (centre of
the rear axle, REP-103 axes) as the ``LateralState`` message requires: vy_base = vy_cg - lr r.

Bad input never raises out of the ``on_*`` methods: the sample is dropped and counted in
:attr:`TyreForceEstimator.stats` as ``<stream>:<kind>``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import drop_key, stamp_after
from tire_estimation.core.lateral.estimate import TYRE_FORCE_SOURCE as SOURCE
from tire_estimation.core.lateral.estimate import LateralEstimate
from tire_estimation.core.lateral.single_track import SingleTrackModel, SingleTrackParams
from tire_estimation.core.lateral.tyre_force_filter import (
    DEVIATION_FILTER_TIME_CONSTANT_S,
    INITIAL_FORCE_VARIANCE_N2,
    INITIAL_VY_VARIANCE_M2_S2,
    INITIAL_YAW_RATE_VARIANCE_RAD2_S2,
    RELAY_OFF_THRESHOLD_N,
    RELAY_ON_THRESHOLD_N,
    HysteresisRelay,
    TyreForceKF,
    axle_force_deviation,
)
from tire_estimation.core.lateral.virtual_tyre import MagicFormulaTyre, virtual_load
from tire_estimation.core.validation import (
    Checked,
    in_range,
    require_positive,
)
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, InputError

GRAVITY_M_S2 = 9.81

# Eq. (12) static load of a sensor wheel, learned while it carries little lateral force:
#: |Fy| below which the measured Fz updates the static load, N (twice the 150 N Fy noise).
STATIC_LOAD_FY_THRESHOLD_N = 300.0
#: time constant of that static-load average, s (slow against a lane change's load transfer).
STATIC_LOAD_TIME_CONSTANT_S = 5.0
#: variance reported for vx, (m/s)^2: the filter does not estimate it, it is the undriven
#: axle's wheel speed at the nominal radius (0.1 m/s: a radius 0.3 % off at 30 m/s)
SPEED_VARIANCE_M2_S2 = 0.01

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
class TyreForceKFConfig(Checked):
    """Configuration of :class:`TyreForceEstimator` (Tuononen 2009; checked at construction).

    m, Iz, lf, lr and the single-track cornering stiffnesses Cf, Cr come from
    :class:`~tire_estimation.core.vehicle.VehicleParams` (Table 1 values for the paper's car:
    :data:`TUONONEN_2009_VEHICLE`). The paper gives Q (Table 1) but no numbers for R; the R
    defaults fit the simulator's tyre sensors (150 N noise per wheel) on the ``lane_change``
    scenario (seeds 0 and 1). The relay thresholds, the initial covariance and the Magic Formula
    shape are module constants (:mod:`.tyre_force_filter`, :mod:`.virtual_tyre`).

    Attributes:
        process_noise_vy_m2_s2: Q of vy per filter step, (m/s)^2, in (0, 1e12]. Default 0.01
            (Table 1).
        process_noise_yaw_rate_rad2_s2: Q of the yaw rate per filter step, (rad/s)^2, in
            (0, 1e12]. Default 0.01 (Table 1).
        process_noise_force_n2: Q of each axle lateral force per filter step, N^2, in
            (0, 1e12]. Default 1e4 (Table 1).
        force_variance_n2: R of each measured axle lateral force (sensor wheel plus virtual
            wheel), N^2, in (0, 1e12]; constant (sensor accuracy does not depend on the
            driving state). Default 9e4 (twice the 150 N sensor noise).
        linear_vy_variance_m2_s2: R of the single-track vy pseudo-measurement while the relay
            says linear, (m/s)^2, in (0, 1e12]. Default 1e-3.
        linear_yaw_rate_variance_rad2_s2: R of the single-track yaw rate while linear,
            (rad/s)^2, in (0, 1e12]. Default 1e-4.
        nonlinear_vy_variance_m2_s2: R of the single-track vy while nonlinear, (m/s)^2, in
            (0, 1e12]. Default 3.
        nonlinear_yaw_rate_variance_rad2_s2: R of the single-track yaw rate while nonlinear,
            (rad/s)^2, in (0, 1e12]. Default 0.3 (a yaw rate integrated from noisy forces
            drifts by ~1.3 deg/s per sqrt(s) with 150 N sensors, so the model's yaw rate keeps
            some weight; far larger values make the nonlinear-phase yaw rate worse).
        min_speed_m_s: below this forward speed the filter is held at the kinematic state
            and the linearity is ``unknown``, m/s, in [0.5, 100]. Default 5.
        max_gap_s: a gap between tyre-force samples longer than this re-initializes the
            filter, s, in (0, 1e12]. Default 0.5.
        input_timeout_s: steering / wheel-speed samples older than this are stale; a
            tyre-force sample without fresh steering and speed is dropped, s, in (0, 1e12].
            Default 0.5.
    """

    process_noise_vy_m2_s2: float = 0.01
    process_noise_yaw_rate_rad2_s2: float = 0.01
    process_noise_force_n2: float = 1e4
    force_variance_n2: float = 9e4
    linear_vy_variance_m2_s2: float = 1e-3
    linear_yaw_rate_variance_rad2_s2: float = 1e-4
    nonlinear_vy_variance_m2_s2: float = 3.0
    nonlinear_yaw_rate_variance_rad2_s2: float = 0.3
    min_speed_m_s: Annotated[float, in_range(0.5, 100.0)] = 5.0
    max_gap_s: float = 0.5
    input_timeout_s: float = 0.5

    def check(self) -> None:
        for f in dataclasses.fields(self):
            if f.name == "min_speed_m_s":
                continue
            value = getattr(self, f.name)
            require_positive(f.name, value)
            if value > 1e12:
                raise ConfigError(f.name, value, "must be <= 1e12")

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping of every field."""
        return dataclasses.asdict(self)


@dataclass
class _Held:
    """Latest sample of an input stream: stamp and value."""

    t_ns: int | None = None
    value: Any = None


def _finite(kind: str, values: list[float]) -> None:
    if not all(map(math.isfinite, values)):
        raise InputError("nan", f"{kind}: non-finite value in {values!r}")


#: the state rows measured (eq. 22) by which axles have a force: vy and r always
_ROWS = {
    (True, True): np.array([0, 1, 2, 3], dtype=np.intp),
    (True, False): np.array([0, 1, 2], dtype=np.intp),
    (False, True): np.array([0, 1, 3], dtype=np.intp),
    (False, False): np.array([0, 1], dtype=np.intp),
}


class TyreForceEstimator:
    """Front-end of the tyre-force Kalman filter: inputs in, :class:`LateralEstimate` out.

    ``stats`` counts, as ``<stream>:<kind>``, dropped samples (kinds ``nan``,
    ``out_of_order``, ``duplicate``, ``wrong_length``, ``bad_stamp``, ``bad_value``,
    ``out_of_range``; ``tire_forces:no_valid_sensor``, ``:no_steering``, ``:no_speed``), filter
    re-initializations (``tire_forces:gap``, ``tire_forces:diverged``) and degraded steps where
    one axle had no sensor (``tire_forces:axle_unobserved``: that axle's force row is left out
    of the update).

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
            MagicFormulaTyre(vehicle.cornering_stiffness_front_n_rad / 2.0),
            MagicFormulaTyre(vehicle.cornering_stiffness_rear_n_rad / 2.0),
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
        self.relay = HysteresisRelay(RELAY_ON_THRESHOLD_N, RELAY_OFF_THRESHOLD_N)
        #: Static load of each wheel, N, (4,) in the order fl, fr, rl, rr (eq. 12).
        self.static_load_n = np.repeat(self.nominal_static_load_n, 2)
        self._held = {k: _Held() for k in ("forces", "steering", "wheels")}
        self._speed_m_s: float | None = None
        self._t_ns: int | None = None
        self._initialized = False
        self._linearity = "unknown"
        self._deviation_lp_n = (0.0, 0.0)
        self._moment_nm = 0.0
        self._deviation_n = 0.0
        self._measured_axle_n = (0.0, 0.0)
        #: Steer angle of the previous filter step (start of the single-track model's step).
        self._st_delta_rad = 0.0

    def _drop(self, stream: str, kind: str) -> None:
        key = drop_key(stream, kind)
        self.stats[key] = self.stats.get(key, 0) + 1

    def _check_stamp(self, stream: str, t_ns: int) -> int:
        return stamp_after(stream, t_ns, self._held[stream].t_ns)

    @staticmethod
    def _vector(kind: str, values: Any, n: int) -> list[float]:
        arr = np.asarray(values, dtype=float).reshape(-1)
        if arr.shape != (n,):
            raise InputError("wrong_length", f"{kind}: need {n} values, got {arr.size}")
        return arr.tolist()

    def _fresh(self, stream: str, t_ns: int) -> bool:
        held = self._held[stream]
        if held.t_ns is None:
            return False
        # an input stamped after the tyre forces is not fresh (its age is negative)
        return 0 <= t_ns - held.t_ns <= self.config.input_timeout_s * 1e9

    # ------------------------------------------------------------------ inputs
    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle delta, rad (positive left)."""
        try:
            t = self._check_stamp("steering", t_ns)
            angle = float(angle_rad)
            _finite("steering", [angle])
            if abs(angle) > 1.2:
                raise InputError("out_of_range", f"steering angle {angle} rad")
        except (InputError, TypeError, ValueError) as exc:
            self._drop("steering", exc.kind if isinstance(exc, InputError) else "bad_value")
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
            if max(map(abs, ws)) > 1000.0:
                raise InputError("out_of_range", f"wheel speed above 1000 rad/s: {ws}")
        except (InputError, TypeError, ValueError) as exc:
            self._drop("wheel_speeds", exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._held["wheels"] = _Held(t, ws)
        radius = self.vehicle.nominal_tire_radius_m
        if self.vehicle.drive == "rear":
            delta = self._held["steering"].value or 0.0
            self._speed_m_s = float(0.5 * (ws[0] + ws[1]) * radius * math.cos(delta))
        else:
            self._speed_m_s = float(0.5 * (ws[2] + ws[3]) * radius)

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
            flags = np.asarray(valid, dtype=bool).reshape(-1)
            if flags.shape != (4,):
                raise InputError("wrong_length", f"valid: need 4 flags, got {flags.size}")
            ok: list[bool] = flags.tolist()
            if not any(ok):
                raise InputError("no_valid_sensor", "no tyre-force sensor is valid")
            used = [f[i] for f in (fx, fy, fz) for i in range(4) if ok[i]]
            _finite("tyre forces", used)
            if max(map(abs, used)) > 1e6:
                raise InputError("out_of_range", "tyre force above 1e6 N")
            if any(fz[i] < 0.0 for i in range(4) if ok[i]):
                raise InputError("out_of_range", f"negative vertical load {fz}")
            if not self._fresh("steering", t):
                raise InputError("no_steering", "no fresh steering angle")
            if self._speed_m_s is None or not self._fresh("wheels", t):
                raise InputError("no_speed", "no fresh forward speed")
        except (InputError, TypeError, ValueError) as exc:
            self._drop("tire_forces", exc.kind if isinstance(exc, InputError) else "bad_value")
            return None
        self._held["forces"] = _Held(t, None)
        self._step(t, fx, fy, fz, ok)
        return self.estimate()

    # ------------------------------------------------------------------ filter step
    def _axle_forces(
        self,
        dt_s: float,
        fx: list[float],
        fy: list[float],
        fz: list[float],
        ok: list[bool],
        delta: float,
    ) -> tuple[tuple[float, float], tuple[bool, bool], float]:
        """Measured (sensor + virtual) axle lateral forces in body axes [front, rear] (N),
        which axles are measured, and the track yaw moment (N m, 0 when an axle is not
        measured)."""
        out = [0.0, 0.0]
        have = [False, False]
        moment = 0.0
        half_track = 0.5 * self.vehicle.track_width_m
        for axle, (i, j) in enumerate(((0, 1), (2, 3))):
            # per-wheel [left, right] forces in the wheel frames
            if ok[i] and ok[j]:
                fy_l, fy_r, fx_l, fx_r = fy[i], fy[j], fx[i], fx[j]
            elif ok[i] or ok[j]:
                s, v = (i, j) if ok[i] else (j, i)
                self._learn_static_load(dt_s, s, fy[s], fz[s])
                fz_v = virtual_load(fz[s], self.static_load_n[s], self.static_load_n[v])
                fy_v = self.tyres[axle].virtual_force(fy[s], fz[s], fz_v)
                fy_l, fy_r = (fy[s], fy_v) if s == i else (fy_v, fy[s])
                # longitudinal force of the virtual wheel: that of its axle partner
                fx_l = fx_r = fx[s]
            else:
                continue
            have[axle] = True
            steer = delta if axle == 0 else 0.0
            cos_s, sin_s = math.cos(steer), math.sin(steer)
            # wheel frame -> body axes (front wheels steered by delta; beyond the paper)
            out[axle] = (fy_l * cos_s + fx_l * sin_s) + (fy_r * cos_s + fx_r * sin_s)
            # yaw moment of the body-x forces: -y_i Fx_i with y = +half (left), -half (right)
            moment += -half_track * ((fx_l * cos_s - fy_l * sin_s) - (fx_r * cos_s - fy_r * sin_s))
        if not (have[0] and have[1]):
            moment = 0.0
        return (out[0], out[1]), (have[0], have[1]), moment

    def _learn_static_load(self, dt_s: float, i: int, fy: float, fz: float) -> None:
        """Eq. (12) static load: average of Fz,1 recorded while Fy,1 ~ 0."""
        if abs(fy) < STATIC_LOAD_FY_THRESHOLD_N and dt_s > 0.0:
            w = min(1.0, dt_s / STATIC_LOAD_TIME_CONSTANT_S)
            self.static_load_n[i] += w * (fz - self.static_load_n[i])
            # the virtual partner of the same axle has the same static load (symmetric car)
            self.static_load_n[i ^ 1] = self.static_load_n[i]

    def _initialize(self, t: int, vx: float, delta: float, forces: F64) -> None:
        self.single_track.reset(vx, delta)
        self._st_delta_rad = delta
        x0 = np.concatenate([self.single_track.x, forces])
        p0 = np.array(
            [
                INITIAL_VY_VARIANCE_M2_S2,
                INITIAL_YAW_RATE_VARIANCE_RAD2_S2,
                INITIAL_FORCE_VARIANCE_N2,
                INITIAL_FORCE_VARIANCE_N2,
            ]
        )
        self.kf.reset(x0, p0)
        self._initialized = True
        self._t_ns = t
        self._linearity = "unknown" if vx < self.config.min_speed_m_s else "linear"
        self.relay.state = False
        self._deviation_lp_n = (0.0, 0.0)

    def _step(
        self, t: int, fx: list[float], fy: list[float], fz: list[float], ok: list[bool]
    ) -> None:
        c = self.config
        vx = float(self._speed_m_s or 0.0)
        delta = float(self._held["steering"].value)
        dt = 0.0 if self._t_ns is None else (t - self._t_ns) * 1e-9
        if self._initialized and dt > c.max_gap_s:
            self._drop("tire_forces", "gap")
            self._initialized = False
        measured, have, moment = self._axle_forces(dt, fx, fy, fz, ok, delta)
        if not (have[0] and have[1]):
            self._drop("tire_forces", "axle_unobserved")
        self._measured_axle_n = measured
        if not self._initialized or vx < c.min_speed_m_s:
            self._moment_nm = moment
            held = [measured[a] if have[a] else float(self.kf.x[2 + a]) for a in range(2)]
            self._initialize(t, max(vx, 0.0), delta, np.array(held))
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
        w = min(1.0, dt / DEVIATION_FILTER_TIME_CONSTANT_S)
        lp = self._deviation_lp_n
        d0 = float(f_st[0]) - measured[0] if have[0] else 0.0
        d1 = float(f_st[1]) - measured[1] if have[1] else 0.0
        lp = (lp[0] + w * (d0 - lp[0]), lp[1] + w * (d1 - lp[1]))
        self._deviation_lp_n = lp
        self._deviation_n = axle_force_deviation(lp, (0.0, 0.0))
        nonlinear = self.relay.update(self._deviation_n)
        self._linearity = "nonlinear" if nonlinear else "linear"
        if nonlinear:
            r_st = [c.nonlinear_vy_variance_m2_s2, c.nonlinear_yaw_rate_variance_rad2_s2]
        else:
            r_st = [c.linear_vy_variance_m2_s2, c.linear_yaw_rate_variance_rad2_s2]
        # eq. (21): prediction with the forward speed as the time-varying parameter
        self.kf.predict(dt, vx, self._moment_nm)
        self._moment_nm = moment
        # eq. (22): z = [vy_st, r_st, Ff, Fr] (rows of absent axles removed)
        present = [a for a in range(2) if have[a]]
        z = np.array([float(st[0]), float(st[1]), *(measured[a] for a in present)])
        r_diag = np.array(r_st + [c.force_variance_n2] * len(present))
        if not self.kf.update(_ROWS[have], z, r_diag):
            self._drop("tire_forces", "diverged")
            forces = np.array([measured[a] if have[a] else 0.0 for a in range(2)])
            self._initialize(t, vx, delta, forces)

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
        return np.array(self._measured_axle_n)

    def _to_base_link(
        self, t_ns: int, vx: float, x2: F64, p2: F64, forces: F64, source: str
    ) -> LateralEstimate:
        lr = self.vehicle.lr_m
        # base_link = CG - lr along x: vy_base = vy_cg - lr r, covariance J P J^T with
        # J = [[1, -lr], [0, 1]]
        vy = float(x2[0] - lr * x2[1])
        p00, p01, p10, p11 = float(p2[0, 0]), float(p2[0, 1]), float(p2[1, 0]), float(p2[1, 1])
        cov = np.zeros((3, 3))
        cov[0, 0] = SPEED_VARIANCE_M2_S2
        cov[1, 1] = (p00 - lr * p10) - lr * (p01 - lr * p11)
        cov[1, 2] = p01 - lr * p11
        cov[2, 1] = p10 - lr * p11
        cov[2, 2] = p11
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
            p2 = np.diag([INITIAL_VY_VARIANCE_M2_S2, INITIAL_YAW_RATE_VARIANCE_RAD2_S2])
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
