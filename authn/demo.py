"""`authn demo`: register example identities, simulate six telling scenes, check each.

Scenes (paper preset, SNR 15 dB): a genuine flight, a spoofed type (a Phantom 4
broadcasting an M600's serial), a spoofed position (Remote ID 300 m beyond where
the radar sees the drone), an unregistered serial, a revoked one, and a bird
checked against a registered serial.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from authn.scenario import Broadcast, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.scene import Scene

IDENTITIES = (  # serial, model, status
    ("1581BDEM00000001", "m600", "active"),
    ("1581BDEM00000002", "m300", "active"),
    ("1581BDEM00000003", "phantom4", "revoked"),
)
UNREGISTERED = "1581BDEM00000099"
VALID_FROM = datetime(2025, 1, 1, tzinfo=timezone.utc)


@dataclass(frozen=True)
class DemoScene:
    name: str
    model: str  # what really flies
    serial: str  # what it claims
    expected: str  # accept | reject
    range_m: float
    speed: float
    offset_m: float = 0.0
    broadcast: bool = True


SCENES = (
    DemoScene("genuine M300", "m300", "1581BDEM00000002", "accept", 420.0, 4.0),
    DemoScene("Phantom 4 claiming an M600", "phantom4", "1581BDEM00000001", "reject", 350.0, -3.0),
    DemoScene("position spoofed by 300 m", "m600", "1581BDEM00000001", "reject", 610.0, 2.5, offset_m=300.0),
    DemoScene("unregistered serial", "m300", UNREGISTERED, "reject", 500.0, 0.0),
    DemoScene("revoked serial", "phantom4", "1581BDEM00000003", "reject", 280.0, 1.5),
    DemoScene("bird checked as the M300", "bird", "1581BDEM00000002", "reject", 150.0, 6.0, broadcast=False),
)


def register_examples(db_url: str | None) -> None:
    """Idempotent: existing serials are left as they are."""
    from registry.db import session_scope
    from registry.store import NewIdentity, get_identity, register_identity, revoke_identity

    with session_scope(db_url) as s:
        for serial, model, status in IDENTITIES:
            if get_identity(s, serial) is None:
                register_identity(s, NewIdentity(serial=serial, model=model, operator_id="DEMO-OPERATOR",
                                                 valid_from=VALID_FROM, notes="authn demo"))
                if status == "revoked":
                    revoke_identity(s, serial, "demo: revoked identity")


def write_scenes(out: Path, seed: int = 2026) -> list[tuple[DemoScene, Path]]:
    pre = get_preset("paper")
    profiles = shipped_profiles()
    now = datetime.now(timezone.utc)
    written = []
    for i, sc in enumerate(SCENES):
        kind = "bird" if sc.model == "bird" else "uav"
        scene = Scene(kind=kind, profile=profiles.get(sc.model), range_m=sc.range_m, radial_speed_mps=sc.speed,
                      snr_db=15.0, clutter_db=10.0, elevation_deg=12.0)
        bc = Broadcast(serial=sc.serial, offset_along_los_m=sc.offset_m) if sc.broadcast else None
        rec, _ = simulate_flight(scene, pre, seed + i, bc, azimuth_deg=35.0 + 40 * i, start_time=now)
        path = out / f"{i + 1}-{sc.name.replace(' ', '-')}.h5"
        write_recording(rec, path)
        written.append((sc, path))
    return written
