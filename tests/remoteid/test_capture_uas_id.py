"""A capture's drones are named by the normal form of the UAS ID they broadcast
(`core.uasid.as_heard`), so a lower-case serial heard over the air is the registered one."""

from __future__ import annotations

from datetime import timedelta

from remoteid.capture import broadcasters, read_capture
from tests.remoteid.capture_tools import DATA, rewrite


def test_a_lower_case_broadcast_serial_is_heard_in_its_normal_form(tmp_path):
    pcap = rewrite(DATA / "odid_wifi_bcn_sample.pcap", tmp_path / "lower.pcap", uas_id="1581f5fjd12345678901")
    captured = read_capture(pcap)
    times = [c.captured_at for c in captured if c.captured_at is not None]
    found, _ = broadcasters(captured, min(times) - timedelta(seconds=1), max(times) + timedelta(seconds=1))
    assert [b.uas_id for b in found] == ["1581F5FJD12345678901"]
