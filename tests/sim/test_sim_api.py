"""Public API of the simulator: scenarios, options, reproducibility, configuration errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tire_estimation.errors import ConfigError, ScenarioError
from tire_estimation.sim import SCENARIOS, SensorConfig, SimResult, simulate


def _arrays(res: SimResult) -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    for name in ("wheel_speeds", "steering", "imu", "gnss", "truth", "tire_forces"):
        stream = getattr(res, name)
        for f in dataclasses.fields(stream):
            value = getattr(stream, f.name)
            if isinstance(value, np.ndarray):
                out[f"{name}.{f.name}"] = value
    return out


def test_scenario_list_has_descriptions() -> None:
    expected = {
        "ece_r64",
        "robustness",
        "diffusion",
        "city",
        "slow",
        "stiffness_step",
        "snow_sine",
        "asphalt_sine",
        "lane_change",
    }
    assert set(SCENARIOS) == expected
    assert all(isinstance(d, str) and len(d) > 10 for d in SCENARIOS.values())


@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_every_scenario_runs_and_streams_are_sane(scenario: str) -> None:
    res = simulate(scenario, seed=1, minutes=0.25)
    assert res.scenario == scenario
    assert res.duration_s == pytest.approx(15.0, abs=0.03)
    for key, arr in _arrays(res).items():
        if arr.dtype.kind == "f":
            assert np.all(np.isfinite(arr)), key
    assert res.wheel_speeds.wheel_speed_rad_s.shape[1] == 4
    assert res.truth.stiffness.shape[1] == 3
    assert np.all(np.diff(res.truth.t_ns) == 20_000_000)  # 50 Hz truth
    assert res.config["scenario"] == scenario and res.config["seed"] == 1


def test_same_seed_identical_different_seed_different() -> None:
    a = _arrays(simulate("ece_r64", seed=42, minutes=0.3))
    b = _arrays(simulate("ece_r64", seed=42, minutes=0.3))
    c = _arrays(simulate("ece_r64", seed=43, minutes=0.3))
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    for key in (
        "wheel_speeds.wheel_speed_rad_s",
        "gnss.lat_deg",
        "imu.angular_velocity_rad_s",
        "truth.velocity_m_s",
        "truth.wheel_radius_m",
    ):
        assert not np.array_equal(a[key], c[key]), key


def test_sensor_noise_streams_are_independent() -> None:
    base = simulate("asphalt_sine", seed=9, minutes=0.2)
    noisy_gnss = simulate(
        "asphalt_sine", seed=9, minutes=0.2, sensors=SensorConfig(gnss_white_std_m=3.0)
    )
    np.testing.assert_array_equal(
        base.imu.angular_velocity_rad_s, noisy_gnss.imu.angular_velocity_rad_s
    )
    np.testing.assert_array_equal(
        base.wheel_speeds.wheel_speed_rad_s, noisy_gnss.wheel_speeds.wheel_speed_rad_s
    )
    assert not np.array_equal(base.gnss.lat_deg, noisy_gnss.gnss.lat_deg)


def test_default_minutes_come_from_the_scenario() -> None:
    res = simulate("asphalt_sine")
    assert res.duration_s == pytest.approx(40.0, abs=0.03)


def test_unknown_scenario_and_option_are_named() -> None:
    with pytest.raises(ScenarioError, match="no_such"):
        simulate("no_such")
    with pytest.raises(ScenarioError, match="bogus_option"):
        simulate("ece_r64", minutes=0.1, bogus_option=1)
    with pytest.raises(ScenarioError, match="deflate_wheel"):
        simulate("ece_r64", minutes=0.1, deflate_wheel="wheel_xx")
    with pytest.raises(ScenarioError, match="deflation_fraction"):
        simulate("ece_r64", minutes=0.1, deflation_fraction=2.0)
    with pytest.raises(ScenarioError, match="wheels"):
        simulate("diffusion", minutes=0.1, wheels=["wheel_zz"])
    with pytest.raises(ScenarioError, match="minutes"):
        simulate("city", minutes=-1.0)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("wheel_speed_rate_hz", 5.0),
        ("wheel_speed_teeth", 48.5),
        ("gnss_rate_hz", 0.0),
        ("gnss_white_std_m", -1.0),
        ("gnss_gm_tau_s", float("nan")),
        ("gyro_bias_rad_s", (0.0, 0.0)),
        ("tire_force_wheels", ("wheel_fl", "wheel_xx")),
        ("gnss_latency_s", 5.0),
        ("gnss_velocity_enabled", "yes"),
    ],
)
def test_sensor_config_validation_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError) as info:
        SensorConfig(**{field: value})
    assert field in info.value.field
    assert field in str(info.value)


def test_sensor_config_is_frozen_and_serializable() -> None:
    cfg = SensorConfig()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.gnss_rate_hz = 5.0  # type: ignore[misc]
    d = cfg.to_dict()
    assert d["wheel_speed_teeth"] == 48 and d["gnss_rate_hz"] == 10.0
    assert isinstance(d["gyro_bias_rad_s"], list)


def test_sensor_rates_follow_configuration() -> None:
    res = simulate(
        "asphalt_sine",
        seed=1,
        minutes=0.1,
        sensors=SensorConfig(wheel_speed_rate_hz=50.0, gnss_rate_hz=1.0, imu_rate_hz=200.0),
    )
    assert np.all(np.diff(res.wheel_speeds.t_ns) == 20_000_000)
    assert np.all(np.diff(res.gnss.t_ns) == 1_000_000_000)
    assert np.all(np.diff(res.imu.t_ns) == 5_000_000)
