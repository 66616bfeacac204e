"""A claim that rests on Remote ID must say where the drone is: a return whose Remote ID holds a
Basic ID and no Location (unsigned, or DRIP-signed) is `remote-id-no-location`, decided before any
radar work; an operator's claim (`--serial`, no Remote ID) decides as before and says its position
was not checked. Real CLI, real HDF5 from the simulator."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from datetime import timedelta
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from authn.cli import main
from signatures.recording import read_recording, write_recording

SERIAL, SIGNED = "1581BDEM00000042", "1581BDEM00000099"
NOT_CHECKED = "not checked: no Remote ID position"
RADAR_STAGES = {"radar_features", "classify", "kinematics"}


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("rid-position")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    assert main(["keys", "generate", "--out", str(root / "ua.pem"), "--json"]) == 0
    assert main(["--db", db, "register", "--serial", SERIAL, "--model", "m300", "--valid-from", "2026-01-01"]) == 0
    assert main(["--db", db, "register", "--serial", SIGNED, "--model", "m300", "--public-key",
                 str(root / "ua.pub.pem"), "--valid-from", "2026-01-01"]) == 0
    return {"root": root, "db": db, "key": root / "ua.pem"}


def _fly(world: dict, name: str, *extra: str) -> Path:
    out = world["root"] / f"{name}.h5"
    assert main(["simulate", "--model", "m300", "--range", "500", "--speed", "4", "--out", str(out), *extra]) == 0
    return out


def _keep(src: Path, dst: Path, rows: np.ndarray, times: np.ndarray) -> Path:
    return write_recording(replace(read_recording(src), remote_id=rows, remote_id_time_s=times), dst)


def _check(world: dict, capsys, path: Path, *extra: str) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(["--db", world["db"], "check", str(path), "--json", *extra])
    return code, json.loads(capsys.readouterr().out)


def test_basic_id_without_location_is_remote_id_no_location(world: dict, capsys) -> None:
    spoof = _fly(world, "spoof", "--rid-serial", SERIAL, "--rid-offset", "300")
    code, out = _check(world, capsys, spoof)
    assert code == 1 and "range-mismatch" in out["reasons"]  # with its Location, the position betrays it
    rec = read_recording(spoof)
    basic = _keep(spoof, world["root"] / "basic-only.h5", rec.remote_id[:1], rec.remote_id_time_s[:1])
    code, out = _check(world, capsys, basic)
    assert code == 1 and out["decision"] != "accept" and out["reasons"] == ["remote-id-no-location"]
    assert set(out["skipped"]) == RADAR_STAGES and out["radar"] is None  # decided before any radar work
    assert out["claim"]["source"] == "remote_id" and out["claim"]["position"] == NOT_CHECKED
    assert out["kinematics"] is None and out["remote_id"]["messages"] == 1


def test_signed_basic_id_without_location_is_remote_id_no_location(world: dict, capsys) -> None:
    """A valid signature over a Basic ID alone says who, never where: any drone of the type could
    replay it."""
    from authn.uakeys import load
    from remoteid.drip import encode_wrapper, paginate

    signed = _fly(world, "signed", "--rid-serial", SIGNED, "--sign-key", str(world["key"]))
    code, out = _check(world, capsys, signed)
    assert out["remote_id_auth"]["status"] == "valid" and "remote-id-no-location" not in out["reasons"]
    rec, key = read_recording(signed), load(world["key"])
    basic = bytes(rec.remote_id[0])
    start = rec.start_time
    data = encode_wrapper([basic], key.det, key.private_raw, start - timedelta(seconds=60),
                          start + timedelta(seconds=300))
    pages = paginate(data, start)
    rows = np.frombuffer(basic + b"".join(pages), np.uint8).reshape(-1, 25).copy()
    only = _keep(signed, world["root"] / "signed-basic-only.h5", rows, np.zeros(len(rows)))
    code, out = _check(world, capsys, only)
    assert out["remote_id_auth"]["status"] == "valid" and out["remote_id_auth"]["covered_messages"] == [0]
    assert code == 1 and out["decision"] != "accept" and out["reasons"] == ["remote-id-no-location"]
    assert out["claim"]["position"] == NOT_CHECKED and out["radar"] is None


def _without_new_rules(tmp_path: Path) -> Path:
    """The default policy less the two Remote ID rules: what deciding was before them."""
    text = resources.files("authn.policies").joinpath("default.cedar").read_text()
    for rule in ("remote-id-no-location", "remote-id-conflict"):
        shipped = f'@id("{rule}")' in text
        text, n = re.subn(r'@id\("' + rule + r'"\)\nforbid[^;]*?\};\n', "", text)
        assert n == shipped, rule
    out = tmp_path / "before.cedar"
    out.write_text(text)
    return out


def test_operator_claim_without_remote_id_decides_as_before(world: dict, capsys, tmp_path: Path) -> None:
    plain = _fly(world, "plain")
    code, out = _check(world, capsys, plain, "--serial", SERIAL)
    before = _without_new_rules(tmp_path)
    before_code, before = _check(world, capsys, plain, "--serial", SERIAL, "--policy", str(before))
    assert (code, out["decision"], out["reasons"]) == (before_code, before["decision"], before["reasons"])
    assert "remote-id-no-location" not in out["reasons"] and out["radar"] is not None
    assert out["claim"] == {"serial": SERIAL, "source": "cli", "remote_id_serial": None, "position": NOT_CHECKED}
    assert out["kinematics"] is None and out["remote_id"]["messages"] == 0
    capsys.readouterr()
    assert main(["--db", world["db"], "audit", "list", "--json"]) == 0
    entry = [e for e in json.loads(capsys.readouterr().out) if e.get("seq") == out["audit_id"]][0]
    context = entry["payload"]["policy_input"]["context"]
    assert "remote_id_no_location" not in context and "remote_id_conflict" not in context  # the request as before
