"""`POST /v1/checks` takes the one rule's error targets, as `authn check --false-accept/--false-reject`
does: one dwell is a track of one (docs/policies.md)."""

from __future__ import annotations


def test_a_single_check_takes_its_error_targets(server, keys, returns) -> None:
    """A Phantom 4 claiming the registered M600: inconclusive at the default targets (one dwell counts
    at most 4 nats), refuted at 2 % targets; out-of-range targets are bad input (422)."""
    spoof = returns["type"]
    with server.client(keys.operator) as c:
        default = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())})
        loose = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())},
                       data={"false_accept": "0.02", "false_reject": "0.02"})
        bad = c.post("/v1/checks", files={"file": (spoof.name, spoof.read_bytes())}, data={"false_accept": "0.5"})
    assert default.status_code == loose.status_code == 200, default.text
    d, lo = default.json(), loose.json()
    assert d["decision"] == "inconclusive" and d["to_decide"]["llr_nats"] < 0
    assert lo["decision"] == "reject" and "radar-claim-inconsistent" in lo["reasons"]
    assert bad.status_code == 422
