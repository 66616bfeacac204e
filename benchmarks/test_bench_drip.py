"""DRIP verification cost (target: < 0.5 ms a check; one Ed25519 verification ~0.1 ms): `verify` on
decoded rows, and the check's whole authentication stage on a signed recording."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from authn import uakeys
from remoteid import BasicId, Location, decode_rows_raw, encode
from remoteid.drip import (
    det_from_public_key,
    encode_link,
    encode_manifest,
    encode_wrapper,
    paginate,
    verify,
)

T = datetime(2026, 5, 1, 12, tzinfo=timezone.utc)
SK = Ed25519PrivateKey.from_private_bytes(bytes(range(32)))
PK = SK.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
DET = det_from_public_key(PK, 10, 20)
UA = uakeys.generate()
SERIAL = "1581BDEM00000002"
MSGS = [encode(BasicId(uas_id="1596F0000000000001")),
        encode(Location(latitude_deg=52.52, longitude_deg=13.405, timestamp_s=12.0))]


def _rows(auth_data: bytes) -> list:
    return decode_rows_raw([*MSGS, *paginate(auth_data, T)])


def test_verify_wrapper(benchmark) -> None:
    rows = _rows(encode_wrapper(MSGS, DET, SK, T - timedelta(seconds=5), T + timedelta(seconds=60)))
    assert benchmark(verify, rows, lambda det: PK, T).status == "valid"


def test_verify_manifest(benchmark) -> None:
    rows = _rows(encode_manifest(MSGS, DET, SK, T - timedelta(seconds=5), T + timedelta(seconds=60)))
    assert benchmark(verify, rows, lambda det: PK, T).status == "valid"


def test_verify_link_and_wrapper(benchmark) -> None:
    hda = Ed25519PrivateKey.from_private_bytes(bytes(range(32, 64)))
    hda_pk = hda.public_key().public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
    hda_det = det_from_public_key(hda_pk, 10, 0)
    link = encode_link(DET, PK, hda_det, hda, T - timedelta(days=1), T + timedelta(days=1))
    wrapper = encode_wrapper(MSGS, DET, SK, T - timedelta(seconds=5), T + timedelta(seconds=60))
    rows = decode_rows_raw([*MSGS, *paginate(wrapper, T), *paginate(link, T)])
    result = benchmark(verify, rows, lambda det: None, T, trusted_registry_keys={hda_det: hda_pk})
    assert result.sam_types == ("link", "wrapper")


# --- the check's authentication stage on a simulated recording ------------------------------
# What `authn check` spends on Remote ID before the policy: decoding the claim from the recording
# (`read_claim`) and DRIP verification against the claimed identity's registered key
# (`authenticate`), for each SAM type and, for comparison, an unsigned broadcast.


@pytest.fixture(scope="module")
def recordings() -> dict[str, object]:
    from authn.scenario import Broadcast, Signing, simulate_flight
    from signatures.profiles import shipped_profiles
    from signatures.radar import get_preset
    from signatures.sim.scene import Scene

    scene = Scene(profile=shipped_profiles()["m300"], range_m=420.0, radial_speed_mps=4.0, snr_db=15.0)
    out = {}
    for sam in (None, "wrapper", "manifest", "frame"):
        signing = Signing(private_key=UA.private_raw, det=UA.det, sam=sam) if sam else None
        rec, _ = simulate_flight(scene, get_preset("paper"), 1, Broadcast(serial=SERIAL, signing=signing),
                                 start_time=T)
        out[sam or "unsigned"] = rec
    return out


def _auth_stage(rec, facts):
    from authn.evidence import authenticate, read_claim

    return authenticate(read_claim(rec, None), facts, rec.mid_time)


@pytest.mark.parametrize("sam", ["unsigned", "wrapper", "manifest", "frame"])
def test_check_auth_stage(benchmark, recordings, sam: str) -> None:
    from authn.evidence import RegistryFacts
    from registry.dbapi import IdentityFacts

    facts = RegistryFacts(IdentityFacts("1581F000", "serial", "m300", "active", T - timedelta(days=365), None,
                                        UA.public_raw))
    auth = benchmark(_auth_stage, recordings[sam], facts)
    assert auth.status == ("absent" if sam == "unsigned" else "valid")
    assert sam == "unsigned" or auth.sam_types == (sam,)
