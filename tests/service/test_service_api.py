"""`authn serve` end to end: a real uvicorn process, real HTTP, every endpoint, auth, bad uploads.

One upload is a track of one dwell, decided by Wald's sequential test: at the default targets one
unsigned dwell (capped at +-4 nats) neither reaches the accept bound (6.90 nats) nor the reject
bound (-4.61), so the returns here are `inconclusive` (HTTP 200, as accept and reject are); the
genuine M300 also has the M600, which radar confuses with it, registered beside it. The form
fields `false_accept` and `false_reject` (0.02: +-3.89 nats) let one dwell refute a type spoof."""

from __future__ import annotations

import json
import shutil

import h5py
import numpy as np

from authn.cli import main
from tests.service.server import M300

CONTRACT_KEYS = {"decision", "reasons", "claim", "registry", "radar", "kinematics", "skipped", "timings_ms", "audit_id"}
#: A genuine unsigned M300 claim where an M600 is registered, at the default targets.
UNDECIDED = ["radar-confusable-unsigned", "radar-inconclusive"]


def _upload(path, name=None, mime="application/x-hdf5"):
    return {"file": (name or path.name, path.read_bytes(), mime)}


def _one_line_error(resp) -> str:
    doc = resp.json()
    assert set(doc) == {"error"}, doc
    assert doc["error"] and "\n" not in doc["error"] and "Traceback" not in doc["error"]
    return doc["error"]


def test_ready_within_seconds_of_start(server) -> None:
    """Start-up to /readyz green: the issue asks < 3 s; asserted generously on a shared CI box."""
    assert server.ready_s < 10.0, server.ready_s
    with server.client() as c:
        assert c.get("/healthz").json()["status"] == "ok"
        ready = c.get("/readyz").json()
    assert ready["ready"] and ready["migrations_current"] and "paper" in ready["models"]


def test_check_answers_the_cli_json_object(server, keys, returns, sqlite_db, capsys) -> None:
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_upload(returns["genuine"]))
        assert resp.status_code == 200, resp.text
        out = resp.json()
        entry = c.get(f"/v1/audit/{out['audit_id']}").json()
    assert out["decision"] == "inconclusive" and out["reasons"] == UNDECIDED
    assert out["file"] == "genuine.h5" and out["claim"]["serial"] == M300
    capsys.readouterr()
    assert main(["--db", sqlite_db, "check", str(returns["genuine"]), "--json"]) == 4
    cli = json.loads(capsys.readouterr().out)
    assert CONTRACT_KEYS | {"to_decide"} <= set(out) and set(out) == set(cli)
    fields = ("decision", "reasons", "file_sha256", "to_decide")
    assert [out[k] for k in fields] == [cli[k] for k in fields]
    assert "read" in out["timings_ms"] and "audit" in out["timings_ms"]
    assert entry["kind"] == "decision" and entry["payload"]["file_sha256"] == out["file_sha256"]
    assert entry["decision"] == "inconclusive"


def test_reject_is_200_with_reasons(server, keys, returns) -> None:
    """A Phantom 4 claiming an M600: its one dwell, capped at -4 nats, is inconclusive with the
    evidence against it (refuting reads the alternatives together, and the registered M300 explains the
    dwell as well as the M600 claim); an unregistered serial is rejected. Both are answers, 200, with
    their reasons."""
    with server.client(keys.operator) as c:
        unsure = c.post("/v1/checks", files=_upload(returns["type"]))
        resp = c.post("/v1/checks", files=_upload(returns["type"]), data={"serial": "1581BDEM00000099"})
    assert unsure.status_code == 200 and unsure.json()["decision"] == "inconclusive"
    assert "radar-inconclusive" in unsure.json()["reasons"] and unsure.json()["to_decide"]["llr_nats"] < 0
    assert resp.status_code == 200 and resp.json()["decision"] == "reject"
    assert "unregistered" in resp.json()["reasons"] and resp.json()["radar"] is None


def test_claimed_serial_form_field(server, keys, returns) -> None:
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks", files=_upload(returns["genuine"]), data={"serial": "1581BDEM00000001"})
    assert resp.status_code == 200 and resp.json()["claim"]["serial"] == "1581BDEM00000001"


def _nan_return(src, dst):
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        iq = f["iq"][...]
        iq[3, 5] = np.nan
        f["iq"][...] = iq
    return dst


def test_bad_uploads_are_4xx_one_line_and_audited(server, keys, returns, tmp_path) -> None:
    nan = _nan_return(returns["genuine"], tmp_path / "nan.h5")
    with server.client(keys.operator) as c:
        before = c.get("/v1/audit", params={"limit": 500}).json()["entries"]
        junk = c.post("/v1/checks", files={"file": ("junk.h5", b"not an HDF5 file at all", "application/x-hdf5")})
        nan_resp = c.post("/v1/checks", files=_upload(nan))
        pickled = b"\x80\x04\x95" + b"x" * 64
        pickle = c.post("/v1/checks", files={"file": ("p.npz", pickled, "application/octet-stream")})
        big = c.post("/v1/checks", files={"file": ("big.h5", b"\0" * (5 * 2**20), "application/x-hdf5")})
        as_json = c.post("/v1/checks", json={"file": "genuine.h5"})
        no_file = c.post("/v1/checks", files={"other": ("x", b"x")}, data={"serial": M300})
        after = c.get("/v1/audit", params={"after": before[-1]["seq"] if before else 0}).json()["entries"]
    assert junk.status_code == 400 and "junk.h5" in _one_line_error(junk)
    assert nan_resp.status_code == 400 and "non-finite" in _one_line_error(nan_resp)
    assert pickle.status_code == 400 and _one_line_error(pickle)
    assert big.status_code == 413 and "limit" in _one_line_error(big)
    assert as_json.status_code == 415 and _one_line_error(as_json)
    assert no_file.status_code == 422 and "file" in _one_line_error(no_file)
    errors = [e for e in after if e["kind"] == "error"]
    assert [e["payload"]["file"] for e in errors] == ["junk.h5", "nan.h5", "p.npz"]
    assert all(e["payload"]["error_kind"] == "bad-input" for e in errors)
    assert server.proc.poll() is None


def test_slow_upload_is_cut_off_and_blocks_nothing(server, keys) -> None:
    """A client that stops sending its body gets 408 after the upload timeout (3 s here);
    meanwhile the same worker answers others."""
    import socket
    import time
    from urllib.parse import urlsplit

    url = urlsplit(server.url)
    head = (f"POST /v1/checks HTTP/1.1\r\nHost: {url.netloc}\r\nAuthorization: Bearer {keys.operator}\r\n"
            "Content-Type: multipart/form-data; boundary=b\r\nContent-Length: 100000\r\n\r\n--b\r\n")
    with socket.create_connection((url.hostname, url.port), timeout=30) as sock:
        t0 = time.monotonic()
        sock.sendall(head.encode())
        with server.client() as c:
            assert c.get("/healthz").status_code == 200 and time.monotonic() - t0 < 2.0
        reply = sock.recv(65536)
        waited = time.monotonic() - t0
        while chunk := sock.recv(65536):  # the head and the body may come in separate segments
            reply += chunk
    status, _, rest = reply.decode().partition("\r\n")
    assert status == "HTTP/1.1 408 Request Timeout" and 2.5 < waited < 15.0, (reply, waited)
    assert json.loads(rest.split("\r\n\r\n", 1)[1]) == {"error": "upload not received within 3 s"}


def test_batch_answers_each_file_in_order(server, keys, returns) -> None:
    files = [("files", ("a.h5", returns["genuine"].read_bytes(), "application/x-hdf5")),
             ("files", ("junk.h5", b"junk", "application/x-hdf5")),
             ("files", ("b.h5", returns["type"].read_bytes(), "application/x-hdf5"))]
    with server.client(keys.operator) as c:
        resp = c.post("/v1/checks:batch", files=files)
        results = resp.json()["results"]
        ids = [r["audit_id"] for r in results if "audit_id" in r]
    assert resp.status_code == 200
    assert [r["file"] for r in results] == ["a.h5", "junk.h5", "b.h5"]
    # one unsigned dwell each at the default targets: neither the genuine nor the spoof is decided
    assert [r.get("decision", "error") for r in results] == ["inconclusive", "error", "inconclusive"]
    assert results[0]["to_decide"]["llr_nats"] > 0 > results[2]["to_decide"]["llr_nats"]
    assert results[1]["exit_code"] == 2 and "junk.h5" in results[1]["error"]
    assert ids[1] == ids[0] + 2  # the failed file's entry lies between them, one transaction


def test_auth_401_and_403(server, keys, sqlite_db) -> None:
    from authn.service.keys import create_key, revoke_key

    revoked, token = create_key(sqlite_db, "admin", "to-revoke")
    with server.client() as c:
        assert c.get("/v1/audit").status_code == 401
        assert c.get("/v1/audit", headers={"Authorization": "Bearer nope"}).status_code == 401
        assert c.get("/v1/audit", headers={"Authorization": f"Basic {keys.admin}"}).status_code == 401
        assert c.get("/v1/audit", headers={"X-API-Key": keys.operator}).status_code == 200
        assert c.get("/v1/profiles", headers={"X-API-Key": token}).status_code == 200
        revoke_key(sqlite_db, revoked.id)
        resp = c.get("/v1/profiles", headers={"X-API-Key": token})
        assert resp.status_code == 401 and resp.headers["www-authenticate"] == "Bearer"
        _one_line_error(resp)
    with server.client(keys.operator) as c:
        for method, path in (("POST", "/v1/audit:checkpoint"), ("GET", "/v1/identities"),
                             ("POST", f"/v1/identities/{M300}:revoke"), ("GET", "/v1/profiles")):
            resp = c.request(method, path)
            assert resp.status_code == 403 and "operator" in _one_line_error(resp), (method, path)
        assert c.post("/v1/identities", json={"serial": "1581BDEM00000077", "model": "m300"}).status_code == 403


def test_registry_changes_are_audited_with_the_key(server, keys) -> None:
    serial = "1581BDEM00000077"
    with server.client(keys.admin) as c:
        created = c.post("/v1/identities", json={"serial": serial, "model": "m600", "notes": "api"})
        dup = c.post("/v1/identities", json={"serial": serial, "model": "m600"})
        bad_model = c.post("/v1/identities", json={"serial": "1581BDEM00000078", "model": "nope"})
        got = c.get(f"/v1/identities/{serial}").json()
        listed = [r["serial"] for r in c.get("/v1/identities").json()]
        revoked = c.post(f"/v1/identities/{serial}:revoke", json={"reason": "stolen"})
        again = c.post(f"/v1/identities/{serial}:revoke")
        missing = c.get("/v1/identities/1581BDEM00000099")
        slugs = {p["slug"] for p in c.get("/v1/profiles").json()}
        entries = c.get("/v1/audit", params={"serial": serial}).json()["entries"]
    assert created.status_code == 201 and created.json()["status"] == "active"
    assert dup.status_code == 400 and "already registered" in _one_line_error(dup)
    assert bad_model.status_code == 400 and "unknown model" in _one_line_error(bad_model)
    assert got["model"] == "m600" and serial in listed and M300 in listed
    assert revoked.status_code == 200 and revoked.json()["status"] == "revoked"
    assert again.status_code == 400 and missing.status_code == 404
    assert {"m300", "m600", "phantom4"} <= slugs
    # write-ahead: every attempt is logged before it runs, a failed one is followed by its reason
    assert [(e["kind"], e["payload"]["action"], e["payload"]["api_key_id"]) for e in entries] == \
        [("registry", a, keys.admin_id) for a in ("register", "register", "register-failed", "revoke", "revoke",
                                                   "revoke-failed")]
    assert "already registered" in entries[2]["payload"]["error"]


def test_audit_paging_verify_and_checkpoint(server, keys, returns, sqlite_db) -> None:
    with server.client(keys.operator) as c:
        for _ in range(3):
            assert c.post("/v1/checks", files=_upload(returns["genuine"])).status_code == 200
        first = c.get("/v1/audit", params={"limit": 2}).json()
        second = c.get("/v1/audit", params={"limit": 2, "after": first["next_after"]}).json()
        assert c.get("/v1/audit/999999").status_code == 404
        verified = c.get("/v1/audit:verify").json()
    with server.client(keys.admin) as c:
        sth = c.post("/v1/audit:checkpoint").json()
    assert [e["seq"] for e in first["entries"]] == [1, 2] and first["next_after"] == 2
    assert [e["seq"] for e in second["entries"]] == [3, 4]
    assert verified["ok"] and verified["size"] >= 5 and verified["problem"] is None
    assert sth["format"] == "authn-checkpoint/1" and sth["tree_size"] == verified["size"]
    assert main(["--db", sqlite_db, "audit", "verify"]) == 0


def test_metrics_docs_and_errors(server, keys, returns) -> None:
    with server.client(keys.operator) as c:
        assert c.post("/v1/checks", files=_upload(returns["genuine"])).status_code == 200
        text = c.get("/metrics").text
        assert c.get("/docs").status_code == 200
        paths = set(c.get("/openapi.json").json()["paths"])
        not_found = c.get("/v1/nothing")
    assert 'authn_checks_total{decision="inconclusive"}' in text
    assert 'authn_check_stage_seconds_bucket{le="0.005",stage="radar_features"}' in text
    assert 'authn_check_reasons_total{decision="inconclusive",reason="radar-inconclusive"}' in text
    assert "authn_errors_total" in text
    assert {"/v1/checks", "/v1/checks:batch", "/v1/audit", "/v1/audit/{seq}", "/v1/audit:verify",
            "/v1/audit:checkpoint", "/v1/identities", "/v1/identities/{serial}", "/v1/identities/{serial}:revoke",
            "/v1/profiles", "/healthz", "/readyz", "/metrics"} <= paths
    assert not_found.status_code == 404 and _one_line_error(not_found)


def test_no_secret_in_the_log(server, keys) -> None:
    with server.client(keys.admin) as c:
        c.get("/v1/audit", params={"limit": 1})
    log = server.log.read_text()
    assert keys.admin not in log and keys.operator not in log
