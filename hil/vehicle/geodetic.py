"""The map's world frame on the Earth: a local east-north tangent plane at a geodetic origin (WGS-84), so that
GNSS latitude/longitude become world x (east) and y (north) in metres and back."""

from __future__ import annotations

import math
from dataclasses import dataclass

from testbed.errors import UserError

WGS84_A = 6_378_137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
DEFAULT_ORIGIN = (48.137, 11.575)
"""Where a map without its own georeference is placed (degrees); any origin works for a simulated drive."""


@dataclass(frozen=True)
class LocalTangentPlane:
    """East-north plane tangent to the WGS-84 ellipsoid at (`lat0`, `lon0`) degrees; heights are ignored."""

    lat0: float
    lon0: float

    def __post_init__(self) -> None:
        if not (-90.0 < self.lat0 < 90.0 and -180.0 <= self.lon0 <= 180.0):
            raise ValueError(f"origin must be a latitude in (-90, 90) and a longitude in [-180, 180], "
                             f"got {self.lat0}, {self.lon0}")

    @staticmethod
    def _ecef(lat: float, lon: float) -> tuple[float, float, float]:
        phi, lam = math.radians(lat), math.radians(lon)
        n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(phi) ** 2)
        return (n * math.cos(phi) * math.cos(lam), n * math.cos(phi) * math.sin(lam),
                n * (1.0 - WGS84_E2) * math.sin(phi))

    def to_xy(self, lat: float, lon: float) -> tuple[float, float]:
        """Degrees -> (east, north) metres from the origin, on the tangent plane."""
        x0, y0, z0 = self._ecef(self.lat0, self.lon0)
        x, y, z = self._ecef(lat, lon)
        dx, dy, dz = x - x0, y - y0, z - z0
        phi, lam = math.radians(self.lat0), math.radians(self.lon0)
        east = -math.sin(lam) * dx + math.cos(lam) * dy
        north = -math.sin(phi) * math.cos(lam) * dx - math.sin(phi) * math.sin(lam) * dy + math.cos(phi) * dz
        return east, north

    def to_latlon(self, east: float, north: float) -> tuple[float, float]:
        """(east, north) metres -> degrees: Newton steps on `to_xy` from the spherical first guess."""
        phi = math.radians(self.lat0)
        m = WGS84_A * (1.0 - WGS84_E2) / (1.0 - WGS84_E2 * math.sin(phi) ** 2) ** 1.5
        n = WGS84_A / math.sqrt(1.0 - WGS84_E2 * math.sin(phi) ** 2)
        dlat, dlon = 1.0 / m, 1.0 / (n * math.cos(phi))
        lat = self.lat0 + math.degrees(north * dlat)
        lon = self.lon0 + math.degrees(east * dlon)
        for _ in range(3):
            e, nn = self.to_xy(lat, lon)
            lat += math.degrees((north - nn) * dlat)
            lon += math.degrees((east - e) * dlon)
        return lat, lon


def parse_origin(text: str) -> LocalTangentPlane:
    """`LAT,LON` in degrees -> the plane at that origin (a one-line UserError naming the format otherwise)."""
    try:
        lat, lon = (float(part) for part in text.split(","))
        return LocalTangentPlane(lat, lon)
    except ValueError as exc:
        why = f" ({exc})" if str(exc).startswith("origin must") else ""
        raise UserError(f"--origin takes LAT,LON in degrees, e.g. 48.137,11.575; got {text!r}{why}") from None
