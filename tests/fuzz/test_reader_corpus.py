"""Every corpus case through `read_recording` in-process: a Recording (valid cases only)
or a one-line RecordingError, never another exception, never a hang."""

from __future__ import annotations

import os
import subprocess
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

import pytest

from tests.fuzz.corpus import BAD, EITHER, VALID
from tests.fuzz.helpers import CASE_SECONDS, Hang, check_recording, deadline, is_one_line, read_outcome


def test_corpus_is_large_and_covers_every_class(corpus) -> None:
    classes = Counter(c.cls for c in corpus)
    assert len(corpus) >= 400
    assert classes["bitflip"] + classes["bitflip_meta"] >= 150
    for cls in ("attr_missing", "attr_extra", "attr_type", "start_time", "iq_link", "iq_external_storage",
                "iq_virtual", "iq_null", "iq_group", "iq_bigendian", "iq_huge", "rid_group", "rid_dtype",
                "truncation", "npz_encrypted", "npz_compression", "npz_member", "npz_header", "special_file"):
        assert classes[cls] > 0, cls
    assert {c.expect for c in corpus} == {VALID, BAD, EITHER}


def test_every_case_is_a_recording_or_a_one_line_recording_error(corpus) -> None:
    failures: list[str] = []
    for case in corpus:
        t0 = time.perf_counter()
        try:
            with deadline(CASE_SECONDS):
                got, msg = read_outcome(case.path)
                if got == VALID:
                    from signatures.recording import read_recording

                    check_recording(read_recording(case.path))
        except Hang:
            failures.append(f"{case.name}: hung (> {CASE_SECONDS} s)")
            continue
        except BaseException as exc:  # noqa: BLE001  the point: nothing else may escape
            tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
            failures.append(f"{case.name}: {tb}")
            continue
        elapsed = time.perf_counter() - t0
        if elapsed > CASE_SECONDS:
            failures.append(f"{case.name}: took {elapsed:.1f} s")
        if got == "bad" and not is_one_line(msg):
            failures.append(f"{case.name}: message not one line: {msg!r}")
        if case.expect != EITHER and got != case.expect:
            failures.append(f"{case.name} ({case.cls}): expected {case.expect}, got {got} {msg!r}")
    assert not failures, f"{len(failures)} of {len(corpus)} cases:\n" + "\n".join(failures)


@pytest.mark.parametrize("name, needle", [
    ("start_time_year_9999", "attribute 'start_time'"),
    ("start_time_year_1", "attribute 'start_time'"),
    ("start_time_year_2100", "attribute 'start_time'"),
    ("attr_type_carrier_hz_complex", "attribute 'carrier_hz'"),
    ("attr_type_carrier_hz_opaque", "attribute 'carrier_hz'"),
    ("iq_null_dataspace", "dataset '/iq'"),
    ("iq_soft_link_dangling", "dataset '/iq'"),
    ("iq_external_link", "dataset '/iq'"),
    ("iq_external_storage", "dataset '/iq'"),
    ("iq_virtual", "dataset '/iq'"),
    ("remote_id_group", "dataset '/remote_id'"),
    ("remote_id_time_s_vlen_strings", "dataset '/remote_id_time_s'"),
    ("npz_encrypted_iq", "member 'iq'"),
    ("npz_method99_carrier_hz", "member 'carrier_hz'"),
    ("oversize_file", "exceed the limit"),
])
def test_message_names_the_field(corpus, name: str, needle: str) -> None:
    case = next(c for c in corpus if c.name == name)
    got, msg = read_outcome(case.path)
    assert got == BAD and needle in msg and is_one_line(msg), msg


def test_big_endian_iq_reads_as_native_and_equal(corpus) -> None:
    import numpy as np

    from signatures.recording import read_recording

    base = read_recording(next(c for c in corpus if c.name == "baseline_h5").path)
    for name in ("iq_bigendian_c8", "iq_bigendian_c16", "npz_iq_bigendian_c8", "npz_iq_bigendian_c16"):
        rec = read_recording(next(c for c in corpus if c.name == name).path)
        assert rec.iq.dtype.isnative and np.array_equal(rec.iq, base.iq), name
    rec = read_recording(next(c for c in corpus if c.name == "times_dtype_f8_be").path)
    assert rec.remote_id_time_s.dtype == np.float64 and np.array_equal(rec.remote_id_time_s, base.remote_id_time_s)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="os.mkfifo not available")
def test_fifo_named_h5_is_refused_quickly(tmp_path: Path) -> None:
    fifo = tmp_path / "x.h5"
    os.mkfifo(fifo)
    t0 = time.perf_counter()
    with deadline(CASE_SECONDS):
        got, msg = read_outcome(fifo)
    assert got == BAD and "not a regular file" in msg
    assert time.perf_counter() - t0 < 1.0


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="os.mkfifo not available")
def test_fifo_refused_by_the_cli_in_a_subprocess(tmp_path: Path) -> None:
    """Out of process too: a hang inside C code would escape SIGALRM, not a subprocess timeout."""
    fifo = tmp_path / "x.h5"
    os.mkfifo(fifo)
    env = {**os.environ, "AUTHN_DATABASE_URL": f"sqlite:///{tmp_path / 'db.sqlite3'}"}
    proc = subprocess.run([sys.executable, "-m", "authn", "inspect", str(fifo)], capture_output=True, text=True,
                          timeout=60, env=env)
    assert proc.returncode == 2 and "not a regular file" in proc.stderr and "Traceback" not in proc.stderr


def test_byte_limits_are_checked_before_reading(corpus) -> None:
    from signatures.errors import RecordingError
    from signatures.recording import MAX_FILE_BYTES, read_recording

    path = next(c for c in corpus if c.name == "baseline_h5").path
    with pytest.raises(RecordingError, match="bytes exceed the limit"):
        read_recording(path, max_bytes=1000)
    with pytest.raises(RecordingError, match="bytes exceed the limit"):
        read_recording(path, max_file_bytes=1000)
    assert path.stat().st_size < MAX_FILE_BYTES


def _heap_damaged(src: Path, dst: Path, how: str) -> Path:
    """A copy of src whose first global heap collection makes HDF5 2.0 loop forever."""
    import struct

    data = bytearray(src.read_bytes())
    gcol = data.find(b"GCOL\x01\x00\x00\x00")
    assert gcol >= 0
    if how == "grown":  # the collection size bit-flipped past its end, into zeroed space
        size = struct.unpack_from("<Q", data, gcol + 8)[0]
        struct.pack_into("<Q", data, gcol + 8, size | 0x400)
    else:  # the free-space object's size zeroed
        p = gcol + 16
        while struct.unpack_from("<H", data, p)[0] != 0:
            p += 16 + (struct.unpack_from("<Q", data, p + 8)[0] + 7) // 8 * 8
        struct.pack_into("<Q", data, p + 8, 0)
    dst.write_bytes(bytes(data))
    return dst


@pytest.mark.parametrize("how", ["free_space_zero", "grown"])
def test_global_heap_infinite_loop_is_refused(corpus, tmp_path: Path, how: str) -> None:
    """Read in a killable child: without the guard, HDF5 spins in C where SIGALRM cannot reach."""
    from tests.fuzz.helpers import read_in_child

    base = next(c for c in corpus if c.name == "baseline_h5").path
    path = _heap_damaged(base, tmp_path / f"heap_{how}.h5", how)
    got, msg = read_in_child(path, 20.0)
    assert got == BAD and "global heap" in msg and is_one_line(msg), (got, msg)
