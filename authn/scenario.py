"""A simulated flight together with the Remote ID it broadcasts (truthful or spoofed).

Composes the radar simulator (signatures) with the F3411 codec (registry): the
true position comes from the scene geometry (slant range, elevation, azimuth
from the radar site), converted to WGS-84 with pymap3d; a spoof replaces the
declared serial, position or UA type.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from datetime import datetime, timedelta

import numpy as np

from signatures.radar import Preset
from signatures.recording import Recording
from signatures.sim.scene import Scene
from signatures.sim.simulate import DEFAULT_START, Truth, simulate

UA_TYPE_MULTIROTOR = 2


@dataclass(frozen=True)
class Signing:
    """DRIP authentication the drone appends to its Remote ID (RFC 9575), and the ways a
    spoofer gets it wrong: another key, an old signature replayed, a message changed after
    signing."""

    private_key: bytes  # raw Ed25519 private key (32 bytes)
    det: bytes  # the DET the signature names (RFC 9374)
    sam: str = "wrapper"  # wrapper | manifest | frame
    window_s: tuple[float, float] = (-60.0, 300.0)  # valid-not-before/after, s from the dwell's start
    signed_at_offset_s: float = 0.0  # shift the window (a replayed signature: e.g. -86400)
    tamper_after_signing: bool = False  # move the first Location 50 m after signing it
    link: bytes | None = None  # a DRIP Link (auth data) from the drone's registry, broadcast too
    fec: bool = False  # end each authentication message with a forward-error-correction page (RFC 9575)


@dataclass(frozen=True)
class Broadcast:
    """What the drone says about itself; None fields are taken from the truth."""

    serial: str
    ua_type: int = UA_TYPE_MULTIROTOR
    id_type: int = 1  # F3411 UAS ID type: 1 serial number, 4 session ID (a DRIP DET)
    lat_deg: float | None = None
    lon_deg: float | None = None
    alt_m: float | None = None
    offset_along_los_m: float = 0.0  # declared position this far beyond the true one
    horizontal_accuracy: int = 11  # < 3 m
    vertical_accuracy: int = 5  # < 3 m
    speed_accuracy: int = 3  # < 1 m/s
    messages: int = 3  # Basic ID + this many Location messages, from mid-dwell, 0.33 s apart
    signing: Signing | None = None


def _line_of_sight(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])


def remote_id_rows(rec: Recording, scene: Scene, bc: Broadcast, azimuth_deg: float,
                   dwell_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, 25) uint8 messages and their times (s after the first chirp)."""
    import pymap3d

    from remoteid import BasicId, Location, encode

    u = _line_of_sight(scene.elevation_deg, azimuth_deg)
    vel = scene.radial_speed_mps * u
    rows, times = [encode(BasicId(id_type=bc.id_type, ua_type=bc.ua_type, uas_id=bc.serial))], [0.0]
    for i in range(bc.messages):
        t = dwell_s / 2 + i / 3.0
        pos = (scene.range_m + bc.offset_along_los_m) * u + vel * t
        lat, lon, alt = pymap3d.enu2geodetic(pos[0], pos[1], pos[2], rec.site.lat_deg, rec.site.lon_deg,
                                             rec.site.alt_m)
        when = rec.start_time + timedelta(seconds=t)
        loc = Location(
            status=2, height_type=0,
            direction_deg=math.degrees(math.atan2(vel[0], vel[1])) % 360.0,
            speed_horizontal_mps=min(float(np.hypot(vel[0], vel[1])), 254.25),
            speed_vertical_mps=float(np.clip(vel[2], -62.0, 62.0)),
            latitude_deg=bc.lat_deg if bc.lat_deg is not None else float(lat),
            longitude_deg=bc.lon_deg if bc.lon_deg is not None else float(lon),
            altitude_geo_m=bc.alt_m if bc.alt_m is not None else float(alt),
            altitude_baro_m=None, height_m=None,
            horizontal_accuracy=bc.horizontal_accuracy, vertical_accuracy=bc.vertical_accuracy,
            baro_accuracy=0, speed_accuracy=bc.speed_accuracy,
            timestamp_s=round((when.minute * 60 + when.second + when.microsecond / 1e6) * 10) / 10 % 3600.0,
            timestamp_accuracy_s=0.1,
        )
        rows.append(encode(loc))
        times.append(t)
    if bc.signing is not None:
        rows, times = _signed(rows, times, bc.signing, rec.start_time, dwell_s)
    return np.frombuffer(b"".join(rows), dtype=np.uint8).reshape(-1, 25).copy(), np.array(times)


def _signed(rows: list[bytes], times: list[float], signing: Signing, start: datetime,
            dwell_s: float) -> tuple[list[bytes], list[float]]:
    """The messages followed by the Authentication pages of one DRIP SAM over them."""
    from remoteid import Location, decode, encode
    from remoteid.drip import FRAME_F3411_MESSAGES, encode_frame, encode_manifest, encode_wrapper, paginate

    shift = timedelta(seconds=signing.signed_at_offset_s)
    vnb = start + shift + timedelta(seconds=signing.window_s[0])
    vna = start + shift + timedelta(seconds=signing.window_s[1])
    subjects = rows[:4]  # a wrapper holds at most 4 messages: the Basic ID and the first Locations
    if signing.sam == "wrapper":
        data = encode_wrapper(subjects, signing.det, signing.private_key, vnb, vna)
    elif signing.sam == "manifest":
        data = encode_manifest(rows, signing.det, signing.private_key, vnb, vna)
    elif signing.sam == "frame":
        data = encode_frame(FRAME_F3411_MESSAGES, b"".join(subjects), signing.det, signing.private_key, vnb, vna)
    else:
        raise ValueError(f"unknown DRIP SAM {signing.sam!r}: wrapper, manifest or frame")
    if signing.tamper_after_signing:
        first = next(i for i, r in enumerate(rows) if isinstance(decode(r), Location))
        loc = decode(rows[first])
        rows = [*rows[:first], encode(loc.replace(latitude_deg=loc.latitude_deg + 50.0 / 111_320.0)),
                *rows[first + 1:]]
    pages = paginate(data, start + shift, fec=signing.fec)
    if signing.link is not None:  # a different page-0 timestamp keeps the two messages apart
        pages = paginate(signing.link, start + shift - timedelta(seconds=1), fec=signing.fec) + pages
    t = dwell_s / 2
    return rows + list(pages), times + [t] * len(pages)


def simulate_flight(scene: Scene, preset: Preset, seed: int | None, broadcast: Broadcast | None = None,
                    azimuth_deg: float = 0.0, range_offset_m: float | None = None,
                    start_time: datetime = DEFAULT_START) -> tuple[Recording, Truth]:
    """Simulate a dwell; with a broadcast, embed its Remote ID messages in the recording."""
    rec, truth = simulate(scene, preset, seed, range_offset_m=range_offset_m, start_time=start_time)
    if broadcast is None:
        return rec, truth
    rows, times = remote_id_rows(rec, scene, broadcast, azimuth_deg, preset.dwell_s)
    return replace(rec, remote_id=rows, remote_id_time_s=times), truth
