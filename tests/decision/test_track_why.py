"""A track says why it ended where it did (`TrackOutcome.why`): refuted after so many of its
dwells, or inconclusive only when it ran out of dwells; and `simulate --track` writes the tracks
of two drones that `check --track` decides each on its own claim."""

from __future__ import annotations

import json

import pytest

from authn.cli import main
from tests.proc_signals import wait_until_running
from tests.registry_tools import register

M300, PHANTOM4 = "1581BDEM00000042", "1581BDEM00000044"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("why")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    register(db, (M300, "m300"), (PHANTOM4, "phantom4"))
    for name, model, serial in (("m300", "m300", M300), ("phantom4", "phantom4", PHANTOM4),
                                ("impostor", "phantom4", M300)):
        assert main(["simulate", "--model", model, "--range", "300", "--speed", "2", "--rid-serial", serial,
                     "--track", "6", "--interval-s", "1", "--seed", "7", "--out", str(root / name)]) == 0
    return {"db": db, "root": root}


def _track(world, capsys, name: str, *extra: str) -> tuple[int, dict, str]:
    capsys.readouterr()
    code = main(["--db", world["db"], "check", "--track", str(world["root"] / name), "--json", *extra])
    out = json.loads(capsys.readouterr().out)
    main(["--db", world["db"], "check", "--track", str(world["root"] / name), *extra])
    return code, out, capsys.readouterr().out


def test_two_drones_tracks_are_decided_each_on_its_own_claim(world, capsys):
    for name, serial in (("m300", M300), ("phantom4", PHANTOM4)):
        code, out, _ = _track(world, capsys, name)
        assert out["claim"]["serial"] == serial and out["decision"] == "accept" and code == 0, out["reasons"]
        assert out["why"].startswith(f"the claim is accepted after {out['dwells_read']} of 6 dwells")


def test_a_refuted_track_says_it_is_refuted_after_how_many_dwells(world, capsys):
    """A Phantom 4 broadcasting the M300's serial: refuted before its last dwell, and said so
    (not 'inconclusive')."""
    code, out, human = _track(world, capsys, "impostor")
    assert code == 1 and out["decision"] == "reject" and out["dwells_skipped"] > 0, out["reasons"]
    assert out["why"].startswith(f"the claim is refuted after {out['dwells_read']} of 6 dwells: LLR -")
    assert "inconclusive" not in out["why"]
    assert f"  why      {out['why']}" in human


def test_inconclusive_only_when_the_dwells_ran_out(world, capsys, tmp_path):
    """One dwell of the genuine M300 (capped below both bounds): inconclusive, all dwells read."""
    one = tmp_path / "one"
    one.mkdir()
    (one / "dwell_000000.h5").write_bytes((world["root"] / "m300" / "dwell_000000.h5").read_bytes())
    capsys.readouterr()
    code = main(["--db", world["db"], "check", "--track", str(one), "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 4 and out["decision"] == "inconclusive" and out["dwells_skipped"] == 0
    assert out["why"].startswith("inconclusive: all 1 dwell read and neither bound crossed")


@pytest.mark.slow
def test_sigterm_mid_track_exits_143_with_nothing_printed(tmp_path):
    """A track whose dwells never see the target goes on through all of them; SIGTERM once the
    command runs stops it with 143 and one line, and no decision printed."""
    import os
    import signal
    import subprocess
    import sys

    db = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    register(db, (M300, "m300"))
    folder = tmp_path / "faint"
    assert main(["simulate", "--model", "m300", "--range", "300", "--speed", "2", "--snr", "-30", "--rid-serial",
                 M300, "--track", "200", "--interval-s", "1", "--out", str(folder)]) == 0
    env = {**os.environ, "AUTHN_DATABASE_URL": db}
    proc = subprocess.Popen([sys.executable, "-m", "authn", "check", "--track", str(folder)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_until_running(proc.pid, 0.3)  # into the track: its 200 dwells take seconds
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143 and out == "", (out, err)
    assert err.strip().splitlines() == ["error: interrupted by SIGTERM"], err
    assert main(["--db", db, "audit", "verify"]) == 0

