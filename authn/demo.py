"""`authn demo`: register example identities, simulate nine telling scenes, check each.

Scenes (paper preset, SNR 15 dB): a genuine flight, a spoofed type (a Phantom 4
broadcasting an M600's serial), a spoofed position (Remote ID 300 m beyond where
the radar sees the drone), an unregistered serial, a revoked one, and a bird
checked against a registered serial. Then signed Remote ID (IETF DRIP, RFC 9575): an
M300 registered with a key flies and signs with it; another M300 broadcasts its
identity, unsigned and then signed with its own (wrong) key, a same-type impersonation
the radar cannot see through and the signature can.

The DRIP keys are generated in memory on every run, and the keyed identity is
registered under its DRIP session ID (the UAS ID that names the key's DET), so a
run never depends on a key an earlier run threw away.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from authn import uakeys
from authn.scenario import Broadcast, Signing, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

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
    expected: str  # accept | reject | inconclusive
    range_m: float
    speed: float
    offset_m: float = 0.0
    broadcast: bool = True
    signer: str | None = None  # DRIP: None unsigned, "owner" the keyed identity's key, "impersonator" another


#: What the DRIP scenes claim: the keyed M300's session ID, known only once its key exists.
KEYED_M300 = "keyed M300"


@dataclass(frozen=True)
class DemoKeys:
    """This run's DRIP keys: the registered M300's and an impersonator's (never registered)."""

    owner: uakeys.UaKey
    impersonator: uakeys.UaKey

    @classmethod
    def generate(cls) -> "DemoKeys":
        return cls(uakeys.generate(), uakeys.generate())


SCENES = (
    # one unsigned dwell never decides on radar alone at the default error targets (docs/policies.md)
    DemoScene("genuine M300", "m300", "1581BDEM00000002", "inconclusive", 420.0, 4.0),
    DemoScene("Phantom 4 claiming an M600", "phantom4", "1581BDEM00000001", "inconclusive", 350.0, -3.0),
    DemoScene("position spoofed by 300 m", "m600", "1581BDEM00000001", "reject", 610.0, 2.5, offset_m=300.0),
    DemoScene("unregistered serial", "m300", UNREGISTERED, "reject", 500.0, 0.0),
    DemoScene("revoked serial", "phantom4", "1581BDEM00000003", "reject", 280.0, 1.5),
    DemoScene("bird checked as the M300", "bird", "1581BDEM00000002", "inconclusive", 150.0, 6.0, broadcast=False),
    DemoScene("genuine signed M300 (DRIP)", "m300", KEYED_M300, "accept", 450.0, 3.0, signer="owner"),
    DemoScene("M300 claiming the keyed M300, unsigned", "m300", KEYED_M300, "reject", 380.0, -2.0),
    DemoScene("M300 claiming the keyed M300, own key", "m300", KEYED_M300, "reject", 520.0, 3.5,
              signer="impersonator"),
)


def register_examples(db_url: str | None, keys: DemoKeys | None = None) -> None:
    """Idempotent: existing serials are left as they are. With `keys`, also the keyed M300
    (its DRIP session ID, the owner's public key): a new identity for every new key."""
    from registry.dbapi import transaction
    from registry.store import NewIdentity, get_identity, register_identity, revoke_identity

    with transaction(db_url) as s:
        if keys is not None and get_identity(s, keys.owner.session_id) is None:
            register_identity(s, NewIdentity(serial=keys.owner.session_id, id_type="specific_session", model="m300",
                                             operator_id="DEMO-OPERATOR", public_key=keys.owner.public_raw,
                                             valid_from=VALID_FROM, notes="authn demo: DRIP key of one run"))
        for serial, model, status in IDENTITIES:
            if get_identity(s, serial) is None:
                register_identity(s, NewIdentity(serial=serial, model=model, operator_id="DEMO-OPERATOR",
                                                 valid_from=VALID_FROM, notes="authn demo"))
                if status == "revoked":
                    revoke_identity(s, serial, "demo: revoked identity")


def _broadcast(sc: DemoScene, keys: DemoKeys | None) -> Broadcast | None:
    if not sc.broadcast:
        return None
    if sc.serial != KEYED_M300:
        return Broadcast(serial=sc.serial, offset_along_los_m=sc.offset_m)
    if keys is None:
        raise ValueError(f"scene {sc.name!r} needs this run's DRIP keys")
    signing = None
    if sc.signer is not None:
        key = keys.owner if sc.signer == "owner" else keys.impersonator
        signing = Signing(private_key=key.private_raw, det=key.det)
    return Broadcast(serial=keys.owner.session_id, id_type=4, offset_along_los_m=sc.offset_m, signing=signing)


def claimed_serial(sc: DemoScene, keys: DemoKeys | None) -> str:
    return keys.owner.session_id if sc.serial == KEYED_M300 and keys is not None else sc.serial


def write_scenes(out: Path, seed: int = 2026, keys: DemoKeys | None = None) -> list[tuple[DemoScene, Path]]:
    """Every scene of `SCENES` (the DRIP ones only with `keys`) as a recording under `out`."""
    pre = get_preset("paper")
    profiles = shipped_profiles()
    now = datetime.now(timezone.utc)
    written = []
    for i, sc in enumerate(SCENES):
        if sc.serial == KEYED_M300 and keys is None:
            continue
        kind = "bird" if sc.model == "bird" else "uav"
        scene = Scene(kind=kind, profile=profiles.get(sc.model), range_m=sc.range_m, radial_speed_mps=sc.speed,
                      snr_db=15.0, clutter_db=10.0, elevation_deg=12.0)
        bc = _broadcast(sc, keys)
        rec, _ = simulate_flight(scene, pre, seed + i, bc, azimuth_deg=35.0 + 40 * i, start_time=now)
        path = out / f"{i + 1}-{re.sub(r'[^A-Za-z0-9]+', '-', sc.name).strip('-')}.h5"
        write_recording(rec, path)
        written.append((sc, path))
    return written
