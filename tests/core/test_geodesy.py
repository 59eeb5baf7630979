"""LocalTangentPlane: WGS-84 <-> ENU round trips and known distances."""

from __future__ import annotations

import numpy as np
import pytest

from tire_estimation.core.geodesy import LocalTangentPlane
from tire_estimation.errors import ConfigError

LTP = LocalTangentPlane(58.4, 15.6, 100.0)


def test_origin_maps_to_zero() -> None:
    e, n, u = LTP.to_enu(58.4, 15.6, 100.0)
    assert abs(float(e)) < 1e-9 and abs(float(n)) < 1e-9 and abs(float(u)) < 1e-9


def test_round_trip_enu_lla_enu_is_exact_to_micrometres() -> None:
    rng = np.random.default_rng(1)
    e = rng.uniform(-30_000, 30_000, 500)
    n = rng.uniform(-30_000, 30_000, 500)
    u = rng.uniform(-50, 200, 500)
    lat, lon, alt = LTP.to_lla(e, n, u)
    assert lat.shape == (500,)
    e2, n2, u2 = LTP.to_enu(lat, lon, alt)
    assert np.max(np.abs(e2 - e)) < 1e-6
    assert np.max(np.abs(n2 - n)) < 1e-6
    assert np.max(np.abs(u2 - u)) < 1e-6


def test_round_trip_lla_enu_lla() -> None:
    lat = np.array([58.41, 58.39, 58.4005])
    lon = np.array([15.61, 15.58, 15.6001])
    alt = np.array([90.0, 120.0, 100.0])
    lat2, lon2, alt2 = LTP.to_lla(*LTP.to_enu(lat, lon, alt))
    assert np.max(np.abs(lat2 - lat)) < 1e-10
    assert np.max(np.abs(lon2 - lon)) < 1e-10
    assert np.max(np.abs(alt2 - alt)) < 1e-6


def test_known_distances() -> None:
    # WGS-84 meridian radius at 58.4 deg: M = a (1 - e^2) / (1 - e^2 sin^2)^1.5 = 6.3819e6 m,
    # so 1e-3 deg of latitude is 111.39 m; prime-vertical N cos(lat) gives 58.47 m per 1e-3 deg
    # of longitude.
    _, n, _ = LTP.to_enu(58.401, 15.6, 100.0)
    assert float(n) == pytest.approx(111.39, abs=0.02)
    e, _, _ = LTP.to_enu(58.4, 15.601, 100.0)
    assert float(e) == pytest.approx(58.47, abs=0.02)
    # going up: pure "up"
    e, n, u = LTP.to_enu(58.4, 15.6, 110.0)
    assert float(u) == pytest.approx(10.0, abs=1e-6)
    assert abs(float(e)) < 1e-6 and abs(float(n)) < 1e-6


def test_invalid_origin_names_the_field() -> None:
    with pytest.raises(ConfigError, match="origin_lat_deg"):
        LocalTangentPlane(95.0, 15.0, 0.0)
