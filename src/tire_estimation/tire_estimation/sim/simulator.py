"""``simulate()``: one scenario, one seed -> every sensor stream and the truth.

Random numbers: one :class:`numpy.random.SeedSequence` per run, spawned into independent child
generators (scenario, tyres, wheel speeds, steering, IMU, GNSS, tyre forces), so switching a
sensor on or changing its settings never changes another sensor's noise.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.core.validation import known_names
from tire_estimation.core.vehicle import VehicleParams
from tire_estimation.errors import ConfigError, ScenarioError
from tire_estimation.sim import sensors as sensor_models
from tire_estimation.sim.config import SensorConfig
from tire_estimation.sim.dynamics import integrate
from tire_estimation.sim.scenarios import SCENARIOS, build_plan, scenario_defaults
from tire_estimation.sim.streams import SimResult
from tire_estimation.sim.tires import TireModelConfig

#: Integration step, s (5 ms).
INTEGRATION_STEP_S = 0.005
#: Rate of the truth stream, Hz (every 4th integration step).
TRUTH_RATE_HZ = 50.0
#: Wall-clock stamp of t = 0 of every simulated drive, ns since the Unix epoch (2023-11-14).
START_TIME_NS = 1_700_000_000 * 1_000_000_000

_STREAMS = ("scenario", "tires", "wheel_speeds", "steering", "imu", "gnss", "tire_forces")


def simulate(
    scenario: str,
    seed: int = 0,
    minutes: float | None = None,
    sensors: SensorConfig | None = None,
    vehicle: VehicleParams | None = None,
    **scenario_options: Any,
) -> SimResult:
    """Simulate ``scenario`` for ``minutes`` (None: its default) with seed ``seed``.

    Raises:
        ScenarioError: unknown scenario, unknown or invalid option, or invalid minutes/seed.
        ConfigError: ``sensors`` / ``vehicle`` of the wrong type.
    """
    if scenario not in SCENARIOS:
        raise ScenarioError(f"unknown scenario {scenario!r}; {known_names(scenario, SCENARIOS)}")
    default_minutes, _ = scenario_defaults(scenario)
    if minutes is None:
        minutes = default_minutes
    if isinstance(minutes, bool) or not isinstance(minutes, (int, float)):
        raise ScenarioError(f"minutes={minutes!r}: must be a number")
    if not (math.isfinite(minutes) and 0.05 <= minutes <= 24 * 60):
        raise ScenarioError(f"minutes={minutes!r}: must be within [0.05, 1440]")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ScenarioError(f"seed={seed!r}: must be a non-negative integer")
    sensors = SensorConfig() if sensors is None else sensors
    if not isinstance(sensors, SensorConfig):
        raise ConfigError("sensors", sensors, "must be a SensorConfig")
    vehicle = VehicleParams() if vehicle is None else vehicle
    if not isinstance(vehicle, VehicleParams):
        raise ConfigError("vehicle", vehicle, "must be a VehicleParams")

    rngs = dict(
        zip(
            _STREAMS,
            (
                np.random.default_rng(s)
                for s in np.random.SeedSequence(int(seed)).spawn(len(_STREAMS))
            ),
            strict=True,
        )
    )
    duration_s = 60.0 * float(minutes)
    plan = build_plan(scenario, duration_s, rngs["scenario"], INTEGRATION_STEP_S, scenario_options)
    opts = plan.options
    try:
        tires = TireModelConfig(
            nominal_pressure_kpa=float(opts["nominal_pressure_kpa"]),
            pressure_sensitivity_mm_per_kpa=float(opts["pressure_sensitivity_mm_per_kpa"]),
            radius_offset_std_mm=float(opts["radius_offset_std_mm"]),
        )
        ltp = LocalTangentPlane(
            float(opts["origin_lat_deg"]),
            float(opts["origin_lon_deg"]),
            float(opts["origin_alt_m"]),
        )
    except ConfigError as exc:
        raise ScenarioError(
            f"option {exc.field.split('.')[-1]}={exc.value!r}: {exc.reason}"
        ) from exc
    # per-tyre manufacturing / wear offset of the effective rolling radius
    offsets = rngs["tires"].standard_normal(4) * tires.radius_offset_std_mm * 1e-3
    radius_offset_m = (float(offsets[0]), float(offsets[1]), float(offsets[2]), float(offsets[3]))

    log = integrate(plan, vehicle, tires, sensors, radius_offset_m)

    t0 = START_TIME_NS
    wheel = sensor_models.wheel_speeds(log, sensors, rngs["wheel_speeds"], t0)
    steer = sensor_models.steering(log, sensors, rngs["steering"], t0)
    imu = sensor_models.imu(log, sensors, vehicle, rngs["imu"], t0)
    gnss = sensor_models.gnss(log, sensors, vehicle, ltp, rngs["gnss"], t0)
    forces = (
        sensor_models.tire_forces(log, sensors, rngs["tire_forces"], t0)
        if sensors.tire_force_enabled
        else None
    )
    truth = sensor_models.truth(log, ltp, TRUTH_RATE_HZ, t0)
    config: dict[str, Any] = {
        "scenario": scenario,
        "seed": int(seed),
        "minutes": float(minutes),
        "options": {k: v for k, v in opts.items()},
        "sensors": sensors.to_dict(),
        "tires": {
            "nominal_pressure_kpa": tires.nominal_pressure_kpa,
            "pressure_sensitivity_mm_per_kpa": tires.pressure_sensitivity_mm_per_kpa,
            "radius_offset_m": [float(v) for v in radius_offset_m],
            "lateral_shape_c": tires.lateral_shape_c,
            "lateral_curvature_e": tires.lateral_curvature_e,
            "longitudinal_shape_c": tires.longitudinal_shape_c,
        },
        "integration_step_s": INTEGRATION_STEP_S,
        "truth_rate_hz": TRUTH_RATE_HZ,
        "start_time_ns": START_TIME_NS,
    }
    return SimResult(
        scenario=scenario,
        seed=int(seed),
        vehicle=vehicle,
        origin_lla=ltp.origin_lla,
        wheel_speeds=wheel,
        steering=steer,
        imu=imu,
        gnss=gnss,
        truth=truth,
        tire_forces=forces,
        events=tuple(plan.events),
        config=config,
    )
