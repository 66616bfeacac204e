"""The DRIP example pages of the IETF: conformance of pages, FEC, DET and signatures.

Source: draft-ietf-drip-auth-49 (published as RFC 9575), the Appendix examples of a DRIP
Wrapper and a DRIP Manifest sent as F3411 Authentication messages, with their Ed25519 host
identity and DET: tests/data/drip/draft-ietf-drip-auth-49-examples.json (README.md there
gives the source and licence). Both end with a forward-error-correction (FEC) page; their
signatures were valid from 2023-12-15T23:14:40Z to 2024-12-14T23:14:40Z (VNB / VNA are Unix
times), so today (2026) they verify but are expired.
"""

from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path

import pytest

from authn.cli import main
from remoteid import decode, decode_rows_raw
from remoteid.drip import (
    det_fields,
    det_from_public_key,
    det_matches_key,
    det_to_text,
    paginate,
    parse_det,
    parse_sam,
    reassemble,
    to_drip_time,
    verify,
    xor_pages,
)

EXAMPLES = json.loads((Path(__file__).parents[1] / "data" / "drip" /
                       "draft-ietf-drip-auth-49-examples.json").read_text())
KEY = bytes.fromhex(EXAMPLES["host_identity_ed25519_public_key"])
DET = parse_det(EXAMPLES["det"])
PAGES = {name: [bytes.fromhex(p) for p in EXAMPLES[f"{name}_pages"]] for name in ("wrapper", "manifest")}
SAM_TYPE = {"wrapper": 0x02, "manifest": 0x03}
TODAY_2026 = datetime(2026, 6, 1, 12, 0, tzinfo=timezone.utc)
IN_WINDOW = datetime(2024, 6, 1, tzinfo=timezone.utc)
BEFORE = datetime(2023, 12, 15, 18, 14, 40, tzinfo=timezone.utc)  # the page-0 timestamp: before VNB
WINDOW = "valid 2023-12-15T23:14:40Z to 2024-12-14T23:14:40Z"


def registry(det: bytes) -> bytes | None:
    """The registry's lookup: the key only for its own DET (RFC 9374's binding)."""
    return KEY if det_matches_key(det, KEY) else None


def _verify(pages: list[bytes], when: datetime = TODAY_2026, key_for=registry):
    return verify(decode_rows_raw(pages), key_for, when)


def _auth_data(name: str) -> bytes:
    (msg,) = reassemble(decode(p) for p in PAGES[name])
    return msg.data


# ------------------------------------------------------------------ the DET
def test_det_of_the_example_host_identity() -> None:
    assert det_fields(DET)[:3] == (16376, 1, 5)  # RAA 16376, HDA 1, suite 5 (EdDSA/cSHAKE128)
    assert det_from_public_key(KEY, 16376, 1) == DET
    assert det_from_public_key(KEY, 16376, 1).hex() == "2001003ffe000105a29b3ff42226c04e"
    assert det_matches_key(DET, KEY)
    assert det_to_text(DET) == "2001:3f:fe00:105:a29b:3ff4:2226:c04e"
    for name in PAGES:
        assert parse_sam(_auth_data(name)).det == DET


def test_keys_show_prints_the_example_det(capsys) -> None:
    capsys.readouterr()
    assert main(["keys", "show", "--public-key", KEY.hex(), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["det_hex"] == DET.hex() and doc["session_id"] == "01" + DET.hex().upper()


# ------------------------------------------------------------------ pages and FEC
@pytest.mark.parametrize("name", PAGES)
def test_the_last_page_is_the_xor_parity(name: str) -> None:
    pages = PAGES[name]
    last, length = pages[0][2], pages[0][3]
    assert (last, length) == {"wrapper": (7, 139), "manifest": (8, 177)}[name] and len(pages) == last + 1
    assert xor_pages(p[2:] for p in pages[:-1]) == pages[-1][2:]
    (msg,) = reassemble(decode(p) for p in pages)
    assert msg.fec and msg.rebuilt is None and msg.reason is None
    assert len(msg.data) == length and msg.data[0] == SAM_TYPE[name]


@pytest.mark.parametrize("name", PAGES)
def test_paginate_with_fec_sends_what_the_examples_send(name: str) -> None:
    """Our sender's pages equal the example's, up to the padding after Length, which the examples
    do not leave zero (one byte, covered by their FEC page)."""
    pages, data = PAGES[name], _auth_data(name)
    ours = paginate(data, to_drip_time(decode(pages[0]).timestamp), fec=True)
    assert len(ours) == len(pages)
    stream = b"".join(p[8:] if k == 0 else p[2:] for k, p in enumerate(pages[:-1]))
    padding = stream[len(data):]
    assert any(padding) and stream[:len(data)] == data
    zeroed = stream[:len(data)] + bytes(len(padding))
    bodies = [pages[0][2:8] + zeroed[:17]] + [zeroed[17 + 23 * k:40 + 23 * k] for k in range(len(pages) - 2)]
    want = [pages[0][:2] + bodies[0]] + [p[:2] + b for p, b in zip(pages[1:-1], bodies[1:])]
    want.append(pages[-1][:2] + xor_pages(bodies))
    assert ours == want


# ------------------------------------------------------------------ the examples verify
@pytest.mark.parametrize("name", PAGES)
def test_the_examples_verify_but_are_expired_today(name: str) -> None:
    """The examples verify: verified-but-expired at today's date (2026), never invalid."""
    for when in (TODAY_2026, datetime.now(timezone.utc)):
        r = _verify(PAGES[name], when)
        assert r.status == "expired", r
        assert r.reason.startswith(f"verified-but-expired: DRIP {name} signature verifies ({WINDOW}"), r.reason
        assert r.sam_types == (name,) and r.det == DET.hex() and r.covered == ()


@pytest.mark.parametrize("name", PAGES)
def test_the_examples_before_their_window_are_not_yet_valid(name: str) -> None:
    r = _verify(PAGES[name], BEFORE)
    assert r.status == "not-yet-valid" and r.reason.startswith("verified-but-not-yet-valid: "), r


def test_the_examples_inside_their_window() -> None:
    r = _verify(PAGES["manifest"], IN_WINDOW)
    assert (r.status, r.sam_types, r.det) == ("valid", ("manifest",), DET.hex())
    # The Wrapper carries a Location and a System message: valid once they are received too.
    wrapped = parse_sam(_auth_data("wrapper")).wrapped()
    r = _verify([*wrapped, *PAGES["wrapper"]], IN_WINDOW)
    assert (r.status, r.sam_types, r.covered) == ("valid", ("wrapper",), (0,))  # the Location is covered
    r = _verify(PAGES["wrapper"], IN_WINDOW)  # our rule: a wrapped message must also be received
    assert r.status == "invalid" and "not among the decoded messages" in r.reason


def test_without_the_key_it_is_an_unknown_key() -> None:
    for name in PAGES:
        r = _verify(PAGES[name], key_for=lambda det: None)
        assert r.status == "unknown-key" and DET.hex() in r.reason


# ------------------------------------------------------------------ one page missing
@pytest.mark.parametrize("name", PAGES)
def test_every_single_missing_page_is_rebuilt_from_fec(name: str) -> None:
    pages, data = PAGES[name], _auth_data(name)
    for k in range(len(pages)):
        rest = pages[:k] + pages[k + 1:]
        (msg,) = reassemble(decode(p) for p in rest)
        assert msg.data == data and msg.fec, k
        assert msg.rebuilt == (None if k == len(pages) - 1 else k), k  # a lost FEC page needs no rebuild
        if k == 0:
            assert msg.timestamp == decode(pages[0]).timestamp
        r = _verify(rest)
        assert r.status == "expired" and r.reason.startswith("verified-but-expired"), (k, r)


def test_one_page_missing_from_each_of_two_messages_in_one_stream() -> None:
    """Wrapper then Manifest (both auth type 5, the same page-0 timestamp) in one recording: a lost
    page in either, page 0 included, is rebuilt and both messages verify."""
    both = PAGES["wrapper"] + PAGES["manifest"]
    want = sorted([_auth_data("wrapper"), _auth_data("manifest")])
    for k in range(len(both)):
        rest = both[:k] + both[k + 1:]
        got = reassemble(decode(p) for p in rest)
        assert sorted(m.data for m in got) == want, (k, [m.reason for m in got])
        r = _verify(rest)
        assert r.status == "expired" and set(r.sam_types) == {"wrapper", "manifest"}, (k, r)
    # one lost page in each message
    rest = both[:2] + both[3:len(PAGES["wrapper"]) + 4] + both[len(PAGES["wrapper"]) + 5:]
    assert sorted(m.data for m in reassemble(decode(p) for p in rest)) == want


@pytest.mark.parametrize("name", PAGES)
def test_two_missing_pages_are_invalid(name: str) -> None:
    pages = PAGES[name]
    r = _verify(pages[:2] + pages[4:])
    assert r.status == "invalid" and "2, 3 of 0.." in r.reason and "FEC" in r.reason, r
    r = _verify(pages[2:])  # pages 0 and 1 lost: page 0 cannot be rebuilt
    assert r.status == "invalid" and "no page 0" in r.reason, r


# ------------------------------------------------------------------ bit flips
@pytest.mark.parametrize("name", PAGES)
def test_every_flipped_bit_of_the_signed_bytes_is_invalid(name: str) -> None:
    """As sent by a sender with the flipped bit (its FEC page recomputed): the signature fails.
    VNB .. DET are the signed bytes; the signature's own bits are checked too."""
    data = _auth_data(name)
    ts = to_drip_time(decode(PAGES[name][0]).timestamp)
    for byte in range(1, len(data)):
        for bit in range(8):
            bad = bytearray(data)
            bad[byte] ^= 1 << bit
            r = _verify(paginate(bytes(bad), ts, fec=True), key_for=lambda det: KEY)
            assert r.status == "invalid", (byte, bit, r)
    det_at = len(data) - 64 - 16
    bad = bytearray(data)
    bad[det_at + 15] ^= 1  # another DET: the registry has no key for it
    assert _verify(paginate(bytes(bad), ts, fec=True)).status == "unknown-key"


@pytest.mark.parametrize("name", PAGES)
def test_a_flipped_bit_with_all_pages_is_a_parity_error(name: str) -> None:
    pages = PAGES[name]
    for k in range(len(pages)):  # the FEC page itself, and every other page's covered bytes
        for byte in (2, 13, 24) if k else (4, 7, 8, 24):  # page 0: timestamp and data
            for bit in range(8):
                bad = bytearray(pages[k])
                bad[byte] ^= 1 << bit
                r = _verify(pages[:k] + [bytes(bad)] + pages[k + 1:])
                assert r.status == "invalid" and "FEC parity error" in r.reason, (k, byte, r)
    for byte in (2, 3):  # page 0's last page index or length: the layout no longer adds up
        bad = bytearray(pages[0])
        bad[byte] ^= 1
        assert _verify([bytes(bad), *pages[1:]]).status == "invalid"


@pytest.mark.parametrize("name", PAGES)
def test_a_flipped_bit_without_the_fec_page_is_invalid(name: str) -> None:
    pages = PAGES[name]
    bad = bytearray(pages[5])
    bad[10] ^= 1  # a signature byte in both examples
    r = _verify(pages[:5] + [bytes(bad)] + pages[6:-1])
    assert r.status == "invalid" and "signature does not verify" in r.reason, r


# ------------------------------------------------------------------ the CLI
@pytest.mark.parametrize("name", PAGES)
def test_rid_decode_of_the_examples_prints_verified_but_expired(name: str, capsys, tmp_path: Path) -> None:
    hexes = EXAMPLES[f"{name}_pages"]
    capsys.readouterr()
    assert main(["rid", "decode", *hexes, "--public-key", KEY.hex(), "--at", "2026-06-01T12:00:00Z"]) == 0
    out = capsys.readouterr().out
    assert f"DRIP {name}, FEC page, {WINDOW}, DET 2001:3f:fe00:105:a29b:3ff4:2226:c04e" in out
    assert "verification: expired (verified-but-expired: " in out
    # one page lost, the key in a file (64 hex digits), JSON, today's date
    (tmp_path / "hi.hex").write_text(KEY.hex() + "\n")
    assert main(["rid", "decode", *hexes[:2], *hexes[3:], "--public-key", str(tmp_path / "hi.hex"), "--json"]) == 0
    text = capsys.readouterr().out
    doc = json.loads(text[text.rindex('{\n  "authentication"'):])
    assert doc["verification"]["status"] == "expired"
    assert doc["verification"]["reason"].startswith("verified-but-expired")
    assert "(page 2 rebuilt from it)" in doc["authentication"][0]
