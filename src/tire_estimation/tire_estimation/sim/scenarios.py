"""Scenarios: what the driver is asked to do and how the tyres and road change over time.

A scenario turns (options, duration, random generator) into a :class:`Plan` sampled on the
integration grid: a speed reference, either a path curvature or a direct steering command, the
tyre pressures, stiffness factors and road friction, and the events to record.

Highway-type drives are built from piecewise-linear knots of speed and *lateral acceleration*
(curvature = a_lat / v^2), which keeps the lateral acceleration realistic whatever the speed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tire_estimation.core.arrays import F64
from tire_estimation.core.validation import known_names
from tire_estimation.core.wheels import WHEEL_INDEX, WHEELS
from tire_estimation.errors import ScenarioError
from tire_estimation.sim.streams import SimEvent

KMH = 1.0 / 3.6

#: One-line description of every scenario (printed by the command line).
SCENARIOS: dict[str, str] = {
    "ece_r64": "ECE R-64 drive: >=20 min calibration at 40-120 km/h on mixed roads with curves, "
    "then a 20 % pressure step on one wheel (deflate_wheel, deflation_fraction) and >=10 min",
    "robustness": "long mixed-road drive at 40-120 km/h without any deflation (false alarms)",
    "diffusion": "mixed-road drive with slow pressure loss on up to four wheels "
    "(wheels, rate_kpa_per_min, start_min)",
    "city": "low-speed city driving with junction turns, stops and roundabouts",
    "slow": "car-park / yard driving at 1-8 m/s: tight turns (5-12 m radius), creeping, stops",
    "stiffness_step": "Berntorp & Di Cairano 2018 sim study: square-wave steering and wheel "
    "torque at 22 m/s, tyre stiffness drops by 50 % at 30 s",
    "snow_sine": "snow (low mu, low stiffness): straight line then sine steering",
    "asphalt_sine": "dry asphalt: straight line then sine steering",
    "lane_change": "Tuononen 2009: aggressive sequential double lane changes at 60 km/h on dry "
    "tarmac, into the nonlinear tyre range",
}

#: Options every scenario accepts, with defaults.
COMMON_OPTIONS: dict[str, Any] = {
    "nominal_pressure_kpa": 230.0,
    "pressure_sensitivity_mm_per_kpa": 0.03,
    "radius_offset_std_mm": 0.3,
    "origin_lat_deg": 58.4,
    "origin_lon_deg": 15.6,
    "origin_alt_m": 100.0,
}


@dataclass
class Plan:
    """A scenario sampled on the integration grid ``t = k * dt_s`` (k = 0 .. n-1)."""

    dt_s: float
    n_steps: int
    speed_ref_m_s: F64
    accel_ref_m_s2: F64
    curvature_ref_1_m: F64 | None
    steer_cmd_rad: F64 | None
    pressure_kpa: F64  # (n, 4)
    stiffness_factor: F64  # (n, 3): [cx (both axles), cy_front, cy_rear]
    mu: F64  # (n,)
    extra_drive_force_n: F64 | None = None  # added to the driven wheels ("torque mode")
    speed_gain_1_s: float = 0.5
    steer_lag_s: float = 0.15
    initial_speed_m_s: float = 0.0
    initial_lateral_velocity_m_s: float = 0.0
    initial_yaw_rate_rad_s: float = 0.0
    initial_yaw_rad: float = 0.0
    events: list[SimEvent] = field(default_factory=list)
    options: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class _ScenarioDef:
    default_minutes: float
    options: Mapping[str, Any]
    build: Callable[[dict[str, Any], float, np.random.Generator, float], Plan]


# ---------------------------------------------------------------------------------------------
# helpers


def _grid(duration_s: float, dt_s: float) -> tuple[int, F64]:
    n = round(duration_s / dt_s) + 1
    return n, np.arange(n, dtype=np.float64) * dt_s


def _smooth(x: F64, window_n: int) -> F64:
    """Centred moving average with edge padding (keeps ramps, removes corners)."""
    if window_n <= 1:
        return x
    pad = window_n // 2
    xp = np.concatenate([np.full(pad, x[0]), x, np.full(window_n - 1 - pad, x[-1])])
    c = np.concatenate([[0.0], np.cumsum(xp)])
    return (c[window_n:] - c[:-window_n]) / window_n


def _base_plan(
    t: F64,
    dt_s: float,
    speed_ref: F64,
    opts: Mapping[str, Any],
) -> Plan:
    n = t.size
    p0 = float(opts["nominal_pressure_kpa"])
    return Plan(
        dt_s=dt_s,
        n_steps=n,
        speed_ref_m_s=speed_ref,
        accel_ref_m_s2=np.gradient(speed_ref, dt_s) if n > 1 else np.zeros(n),
        curvature_ref_1_m=None,
        steer_cmd_rad=None,
        pressure_kpa=np.full((n, 4), p0),
        stiffness_factor=np.ones((n, 3)),
        mu=np.ones(n),
    )


def _lateral_noise(rng: np.random.Generator, t: F64, std_m_s2: float, tau_s: float) -> F64:
    """Lane-keeping lateral acceleration: first-order Gauss-Markov, sampled at 10 Hz, linear
    interpolation onto ``t``."""
    step = 0.1
    m = int(t[-1] / step) + 2
    phi = math.exp(-step / tau_s)
    # x_{k+1} = phi x_k + sqrt(1 - phi^2) sigma w_k (stationary first-order Gauss-Markov)
    w = rng.standard_normal(m) * std_m_s2 * math.sqrt(1.0 - phi * phi)
    x = np.empty(m)
    x[0] = rng.standard_normal() * std_m_s2
    for k in range(1, m):
        x[k] = phi * x[k - 1] + w[k]
    return np.interp(t, np.arange(m) * step, x)


def _curvature_from_lateral(a_lat: F64, speed: F64, max_curvature_1_m: float = 0.2) -> F64:
    # path curvature kappa = a_lat / v^2 (speed floored to avoid the singularity at rest)
    kappa = a_lat / np.maximum(speed, 3.0) ** 2
    return np.clip(kappa, -max_curvature_1_m, max_curvature_1_m)


def _highway_profile(
    rng: np.random.Generator, duration_s: float, t: F64, dt_s: float
) -> tuple[F64, F64, float]:
    """Speed reference and path curvature of a mixed rural/motorway drive within 40-120 km/h.

    Returns (speed_ref, curvature, initial speed).
    """
    v0 = float(rng.uniform(70.0, 90.0)) * KMH
    sections: list[tuple[float, float, str]] = []
    ts = 0.0
    kind = "rural" if rng.random() < 0.5 else "motorway"
    while ts < duration_s:
        te = ts + float(rng.uniform(180.0, 360.0))
        sections.append((ts, te, kind))
        kind = "motorway" if kind == "rural" else "rural"
        ts = te
    # speed knots
    vt, vv = [0.0, 5.0], [v0, v0]
    v = v0
    for s0, s1, kind in sections:
        lo, hi = (55.0, 90.0) if kind == "rural" else (90.0, 118.0)
        tk = max(vt[-1], s0)
        while tk < s1:
            v_new = float(rng.uniform(lo, hi)) * KMH
            acc = float(rng.uniform(0.3, 1.0))
            tk += abs(v_new - v) / acc
            vt.append(tk)
            vv.append(v_new)
            tk += float(rng.uniform(20.0, 90.0))
            vt.append(tk)
            vv.append(v_new)
            v = v_new
    # lateral-acceleration knots: curves, and lane changes on motorways
    at, av = [0.0], [0.0]
    for s0, s1, kind in sections:
        tk = max(at[-1], s0) + float(rng.uniform(5.0, 20.0))
        while tk < s1:
            if kind == "motorway" and rng.random() < 0.3:
                a = float(rng.uniform(0.6, 1.2)) * float(rng.choice([-1.0, 1.0]))
                for dt_k, a_k in ((0.0, 0.0), (1.2, a), (2.4, 0.0), (3.6, -a), (4.8, 0.0)):
                    at.append(tk + dt_k)
                    av.append(a_k)
                tk += 4.8
            else:
                a_max = 2.5 if kind == "rural" else 1.5
                a = float(rng.uniform(0.4, a_max)) * float(rng.choice([-1.0, 1.0]))
                ramp = float(rng.uniform(2.0, 4.0))
                hold = float(rng.uniform(4.0, 25.0))
                for dt_k, a_k in ((0.0, 0.0), (ramp, a), (ramp + hold, a), (2 * ramp + hold, 0.0)):
                    at.append(tk + dt_k)
                    av.append(a_k)
                tk += 2 * ramp + hold
            gap = (5.0, 40.0) if kind == "rural" else (15.0, 90.0)
            tk += float(rng.uniform(*gap))
    speed = _smooth(np.interp(t, vt, vv), int(2.0 / dt_s))
    a_lat = _smooth(np.interp(t, at, av), int(1.0 / dt_s)) + _lateral_noise(rng, t, 0.1, 2.0)
    return speed, _curvature_from_lateral(a_lat, speed), v0


@dataclass
class _SpeedKnots:
    """Knots ``(t, v)`` of a piecewise-linear speed reference, appended piece by piece from
    the time ``t_s`` and the speed ``speed_m_s`` reached so far."""

    t: list[float]
    v: list[float]
    t_s: float
    speed_m_s: float = 0.0
    #: shortest speed change, s
    min_change_s: float = 0.0

    def knot(self) -> None:
        """A knot at the current time and speed."""
        self.t.append(self.t_s)
        self.v.append(self.speed_m_s)

    def go(self, v_new: float, acc: float) -> None:
        """Change the speed to ``v_new`` at ``acc`` (m/s^2)."""
        self.t_s += max(abs(v_new - self.speed_m_s) / acc, self.min_change_s)
        self.speed_m_s = v_new
        self.knot()

    def hold(self, seconds: float) -> None:
        """Keep the speed for ``seconds``."""
        self.t_s += seconds
        self.knot()


def _city_profile(
    rng: np.random.Generator, duration_s: float, t: F64, dt_s: float
) -> tuple[F64, F64]:
    """Speed reference and curvature of city driving: stops, junction turns, roundabouts."""
    ref = _SpeedKnots([0.0], [0.0], 2.0)
    ref.knot()
    go, hold = ref.go, ref.hold
    at, av = [0.0], [0.0]

    def lateral(pattern: Sequence[tuple[float, float]]) -> None:
        # pattern: (duration, a_lat at the end of the piece); speed held meanwhile
        at.append(ref.t_s)
        av.append(0.0)
        for d, a in pattern:
            ref.t_s += d
            at.append(ref.t_s)
            av.append(a)
        ref.knot()

    while ref.t_s < duration_s:
        kind = rng.choice(["cruise", "stop", "turn", "roundabout"], p=[0.35, 0.25, 0.25, 0.15])
        if kind == "cruise":
            go(float(rng.uniform(30.0, 50.0)) * KMH, float(rng.uniform(0.8, 1.6)))
            hold(float(rng.uniform(5.0, 25.0)))
        elif kind == "stop":
            go(0.0, float(rng.uniform(1.0, 2.0)))
            hold(float(rng.uniform(3.0, 15.0)))
            go(float(rng.uniform(30.0, 45.0)) * KMH, float(rng.uniform(1.0, 1.8)))
        elif kind == "turn":
            go(float(rng.uniform(14.0, 20.0)) * KMH, 1.5)
            a = float(rng.uniform(1.5, 2.5)) * float(rng.choice([-1.0, 1.0]))
            # heading change = integral(a / v dt) = pi/2 over the hold plus half the ramps
            hold_s = max(0.5, math.pi / 2 * ref.speed_m_s / abs(a) - 1.0)
            lateral([(1.0, a), (hold_s, a), (1.0, 0.0)])
            go(float(rng.uniform(30.0, 45.0)) * KMH, 1.3)
        else:
            go(float(rng.uniform(20.0, 25.0)) * KMH, 1.5)
            a = float(rng.uniform(1.5, 2.2))
            angle = float(rng.uniform(0.5, 1.5)) * math.pi  # around the central island
            hold_s = max(0.5, angle * ref.speed_m_s / a - 1.0)
            lateral([(0.8, -1.0), (0.8, 0.0), (1.0, a), (hold_s, a), (1.0, 0.0), (0.8, -1.0)])
            lateral([(0.8, 0.0)])
            go(float(rng.uniform(30.0, 45.0)) * KMH, 1.3)
    speed = np.maximum(_smooth(np.interp(t, ref.t, ref.v), int(1.5 / dt_s)), 0.0)
    a_lat = _smooth(np.interp(t, at, av), int(1.0 / dt_s))
    a_lat = a_lat + _lateral_noise(rng, t, 0.1, 1.5) * np.minimum(speed / 5.0, 1.0)
    return speed, _curvature_from_lateral(a_lat, speed)


def _slow_profile(
    rng: np.random.Generator, duration_s: float, t: F64, dt_s: float
) -> tuple[F64, F64]:
    """Speed reference and path curvature of slow manoeuvring (car park, yard, robot): straight
    runs at 3-8 m/s, creeping at 1-2.5 m/s, tight turns of 5-12 m radius at 2-4 m/s through a
    quarter to a half circle, stops. The curvature is set directly (not from a lateral
    acceleration), so it holds at any speed."""
    ref = _SpeedKnots([0.0, 1.0], [0.0, 0.0], 1.0, min_change_s=0.5)
    go, hold = ref.go, ref.hold
    kt, kv = [0.0], [0.0]

    go(float(rng.uniform(3.0, 6.0)), 0.8)
    while ref.t_s < duration_s:
        kind = rng.choice(["straight", "creep", "turn", "stop"], p=[0.3, 0.15, 0.4, 0.15])
        if kind == "straight":
            go(float(rng.uniform(3.0, 8.0)), float(rng.uniform(0.5, 1.0)))
            hold(float(rng.uniform(4.0, 15.0)))
        elif kind == "creep":
            go(float(rng.uniform(1.0, 2.5)), 0.6)
            hold(float(rng.uniform(4.0, 12.0)))
        elif kind == "turn":
            go(float(rng.uniform(2.0, 4.0)), 0.8)
            radius = float(rng.uniform(5.0, 12.0))
            kappa = float(rng.choice([-1.0, 1.0])) / radius
            angle = float(rng.uniform(0.5, 1.0)) * math.pi
            # heading change = v * integral(kappa dt): the hold plus half of the two 1-s ramps
            hold_s = max(0.5, angle * radius / ref.speed_m_s - 1.0)
            kt.extend([ref.t_s, ref.t_s + 1.0, ref.t_s + 1.0 + hold_s, ref.t_s + 2.0 + hold_s])
            kv.extend([0.0, kappa, kappa, 0.0])
            hold(2.0 + hold_s)
        else:
            go(0.0, float(rng.uniform(0.8, 1.5)))
            hold(float(rng.uniform(2.0, 8.0)))
            go(float(rng.uniform(2.0, 5.0)), 0.8)
    speed = np.maximum(_smooth(np.interp(t, ref.t, ref.v), int(1.0 / dt_s)), 0.0)
    kappa_ref = _smooth(np.interp(t, kt, kv), int(0.5 / dt_s))
    return speed, kappa_ref


def _wheels_option(value: Any) -> tuple[str, ...]:
    if isinstance(value, str):
        items = [w.strip() for w in value.split(",") if w.strip()]
        if value.strip() == "all":
            items = list(WHEELS)
    elif isinstance(value, Sequence):
        items = [str(w) for w in value]
    else:
        raise ScenarioError(f"option wheels={value!r}: must be wheel names or 'all'")
    if not items or len(items) > 4 or any(w not in WHEELS for w in items):
        raise ScenarioError(f"option wheels={value!r}: must be 1-4 of {WHEELS} (or 'all')")
    return tuple(dict.fromkeys(items))


# ---------------------------------------------------------------------------------------------
# scenario builders


def _highway_plan(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    _, t = _grid(duration_s, dt_s)
    speed, kappa, _ = _highway_profile(rng, duration_s, t, dt_s)
    plan = _base_plan(t, dt_s, speed, opts)
    plan.curvature_ref_1_m = kappa
    plan.initial_speed_m_s = float(speed[0])
    plan.initial_yaw_rad = float(rng.uniform(-math.pi, math.pi))
    return plan


def _build_ece_r64(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    plan = _highway_plan(opts, duration_s, rng, dt_s)
    wheel = str(opts["deflate_wheel"])
    if wheel not in WHEEL_INDEX:
        raise ScenarioError(f"option deflate_wheel={wheel!r}: must be one of {WHEELS}")
    frac = _number(opts, "deflation_fraction", 0.0, 0.9)
    t_def_min = opts["deflation_time_min"]
    # default: >= 20 min of calibration for the default 35 min drive, 63 % of shorter drives
    t_def_s = min(22.0 * 60.0, 0.63 * duration_s) if t_def_min is None else 60.0 * float(t_def_min)
    if not 0.0 <= t_def_s <= duration_s:
        raise ScenarioError(f"option deflation_time_min={t_def_min!r}: must be within the drive")
    k = round(t_def_s / dt_s)
    i = WHEEL_INDEX[wheel]
    p_before = float(plan.pressure_kpa[k, i])
    p_after = p_before * (1.0 - frac)  # ECE R-64: 20 % below the pressure at deflation time
    plan.pressure_kpa[k:, i] = p_after
    plan.events.append(
        SimEvent(
            t_s=k * dt_s,
            kind="pressure_step",
            detail={
                "wheel": wheel,
                "from_pa": p_before * 1e3,
                "to_pa": p_after * 1e3,
                "fraction": frac,
            },
        )
    )
    return plan


def _build_robustness(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    return _highway_plan(opts, duration_s, rng, dt_s)


def _build_diffusion(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    plan = _highway_plan(opts, duration_s, rng, dt_s)
    wheels = _wheels_option(opts["wheels"])
    rate = _number(opts, "rate_kpa_per_min", 0.0, 100.0)
    start_s = 60.0 * _number(opts, "start_min", 0.0, 1e4)
    t = np.arange(plan.n_steps) * dt_s
    # p(t) = p0 - rate * (t - t_start) for t > t_start (diffusion through the rubber), floored
    loss = np.maximum(t - start_s, 0.0) / 60.0 * rate
    for w in wheels:
        i = WHEEL_INDEX[w]
        plan.pressure_kpa[:, i] = np.maximum(
            plan.pressure_kpa[:, i] - loss, 0.3 * plan.pressure_kpa[0, i]
        )
    if start_s <= duration_s:
        plan.events.append(
            SimEvent(
                t_s=start_s,
                kind="diffusion_start",
                detail={"wheels": list(wheels), "rate_kpa_per_min": rate},
            )
        )
    return plan


def _from_standstill(
    profile: Callable[[np.random.Generator, float, F64, float], tuple[F64, F64]],
) -> Callable[[dict[str, Any], float, np.random.Generator, float], Plan]:
    """A scenario builder that follows ``profile``'s speed and path curvature from standstill,
    with a random initial heading."""

    def build(
        opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
    ) -> Plan:
        _, t = _grid(duration_s, dt_s)
        speed, kappa = profile(rng, duration_s, t, dt_s)
        plan = _base_plan(t, dt_s, speed, opts)
        plan.curvature_ref_1_m = kappa
        plan.initial_speed_m_s = 0.0
        plan.initial_yaw_rad = float(rng.uniform(-math.pi, math.pi))
        plan.steer_lag_s = 0.1
        return plan

    return build


_build_city = _from_standstill(_city_profile)
_build_slow = _from_standstill(_slow_profile)


def _square(t: F64, period_s: float) -> F64:
    return np.where((t % period_s) < 0.5 * period_s, 1.0, -1.0)


def _constant_speed_plan(
    duration_s: float, dt_s: float, speed_m_s: float, opts: Mapping[str, Any]
) -> tuple[F64, Plan]:
    """Time grid and base plan of a drive at the constant reference speed ``speed_m_s``."""
    n, t = _grid(duration_s, dt_s)
    return t, _base_plan(t, dt_s, np.full(n, speed_m_s), opts)


def _build_stiffness_step(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    v0 = _number(opts, "speed_m_s", 5.0, 60.0)
    t, plan = _constant_speed_plan(duration_s, dt_s, v0, opts)
    # Berntorp & Di Cairano 2018, Sec. VI-A: square-wave steering (period 4 s) and wheel torque
    # (period 5 s); small slip (< 5 %) so the linear tyre model holds.
    plan.steer_cmd_rad = _number(opts, "steer_amplitude_rad", 0.0, 0.2) * _square(t, 4.0)
    plan.extra_drive_force_n = _number(opts, "force_amplitude_n", 0.0, 1e4) * _square(t, 5.0)
    plan.speed_gain_1_s = 0.1
    plan.steer_lag_s = 0.05
    # stiffness individually Gaussian with ~5 % std around nominal (paper), then a sudden
    # surface change at step_time_s scales all of them by (1 - drop)
    base = 1.0 + _number(opts, "stiffness_std_fraction", 0.0, 0.3) * rng.standard_normal(3)
    drop = _number(opts, "stiffness_drop_fraction", 0.0, 0.9)
    t_step = _number(opts, "step_time_s", 0.0, 1e5)
    factor = np.where((t >= t_step)[:, None], (1.0 - drop) * base[None, :], base[None, :])
    plan.stiffness_factor = factor
    # initial state x0 ~ N([22, 0, 0], diag([1, 1, pi/180])^2) as in the paper
    plan.initial_speed_m_s = v0 + float(rng.standard_normal())
    plan.initial_lateral_velocity_m_s = float(rng.standard_normal()) * 1.0
    plan.initial_yaw_rate_rad_s = float(rng.standard_normal()) * math.pi / 180.0
    if t_step <= duration_s:
        plan.events.append(
            SimEvent(t_s=t_step, kind="stiffness_step", detail={"factor": 1.0 - drop})
        )
    return plan


def _build_sine(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    v0 = _number(opts, "speed_m_s", 3.0, 60.0)
    t, plan = _constant_speed_plan(duration_s, dt_s, v0, opts)
    t0 = _number(opts, "straight_s", 0.0, 1e5)
    f = _number(opts, "sine_frequency_hz", 0.01, 5.0)
    periods = _number(opts, "sine_periods", 0.0, 100.0)
    amp = _number(opts, "steer_amplitude_rad", 0.0, 0.3)
    tau = t - t0
    on = (tau >= 0.0) & (tau <= periods / f)
    plan.steer_cmd_rad = np.where(on, amp * np.sin(2.0 * math.pi * f * tau), 0.0)
    plan.steer_lag_s = 0.05
    plan.mu[:] = _number(opts, "mu", 0.05, 2.0)
    plan.stiffness_factor[:] = _number(opts, "stiffness_factor", 0.05, 2.0)
    plan.initial_speed_m_s = v0
    return plan


def _build_lane_change(
    opts: dict[str, Any], duration_s: float, rng: np.random.Generator, dt_s: float
) -> Plan:
    v0 = _number(opts, "speed_kmh", 10.0, 150.0) * KMH
    t, plan = _constant_speed_plan(duration_s, dt_s, v0, opts)
    amp = _number(opts, "steer_amplitude_rad", 0.0, 0.3)
    period = _number(opts, "lane_change_period_s", 0.5, 20.0)
    steer = np.zeros(t.size)
    tk = 3.0
    while tk < duration_s:
        # double lane change: out (one steering sine period), short straight, back (negated)
        direction = float(rng.choice([-1.0, 1.0]))
        for sign, pause in ((direction, 1.0), (-direction, 4.0)):
            a = sign * amp * float(rng.uniform(0.9, 1.1))
            tau = t - tk
            on = (tau >= 0.0) & (tau <= period)
            steer += np.where(on, a * np.sin(2.0 * math.pi * tau / period), 0.0)
            tk += period + pause
    plan.steer_cmd_rad = steer
    plan.steer_lag_s = 0.05
    plan.initial_speed_m_s = v0
    return plan


def _number(opts: Mapping[str, Any], name: str, low: float, high: float) -> float:
    value = opts[name]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ScenarioError(f"option {name}={value!r}: must be a finite number")
    if not low <= value <= high:
        raise ScenarioError(f"option {name}={value!r}: must be within [{low}, {high}]")
    return float(value)


_SINE_COMMON = {"straight_s": 22.0, "sine_frequency_hz": 0.25, "sine_periods": 2.5}

_DEFS: dict[str, _ScenarioDef] = {
    "ece_r64": _ScenarioDef(
        35.0,
        {"deflate_wheel": "wheel_rl", "deflation_fraction": 0.2, "deflation_time_min": None},
        _build_ece_r64,
    ),
    "robustness": _ScenarioDef(30.0, {}, _build_robustness),
    "diffusion": _ScenarioDef(
        30.0, {"wheels": "all", "rate_kpa_per_min": 1.5, "start_min": 5.0}, _build_diffusion
    ),
    "city": _ScenarioDef(20.0, {}, _build_city),
    "slow": _ScenarioDef(10.0, {}, _build_slow),
    "stiffness_step": _ScenarioDef(
        1.0,
        {
            "speed_m_s": 22.0,
            "steer_amplitude_rad": 0.015,
            "force_amplitude_n": 1500.0,
            "stiffness_std_fraction": 0.05,
            "stiffness_drop_fraction": 0.5,
            "step_time_s": 30.0,
        },
        _build_stiffness_step,
    ),
    "snow_sine": _ScenarioDef(
        40.0 / 60.0,
        {
            **_SINE_COMMON,
            "speed_m_s": 15.0,
            "steer_amplitude_rad": 0.03,
            "mu": 0.3,
            "stiffness_factor": 0.5,
        },
        _build_sine,
    ),
    "asphalt_sine": _ScenarioDef(
        40.0 / 60.0,
        {
            **_SINE_COMMON,
            "speed_m_s": 20.0,
            "steer_amplitude_rad": 0.03,
            "mu": 1.0,
            "stiffness_factor": 1.0,
        },
        _build_sine,
    ),
    "lane_change": _ScenarioDef(
        1.0,
        {"speed_kmh": 60.0, "steer_amplitude_rad": 0.09, "lane_change_period_s": 2.5},
        _build_lane_change,
    ),
}

assert set(_DEFS) == set(SCENARIOS)


def scenario_defaults(name: str) -> tuple[float, dict[str, Any]]:
    """(default minutes, default options including the common ones) of scenario ``name``."""
    if name not in _DEFS:
        raise ScenarioError(f"unknown scenario {name!r}; {known_names(name, SCENARIOS)}")
    d = _DEFS[name]
    return d.default_minutes, {**COMMON_OPTIONS, **d.options}


def build_plan(
    name: str,
    duration_s: float,
    rng: np.random.Generator,
    dt_s: float,
    options: Mapping[str, Any],
) -> Plan:
    """Resolve the options of scenario ``name`` and sample it on the integration grid."""
    _, defaults = scenario_defaults(name)
    unknown = [k for k in options if k not in defaults]
    if unknown:
        raise ScenarioError(
            f"scenario {name!r} has no option {unknown[0]!r}; {known_names(unknown[0], defaults)}"
        )
    opts = {**defaults, **options}
    for key in COMMON_OPTIONS:
        _number(opts, key, -1e9, 1e9)
    plan = _DEFS[name].build(opts, duration_s, rng, dt_s)
    plan.options = {k: (list(v) if isinstance(v, tuple) else v) for k, v in opts.items()}
    return plan
