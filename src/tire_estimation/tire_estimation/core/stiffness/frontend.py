"""Front-end of the tyre-stiffness filters (Berntorp & Di Cairano, IEEE TCST 2018).

:class:`StiffnessFrontEnd` feeds one filter (:class:`~.stiffness_filter.StiffnessFilter`) from
asynchronous sensor callbacks, the same way for Algorithm 1
(:class:`~.stiffness_estimator.StiffnessEstimator`) and for every filter it is compared with.
The IMU drives the filter; the latest wheel speeds (or a measured longitudinal speed) and
steering angle are its inputs ``u``. Per IMU sample it

* checks every stream (integer, increasing stamps; length, finite values, range) and the age of
  the inputs (:data:`MAX_INPUT_AGE_S`); bad input never raises: it is dropped and counted in
  :attr:`StiffnessFrontEnd.stats`;
* takes the speed from the wheel speeds (undriven axle) or from the measured velocity, the
  steering angle, and the measurement ``y`` of eq. (12);
* (re-)initializes the filter at the measured speed (first sample, after a gap of more than
  :data:`MAX_GAP_S`);
* decides the activation (Sec. V) over sliding windows: the stiffness is learned above
  :data:`MIN_LEARN_SPEED_M_S` with an RMS steering angle of at least
  :data:`ACTIVATION_STEER_RAD`; Cx also needs wheel speeds and a std of the measured ax of at
  least :data:`ACTIVATION_ACCEL_X_STD_M_S2`.

A filter's front-end subclass builds the filter (:meth:`StiffnessFrontEnd.make_filter`) and may
add to the steps through the hooks (``_on_initialize``, ``_start_learning``,
``_on_learning_stopped``, ``_after_step``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Generic, NamedTuple, TypeAlias, TypeVar

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.input_checks import drop_key, finite_vector, stamp_after
from tire_estimation.core.stiffness.filter import (
    BaselineConfig,
    FilterEstimate,
    Measurement,
    StiffnessFilter,
)
from tire_estimation.core.stiffness.model import SingleTrackParams
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

F = TypeVar("F", bound=StiffnessFilter)
#: the settings the front-end reads (Algorithm 1's extend them)
FrontEndConfig: TypeAlias = BaselineConfig

#: Sec. V activation: below this speed nothing is learned (the slip angles are small against
#: their noise), m/s; the filter starts at half of it.
MIN_LEARN_SPEED_M_S = 5.0
#: Length of the sliding (box) window of the RMS steering angle, s: learning stops at most one
#: window after the excitation ends.
ACTIVATION_WINDOW_S = 1.0
#: Sec. V lateral excitation: minimum RMS road-wheel angle over the window to learn, rad
#: (0.17 deg, above the steering sensor's offset and noise).
ACTIVATION_STEER_RAD = 0.003
#: Length of the sliding window of the longitudinal excitation measure, s.
ACTIVATION_ACCEL_X_WINDOW_S = 3.0
#: Sec. II-B: minimum std of the measured ax over its window to learn Cx (the wheel slip must
#: vary, else Cx is confounded with the accelerometer bias and the resistances), m/s^2.
ACTIVATION_ACCEL_X_STD_M_S2 = 0.2
#: A larger gap between IMU samples re-initializes the filter, s (five 10-Hz samples).
MAX_GAP_S = 0.5
#: Wheel speed / steering / velocity older than this are stale, s.
MAX_INPUT_AGE_S = 0.2
#: Initial std of vX around the measured speed (wheel-speed scale error), m/s.
INITIAL_VX_STD_M_S = 0.3
#: Initial std of the yaw rate around the gyro (its bias prior, 1 deg/s), rad/s.
INITIAL_YAW_RATE_STD_RAD_S = 0.0175

#: input streams and the range of their values (|value| above it is dropped as out of range)
_LIMITS = {"wheel": 1000.0, "steering": 1.2, "velocity": 150.0}


@dataclass(frozen=True)
class StiffnessEstimate:
    """Stiffness and lateral-state estimate.

    Attributes:
        t_ns: stamp of the last IMU update, ns (0 before the first).
        names: ("cx_front", "cy_front", "cy_rear"), with ``cx_rear`` for ``cx_front`` on a
            rear-driven vehicle (the driven axle's Cx).
        stiffness: [Cx N/unit slip, Cy_f N/rad, Cy_r N/rad] axle values (eq. 7, 27a), (3,).
        stiffness_std: sqrt(diag) of eq. (27b), same units, (3,) (a filter other than
            Algorithm 1: the posterior std of its estimate).
        nominal: nominal stiffness C_n, (3,).
        active: learning active (excitation, Sec. V).
        cx_active: learning of Cx active (longitudinal excitation as well).
        reason: why learning is (in)active.
        gyro_bias_rad_s: (0, 0, b_r), (3,).
        accel_bias_m_s2: (b_ax, b_ay, 0), (3,).
        n_eff: effective sample size.
        vx_m_s: longitudinal speed at the CG, m/s.
        vy_m_s: lateral speed at the CG, m/s.
        yaw_rate_rad_s: yaw rate, rad/s.
        sideslip_rad: atan(vy / vx) at the CG, rad.
        covariance: covariance of [vx, vy, r], (3, 3).
        mean_log_predictive: mean over the IMU updates so far of log p(y_k | y_1:k-1), the
            filter's predictive density of each measurement, nats (0 before the first); higher
            = the configuration explains the measured data better (compare configurations on
            the same data, not across data sets). None where the filter does not report it.
    """

    t_ns: int
    names: tuple[str, str, str]
    stiffness: F64
    stiffness_std: F64
    nominal: F64
    active: bool
    cx_active: bool
    reason: str
    gyro_bias_rad_s: F64
    accel_bias_m_s2: F64
    n_eff: float
    vx_m_s: float
    vy_m_s: float
    yaw_rate_rad_s: float
    sideslip_rad: float
    covariance: F64
    mean_log_predictive: float | None = None


class TraceRow(NamedTuple):
    """The part of a :class:`StiffnessEstimate` a recorder keeps at every IMU sample."""

    vx_m_s: float
    vy_m_s: float
    yaw_rate_rad_s: float
    sideslip_rad: float
    stiffness: F64
    stiffness_std: F64
    active: bool
    #: yaw-rate (gyro z) bias, rad/s
    gyro_bias_rad_s: float
    mean_log_predictive: float | None


def sideslip(vx_m_s: float, vy_m_s: float) -> float:
    """Sideslip angle of the velocity (vx, vy), rad (vx floored at 1 mm/s)."""
    return math.atan2(vy_m_s, max(vx_m_s, 1e-3))


class SlidingWindow:
    """Mean and mean square of the samples of the last ``window_s`` seconds (box window).

    A sample stops counting ``window_s`` after its stamp, so the measures reach the level of
    the new samples at most one window after a change (an exponential mean of ``v^2`` needs
    ``ln(v_old^2 / v_new^2)`` time constants).
    """

    def __init__(self, window_s: float) -> None:
        self.window_ns = round(window_s * 1e9)
        self._samples: deque[tuple[int, float]] = deque()
        self._sum = 0.0
        self._sum2 = 0.0

    def reset(self) -> None:
        """Forget every sample."""
        self._samples.clear()
        self._sum = self._sum2 = 0.0

    def add(self, t_ns: int, value: float) -> None:
        """Add ``value`` at ``t_ns`` (non-decreasing stamps)."""
        self._samples.append((t_ns, value))
        self._sum += value
        self._sum2 += value * value
        while self._samples[0][0] <= t_ns - self.window_ns:
            old = self._samples.popleft()[1]
            self._sum -= old
            self._sum2 -= old * old
        if len(self._samples) == 1:
            self._sum, self._sum2 = value, value * value

    @property
    def rms(self) -> float:
        """Root mean square over the window (0 when empty)."""
        n = len(self._samples)
        return math.sqrt(max(self._sum2, 0.0) / n) if n else 0.0

    @property
    def std(self) -> float:
        """Standard deviation over the window (0 when empty)."""
        n = len(self._samples)
        if n == 0:
            return 0.0
        mean = self._sum / n
        return math.sqrt(max(self._sum2 / n - mean * mean, 0.0))


def single_track_params(config: FrontEndConfig, vehicle: VehicleParams) -> SingleTrackParams:
    """The single-track parameters of ``vehicle`` with the settings of ``config``."""
    return SingleTrackParams.from_vehicle(
        vehicle,
        rolling_resistance_n=config.rolling_resistance_n,
        drag_n_s2_m2=config.drag_n_s2_m2,
        friction_coefficient=config.friction_coefficient,
        cornering_stiffness_front_n_rad=config.cornering_stiffness_front_n_rad or None,
        cornering_stiffness_rear_n_rad=config.cornering_stiffness_rear_n_rad or None,
        tyre_shape=config.tyre_shape,
        magic_formula_shape_c=config.magic_formula_shape_c,
        magic_formula_curvature_e=config.magic_formula_curvature_e,
    )


#: the sample streams (:data:`~tire_estimation.core.samples.STREAMS`) of the inputs' own names
_STREAM_KIND = {"wheel": "wheel_speeds"}


def _drop_kind(exc: Exception) -> str:
    return exc.kind if isinstance(exc, InputError) else "bad_value"


class StiffnessFrontEnd(Generic[F]):
    """Sample-by-sample front-end of one stiffness filter (see the module doc).

    Args:
        config: a :class:`BaselineConfig` (Algorithm 1's ``StiffnessEstimatorConfig`` or another
            filter's).
        vehicle: geometry, nominal stiffness and drive.
        rng: random generator of every draw.

    Attributes:
        filter: the filter (:meth:`make_filter`).
        stats: dropped samples as ``<stream>:<kind>`` (kinds ``bad_stamp``, ``duplicate``,
            ``out_of_order``, ``wrong_length``, ``nan``, ``bad_value``, ``out_of_range``;
            ``imu:no_speed``, ``imu:gap``).
    """

    def __init__(
        self, config: FrontEndConfig, vehicle: VehicleParams, rng: np.random.Generator
    ) -> None:
        self.config = config
        self.vehicle = vehicle
        self.rng = rng
        self.params = single_track_params(config, vehicle)
        self.nominal = np.asarray(self.params.nominal, dtype=float)
        self.stats: dict[str, int] = {}
        self.reset()

    def make_filter(self) -> F:
        """A fresh filter (not initialized)."""
        raise NotImplementedError

    def reset(self) -> None:
        """Forget everything learned and all inputs."""
        self.filter: F = self.make_filter()
        self._last: dict[str, int | None] = {
            "imu": None,
            "wheel": None,
            "steering": None,
            "velocity": None,
        }
        self._wheel: list[float] | None = None
        self._steer = 0.0
        self._vx_meas: float | None = None
        self._steer_window = SlidingWindow(ACTIVATION_WINDOW_S)
        self._accel_x_window = SlidingWindow(ACTIVATION_ACCEL_X_WINDOW_S)
        self._active = False
        self._cx_active = False
        self._reason = "not initialized"
        self._t_ns = 0

    @property
    def initialized(self) -> bool:
        """The filter runs (a speed input arrived and the speed was high enough)."""
        return self.filter.initialized

    # ------------------------------------------------------------------ inputs
    def _drop(self, stream: str, kind: str) -> None:
        key = drop_key(_STREAM_KIND.get(stream, stream), kind)
        self.stats[key] = self.stats.get(key, 0) + 1

    def _check_stamp(self, stream: str, t_ns: Any) -> int:
        return stamp_after(stream, t_ns, self._last[stream])

    def _accept(self, stream: str, t_ns: Any, value: Any, n: int) -> list[float] | None:
        """The ``n`` values of an input sample as floats, or None (dropped and counted)."""
        try:
            t = self._check_stamp(stream, t_ns)
            v = finite_vector(value, n, stream).tolist()
            # (finite values: the largest magnitude of these few, without NumPy temporaries)
            if max(map(abs, v)) > _LIMITS[stream]:
                raise InputError("out_of_range", f"{stream}: |value| above {_LIMITS[stream]}")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(stream, _drop_kind(exc))
            return None
        self._last[stream] = t
        return v

    def _fresh(self, stream: str, t_ns: int) -> bool:
        last = self._last[stream]
        # an input stamped after the IMU sample is not fresh: its age would be negative
        return last is not None and 0 <= t_ns - last <= MAX_INPUT_AGE_S * 1e9

    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr), rad/s."""
        ws = self._accept("wheel", t_ns, wheel_speed_rad_s, 4)
        if ws is not None:
            self._wheel = ws

    def on_steering(self, t_ns: int, angle_rad: float) -> None:
        """Mean road-wheel steer angle delta, rad (positive left)."""
        a = self._accept("steering", t_ns, angle_rad, 1)
        if a is not None:
            self._steer = a[0]

    def on_velocity(self, t_ns: int, vx_m_s: float) -> None:
        """Measured longitudinal speed, m/s (used when there are no wheel speeds)."""
        v = self._accept("velocity", t_ns, vx_m_s, 1)
        if v is not None:
            self._vx_meas = v[0]

    def _measurement(self, t_ns: int, gyro: list[float], acc: list[float]) -> Measurement | None:
        """The filter's view of the IMU sample at ``t_ns`` with the latest fresh inputs (None
        without a fresh speed)."""
        have_wheel = self._wheel is not None and self._fresh("wheel", t_ns)
        have_vel = self._vx_meas is not None and self._fresh("velocity", t_ns)
        if have_wheel:
            assert self._wheel is not None
            r_w, w = self.params.wheel_radius_m, self._wheel
            wf = 0.5 * r_w * (w[0] + w[1])
            wr = 0.5 * r_w * (w[2] + w[3])
            speed = wr if self.params.drive == "front" else min(wf, wr)
        elif have_vel:
            assert self._vx_meas is not None
            wf = wr = speed = self._vx_meas
        else:
            return None
        return Measurement(
            # eq. (12) y = [ax, ay, r]
            y=np.array([acc[0], acc[1], gyro[2]]),
            delta_rad=self._steer if self._fresh("steering", t_ns) else 0.0,
            wheel_speed_m_s=(wf, wr),
            speed_m_s=speed,
            vx_measured=not have_wheel,
        )

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        """IMU sample in ``base_link`` axes; runs one filter step."""
        try:
            t = self._check_stamp("imu", t_ns)
            gyro = finite_vector(gyro_rad_s, 3, "gyro").tolist()
            acc = finite_vector(accel_m_s2, 3, "accel").tolist()
        except (InputError, TypeError, ValueError) as exc:
            self._drop("imu", _drop_kind(exc))
            return
        last = self._last["imu"]
        self._last["imu"] = t
        self._t_ns = t
        meas = self._measurement(t, gyro, acc)
        if meas is None:
            self._learning_off("no speed input")
            self._drop("imu", "no_speed")
            return
        dt = None if last is None else (t - last) * 1e-9
        if dt is not None and dt > MAX_GAP_S:
            self._drop("imu", "gap")
            self.filter.initialized = False
        if not self.filter.initialized:
            if meas.speed_m_s < 0.5 * MIN_LEARN_SPEED_M_S:
                self._learning_off("speed below minimum")
                return
            self._initialize(meas)
            dt = None
        self._activation(t, meas)
        if dt is not None:
            self.filter.predict(dt, self._active, self._cx_active)
        self.filter.update(meas, self._active, self._cx_active)
        self._after_step(t, dt, meas)

    # ------------------------------------------------------------------ filter steps
    def _learning_off(self, reason: str) -> None:
        self._reason = reason
        self._active = self._cx_active = False

    def _initialize(self, meas: Measurement) -> None:
        """(Re-)start the filter at the measured speed, no lateral speed and the measured yaw
        rate; forget the activation windows."""
        x0 = np.array([meas.speed_m_s, 0.0, float(meas.y[2])])
        std = np.array(
            [INITIAL_VX_STD_M_S, self.config.initial_vy_std_m_s, INITIAL_YAW_RATE_STD_RAD_S]
        )
        self.filter.initialize(x0, std)
        self._steer_window.reset()
        self._accel_x_window.reset()
        self._active = False
        self._on_initialize(x0, std)

    def _activation(self, t_ns: int, meas: Measurement) -> None:
        """Sec. V activation over sliding windows: the RMS road-wheel angle (lateral excitation)
        and, for Cx, the variation (std) of the measured longitudinal acceleration; starts or
        stops learning."""
        was_active = self._active
        self._steer_window.add(t_ns, meas.delta_rad)
        self._accel_x_window.add(t_ns, float(meas.y[0]))
        if meas.speed_m_s < MIN_LEARN_SPEED_M_S:
            self._active, self._reason = False, "speed below minimum"
        elif self._steer_window.rms < ACTIVATION_STEER_RAD:
            self._active, self._reason = False, "no lateral excitation"
        else:
            self._active, self._reason = True, "excited"
        # without wheel speeds the slip (eq. 3) is unknown: Cx is not observable, keep it frozen
        cx_excited = (
            not meas.vx_measured and self._accel_x_window.std >= ACTIVATION_ACCEL_X_STD_M_S2
        )
        self._cx_active = self._active and cx_excited
        if self._active and not self._cx_active:
            why = "no wheel speeds" if meas.vx_measured else "no longitudinal excitation"
            self._reason = f"excited (Cx frozen: {why})"
        if self._active and not was_active:
            self._start_learning(t_ns)
        elif not self._active:
            self._on_learning_stopped()

    # ------------------------------------------------------------------ hooks
    def _on_initialize(self, x0: F64, x0_std: F64) -> None:
        """The filter was (re-)initialized at ``x0`` with std ``x0_std``."""

    def _start_learning(self, t_ns: int) -> None:
        """Learning starts at ``t_ns`` (before this step's filter step)."""

    def _on_learning_stopped(self) -> None:
        """A step without learning (before this step's filter step)."""

    def _after_step(self, t_ns: int, dt_s: float | None, meas: Measurement) -> None:
        """The filter has run the step at ``t_ns`` (``dt_s`` None: the first after the
        initialization)."""

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> StiffnessEstimate:
        """Current estimate (see :class:`StiffnessEstimate`); biases zero where the filter does
        not estimate them."""
        return self._published(self.filter.estimate())

    def _published(
        self, e: FilterEstimate, mean_log_predictive: float | None = None
    ) -> StiffnessEstimate:
        vx, vy, r = np.asarray(e.state, dtype=float).tolist()
        bias = (0.0, 0.0, 0.0) if e.bias is None else np.asarray(e.bias, dtype=float).tolist()
        return StiffnessEstimate(
            t_ns=self._t_ns,
            names=self.params.names,
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
            sideslip_rad=sideslip(vx, vy),
            covariance=e.state_cov,
            mean_log_predictive=mean_log_predictive,
        )


__all__ = [
    "FrontEndConfig",
    "SlidingWindow",
    "StiffnessEstimate",
    "StiffnessFrontEnd",
    "TraceRow",
    "sideslip",
    "single_track_params",
]
