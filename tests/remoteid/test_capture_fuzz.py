"""pcap/pcapng reader against hostile input: a huge pcapng timestamp, a truncated
if_tsresol option, a FIFO, and a seeded mutation loop (bit flips, truncation, overwritten
length fields) over synthetic captures and the shipped sample captures. Anything but a
list of messages or a one-line CaptureError is a bug."""

from __future__ import annotations

import os
import random
import struct
import time
from pathlib import Path

import pytest

from authn.cli import main
from remoteid import BasicId, encode
from remoteid.capture import extract, read_capture
from remoteid.errors import CaptureError

SAMPLES = Path(__file__).resolve().parents[1] / "data" / "remoteid-captures"
MUTATIONS = max(150, int(os.environ.get("AUTHN_FUZZ_EXAMPLES", "0")) // 10)


def _block(btype: int, body: bytes, endian: str = "<") -> bytes:
    body += bytes(-len(body) % 4)
    return struct.pack(endian + "II", btype, 12 + len(body)) + body + struct.pack(endian + "I", 12 + len(body))


def _beacon() -> bytes:
    msg = encode(BasicId(uas_id="1581F5FJD12345678901"))
    ie = b"\xdd" + bytes([4 + 1 + len(msg)]) + b"\xfa\x0b\xbc\x0d" + b"\x01" + msg
    return b"\x80\x00" + bytes(22) + bytes(12) + ie


def _pcapng(ts_ticks: int = 1_700_000_000_000_000, options: bytes = b"", linktype: int = 105) -> bytes:
    shb = _block(0x0A0D0D0A, b"\x4d\x3c\x2b\x1a" + struct.pack("<HHq", 1, 0, -1))
    idb = _block(1, struct.pack("<HHI", linktype, 0, 65535) + options)
    pkt = _beacon()
    epb = _block(6, struct.pack("<IIIII", 0, ts_ticks >> 32, ts_ticks & 0xFFFFFFFF, len(pkt), len(pkt)) + pkt)
    return shb + idb + epb


def _pcap(packets: list[bytes], linktype: int = 105) -> bytes:
    out = b"\xd4\xc3\xb2\xa1" + struct.pack("<HHiIII", 2, 4, 0, 0, 65535, linktype)
    for i, p in enumerate(packets):
        out += struct.pack("<IIII", 1_700_000_000 + i, 500, len(p), len(p)) + p
    return out


def test_synthetic_captures_decode() -> None:
    assert len(extract(_pcapng())) == 1
    assert len(extract(_pcap([_beacon(), _beacon()]))) == 2


@pytest.mark.parametrize("ticks", [2**64 - 1, 2**63, 253_402_300_800 * 1_000_000])  # the last: year 10000
def test_huge_pcapng_timestamp_is_a_one_line_capture_error(ticks: int, tmp_path: Path, capsys) -> None:
    data = _pcapng(ticks)
    with pytest.raises(CaptureError, match=r"packet 1: timestamp out of range"):
        extract(data)
    path = tmp_path / "huge.pcapng"
    path.write_bytes(data)
    assert main(["rid", "decode", "--pcap", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and "\n" not in err and "timestamp out of range" in err


def test_large_timestamp_resolution_is_still_in_range() -> None:
    # if_tsresol 2^-127 s per tick: 64-bit ticks are a tiny fraction of a second, not an overflow
    found = extract(_pcapng(2**64 - 1, options=struct.pack("<HH", 9, 1) + b"\xff\x00\x00\x00"))
    assert found[0].captured_at.year == 1970


def test_truncated_tsresol_option_is_not_an_index_error() -> None:
    """An if_tsresol option whose value byte lies past the options (IndexError before)."""
    idb_body = struct.pack("<HHI", 105, 0, 65535) + struct.pack("<HH", 9, 1)  # no value byte
    shb = _block(0x0A0D0D0A, b"\x4d\x3c\x2b\x1a" + struct.pack("<HHq", 1, 0, -1))
    idb = struct.pack("<II", 1, 12 + len(idb_body)) + idb_body + struct.pack("<I", 12 + len(idb_body))
    found = extract(shb + idb)
    assert found == []


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="os.mkfifo not available")
def test_fifo_capture_is_refused_without_blocking(tmp_path: Path) -> None:
    fifo = tmp_path / "x.pcap"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with pytest.raises(CaptureError, match="not a regular file"):
        read_capture(fifo)
    assert time.perf_counter() - t0 < 1.0


def _mutants(data: bytes, rng: random.Random, n: int):
    for k in range(n):
        b = bytearray(data)
        mode = k % 5
        if mode == 0:  # bit flips
            for _ in range(rng.randint(1, 8)):
                i = rng.randrange(len(b))
                b[i] ^= 1 << rng.randrange(8)
        elif mode == 1:  # truncation
            del b[rng.randrange(len(b)):]
        elif mode == 2:  # a length or timestamp field overwritten with an extreme value
            i = rng.randrange(max(1, len(b) - 4))
            b[i:i + 4] = rng.choice([b"\xff\xff\xff\xff", b"\x00\x00\x00\x00", b"\x7f\xff\xff\xff",
                                     b"\x80\x00\x00\x00"])
        elif mode == 3:  # a random byte
            b[rng.randrange(len(b))] = rng.randrange(256)
        else:  # a slice duplicated or removed
            i, j = sorted(rng.randrange(len(b)) for _ in range(2))
            b = b[:i] + b[i:j] * rng.randint(0, 2) + b[j:]
        yield k, bytes(b)


def _fuzz(name: str, data: bytes, seed: int) -> list[str]:
    rng = random.Random(seed)
    failures = []
    for k, mutant in _mutants(data, rng, MUTATIONS):
        try:
            found = extract(mutant)
        except CaptureError as exc:
            if "\n" in str(exc) or not str(exc).strip():
                failures.append(f"{name} #{k}: message not one line: {exc!r}")
        except Exception as exc:  # noqa: BLE001  the point of the test
            failures.append(f"{name} #{k}: {type(exc).__name__}: {exc}")
        else:
            assert isinstance(found, list)
    return failures


def test_seeded_mutations_of_synthetic_captures() -> None:
    failures = _fuzz("synthetic.pcapng", _pcapng(), 1) + _fuzz("synthetic.pcap", _pcap([_beacon()] * 3), 2)
    assert not failures, "\n".join(failures)


@pytest.mark.parametrize("name", ["odid_wifi_bcn_sample.pcap", "odid_wifi_sample.pcap", "odid_bt5_lr_sample.pcapng"])
def test_seeded_mutations_of_shipped_captures(name: str) -> None:
    failures = _fuzz(name, (SAMPLES / name).read_bytes(), 3)
    assert not failures, "\n".join(failures)
