"""The WGS-84 conversion a check runs (`authn.geodesy`) agrees with pymap3d's to 1e-6 m, so
dropping pymap3d from the check's imports changed no expected range or radial velocity."""

from __future__ import annotations

import random

import pymap3d
import pytest

from authn.geodesy import geodetic2ecef, geodetic2enu


def _points(n: int, seed: int) -> list[tuple[float, ...]]:
    """Sites anywhere (poles and the antimeridian included) and targets from metres to 50 km away."""
    rnd = random.Random(seed)
    sites = [(90.0, 0.0, 0.0), (-90.0, 179.9, 10.0), (0.0, 180.0, -50.0), (0.0, -180.0, 0.0)]
    sites += [(rnd.uniform(-90, 90), rnd.uniform(-180, 180), rnd.uniform(-400, 4000)) for _ in range(n)]
    out = []
    for lat0, lon0, alt0 in sites:
        span = rnd.choice((1e-5, 1e-3, 0.05, 0.45))
        lat = max(-90.0, min(90.0, lat0 + rnd.uniform(-span, span)))
        out.append((lat, lon0 + rnd.uniform(-span, span), alt0 + rnd.uniform(-100, 3000), lat0, lon0, alt0))
    return out


@pytest.mark.parametrize("seed", range(4))
def test_enu_matches_pymap3d(seed: int) -> None:
    for p in _points(250, seed):
        ours, theirs = geodetic2enu(*p), pymap3d.geodetic2enu(*p)
        assert max(abs(a - b) for a, b in zip(ours, theirs)) <= 1e-6, p


def test_ecef_matches_pymap3d() -> None:
    for lat, lon, alt, *_ in _points(250, 99):
        assert max(abs(a - b) for a, b in zip(geodetic2ecef(lat, lon, alt), pymap3d.geodetic2ecef(lat, lon, alt))) \
            <= 1e-6


def test_known_values() -> None:
    """The equator at the prime meridian is the semi-major axis on x; 1 km up is 1 km up."""
    assert geodetic2ecef(0.0, 0.0, 0.0) == pytest.approx((6378137.0, 0.0, 0.0), abs=1e-9)
    assert geodetic2enu(52.0, 4.0, 1000.0, 52.0, 4.0, 0.0) == pytest.approx((0.0, 0.0, 1000.0), abs=1e-6)
