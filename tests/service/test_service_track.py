"""`POST /v1/checks:track` against a real server: one decision over a track's dwells, recorded
as one audit entry before it is answered; the single check's keys, roles and limits."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.service.server import M300, M600

DWELLS = 5


@pytest.fixture(scope="module")
def tracks(tmp_path_factory) -> dict[str, list[Path]]:
    from lab.bench.track import track_recordings
    from signatures.profiles import shipped_profiles
    from signatures.recording import write_recording
    from signatures.scene import Scene

    root = tmp_path_factory.mktemp("tracks")
    out: dict[str, list[Path]] = {}
    for name, flies, serial, seed in (("genuine", "m300", M300, 40), ("type", "phantom4", M600, 60)):
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
        assert genuine.status_code == spoof.status_code == 200, genuine.text
        g, s = genuine.json(), spoof.json()
        entry = c.get(f"/v1/audit/{g['audit_id']}")
    assert g["decision"] == "accept" and g["track"] and 1 < g["dwells_used"] < DWELLS
    assert g["skipped_files"] == [p.name for p in tracks["genuine"][g["dwells_used"]:]]
    assert s["decision"] == "reject" and s["reasons"] == ["radar-claim-inconsistent"]
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
