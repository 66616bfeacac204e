"""Requests that would fan out past a cap are 413, audited, and decide nothing: a `rid_capture`
naming more drones than the server's `--max-drones` (default 64), and a `:batch` of more files
than its limit (64). A return whose captured message times no datetime can hold is a bad
recorded return (400, audited), not a 503. The real server, real pcap bytes, simulated returns."""

from __future__ import annotations

import pytest

from signatures.recording import read_recording
from tests.remoteid.capture_tools import crowd, heard_at
from tests.service.server import flight


@pytest.fixture(scope="module")
def crowds(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("svc-caps")
    ret = flight(root, "f", "m300", None)
    at = read_recording(ret).start_time
    return {"ret": ret, "65": crowd(root / "65.pcap", at, 65), "64": crowd(root / "64.pcap", at, 64)}


def _newest(c, after: int) -> list[dict]:
    return c.get("/v1/audit", params={"after": after, "limit": 500}).json()["entries"]


def _last_seq(c) -> int:
    seq, after = 0, 0
    while after is not None:
        page = c.get("/v1/audit", params={"after": after, "limit": 500}).json()
        seq = page["entries"][-1]["seq"] if page["entries"] else seq
        after = page["next_after"]
    return seq


def _post(c, ret, capture):
    return c.post("/v1/checks", files={"file": (ret.name, ret.read_bytes(), "application/x-hdf5"),
                                       "rid_capture": (capture.name, capture.read_bytes(), "application/octet-stream")})


def test_a_capture_over_the_drone_limit_is_413_and_audited(server, keys, crowds) -> None:
    with server.client(keys.operator) as c:
        before = _last_seq(c)
        resp = _post(c, crowds["ret"], crowds["65"])
        assert resp.status_code == 413, resp.text
        error = resp.json()["error"]
        assert "65 drones heard" in error and "limit of 64" in error and "--max-drones" in error
        new = _newest(c, before)
        assert [e["kind"] for e in new] == ["error"] and "65 drones" in new[0]["payload"]["error"]
        resp = _post(c, crowds["ret"], crowds["64"])  # at the limit: one decision each
        assert resp.status_code == 200 and len(resp.json()) == 64


@pytest.mark.parametrize("value", [1e15, -1e15, 2**62])
def test_captured_message_times_beyond_datetime_are_400_and_audited(server, keys, tmp_path, value) -> None:
    good = flight(tmp_path, "g", "m300", "1581F5FJD12345678901")
    bad = heard_at(good, tmp_path / "t.h5", value)
    with server.client(keys.operator) as c:
        before = _last_seq(c)
        resp = c.post("/v1/checks", files={"file": (bad.name, bad.read_bytes(), "application/x-hdf5")})
        assert resp.status_code == 400, resp.text
        assert "remote_id_time_s" in resp.json()["error"] and "from start_time" in resp.json()["error"]
        new = _newest(c, before)
    assert [e["kind"] for e in new] == ["error"] and new[0]["payload"]["error_kind"] == "bad-input"


def test_a_batch_over_the_file_limit_is_413_and_audited(server, keys) -> None:
    files = [("files", (f"r{i}.h5", b"not read", "application/x-hdf5")) for i in range(65)]
    with server.client(keys.operator) as c:
        before = _last_seq(c)
        resp = c.post("/v1/checks:batch", files=files)
        assert resp.status_code == 413, resp.text
        assert "65 files" in resp.json()["error"] and "limit of 64" in resp.json()["error"]
        new = _newest(c, before)
    assert [e["kind"] for e in new] == ["error"] and new[0]["payload"]["file"] == "checks:batch"
