"""Hot paths of the decision layer: policy decisions, audit appends, a whole in-process check."""

from __future__ import annotations

from datetime import datetime, timezone
from pathlib import Path

import pytest

from authn.audit import NewEntry, append
from authn.check import Checker
from authn.demo import register_examples
from authn.policy import PolicyEngine
from authn.scenario import Broadcast, simulate_flight
from registry.dbapi import Database
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

PRINCIPAL = dict(registered=True, status="active", model="m300", id_type="serial", valid_from_s=0, has_key=False)
SITE = dict(time_s=1_767_268_800, preset="paper")
CONTEXT = dict(claim_source="remote_id", radar_run=True, target_detected=True, radar_model="m300",
               radar_known=True, radar_confidence_bp=9700, has_kinematics=True, range_residual_cm=120,
               range_tolerance_cm=850, velocity_residual_cmps=40, velocity_tolerance_cmps=170,
               remote_id_present=True, remote_id_issues=[], remote_id_auth="absent",
               track={"llr_cn": 700, "accept_cn": 690, "reject_cn": -461, "dwells": 1})


@pytest.fixture(scope="module")
def engine() -> PolicyEngine:
    return PolicyEngine.load()


def test_policy_decision(benchmark, engine: PolicyEngine) -> None:
    assert benchmark(engine.decide, "S1", PRINCIPAL, SITE, CONTEXT).decision == "accept"


def test_policy_early_rejection(benchmark, engine: PolicyEngine) -> None:
    no_radar = {**CONTEXT, "radar_run": False, "target_detected": False, "radar_model": "", "radar_known": False,
                "radar_confidence_bp": 0, "has_kinematics": False}
    result = benchmark(engine.decide_without_evidence, "S1", {**PRINCIPAL, "status": "revoked"}, SITE, no_radar)
    assert result is not None and result.reasons == ["revoked"]


def test_audit_append_one_transaction(benchmark, tmp_path: Path) -> None:
    db = Database(f"sqlite:///{tmp_path / 'a.sqlite3'}")
    entry = [NewEntry("decision", "S1", "accept", {"reasons": ["registered-active"]})]
    assert benchmark(append, db, entry)[0].seq >= 1


@pytest.mark.parametrize("preset", ["paper", "wide"])
def test_whole_check_in_process(benchmark, tmp_path: Path, preset: str) -> None:
    db = f"sqlite:///{tmp_path / 'c.sqlite3'}"
    register_examples(db)
    scene = Scene(profile=shipped_profiles()["m300"], range_m=420.0, radial_speed_mps=4.0, snr_db=15.0)
    rec, _ = simulate_flight(scene, get_preset(preset), 1, Broadcast(serial="1581BDEM00000002"),
                             start_time=datetime.now(timezone.utc))
    path = write_recording(rec, tmp_path / "f.h5")
    checker = Checker(db)
    assert benchmark(checker.evaluate, path).radar is not None
