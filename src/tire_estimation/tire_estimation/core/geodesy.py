"""WGS-84 <-> local East-North-Up (ENU) conversion about a fixed origin.

The ellipsoid maths is delegated to :mod:`pymap3d` (geodetic -> ECEF -> ENU with the WGS-84
ellipsoid); this module only fixes the origin and the argument conventions (degrees, metres,
vectorized over NumPy arrays).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pymap3d
from numpy.typing import ArrayLike

from tire_estimation.core.arrays import F64
from tire_estimation.core.validation import require_range
from tire_estimation.errors import ConfigError


@dataclass(frozen=True)
class LocalTangentPlane:
    """ENU frame tangent to the WGS-84 ellipsoid at a fixed origin.

    Attributes:
        origin_lat_deg: geodetic latitude of the origin, deg, in [-90, 90].
        origin_lon_deg: longitude of the origin, deg, in [-180, 360].
        origin_alt_m: ellipsoidal height of the origin, m.
    """

    origin_lat_deg: float
    origin_lon_deg: float
    origin_alt_m: float = 0.0

    def __post_init__(self) -> None:
        require_range("origin_lat_deg", self.origin_lat_deg, -90.0, 90.0, ConfigError)
        require_range("origin_lon_deg", self.origin_lon_deg, -180.0, 360.0, ConfigError)
        require_range("origin_alt_m", self.origin_alt_m, -1.0e4, 1.0e5, ConfigError)

    @functools.cached_property
    def _origin_ecef_m(self) -> tuple[float, float, float]:
        x, y, z = pymap3d.geodetic2ecef(
            self.origin_lat_deg, self.origin_lon_deg, self.origin_alt_m, deg=True
        )
        return float(x), float(y), float(z)

    def to_enu(
        self, lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike
    ) -> tuple[F64, F64, F64]:
        """WGS-84 (deg, deg, m) -> (east, north, up) in metres; broadcasts like NumPy.

        Same steps as ``pymap3d.geodetic2enu`` (ECEF difference to the origin, rotated into
        ENU), with the origin's ECEF position computed once.
        """
        x, y, z = pymap3d.geodetic2ecef(
            np.asarray(lat_deg, dtype=np.float64),
            np.asarray(lon_deg, dtype=np.float64),
            np.asarray(alt_m, dtype=np.float64),
            deg=True,
        )
        x0, y0, z0 = self._origin_ecef_m
        e, n, u = pymap3d.uvw2enu(
            x - x0, y - y0, z - z0, self.origin_lat_deg, self.origin_lon_deg, deg=True
        )
        return np.asarray(e, np.float64), np.asarray(n, np.float64), np.asarray(u, np.float64)

    def to_lla(
        self, east_m: ArrayLike, north_m: ArrayLike, up_m: ArrayLike
    ) -> tuple[F64, F64, F64]:
        """(east, north, up) in metres -> WGS-84 (lat deg, lon deg, alt m); broadcasts."""
        lat, lon, alt = pymap3d.enu2geodetic(
            np.asarray(east_m, dtype=np.float64),
            np.asarray(north_m, dtype=np.float64),
            np.asarray(up_m, dtype=np.float64),
            self.origin_lat_deg,
            self.origin_lon_deg,
            self.origin_alt_m,
            deg=True,
        )
        return (
            np.asarray(lat, np.float64),
            np.asarray(lon, np.float64),
            np.asarray(alt, np.float64),
        )

    @property
    def origin_lla(self) -> tuple[float, float, float]:
        """The origin as a plain (lat deg, lon deg, alt m) tuple."""
        return (float(self.origin_lat_deg), float(self.origin_lon_deg), float(self.origin_alt_m))
