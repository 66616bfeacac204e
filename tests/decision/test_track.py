"""`authn check --track`: one decision over a target's dwells by Wald's sequential test, the Cedar
policy deciding each step; the dwells after the deciding one are never read whole; one audit
entry per track; a track that is not one target's is bad input (exit 2, one line)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from authn.cli import main
from authn.track import DWELL_CAP_NATS, KINEMATIC_DWELLS, Sprt
from lab.bench.track import icc, track_recordings
from signatures.profiles import shipped_profiles
from signatures.recording import read_header, read_recording, write_recording
from signatures.sim.scene import Scene
from tests.decision.test_policy import ACTIVE, GOOD, SITE
from tests.lab_plugin import needs_lab
from tests.registry_tools import register

#: Two M300 identities and a Phantom 4: no radar-confusable pair is registered (an M600 beside an M300
#: would make every unsigned claim of either inconclusive, docs/classifiers.md "Separation"), so these
#: tracks show the sequential test itself.
M300, M300_B, PHANTOM4 = "1581BDEM00000002", "1581BDEM00000012", "1581BDEM00000004"
DWELLS = 6


def _track(folder: Path, flies: str, serial: str | None, seed: int = 100, **scene) -> Path:
    folder.mkdir()
    sc = Scene(kind="uav", profile=shipped_profiles()[flies], snr_db=20.0,
               **{"range_m": 400.0, "radial_speed_mps": 3.0, "elevation_deg": 10.0, **scene})
    for i, rec in enumerate(track_recordings(sc, "paper", list(range(seed, seed + DWELLS)), serial)):
        write_recording(rec, folder / f"dwell_{i:06d}.h5")
    return folder


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("track")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    register(db, (M300, "m300"), (M300_B, "m300"), (PHANTOM4, "phantom4"))
    tracks = {"genuine": _track(root / "genuine", "m300", M300),
              "type": _track(root / "type", "phantom4", M300_B, seed=200)}
    return root, db, tracks


def _run(db: str, capsys, *args: str) -> tuple[int, dict, str]:
    capsys.readouterr()
    code = main(["--db", db, "check", "--track", *args, "--json"])
    out = capsys.readouterr()
    return code, json.loads(out.out) if out.out.strip() else {}, out.err


def _entry(db: str, seq: int) -> dict:
    from authn.audit import get_entry
    from registry.dbapi import Database

    return get_entry(Database(db), seq).payload


def test_a_genuine_track_is_accepted_at_the_bound_and_the_rest_skipped(setup, capsys) -> None:
    _, db, tracks = setup
    code, out, err = _run(db, capsys, str(tracks["genuine"]))
    assert code == 0 and out["decision"] == "accept" and out["reasons"] == ["registered-active"], err
    s = Sprt()
    used = out["dwells_used"]
    increments = [d["increment"] for d in out["dwells"]]
    # the test stopped at the first dwell where the discounted sum reached the accept bound
    assert 1 < used < DWELLS and out["dwells_skipped"] == DWELLS - used == len(out["skipped_files"])
    assert s.track_llr(increments) >= s.accept_nats > s.track_llr(increments[:-1])
    assert math.isclose(out["llr"], s.track_llr(increments), abs_tol=1e-3)
    assert all(abs(x) <= DWELL_CAP_NATS for x in increments)
    assert [Path(f).name for f in out["skipped_files"]] == [f"dwell_{i:06d}.h5" for i in range(used, DWELLS)]
    assert out["sprt"]["accept_nats"] == round(math.log(0.99 / 0.001), 4)
    for d in out["dwells"]:  # what each dwell added against each alternative, and the rate it compared
        assert d["increment"] == min(d["against"].values())
        rate = d["flash_rate"]
        assert rate["measured"] > 0 and rate["claimed"] > 0 and "track_rate" not in rate
    payload = _entry(db, out["audit_id"])
    assert [d["file_sha256"] for d in payload["dwells"]] == [d["file_sha256"] for d in out["dwells"]]
    assert all(len(d["file_sha256"]) == 64 for d in payload["dwells"])
    assert payload["skipped_files"] == out["skipped_files"]
    ctx = payload["policy_input"]["context"]["track"]
    assert ctx["dwells"] == used and ctx["llr_cn"] >= ctx["accept_cn"]
    assert main(["--db", db, "audit", "replay", str(out["audit_id"])]) == 0
    assert main(["--db", db, "audit", "verify"]) == 0


def test_a_type_spoof_track_crosses_the_reject_bound(setup, capsys) -> None:
    _, db, tracks = setup
    code, out, _ = _run(db, capsys, str(tracks["type"]))
    assert code == 1 and out["reasons"] == ["radar-claim-inconsistent"]
    assert out["llr"] <= out["sprt"]["reject_nats"] and out["dwells_used"] < DWELLS
    # the single-dwell verdicts are reported, the track's is the policy's over the combined LLR
    assert all(d["llr"] < 0 for d in out["dwells"])


def _m300_track(folder: Path, dwells: int, seed: int, astray: tuple[int, ...]) -> Path:
    """A genuine M300's track at 20 dB whose Remote ID declares a position 150 m beyond the truth in
    the dwells `astray`."""
    from datetime import datetime, timedelta, timezone

    from authn.scenario import Broadcast, simulate_flight
    from signatures.radar import get_preset

    sc = Scene(kind="uav", profile=shipped_profiles()["m300"], snr_db=20.0, range_m=400.0, radial_speed_mps=3.0)
    folder.mkdir()
    t0 = datetime.now(timezone.utc)
    for i in range(dwells):
        bc = Broadcast(serial=M300, offset_along_los_m=150.0 if i in astray else 0.0)
        rec, _ = simulate_flight(sc, get_preset("paper"), seed + i, bc, azimuth_deg=60.0,
                                 start_time=t0 + timedelta(seconds=i))
        write_recording(rec, folder / f"dwell_{i:06d}.h5")
    return folder


def test_a_position_spoof_stops_the_track_once_most_of_three_dwells_miss(setup, capsys) -> None:
    root, db, _ = setup
    folder = _m300_track(root / "position", KINEMATIC_DWELLS + 1, 300, astray=tuple(range(KINEMATIC_DWELLS + 1)))
    code, out, _ = _run(db, capsys, str(folder))
    assert code == 1 and "range-mismatch" in out["reasons"] and out["dwells_used"] == KINEMATIC_DWELLS
    assert out["dwells_skipped"] == 1


def test_a_one_dwell_track_is_judged_on_its_dwell(setup, capsys) -> None:
    """No later dwell can lift the forbid: the track's last dwell decides."""
    root, db, _ = setup
    folder = _m300_track(root / "position-one", 1, 350, astray=(0,))
    code, out, _ = _run(db, capsys, str(folder))
    assert code == 1 and "range-mismatch" in out["reasons"] and out["dwells_used"] == 1


@pytest.mark.parametrize("astray,decision,reason", [
    ((0,), "accept", "registered-active"),  # the first dwell misses: the next ones outvote it
    ((1,), "accept", "registered-active"),  # one dwell's declared position misses: the others confirm it
    ((1, 2), "reject", "range-mismatch"),  # more than half of the dwells used miss
])
def test_the_track_judges_the_kinematics_of_most_of_its_dwells(setup, capsys, astray, decision, reason) -> None:
    """The track's kinematic residual is its dwells' lower median: a declaration that misses the
    radar in one dwell of several is not a spoof, one that misses in most is."""
    root, db, _ = setup
    folder = _m300_track(root / f"astray-{'-'.join(map(str, astray))}", DWELLS, 400, astray)
    code, out, _ = _run(db, capsys, str(folder))
    assert out["decision"] == decision and reason in out["reasons"] and code == (0 if decision == "accept" else 1)
    if decision == "reject":
        assert out["dwells_used"] == 3  # [fine, astray]: the lower median is fine; a third astray decides
    else:
        assert out["dwells_used"] > max(astray) + 1  # the astray dwell was used, and the track went on past it
        assert astray[0] in [i for i, d in enumerate(out["dwells"]) if "range-mismatch" in d["dwell_reasons"]]


def test_a_missed_detection_is_no_evidence(setup, capsys) -> None:
    """A dwell that sees nothing (here: the target 60 dB under the noise) does not end the track:
    the genuine dwells after it decide; a track that never sees its target is rejected `no-target`
    after its last dwell."""
    from datetime import datetime, timedelta, timezone

    root, db, _ = setup
    t0 = datetime.now(timezone.utc)
    lost = Scene(kind="uav", profile=shipped_profiles()["m300"], snr_db=-60.0, range_m=400.0, radial_speed_mps=3.0,
                 elevation_deg=10.0)
    seen = lost.model_copy(update={"snr_db": 20.0, "range_m": 400.0 + 3.0 * 2.0})
    folder, blind = root / "missed", root / "blind"
    folder.mkdir()
    blind.mkdir()
    recs = (track_recordings(lost, "paper", [500, 501], M300, start=t0)
            + track_recordings(seen, "paper", list(range(502, 502 + DWELLS)), M300, start=t0 + timedelta(seconds=2)))
    for i, rec in enumerate(recs):
        write_recording(rec, folder / f"dwell_{i:06d}.h5")
    for i, rec in enumerate(track_recordings(lost, "paper", [600, 601, 602], M300, start=t0)):
        write_recording(rec, blind / f"dwell_{i:06d}.h5")
    code, out, err = _run(db, capsys, str(folder))
    assert code == 0 and out["decision"] == "accept", (err, out.get("reasons"))
    assert [d["dwell_reasons"] for d in out["dwells"][:2]] == [["no-target"], ["no-target"]]
    assert out["dwells"][0]["increment"] is None and out["dwells_used"] > 2
    code, out, _ = _run(db, capsys, str(blind))
    assert code == 1 and "no-target" in out["reasons"] and out["dwells_used"] == 3 and out["dwells_skipped"] == 0


def test_a_registry_decision_needs_no_dwell(setup, capsys) -> None:
    _, db, tracks = setup
    code, out, _ = _run(db, capsys, str(tracks["genuine"]), "--serial", "1581BUNKNOWN0001")
    assert code == 1 and "unregistered" in out["reasons"]  # and serial-mismatch: --serial is not the Basic ID
    assert out["dwells_used"] == 0 and out["radar"] is None and out["dwells_skipped"] == DWELLS - 1


def test_the_bounds_are_options(setup, capsys) -> None:
    """A looser false-accept target lowers the accept bound below one dwell's cap: one dwell decides."""
    _, db, tracks = setup
    code, out, _ = _run(db, capsys, str(tracks["genuine"]), "--false-accept", "0.1")
    assert code == 0 and out["dwells_used"] == 1 and out["sprt"]["accept_nats"] == round(math.log(0.99 / 0.1), 4)
    code, _, err = _run(db, capsys, str(tracks["genuine"]), "--false-reject", "0.7")
    assert code == 2 and "false reject rate" in err


def test_the_policy_decides_each_step(setup, capsys, tmp_path) -> None:
    """A site policy that allows one dwell's evidence only: the track stops at its second dwell."""
    from importlib import resources

    _, db, tracks = setup
    policy = tmp_path / "site.cedar"
    policy.write_text(resources.files("authn.policies").joinpath("default.cedar").read_text() + """
@id("one-dwell-only")
forbid (principal, action == Action::"authenticate", resource)
when { context has track && context.track.dwells >= 2 };
""")
    code, out, _ = _run(db, capsys, str(tracks["genuine"]), "--policy", str(policy))
    assert code == 1 and "one-dwell-only" in out["reasons"] and out["dwells_used"] == 2


def test_skipped_dwells_are_not_read_beyond_their_headers(setup, capsys, tmp_path) -> None:
    """A dwell whose IQ holds NaN passes the header validation; after the deciding dwell it is never
    read whole (accepted), before it the track is bad input naming it."""
    _, db, tracks = setup
    files = sorted(tracks["genuine"].iterdir())
    bad = _with_nan(files[-1], tmp_path / "nan.h5")
    read_header(bad)  # the header is valid
    code, out, _ = _run(db, capsys, *map(str, files[:-1]), str(bad))
    assert code == 0 and str(bad) in out["skipped_files"]
    code, out, err = _run(db, capsys, str(_with_nan(files[0], tmp_path / "first.h5")), *map(str, files[1:]))
    assert code == 2 and "non-finite" in out["error"]


def _with_nan(src: Path, dst: Path) -> Path:
    """A copy of a dwell with one NaN in its IQ (the writer refuses one: patched in place)."""
    import shutil

    import h5py

    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        f["iq"][0, 0] = np.nan
    return dst


def _cli(db: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "authn", "--db", db, "check", "--track", *args],
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("case", ["empty", "mixed-claims", "mixed-waveforms", "out-of-order"])
def test_a_track_that_is_not_one_targets_is_bad_input(setup, tmp_path, case: str) -> None:
    _, db, tracks = setup
    gen, spoof = sorted(tracks["genuine"].iterdir()), sorted(tracks["type"].iterdir())
    if case == "empty":
        (tmp_path / "empty").mkdir()
        args, words = [str(tmp_path / "empty")], "no .h5/.npz files"
    elif case == "mixed-claims":
        args, words = [str(gen[0]), str(spoof[1])], "a track is one claim"
    elif case == "mixed-waveforms":
        rec = read_recording(gen[1])
        other = tmp_path / "other.h5"
        write_recording(replace(rec, config=rec.config.replace(pri_s=rec.config.pri_s * 1.5)), other)
        args, words = [str(gen[0]), str(other)], "a track is one radar waveform"
    else:
        args, words = [str(gen[2]), str(gen[1])], "must be in time order"
    from authn.audit import list_entries
    from registry.dbapi import Database

    proc = _cli(db, *args)
    assert proc.returncode == 2 and proc.stdout == ""
    assert len(proc.stderr.strip().splitlines()) == 1 and words in proc.stderr and "Traceback" not in proc.stderr
    last = list_entries(Database(db), kind="error")[-1].payload  # the failed attempt is audited
    assert last["error_kind"] == "bad-input" and words in last["error"]


def test_sprt_bounds_discount_and_cap() -> None:
    s = Sprt(false_accept=0.001, false_reject=0.01, correlation=0.2, cap_nats=4.0)
    assert math.isclose(s.accept_nats, math.log(0.99 / 0.001)) and math.isclose(s.reject_nats, math.log(0.01 / 0.999))
    assert s.increment(9.0) == 4.0 and s.increment(-9.0) == -4.0 and s.increment(1.5) == 1.5
    # the classifier alone (no physics term) only ever counts against the claim
    assert s.increment(2.0, physics=False) == 0.0 and s.increment(-9.0, physics=False) == -4.0
    # an LLR that is not a number counts fully against (fail closed), with or without physics
    assert s.increment(math.nan) == -4.0 and s.increment(math.nan, physics=False) == -4.0
    assert s.walk([(math.nan, True)] * 2) == ("reject", 2)
    # n equicorrelated dwells count as n / (1 + (n - 1) rho)
    assert math.isclose(s.track_llr([4.0, 4.0, 4.0]), 12.0 / 1.4)
    assert s.track_llr([]) == 0.0 and Sprt(correlation=0.0).track_llr([1.0, 2.0]) == 3.0
    for bad in ({"false_accept": 0.0}, {"false_reject": 0.5}, {"correlation": 1.0}, {"false_accept": float("nan")}):
        with pytest.raises(ValueError):
            Sprt(**bad)


def test_a_dwell_that_moves_no_sum_does_not_dilute_the_track() -> None:
    """A dwell whose physics term abstained and whose classifier favoured the claim adds 0 to every
    sum: no observation, so it leaves the discount's n alone (before, five such dwells took three
    dwells of +4 nats from an accept at 8.57 to an inconclusive 5.0)."""
    from authn.sprt import observations

    s = Sprt()
    three = [{"unknown": 4.0, "m300": 4.0}] * 3
    quiet = [{"unknown": 0.0, "m300": 0.0}] * 5
    assert s.walk([(4.0, True), (2.0, False), (4.0, True), (2.0, False), (4.0, True)]) == ("accept", 5)
    assert math.isclose(s.track_llr(three + quiet), s.track_llr(three)) and s.track_llr(three) >= s.accept_nats
    assert math.isclose(s.refute_llr(quiet + three), s.refute_llr(three))
    assert s.track_llr(three + [{"unknown": 0.0, "m300": -0.5}]) < s.track_llr(three)  # against the claim: counted
    assert observations([{"a": 0.0, "b": 0.0}, {"a": 0.0, "b": -1.0}, 2.0, 0.0, math.nan]) == 3
    assert s.track_llr(quiet) == 0.0 and s.refute_llr(quiet) == 0.0


def test_icc_of_known_groups() -> None:
    """The intra-class correlation the discount is measured with: 0 for groups with one mean,
    near 1 for groups that differ far more than within."""
    rng = np.random.default_rng(3)
    same = [list(rng.normal(0, 1, 6)) for _ in range(200)]
    apart = [list(m + rng.normal(0, 0.1, 6)) for m in rng.normal(0, 3, 200)]
    assert abs(icc(same)) < 0.05 and icc(apart) > 0.95


@pytest.mark.parametrize("suffix", [".h5", ".npz"])
def test_the_header_is_the_recordings_metadata(setup, tmp_path, suffix: str) -> None:
    """What the track is validated with equals what the full read gives, in both containers."""
    _, _, tracks = setup
    rec = read_recording(sorted(tracks["genuine"].iterdir())[0])
    path = write_recording(rec, tmp_path / f"dwell{suffix}")
    head = read_header(path)
    assert head.config == rec.config and head.site == rec.site and head.start_time == rec.start_time
    assert head.shape == rec.iq.shape and head.domain == rec.domain and head.mid_time == rec.mid_time
    assert np.array_equal(head.remote_id, rec.remote_id) and np.array_equal(head.remote_id_time_s, rec.remote_id_time_s)


@needs_lab
def test_bench_track_rows(capsys) -> None:
    """`authn bench --track`: the correlation rows and dwells per decision, as JSON."""
    capsys.readouterr()
    assert main(["bench", "--track", "--preset", "paper", "--n", "2", "--snr", "20", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert [r["category"] for r in doc["dependence"]] == ["genuine", "type_spoof"]
    assert all(r["dwells"] == 10 for r in doc["dependence"])  # 2 scenes x 5 dwells, every one verified
    rows = {r["category"]: r for r in doc["tracks"]}
    # the bench registers every shipped model: its two genuine tracks (an M600's and an M300's) are of a
    # radar-confusable pair, inconclusive unsigned at their first dwell; none is refuted
    assert rows["genuine"]["right"] == 0.0 and rows["genuine"]["inconclusive"] == 1.0
    assert rows["genuine"]["median_dwells"] == 1
    assert rows["type_spoof"]["right"] == 1.0 and 1 <= rows["type_spoof"]["median_dwells"] <= 10


TRACK = {"accept_cn": 691, "reject_cn": -461}


@pytest.mark.parametrize("llr_cn,ctx,decision,reasons", [
    (691, {}, "accept", ["registered-active"]),  # at the accept bound
    (690, {}, "inconclusive", ["radar-inconclusive"]),
    (0, {}, "inconclusive", ["radar-inconclusive"]),
    (-460, {}, "inconclusive", ["radar-inconclusive"]),
    (-461, {}, "reject", ["radar-claim-inconsistent"]),  # at the reject bound
    (-461, {"radar_model": "bird"}, "reject", ["radar-claim-inconsistent", "radar-not-a-drone"]),
    (None, {}, "inconclusive", ["radar-inconclusive"]),  # nothing verified yet
    (900, {"range_residual_cm": 900}, "reject", ["range-mismatch"]),  # the track's kinematics (its dwells' median)
])
def test_the_default_policy_over_a_track(llr_cn, ctx, decision, reasons) -> None:
    """The rows of tests/decision/test_policy.py over a track of three dwells: one rule."""
    from authn.policy import PolicyEngine

    context = {**GOOD, **ctx, "track": {**TRACK, "llr_cn": 0 if llr_cn is None else llr_cn,
                                        "dwells": 0 if llr_cn is None else 3}}
    result = PolicyEngine.load().decide(M300, ACTIVE, SITE, context)
    assert (result.decision, result.reasons) == (decision, reasons)


def test_simulate_writes_a_track_that_check_takes(setup, tmp_path, capsys) -> None:
    """`authn simulate --track N --interval-s T`: N dwells of one target, T apart in time and its range
    moved by its speed, which `check --track` decides; a file name or --count with it is bad input."""
    _, db, _ = setup
    folder = tmp_path / "sim"
    assert main(["simulate", "--model", "phantom4", "--range", "300", "--speed", "2", "--rid-serial", PHANTOM4,
                 "--track", "4", "--interval-s", "0.5", "--out", str(folder)]) == 0
    files = sorted(folder.iterdir())
    assert [f.name for f in files] == [f"dwell_{i:06d}.h5" for i in range(4)]
    heads = [read_header(f) for f in files]
    gaps = [(b.start_time - a.start_time).total_seconds() for a, b in zip(heads, heads[1:])]
    assert gaps == pytest.approx([0.5] * 3, abs=1e-6)
    code, out, err = _run(db, capsys, str(folder))
    assert code == 0 and out["decision"] == "accept" and out["dwells_used"] >= 2, (err, out.get("reasons"))
    for bad in (["--out", str(tmp_path / "one.h5")], ["--count", "3", "--out", str(tmp_path / "many")]):
        assert main(["simulate", "--model", "m300", "--range", "300", "--track", "2", *bad]) == 2
