"""`POST /v1/checks` takes the one rule's error targets, as `authn check --false-accept/--false-reject`
does: one dwell is a track of one (docs/policies.md)."""

from __future__ import annotations


def test_a_single_check_takes_its_error_targets(server, keys, returns) -> None:
    """The targets set the test's bounds (6.90 / -4.61 nats at the defaults, +-3.89 at 2 %); a Phantom 4
    claiming the registered M600 is never accepted at either; out-of-range targets are bad input (422)."""
    spoof = returns["type"]
    with server.client(keys.operator) as c:
        default = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())})
        loose = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())},
                       data={"false_accept": "0.02", "false_reject": "0.02"})
        bad = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())}, data={"false_accept": "0.5"})
    assert default.status_code == loose.status_code == 200, default.text
    d, lo = default.json(), loose.json()
    assert d["decision"] == "inconclusive" and (d["to_decide"]["accept_nats"], d["to_decide"]["reject_nats"]) == (
        6.9, -4.61)
    assert lo["decision"] != "accept"
    if lo["decision"] == "inconclusive":
        assert (lo["to_decide"]["accept_nats"], lo["to_decide"]["reject_nats"]) == (3.9, -3.9)  # rounded away from 0
        assert lo["to_decide"]["llr_nats"] <= -3.9  # past the bound against the Phantom 4 it is
    assert bad.status_code == 422
