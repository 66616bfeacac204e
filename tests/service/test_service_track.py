"""`POST /v1/checks:track` against a real server: one decision over a track's dwells, recorded
as one audit entry before it is answered; the single check's keys, roles and limits.

Wald's sequential test at the default targets: no dwell counts more than 4 nats, so a genuine
track is accepted on its third dwell at the earliest (12 / 1.4 = 8.6 >= 6.90 nats). Radar can
accept only a claim it can tell from every model registered at the site: the genuine track here
is a Phantom 4 (registered for this module beside the example M300 and M600), while an unsigned
M300 claim, which radar confuses with the M600, stops inconclusive once the radar favours it."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.service.server import M300, M600

DWELLS = 5
P4 = "1581BDEM00000004"  # an active Phantom 4, registered by `tracks`


@pytest.fixture(scope="module")
def tracks(tmp_path_factory, sqlite_db) -> dict[str, list[Path]]:
    from datetime import datetime, timezone

    from lab.bench.track import track_recordings
    from registry.dbapi import transaction
    from registry.store import NewIdentity, register_identity
    from signatures.profiles import shipped_profiles
    from signatures.recording import write_recording
    from signatures.sim.scene import Scene

    with transaction(sqlite_db) as s:
        register_identity(s, NewIdentity(serial=P4, model="phantom4", operator_id="TEST",
                                         valid_from=datetime(2020, 1, 1, tzinfo=timezone.utc)))
    root = tmp_path_factory.mktemp("tracks")
    out: dict[str, list[Path]] = {}
    for name, flies, serial, seed in (("genuine", "phantom4", P4, 40), ("type", "phantom4", M600, 60),
                                      ("confusable", "m300", M300, 40)):
        sc = Scene(kind="uav", profile=shipped_profiles()[flies], snr_db=20.0, range_m=400.0, radial_speed_mps=3.0)
        recs = track_recordings(sc, "paper", list(range(seed, seed + DWELLS)), serial)
        out[name] = [write_recording(r, root / f"{name}-{i}.h5") for i, r in enumerate(recs)]
    return out


def _files(paths: list[Path]) -> list[tuple[str, tuple[str, bytes]]]:
    return [("files", (p.name, p.read_bytes())) for p in paths]


def test_a_track_is_decided_and_recorded_once(server, keys, tracks) -> None:
    with server.client(keys.operator) as c:
        genuine = c.post("/v1/checks:track", files=_files(tracks["genuine"]))
        spoof = c.post("/v1/checks:track", files=_files(tracks["type"]))
        unsure = c.post("/v1/checks:track", files=_files(tracks["confusable"]))
        assert genuine.status_code == spoof.status_code == unsure.status_code == 200, genuine.text
        g, s, u = genuine.json(), spoof.json(), unsure.json()
        entry = c.get(f"/v1/audit/{g['audit_id']}")
        unsure_entry = c.get(f"/v1/audit/{u['audit_id']}")
    assert g["decision"] == "accept" and g["reasons"] == ["registered-active"] and g["track"]
    assert 3 <= g["dwells_used"] < DWELLS and g["llr"] >= 6.90 + 1.0  # decided early, with a margin
    assert g["skipped_files"] == [p.name for p in tracks["genuine"][g["dwells_used"]:]]
    # the Phantom 4 claiming the M600 is refuted (the M600 claim is also radar-confusable with the M300)
    assert s["decision"] == "reject" and s["reasons"] == ["radar-claim-inconsistent", "radar-confusable-unsigned"]
    assert u["decision"] == "inconclusive" and u["reasons"] == ["radar-confusable-unsigned", "radar-inconclusive"]
    assert u["to_decide"]["llr_nats"] > 0 and unsure_entry.json()["decision"] == "inconclusive"
    assert entry.status_code == 200
    recorded = entry.json()["payload"]
    assert [d["file_sha256"] for d in recorded["dwells"]] == [d["file_sha256"] for d in g["dwells"]]


def test_a_bad_track_is_400_and_the_roles_hold(server, keys, tracks) -> None:
    with server.client(keys.operator) as c:
        mixed = c.post("/v1/checks:track", files=_files([tracks["genuine"][0], tracks["type"][1]]))
        backwards = c.post("/v1/checks:track", files=_files(tracks["genuine"][1::-1]))
        loose = c.post("/v1/checks:track", files=_files(tracks["genuine"]), data={"false_accept": "0.7"})
    assert mixed.status_code == 400 and "one claim" in mixed.json()["error"]
    assert backwards.status_code == 400 and "time order" in backwards.json()["error"]
    assert loose.status_code == 422
    with server.client() as anonymous:
        assert anonymous.post("/v1/checks:track", files=_files(tracks["genuine"])).status_code == 401
