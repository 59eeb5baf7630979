"""Tyre-stiffness estimator front-end (Berntorp & Di Cairano, IEEE TCST 2018).

Feeds :class:`~tire_estimation.core.stiffness_mpf.StiffnessMpf` from asynchronous sensor
callbacks. The IMU drives the measurement update; the latest wheel speeds (or a measured
longitudinal speed), and steering angle are the inputs ``u``. Bad input never raises: it is
dropped and counted in :attr:`StiffnessEstimator.stats`.
"""

from __future__ import annotations

import copy
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tire_estimation.core import niw
from tire_estimation.core.activation_replay import ActivationReplay
from tire_estimation.core.stiffness_config import StiffnessEstimatorConfig
from tire_estimation.core.stiffness_model import NAMES, SingleTrackParams, roll_compensate
from tire_estimation.core.stiffness_mpf import StiffnessMpf
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import InputError

F64 = NDArray[np.float64]
STATE_DICT_VERSION = 1

#: one IMU step as the MPF ran it: dt_s (None on the first step), y, steering angle, axle
#: speeds (front, rear), measured vX (None with wheel speeds), Cx excitation (learn_cx when on)
_Step = tuple[float | None, F64, float, tuple[float, float], float | None, bool]


@dataclass(frozen=True)
class StiffnessEstimate:
    """Stiffness and lateral-state estimate.

    Attributes:
        t_ns: stamp of the last IMU update, ns (0 before the first).
        names: ("cx_front", "cy_front", "cy_rear"); ``cx_front`` is the driven axle's Cx.
        stiffness: [Cx N/unit slip, Cy_f N/rad, Cy_r N/rad] axle values (eq. 7, 27a), (3,).
        stiffness_std: sqrt(diag) of eq. (27b), same units, (3,).
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
            the same data, not across data sets).
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


def _is_int(x: Any) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


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


class StiffnessEstimator:
    """Front-end of Algorithm 1.

    Args:
        config: :class:`StiffnessEstimatorConfig`.
        vehicle: :class:`VehicleParams` (geometry, nominal stiffness, drive).
        rng: random generator of every draw.
    """

    def __init__(
        self,
        config: StiffnessEstimatorConfig,
        vehicle: VehicleParams,
        rng: np.random.Generator,
    ) -> None:
        self.config = config
        self.vehicle = vehicle
        self.rng = rng
        drive = vehicle.drive if config.drive == "vehicle" else config.drive
        self.params = SingleTrackParams.from_vehicle(
            vehicle,
            drive=drive,
            wheel_radius_m=config.wheel_radius_m or None,
            rolling_resistance_n=config.rolling_resistance_n,
            drag_n_s2_m2=config.drag_n_s2_m2,
            roll_gain=config.roll_gain,
            friction_coefficient=config.friction_coefficient,
            cornering_stiffness_front_n_rad=config.cornering_stiffness_front_n_rad or None,
            cornering_stiffness_rear_n_rad=config.cornering_stiffness_rear_n_rad or None,
            tyre_shape=config.tyre_shape,
            magic_formula_shape_c=config.magic_formula_shape_c,
            magic_formula_curvature_e=config.magic_formula_curvature_e,
        )
        self.mpf = StiffnessMpf(config, self.params, rng)
        self.stats: dict[str, int] = {}
        #: times learning started with a replay of the window before it
        self.replay_count = 0
        #: times the filter restarted from the start of learning with a recentred prior
        #: (``activation_restart_s``)
        self.restart_count = 0
        #: times the grid handed its posterior to Algorithm 1 (``first_learning`` = ``grid``)
        self.handover_count = 0
        #: times the grid was dropped by its NIS gate (mean NIS above ``grid_handover_max_nis``:
        #: its model does not fit the data, or no longer), before or after the hand-over
        self.grid_rejection_count = 0
        self.reset()

    def reset(self) -> None:
        """Forget everything learned and all inputs."""
        self.mpf = StiffnessMpf(self.config, self.params, self.rng)
        self._replay: ActivationReplay[StiffnessMpf, _Step] = ActivationReplay(
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
        # activation_restart_s: armed while the statistics are the prior's; the copy of the
        # filter taken when learning started, its stamp, and the learning steps since
        self._restart_armed = (
            self.config.activation_restart_s > 0.0 and self.config.first_learning == "mpf"
        )
        self._restart_copy: StiffnessMpf | None = None
        self._restart_t0_ns = 0
        self._restart_steps: list[_Step] = []
        # first_learning = grid: the point-mass filter that learns first (None once dropped)
        self._grid: Any = None
        self._handed_over = False
        if self.config.first_learning == "grid":
            # imported here: stiffness_grid builds on stiffness_baselines, which imports this
            from tire_estimation.core.stiffness_baselines import Measurement
            from tire_estimation.core.stiffness_grid import GridConfig, GridEkf

            self._grid = GridEkf(GridConfig.sharing(self.config), self.params)
            self._grid_measurement = Measurement

    # ------------------------------------------------------------------ helpers
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

    @staticmethod
    def _vector(value: Any, n: int, what: str) -> F64:
        v = np.asarray(value, dtype=float).reshape(-1)
        if v.shape != (n,):
            raise InputError("wrong_length", f"{what}: need {n} values, got {v.shape[0]}")
        if not np.all(np.isfinite(v)):
            raise InputError("nan", f"{what}: non-finite value")
        return v

    def _fresh(self, stream: str, t_ns: int) -> bool:
        last = self._last[stream]
        return last is not None and (t_ns - last) * 1e-9 <= self.config.max_input_age_s

    # ------------------------------------------------------------------ inputs
    def on_wheel_speeds(self, t_ns: int, wheel_speed_rad_s: Any) -> None:
        """Wheel speeds (fl, fr, rl, rr), rad/s."""
        try:
            t = self._check_stamp("wheel", t_ns)
            ws = self._vector(wheel_speed_rad_s, 4, "wheel speeds")
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
            a = float(self._vector(angle_rad, 1, "steering")[0])
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
            v = float(self._vector(vx_m_s, 1, "velocity")[0])
            if abs(v) > 150.0:
                raise InputError("out_of_range", f"speed {v} m/s")
        except (InputError, TypeError, ValueError) as exc:
            self._drop(exc.kind if isinstance(exc, InputError) else "bad_value")
            return
        self._last["velocity"] = t
        self._vx_meas = v

    def on_imu(self, t_ns: int, gyro_rad_s: Any, accel_m_s2: Any) -> None:
        """IMU sample in ``base_link`` axes; runs one step of Algorithm 1."""
        try:
            t = self._check_stamp("imu", t_ns)
            gyro = self._vector(gyro_rad_s, 3, "gyro")
            acc = self._vector(accel_m_s2, 3, "accel")
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
            self._active = False
            self._drop("no_speed")
            return
        r_w = self.params.wheel_radius_m
        if have_wheel:
            assert self._wheel is not None
            wf = float(0.5 * r_w * (self._wheel[0] + self._wheel[1]))
            wr = float(0.5 * r_w * (self._wheel[2] + self._wheel[3]))
            vx_in = None
            speed = wr if self.params.drive == "front" else min(wf, wr)
        else:
            assert self._vx_meas is not None
            wf = wr = self._vx_meas
            vx_in = self._vx_meas
            speed = self._vx_meas
        steer = self._steer if self._fresh("steering", t) else 0.0
        y = np.array([acc[0], roll_compensate(float(acc[1]), self.params.roll_gain), gyro[2]])
        c = self.config
        dt = None if last is None else (t - last) * 1e-9
        if dt is not None and dt > c.max_gap_s:
            self._drop("gap")
            self.mpf.initialized = False
        if not self.mpf.initialized:
            if speed < 0.5 * c.min_speed_m_s:
                self._reason = "speed below minimum"
                self._active = self._cx_active = False
                return
            x0 = np.array([speed, 0.0, float(gyro[2])])
            std = np.array(
                [c.initial_vx_std_m_s, c.initial_vy_std_m_s, c.initial_yaw_rate_std_rad_s]
            )
            self.mpf.initialize(x0, std)
            if self._grid is not None and self._handed_over:
                # Algorithm 1 keeps its learned statistics: a grid from the prior must not be
                # published over them
                self._grid = None
            elif self._grid is not None:
                self._grid.initialize(x0, std)
            self._steer_window.reset()
            self._accel_x_window.reset()
            self._replay.clear()
            # a restart must not bring back the state from before the re-initialization
            self._abandon_restart()
            self._active = False
            dt = None
        was_active = self._active
        # Sec. V activation over sliding windows: RMS road-wheel angle (lateral excitation)
        # and, for Cx, the variation (std) of the measured longitudinal acceleration
        self._steer_window.add(t, steer)
        self._accel_x_window.add(t, float(acc[0]))
        if speed < c.min_speed_m_s:
            self._active, self._reason = False, "speed below minimum"
        elif self._steer_window.rms < c.activation_steer_rad:
            self._active, self._reason = False, "no lateral excitation"
        else:
            self._active, self._reason = True, "excited"
        # without wheel speeds the slip (eq. 3) is unknown: Cx is not observable, keep it frozen
        cx_excited = vx_in is None and self._accel_x_window.std >= c.activation_accel_x_std_m_s2
        self._cx_active = self._active and cx_excited
        if self._active and not self._cx_active:
            why = "no wheel speeds" if vx_in is not None else "no longitudinal excitation"
            self._reason = f"excited (Cx frozen: {why})"
        if self._active and not was_active:
            self._start_learning(t)
        elif not self._active:
            # learning stopped before the restart: the statistics are no longer the prior's
            self._abandon_restart()
        if dt is not None:
            self.mpf.predict(dt, self._active, self._cx_active)
        self.mpf.update(y, steer, (wf, wr), self._active, vx_in, self._cx_active)
        if self._grid is not None:
            self._grid_step(dt, y, steer, (wf, wr), speed, vx_in is not None)
        if self._restart_copy is not None:
            self._restart_steps.append((dt, y, steer, (wf, wr), vx_in, self._cx_active))
            if (t - self._restart_t0_ns) * 1e-9 >= c.activation_restart_s:
                self._restart()
        if speed < c.min_speed_m_s:
            # nothing below the minimum speed is ever learned, not even in a replay
            self._replay.clear()
        elif not self._active:
            self._replay.record(t, (dt, y, steer, (wf, wr), vx_in, cx_excited), self.mpf)

    def _grid_step(
        self,
        dt: float | None,
        y: F64,
        steer: float,
        speeds: tuple[float, float],
        speed: float,
        vx_measured: bool,
    ) -> None:
        """``first_learning`` = ``grid``: one step of the grid with the MPF's inputs and learning
        flags. Once it has learned ``grid_handover_s``: dropped whenever its mean NIS is above
        ``grid_handover_max_nis``; else the hand-over, and the grid goes on (published) until it
        has learned ``grid_publish_s``."""
        grid = self._grid
        if dt is not None:
            grid.predict(dt, self._active, self._cx_active)
        meas = self._grid_measurement(y, steer, speeds, speed, vx_measured)
        grid.update(meas, self._active, self._cx_active)
        c = self.config
        if grid.learned_s < c.grid_handover_s:
            return
        if grid.nis_mean > c.grid_handover_max_nis:
            # the grid's model does not fit these data (or no longer: the stiffness changed):
            # no hand-over, or no more publishing; Algorithm 1 goes on
            self._grid = None
            self.grid_rejection_count += 1
        elif not self._handed_over:
            self._hand_over()
        elif grid.learned_s >= c.grid_publish_s:
            self._grid = None

    def _hand_over(self) -> None:
        """The grid's posterior of ``(Cy_f, Cy_r)`` becomes Algorithm 1's NiW statistics
        (:func:`niw.stats_from_moments`, as a restored state): the grid's mean, and ``gamma`` such
        that ``gamma E[Sigma]`` has the trace of the grid's covariance over the two cornering
        stiffnesses (the NiW shares one ``gamma``: Cx's prior uncertainty must not set it); Cx,
        the expected noise covariance and the dof as the MPF has them."""
        from tire_estimation.core.stiffness_grid import posterior

        m, cov = posterior(self._grid)
        est = niw.mmse(self.mpf.stats, self.mpf.weights)
        mean = est.mean.copy()
        mean[1:] = m
        gamma = np.trace(cov) / max(float(np.trace(est.noise_cov[1:, 1:])), 1e-300)
        self.mpf.stats = niw.stats_from_moments(
            self.mpf.n, mean, gamma * est.noise_cov, est.noise_cov, est.dof
        )
        self._handed_over = True
        if self._grid.learned_s >= self.config.grid_publish_s:
            self._grid = None
        self.handover_count += 1

    def _start_learning(self, t_ns: int) -> None:
        """Learning starts at ``t_ns``: rewind (``activation_replay_s``), keep the copy for a
        restart (``activation_restart_s``), run the rewound steps with learning on."""
        steps = self._replay_window()
        if self._restart_armed:
            memo = {id(obj): obj for obj in (self.rng, self.config, self.params)}
            self._restart_copy = copy.deepcopy(self.mpf, memo)
            self._restart_t0_ns = t_ns
            self._restart_steps = list(steps)
        self._learn_steps(steps)

    def _replay_window(self) -> list[_Step]:
        """Learning starts: rewind the MPF to before the first step of the last
        ``activation_replay_s`` with a steering angle of at least ``activation_steer_rad``
        (:mod:`~.activation_replay`); returns the steps since, to be run again with learning on
        (none without a rewind)."""
        threshold = self.config.activation_steer_rad
        got = self._replay.rewind(excited=lambda step: abs(step[2]) >= threshold)
        if got is None:
            return []
        self.mpf, steps = got
        self.replay_count += 1
        return steps

    def _learn_steps(self, steps: list[_Step]) -> None:
        """Run recorded IMU steps on the MPF with learning on."""
        for dt_s, y, steer, speeds, vx_in, cx_excited in steps:
            if dt_s is not None:
                self.mpf.predict(dt_s, True, cx_excited)
            self.mpf.update(y, steer, speeds, True, vx_in, cx_excited)

    def _abandon_restart(self) -> None:
        """No restart of this learning phase (learning stopped, or the filter re-initialized
        before ``activation_restart_s``); none later either, once anything was learned."""
        if self._restart_copy is not None:
            self._restart_armed = False
        self._restart_copy = None
        self._restart_steps = []

    def _restart(self) -> None:
        """``activation_restart_s`` after learning started: go back to the copy taken then,
        move its prior mean to the current estimate and learn the steps since again.

        Empirical Bayes (not in the paper): the prior keeps its width (``gamma_0 E[Sigma]``,
        ``initial_stiffness_std_fraction`` of nominal), only its centre moves from the initial
        guess to what the first seconds of excitation say, so the estimate no longer carries
        the initial guess once the filter's statistics have narrowed.
        """
        restart, steps = self._restart_copy, self._restart_steps
        assert restart is not None
        # eq. (27a) mu_hat = sum q_i mu_i: the new centre of every particle's prior mean
        restart.stats.mean[...] = self.mpf.weights @ self.mpf.stats.mean
        self.mpf = restart
        self._restart_copy, self._restart_steps = None, []
        self._restart_armed = False
        self._learn_steps(steps)
        self.restart_count += 1

    # ------------------------------------------------------------------ outputs
    def estimate(self) -> StiffnessEstimate:
        """Current estimate (see :class:`StiffnessEstimate`)."""
        e = self.mpf.estimate()
        vx, vy, r = (float(v) for v in e.state)
        stiffness, stiffness_std = e.stiffness, e.stiffness_std
        if self._grid is not None and self._grid.learned_s > 0.0:
            # first_learning = grid: the grid's cornering stiffness until the hand-over, or until
            # grid_publish_s
            g = self._grid.estimate()
            stiffness = np.concatenate([e.stiffness[:1], g.stiffness[1:]])
            stiffness_std = np.concatenate([e.stiffness_std[:1], g.stiffness_std[1:]])
        return StiffnessEstimate(
            t_ns=self._t_ns,
            names=NAMES,
            stiffness=stiffness,
            stiffness_std=stiffness_std,
            nominal=self.mpf.nominal.copy(),
            active=self._active,
            cx_active=self._cx_active,
            reason=self._reason,
            gyro_bias_rad_s=np.array([0.0, 0.0, e.bias[2]]),
            accel_bias_m_s2=np.array([e.bias[0], e.bias[1], 0.0]),
            n_eff=e.n_eff,
            vx_m_s=vx,
            vy_m_s=vy,
            yaw_rate_rad_s=r,
            sideslip_rad=math.atan2(vy, max(vx, 1e-3)),
            covariance=e.state_cov,
            mean_log_predictive=self.mpf.log_evidence / max(self.mpf.evidence_steps, 1),
        )

    def state_dict(self) -> dict[str, Any]:
        """Learned stiffness statistics (JSON-serializable)."""
        est = niw.mmse(self.mpf.stats, self.mpf.weights)
        return {
            "version": STATE_DICT_VERSION,
            "vehicle": self.vehicle.name,
            "names": list(NAMES),
            "nominal": self.mpf.nominal.tolist(),
            "mean": est.mean.tolist(),
            "mean_cov": est.mean_cov.tolist(),
            "noise_cov": est.noise_cov.tolist(),
            "dof": float(est.dof),
        }

    def load_state_dict(self, d: Mapping[str, Any]) -> None:
        """Restore :meth:`state_dict` output; raises InputError (kind ``state``) if invalid."""
        try:
            if d.get("vehicle") != self.vehicle.name:
                raise InputError("state", f"state of vehicle {d.get('vehicle')!r}")
            # the learned part is relative to the nominal stiffness (eq. 7): a state learned
            # with other nominal values would be restored as the wrong stiffness
            nominal = np.asarray(d["nominal"], dtype=float).reshape(3)
            if not np.allclose(nominal, self.mpf.nominal, rtol=1e-6, atol=0.0):
                raise InputError(
                    "state",
                    f"state learned with nominal stiffness {nominal.tolist()}, now "
                    f"{self.mpf.nominal.tolist()}",
                )
            dof = float(d["dof"])
            if not math.isfinite(dof) or dof <= 4.0:
                raise InputError("state", f"invalid dof {dof}")
            stats = niw.stats_from_moments(
                self.mpf.n,
                np.asarray(d["mean"], dtype=float).reshape(3),
                np.asarray(d["mean_cov"], dtype=float).reshape(3, 3),
                np.asarray(d["noise_cov"], dtype=float).reshape(3, 3),
                dof,
            )
            if not all(np.all(np.isfinite(a)) for a in (stats.mean, stats.scale, stats.gamma)):
                raise InputError("state", "non-finite statistics")
        except InputError:
            raise
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InputError("state", f"malformed stiffness state: {exc}") from exc
        self.mpf.stats = stats
        # a copy taken before would bring the old statistics back on the next activation
        self._replay.clear()
        # restored statistics are learned, not a prior to recentre or to learn on a grid
        self._restart_copy, self._restart_steps = None, []
        self._restart_armed = False
        self._grid = None


__all__ = ["StiffnessEstimate", "StiffnessEstimator"]
