"""WGS-84 geodetic position to East-North-Up metres from a site: the one geodetic conversion a
check runs, written out here (a dozen lines) so a check does not import pymap3d, whose time
conversions pull in dateutil and zoneinfo. Same formulas as pymap3d's `geodetic2enu`:
geodetic to Earth-centred Earth-fixed for both points, then the difference rotated into the
site's local frame. tests/test_geodesy.py holds it to pymap3d within 1e-6 m.
"""

from __future__ import annotations

from math import cos, hypot, radians, sin

__all__ = ["SEMIMAJOR_M", "SEMIMINOR_M", "geodetic2ecef", "geodetic2enu"]

#: WGS-84 ellipsoid axes (metres)
SEMIMAJOR_M = 6378137.0
SEMIMINOR_M = 6356752.31424518


def geodetic2ecef(lat_deg: float, lon_deg: float, alt_m: float) -> tuple[float, float, float]:
    """Earth-centred Earth-fixed x, y, z (m) of a latitude, longitude and height above the ellipsoid."""
    lat, lon = radians(lat_deg), radians(lon_deg)
    n = SEMIMAJOR_M ** 2 / hypot(SEMIMAJOR_M * cos(lat), SEMIMINOR_M * sin(lat))  # prime vertical radius
    return ((n + alt_m) * cos(lat) * cos(lon), (n + alt_m) * cos(lat) * sin(lon),
            (n * (SEMIMINOR_M / SEMIMAJOR_M) ** 2 + alt_m) * sin(lat))


def geodetic2enu(lat_deg: float, lon_deg: float, alt_m: float, lat0_deg: float, lon0_deg: float,
                 alt0_m: float) -> tuple[float, float, float]:
    """East, north, up (m) of a geodetic point as seen from the site at (lat0, lon0, alt0)."""
    x1, y1, z1 = geodetic2ecef(lat_deg, lon_deg, alt_m)
    x0, y0, z0 = geodetic2ecef(lat0_deg, lon0_deg, alt0_m)
    u, v, w = x1 - x0, y1 - y0, z1 - z0
    lat0, lon0 = radians(lat0_deg), radians(lon0_deg)
    t = cos(lon0) * u + sin(lon0) * v
    return (-sin(lon0) * u + cos(lon0) * v, -sin(lat0) * t + cos(lat0) * w, cos(lat0) * t + sin(lat0) * w)
