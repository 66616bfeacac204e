"""Helpers for the capture-check tests: radar returns placed where a captured drone broadcast,
and pcap captures rewritten (positions shifted, another drone) or written from scratch."""

from __future__ import annotations

import math
import struct
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np

from remoteid import BasicId, Location, decode, encode, flatten
from remoteid.capture import CapturedMessage, read_capture
from remoteid.codec import split_raw
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import RadarSite, Recording
from signatures.sim.scene import Scene
from signatures.sim.simulate import simulate

DATA = Path(__file__).resolve().parents[1] / "data" / "remoteid-captures"
BEACON = DATA / "odid_wifi_bcn_sample.pcap"
SERIAL = "MFG1A0123456789"  # the Basic ID of the beacon capture
ELEVATION_DEG = 10.0


def locations(path: Path) -> list[tuple[CapturedMessage, Location]]:
    return [(c, m) for c in read_capture(path) for m in flatten([c.message]) if isinstance(m, Location)]


def _los(az_deg: float, el_deg: float = ELEVATION_DEG) -> np.ndarray:
    az, el = math.radians(az_deg), math.radians(el_deg)
    return np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])


def site_and_scene(loc: Location, range_m: float, az_deg: float, profile: str = "m300") -> tuple[RadarSite, Scene]:
    """A radar site from which the declared position lies at `range_m` on azimuth `az_deg`, and
    the scene (its radial speed from the declared velocity) that the radar then sees."""
    import pymap3d

    u = _los(az_deg)
    lat, lon, alt = pymap3d.enu2geodetic(*(-range_m * u), loc.latitude_deg, loc.longitude_deg, loc.altitude_geo_m)
    track = math.radians(loc.direction_deg)
    vel = np.array([loc.speed_horizontal_mps * math.sin(track), loc.speed_horizontal_mps * math.cos(track),
                    loc.speed_vertical_mps or 0.0])
    scene = Scene(kind="uav", profile=shipped_profiles().get(profile), snr_db=20.0, range_m=range_m,
                  radial_speed_mps=float(vel @ u), elevation_deg=ELEVATION_DEG)
    return RadarSite(lat_deg=float(lat), lon_deg=float(lon), alt_m=float(alt)), scene


def radar_return(site: RadarSite, scenes: list[Scene], start: datetime, seed: int = 7) -> Recording:
    """One dwell seeing every scene's target (their IQ summed), no Remote ID embedded."""
    preset = get_preset("paper")
    offset = max(0.0, math.floor(min(s.range_m for s in scenes) - 10.0))
    recs = [simulate(s, preset, seed + i, range_offset_m=offset, site=site, start_time=start)[0]
            for i, s in enumerate(scenes)]
    iq = sum((r.iq for r in recs[1:]), recs[0].iq)
    return replace(recs[0], iq=iq.astype(recs[0].iq.dtype), simulation=None)


def rewrite(src: Path, dst: Path, *, shift_m: float = 0.0, az_deg: float = 0.0, uas_id: str | None = None,
            sender: bytes | None = None, dt_s: float = 0.0) -> Path:
    """The pcap `src` with every Location moved `shift_m` horizontally towards azimuth `az_deg`,
    and optionally another UAS ID, transmitter address and a time shift (lengths unchanged)."""
    import pymap3d

    data = bytearray(src.read_bytes())
    d = _los(az_deg, 0.0) * shift_m
    for c in read_capture(src):
        rows = []
        for row in split_raw(c.raw):
            m = decode(row)
            if isinstance(m, Location) and m.latitude_deg is not None and shift_m:
                lat, lon, _ = pymap3d.enu2geodetic(d[0], d[1], 0.0, m.latitude_deg, m.longitude_deg, 0.0)
                row = encode(m.replace(latitude_deg=round(float(lat), 7), longitude_deg=round(float(lon), 7)))
            elif isinstance(m, BasicId) and uas_id is not None:
                row = encode(m.replace(uas_id=uas_id))
            rows.append(row)
        new = c.raw[:3] + b"".join(rows) if len(c.raw) > 25 else rows[0]
        at = data.find(c.raw)
        data[at:at + len(new)] = new
    if sender is not None:
        data = bytearray(bytes(data).replace(bytes.fromhex("84cca8604324"), sender))
    if dt_s:
        off = 24
        while off < len(data):
            sec, usec, incl, _ = struct.unpack_from("<IIII", data, off)
            t = sec * 1_000_000 + usec + round(dt_s * 1e6)
            struct.pack_into("<II", data, off, t // 1_000_000, t % 1_000_000)
            off += 16 + incl
    dst.write_bytes(bytes(data))
    return dst


def merge_pcaps(a: Path, b: Path, dst: Path) -> Path:
    """Two little-endian microsecond pcaps of one link type as one, packets in time order."""
    def records(path: Path) -> list[tuple[int, bytes]]:
        data = path.read_bytes()
        out, off = [], 24
        while off < len(data):
            sec, usec, incl, _ = struct.unpack_from("<IIII", data, off)
            out.append((sec * 1_000_000 + usec, data[off:off + 16 + incl]))
            off += 16 + incl
        return out

    head = a.read_bytes()[:24]
    dst.write_bytes(head + b"".join(r for _, r in sorted(records(a) + records(b), key=lambda x: x[0])))
    return dst


def beacons(dst: Path, frames: list[tuple[datetime, bytes, bytes]]) -> Path:
    """A pcap (802.11, link type 105) of Wi-Fi beacons, one per (capture time, transmitter address,
    Open Drone ID payload: a single message or a pack), each in its own vendor IE."""
    from remoteid.capture import ODID_OUI_TYPE

    out = b"\xd4\xc3\xb2\xa1" + struct.pack("<HHiIII", 2, 4, 0, 0, 65535, 105)
    for n, (at, sender, payload) in enumerate(frames):
        ie = ODID_OUI_TYPE + bytes([n % 256]) + payload
        frame = b"\x80\x00" + bytes(2) + b"\xff" * 6 + sender + sender + bytes(2) + bytes(12) + \
            bytes([221, len(ie)]) + ie
        t = round(at.timestamp() * 1e6)
        out += struct.pack("<IIII", t // 1_000_000, t % 1_000_000, len(frame), len(frame)) + frame
    dst.write_bytes(out)
    return dst


def start_at(c: CapturedMessage) -> datetime:
    """A dwell starting when the capture heard `c` (its Location is the one nearest mid-dwell)."""
    return c.captured_at - timedelta(seconds=0.0)


def crowd(dst: Path, at: datetime, n: int) -> Path:
    """A capture of `n` drones heard at `at`: each one Basic ID (serial CROWD00000, CROWD00001, ...)
    from its own transmitter."""
    return beacons(dst, [(at, bytes([2, 0, 0, 0, i // 256, i % 256]), encode(BasicId(id_type=1, ua_type=2,
                                                                                     uas_id=f"CROWD{i:05d}")))
                         for i in range(n)])


def heard_at(src: Path, dst: Path, value: float | int) -> Path:
    """The HDF5 return `src` with its Remote ID marked as captured and every message heard `value` s
    after start_time, written by h5py (write_recording refuses such times)."""
    import h5py

    dst.write_bytes(src.read_bytes())
    with h5py.File(dst, "a") as f:
        n = f["remote_id"].shape[0]
        del f["remote_id_time_s"]
        f.create_dataset("remote_id_time_s", data=np.full(n, value, np.int64 if isinstance(value, int) else np.float64))
        f.attrs["remote_id_source"] = "capture"
    return dst
