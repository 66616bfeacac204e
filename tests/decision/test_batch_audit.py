"""Batch mode loses no decision: each result is audited as the batch goes, a bad or crashing
file does not stop it, and a kill at any point leaves every printed decision in the audit.

The good files are one genuine unsigned M300 dwell each. A single check is a track of one dwell
decided by Wald's sequential test: at the default targets one dwell (capped at +-4 nats) reaches
neither bound, and the M300 is radar-confusable with the M600 registered beside it, so each good
file is `inconclusive` (exit 4, below 2 and 3 in the batch's order): a decision all the same,
audited like any other."""

from __future__ import annotations

import json
import os
import random
import re
import signal
import sqlite3
import subprocess
import sys
import time
from datetime import datetime, timezone
from pathlib import Path

import h5py
import numpy as np
import pytest

from authn.cli import main
from authn.demo import register_examples
from authn.scenario import Broadcast, simulate_flight
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

M300 = "1581BDEM00000002"
N_GOOD, N_BAD = 90, 10


def _bad(src: bytes, path: Path, kind: int) -> None:
    """Ten ways a file in an archive goes wrong."""
    if kind == 0:
        path.write_bytes(src[:4000])
    elif kind == 1:
        path.write_text("not a recording")
    elif kind == 2:
        path.write_bytes(b"")
    else:
        path.write_bytes(src)
        with h5py.File(path, "a") as f:
            if kind == 3:
                f.attrs["carrier_hz"] = np.nan
            elif kind == 4:
                del f["iq"]
            elif kind == 5:
                f.attrs["start_time"] = "yesterday"
            elif kind == 6:
                f.attrs["format"] = "other/9"
            elif kind == 7:
                del f["iq"]
                f.create_dataset("iq", data=np.full((8, 8), np.inf, np.complex64))
            elif kind == 8:
                f.attrs["pri_s"] = -1.0
            else:
                del f.attrs["radar_lat_deg"]


@pytest.fixture(scope="module")
def archive(tmp_path_factory) -> Path:
    """90 genuine returns and 10 bad files, interleaved."""
    root = tmp_path_factory.mktemp("archive")
    scene = Scene(profile=shipped_profiles()["m300"], range_m=400.0, radial_speed_mps=3.0, snr_db=20.0,
                  elevation_deg=10.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 11, Broadcast(serial=M300), azimuth_deg=60.0,
                             start_time=datetime.now(timezone.utc))
    src = write_recording(rec, root / "source.h5").read_bytes()
    (root / "source.h5").unlink()
    files = root / "returns"
    files.mkdir()
    bad_at = set(range(5, 100, 10))
    for i in range(N_GOOD + N_BAD):
        path = files / f"r{i:03d}.h5"
        if i in bad_at:
            _bad(src, path, len([b for b in bad_at if b < i]))
        else:
            path.write_bytes(src)
    return files


@pytest.fixture
def db(tmp_path: Path) -> str:
    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register_examples(url)
    return url


def _audit(url: str) -> list[tuple[int, str, str | None, dict]]:
    with sqlite3.connect(url.removeprefix("sqlite:///")) as conn:
        rows = conn.execute("SELECT seq, kind, decision, payload FROM audit_log ORDER BY seq").fetchall()
    return [(seq, kind, decision, json.loads(payload)) for seq, kind, decision, payload in rows]


def test_batch_with_bad_files_audits_every_file(archive: Path, db: str, capsys) -> None:
    capsys.readouterr()
    assert main(["--db", db, "check", str(archive), "--json"]) == 2
    out, err = capsys.readouterr()
    results = json.loads(out)
    assert len(results) == N_GOOD + N_BAD
    decisions = [r for r in results if "decision" in r]
    errors = [r for r in results if "error" in r]
    assert len(decisions) == N_GOOD and all(r["decision"] == "inconclusive" for r in decisions)
    assert all("radar-inconclusive" in r["reasons"] for r in decisions)
    assert len(errors) == N_BAD and {r["exit_code"] for r in errors} == {2}
    assert "Traceback" not in err and err.count("\n") == N_BAD
    entries = _audit(db)
    assert len(entries) == N_GOOD + N_BAD
    assert sum(kind == "decision" for _, kind, _, _ in entries) == N_GOOD
    assert {d for _, kind, d, _ in entries if kind == "decision"} == {"inconclusive"}
    bad_entries = [p for _, kind, _, p in entries if kind == "error"]
    assert len(bad_entries) == N_BAD and {p["error_kind"] for p in bad_entries} == {"bad-input"}
    assert {r["audit_id"] for r in decisions} == {seq for seq, kind, _, _ in entries if kind == "decision"}
    assert main(["--db", db, "audit", "verify"]) == 0


def test_a_crashing_file_does_not_stop_the_batch(archive: Path, db: str, capsys, monkeypatch) -> None:
    """An unexpected exception on one file is that file's system error (exit 3 for the batch, above
    the others' inconclusive 4), and the files after it are still decided and audited."""
    import authn.check

    real = authn.check.Checker._front

    def front(self, rec, serial, file, digest, timer, **kw):
        if Path(file).name == "r001.h5":
            raise OverflowError("date value out of range")
        return real(self, rec, serial, file, digest, timer, **kw)

    monkeypatch.setattr(authn.check.Checker, "_front", front)
    files = sorted(archive.iterdir())[:4]  # r000 good, r001 crashes, r002-r003 good
    capsys.readouterr()
    assert main(["--db", db, "check", *map(str, files), "--json"]) == 3
    results = json.loads(capsys.readouterr().out)
    assert [r.get("decision", "error") for r in results] == ["inconclusive", "error", "inconclusive", "inconclusive"]
    assert results[1]["exit_code"] == 3 and "OverflowError" in results[1]["error"]
    entries = _audit(db)
    assert [kind for _, kind, _, _ in entries] == ["decision", "error", "decision", "decision"]
    assert entries[1][3]["error_kind"] == "system"


def _start(archive: Path, db: str) -> subprocess.Popen:
    env = {**os.environ, "AUTHN_DATABASE_URL": db}
    return subprocess.Popen([sys.executable, "-m", "authn", "check", str(archive), "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env, bufsize=0)


def _wait_for_output(proc: subprocess.Popen) -> bytes:
    """The first bytes the batch prints: the first committed chunk has been decided."""
    first = proc.stdout.read(1)
    assert first == b"[", proc.stderr.read().decode()
    return first


def _printed_ids(text: str) -> list[int]:
    return [int(m) for m in re.findall(r'"audit_id": (\d+)', text)]


@pytest.mark.parametrize("seed", [1, 2])
def test_kill_9_mid_batch_loses_no_printed_decision(archive: Path, db: str, seed: int) -> None:
    proc = _start(archive, db)
    printed = _wait_for_output(proc)
    time.sleep(random.Random(seed).uniform(0.0, 0.8))
    proc.send_signal(signal.SIGKILL)
    out, _ = proc.communicate(timeout=60)
    text = (printed + out).decode()
    ids = _printed_ids(text)
    entries = {seq: (kind, decision) for seq, kind, decision, _ in _audit(db)}
    assert ids, "the batch printed some decisions before the kill"
    assert set(ids) <= set(entries), "a printed decision is missing from the audit"
    assert all(entries[i][0] == "decision" for i in ids)
    assert main(["--db", db, "audit", "verify"]) == 0


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_stop_signal_mid_batch_commits_prints_and_exits_128_plus_its_number(archive: Path, db: str, sig: int,
                                                                              code: int) -> None:
    proc = _start(archive, db)
    printed = _wait_for_output(proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err.decode()
    results = json.loads((printed + out).decode())  # a complete JSON array: the batch stopped cleanly
    assert 0 < len(results) < N_GOOD + N_BAD
    entries = _audit(db)
    assert len(entries) == len(results)  # everything committed was printed and vice versa
    assert err.decode().strip().splitlines()[-1].startswith(f"error: interrupted by {signal.Signals(sig).name}")
    assert main(["--db", db, "audit", "verify"]) == 0


@pytest.mark.parametrize("text", ["r000.h5,1581BDEM00000002\n", "file,serial\nr000.h5,\n", ""])
def test_claims_csv_without_header_or_with_holes_is_refused(archive: Path, db: str, tmp_path: Path, text: str,
                                                            capsys) -> None:
    claims = tmp_path / "claims.csv"
    claims.write_text(text)
    capsys.readouterr()
    assert main(["--db", db, "check", str(archive), "--claims", str(claims)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "claims" in err and err.count("\n") == 1
