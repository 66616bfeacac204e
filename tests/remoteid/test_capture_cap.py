"""A capture naming more drones than `--max-drones` (default 64) is bad input: exit 2, one line
naming the count, the limit and how to raise it, one audit error entry and no decision, refused
before any drone is decided. At the limit every drone is decided as before. Real pcap bytes, a
simulated return, the real CLI."""

from __future__ import annotations

import json

import pytest

from authn.cli import main
from signatures.recording import read_recording
from tests.remoteid.capture_tools import crowd
from tests.service.server import flight


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    root = tmp_path_factory.mktemp("ridcap-cap")
    ret = flight(root, "f", "m300", None)
    at = read_recording(ret).start_time
    return {"db": f"sqlite:///{root / 'r.sqlite3'}", "root": root, "ret": ret,
            **{str(n): crowd(root / f"{n}.pcap", at, n) for n in (65, 3, 4)}}


def _run(w: dict, capsys, *args: str) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["--db", w["db"], "check", *args])
    out, err = capsys.readouterr()
    return code, out, "".join(x for x in err.splitlines(keepends=True) if not x.startswith("authn: created new"))


def _audit(w: dict, capsys) -> list[dict]:
    capsys.readouterr()
    assert main(["--db", w["db"], "audit", "list", "--json", "--limit", "100000"]) == 0
    return json.loads(capsys.readouterr().out)


def test_65_drones_is_refused_at_the_default_limit_and_audited(world, capsys) -> None:
    before = len(_audit(world, capsys))
    code, out, err = _run(world, capsys, str(world["ret"]), "--rid-capture", str(world["65"]))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "65 drones heard" in err and "limit of 64" in err and "--max-drones" in err, err
    new = _audit(world, capsys)[before:]
    assert [e["kind"] for e in new] == ["error"]  # no decision was made
    assert new[0]["payload"]["error_kind"] == "bad-input" and "65 drones" in new[0]["payload"]["error"]
    # a named serial is one decision, whatever the crowd
    code, out, _ = _run(world, capsys, str(world["ret"]), "--rid-capture", str(world["65"]), "--serial",
                        "CROWD00007", "--json")
    assert code == 1 and json.loads(out)["claim"]["serial"] == "CROWD00007"


def test_the_limit_is_an_option_and_at_it_every_drone_is_decided(world, capsys) -> None:
    before = len(_audit(world, capsys))
    code, out, _ = _run(world, capsys, str(world["ret"]), "--rid-capture", str(world["3"]), "--max-drones", "3",
                        "--json")
    assert code == 1 and len(json.loads(out)) == 3  # three unregistered serials: three rejections
    code, out, err = _run(world, capsys, str(world["ret"]), "--rid-capture", str(world["4"]), "--max-drones", "3")
    assert code == 2 and "4 drones heard" in err and "limit of 3" in err and "--max-drones" in err, err
    assert [e["kind"] for e in _audit(world, capsys)[before:]] == ["decision"] * 3 + ["error"]


def test_a_claims_csv_capture_over_the_limit_fails_its_file_only(world, capsys) -> None:
    other = world["root"] / "g.h5"
    other.write_bytes(world["ret"].read_bytes())
    csv = world["root"] / "claims.csv"
    csv.write_text(f"file,serial,rid_capture\nf.h5,,{world['65']}\ng.h5,,{world['3']}\n")
    before = len(_audit(world, capsys))
    code, out, err = _run(world, capsys, str(world["ret"]), str(other), "--claims", str(csv), "--json")
    assert code == 2
    results = json.loads(out)
    assert results[0]["exit_code"] == 2 and "65 drones heard" in results[0]["error"]
    assert [r.get("decision") for r in results[1:]] == ["reject"] * 3
    assert sorted(e["kind"] for e in _audit(world, capsys)[before:]) == ["decision"] * 3 + ["error"]

