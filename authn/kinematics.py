"""Remote ID claim versus radar: expected range and radial velocity, residuals, sanity.

Geodesy is WGS-84 (`authn.geodesy`, held to pymap3d by its test): the Remote ID position
(geodetic altitude, i.e. height above the WGS-84 ellipsoid) becomes an East-North-Up vector
from the radar site, whose norm is the expected slant range and whose unit vector
projects the declared velocity onto the line of sight (+ = receding).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime

import numpy as np

from authn.geodesy import geodetic2enu

# F3411 accuracy enumerations -> metres / metres per second (upper bounds); unknown = None
HORIZONTAL_ACCURACY_M = {1: 18520.0, 2: 7408.0, 3: 3704.0, 4: 1852.0, 5: 926.0, 6: 555.6, 7: 185.2,
                         8: 92.6, 9: 30.0, 10: 10.0, 11: 3.0, 12: 1.0}
VERTICAL_ACCURACY_M = {1: 150.0, 2: 45.0, 3: 25.0, 4: 10.0, 5: 3.0, 6: 1.0}
SPEED_ACCURACY_MPS = {1: 10.0, 2: 3.0, 3: 1.0, 4: 0.3}
ROTORCRAFT_UA_TYPES = {2, 4}  # helicopter or multirotor; hybrid lift (VTOL)

#: Remote ID sanity limits. They define the *issues* a declaration can have (named strings
#: the policy sees in `context.remote_id_issues`); what an issue means for the decision is the
#: policy's (`remote-id-implausible`). The accuracy limits stop a spoofer from widening the
#: range tolerance at will by declaring a poor accuracy.
STALE_AFTER_S = 5.0
MAX_HORIZONTAL_SPEED_MPS = 60.0
MAX_VERTICAL_SPEED_MPS = 30.0
MAX_USABLE_POSITION_ACCURACY_M = 30.0
MAX_USABLE_VERTICAL_ACCURACY_M = 45.0


@dataclass(frozen=True)
class DeclaredState:
    """Position and velocity a Remote ID Location message declares."""

    lat_deg: float
    lon_deg: float
    alt_m: float  # geodetic (WGS-84 ellipsoid)
    time: datetime | None
    speed_horizontal_mps: float | None
    direction_deg: float | None
    speed_vertical_mps: float | None
    horizontal_accuracy_m: float | None
    vertical_accuracy_m: float | None
    speed_accuracy_mps: float | None
    timestamp_accuracy_s: float | None

    @classmethod
    def from_location(cls, loc, reference: datetime) -> "DeclaredState | None":
        """From a decoded `Location` (None when it carries no usable position)."""
        from remoteid import location_time

        alt = loc.altitude_geo_m if loc.altitude_geo_m is not None else loc.altitude_baro_m
        if loc.latitude_deg is None or loc.longitude_deg is None or alt is None:
            return None
        return cls(loc.latitude_deg, loc.longitude_deg, alt, location_time(loc, reference),
                   loc.speed_horizontal_mps, loc.direction_deg, loc.speed_vertical_mps,
                   HORIZONTAL_ACCURACY_M.get(loc.horizontal_accuracy),
                   VERTICAL_ACCURACY_M.get(loc.vertical_accuracy),
                   SPEED_ACCURACY_MPS.get(loc.speed_accuracy), loc.timestamp_accuracy_s)


@dataclass(frozen=True)
class Expected:
    range_m: float
    radial_velocity_mps: float | None
    enu_m: tuple[float, float, float]


def expected_from_radar(state: DeclaredState, site_lat: float, site_lon: float, site_alt: float,
                        at: datetime) -> Expected:
    """Where the radar should see the declared aircraft at time `at` (extrapolated with its velocity)."""
    e, n, u = geodetic2enu(state.lat_deg, state.lon_deg, state.alt_m, site_lat, site_lon, site_alt)
    pos = np.array([e, n, u], dtype=np.float64)
    vel = None
    if state.speed_horizontal_mps is not None and state.direction_deg is not None:
        track = math.radians(state.direction_deg)
        vel = np.array([state.speed_horizontal_mps * math.sin(track),
                        state.speed_horizontal_mps * math.cos(track),
                        state.speed_vertical_mps or 0.0])
        if state.time is not None:
            pos = pos + vel * (at - state.time).total_seconds()
    rng = float(np.linalg.norm(pos))
    radial = None if vel is None or rng == 0.0 else float(vel @ pos / rng)
    return Expected(rng, radial, (float(pos[0]), float(pos[1]), float(pos[2])))


@dataclass(frozen=True)
class Residuals:
    range_residual_m: float
    range_tolerance_m: float
    radial_velocity_residual_mps: float | None
    radial_velocity_tolerance_mps: float | None


def residuals(expected: Expected, state: DeclaredState, measured_range_m: float,
              measured_velocity_mps: float, range_bin_m: float, doppler_bin_mps: float,
              unambiguous_velocity_mps: float) -> Residuals:
    """Measured minus expected, with tolerances from radar resolution and declared accuracies.

    Range: 2 range bins + horizontal + vertical accuracy + 0.5 m altitude quantisation
    + speed x timestamp accuracy. Velocity: 3 Doppler bins + speed accuracy + 0.5 m/s
    quantisation; compared modulo the unambiguous interval (the radar folds).
    """
    speed = state.speed_horizontal_mps or 0.0
    r_tol = (2.0 * range_bin_m + (state.horizontal_accuracy_m or 0.0) + (state.vertical_accuracy_m or 0.0)
             + 0.5 + speed * (state.timestamp_accuracy_s or 0.1))
    r_res = abs(measured_range_m - expected.range_m)
    if expected.radial_velocity_mps is None:
        return Residuals(r_res, r_tol, None, None)
    span = 2.0 * unambiguous_velocity_mps
    diff = (measured_velocity_mps - expected.radial_velocity_mps + unambiguous_velocity_mps) % span \
        - unambiguous_velocity_mps
    v_tol = 3.0 * doppler_bin_mps + (state.speed_accuracy_mps or 10.0) + 0.5
    return Residuals(r_res, r_tol, abs(diff), v_tol)


def sanity(state: DeclaredState | None, ua_type: int | None, rid_serial: str | None, claimed_serial: str,
           dwell_time: datetime, rotorcraft_seen: bool | None) -> list[str]:
    """Remote ID issues that make the claim implausible (names are policy-visible)."""
    issues: list[str] = []
    if rid_serial is not None and rid_serial != claimed_serial:
        issues.append("serial-mismatch")
    # UA type 0 is F3411's "none": not declared, so nothing to contradict (real senders send it)
    if ua_type not in (None, 0) and rotorcraft_seen and ua_type not in ROTORCRAFT_UA_TYPES:
        issues.append("not-rotorcraft")
    if state is None:
        return issues
    if state.time is None or abs((dwell_time - state.time).total_seconds()) > STALE_AFTER_S:
        issues.append("stale-timestamp")
    if ((state.speed_horizontal_mps or 0.0) > MAX_HORIZONTAL_SPEED_MPS
            or abs(state.speed_vertical_mps or 0.0) > MAX_VERTICAL_SPEED_MPS):
        issues.append("impossible-speed")
    if state.horizontal_accuracy_m is None or state.horizontal_accuracy_m > MAX_USABLE_POSITION_ACCURACY_M \
            or state.vertical_accuracy_m is None or state.vertical_accuracy_m > MAX_USABLE_VERTICAL_ACCURACY_M:
        issues.append("poor-position-accuracy")
    return issues
