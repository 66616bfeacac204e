"""`authn rid decode FILE`: a pcap or pcapng given where hex messages go is known by its magic
number and decoded as with --pcap; any other file is bad input that says so (not 'not hex')."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from authn.cli import main

DATA = Path(__file__).resolve().parents[1] / "data" / "remoteid-captures"


@pytest.mark.parametrize("name", ["odid_wifi_sample.pcap", "odid_bt5_lr_sample.pcapng"])
def test_a_capture_in_place_of_messages_is_decoded_as_with_pcap(name, capsys):
    path = str(DATA / name)
    assert main(["rid", "decode", "--pcap", path, "--json"]) == 0
    want = json.loads(capsys.readouterr().out)
    assert main(["rid", "decode", path, "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == want and want


def test_another_file_in_place_of_messages_says_what_it_is(tmp_path, capsys):
    other = tmp_path / "notes.txt"
    other.write_text("hello")
    assert main(["rid", "decode", str(other)]) == 2
    err = capsys.readouterr().err
    assert "is a file" in err and "--pcap" in err and "not hex:" not in err
