"""The service reads a claimed serial as the CLI does (`core.uasid.normalise`): lower case is
the registered drone, a malformed one is a 422 with a one-line error."""

from __future__ import annotations

from tests.service.server import M300


def test_serial_form_field_normalised_or_422(server, keys, returns) -> None:
    upload = {"file": ("genuine.h5", returns["genuine"].read_bytes(), "application/x-hdf5")}
    with server.client(keys.operator) as c:
        lower = c.post("/v1/checks", files=upload, data={"serial": M300.lower()})
        bad = c.post("/v1/checks", files=upload, data={"serial": "not-a-serial"})
        bad_batch = c.post("/v1/checks:batch", files=[("files", upload["file"])], data={"serial": "not-a-serial"})
    assert lower.status_code == 200 and lower.json()["claim"]["serial"] == M300
    assert lower.json()["registry"]["registered"]
    for resp in (bad, bad_batch):
        assert resp.status_code == 422, resp.text
        assert "not a UAS ID" in resp.json()["error"] and "\n" not in resp.json()["error"]
