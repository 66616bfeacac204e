"""4 processes x 250 checks against one database: 1000 entries, one unbroken chain."""

from __future__ import annotations

from pathlib import Path

import pytest
from proc_workers import check_many, run_in_processes

from authn.audit import list_entries, verify
from authn.scenario import Broadcast, simulate_flight
from registry.db import get_engine
from registry.dbapi import Database
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

PROCS, PER_PROC = 4, 250


@pytest.mark.slow  # 7-11 s per database: 4 processes x 250 checks
def test_concurrent_checks_keep_one_chain(db_url: str, tmp_path: Path) -> None:
    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, snr_db=15.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 1, Broadcast(serial="1581BDEM00000002"))
    path = str(write_recording(rec, tmp_path / "f.h5"))
    get_engine(db_url)  # migrate once up front; first-use races are tested in tests/registry
    # unregistered claims: full checks whose radar stage the policy skips, so 1000 run in seconds
    serials = [[f"1581BDEX{p:02d}{i:06d}" for i in range(PER_PROC)] for p in range(PROCS)]
    ids = run_in_processes(check_many, [(db_url, path, s) for s in serials])
    flat = sorted(i for chunk in ids for i in chunk)
    assert flat == list(range(1, PROCS * PER_PROC + 1))  # no entry lost, none duplicated
    db = Database(db_url)
    report = verify(db)
    entries = list_entries(db)
    db.close()
    assert report.ok and report.size == PROCS * PER_PROC
    assert {e.serial for e in entries} == {x for chunk in serials for x in chunk}
    assert {(e.decision, tuple(e.payload["reasons"])) for e in entries} == {
        ("reject", ("remote-id-implausible", "unregistered"))}
