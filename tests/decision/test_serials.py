"""One reading of a UAS ID (`core.uasid.normalise`) at every entry point: `authn register`,
`check --serial`, `--claims`, a Remote ID broadcast, the registry import; a malformed one is
bad input (exit 2). The service's form field is tests/service/test_service_serials.py."""

from __future__ import annotations

import json

import pytest

from authn.cli import main
from authn.scenario import Broadcast, simulate_flight
from core.errors import BadInput
from core.uasid import SerialError, as_heard, normalise
from signatures.profiles import shipped_profiles
from signatures.radar import get_preset
from signatures.recording import write_recording
from signatures.sim.scene import Scene

LOWER = "1581a0000000080"
UPPER = LOWER.upper()


def test_one_normal_form_per_id():
    assert normalise(" 1581f5fjd12345678901 ") == "1581F5FJD12345678901"
    u = "123e4567-e89b-12d3-a456-426614174000"
    assert normalise(u.upper()) == u
    assert normalise("0xE1deadbeef") == "E1DEADBEEF"
    assert normalise("fa3abc1234") == "FA3ABC1234"
    for bad in ("not-a-serial", "has space", "", "x" * 65):
        with pytest.raises(SerialError) as err:
            normalise(bad)
        assert isinstance(err.value, BadInput)
    assert as_heard(" 1581a0000000080") == UPPER and as_heard("not a serial ") == "not a serial"


@pytest.fixture(scope="module")
def world(tmp_path_factory) -> dict:
    """A registry with the serial registered in lower case, and a return of that drone that
    broadcasts its serial in lower case too."""
    root = tmp_path_factory.mktemp("serials")
    db = f"sqlite:///{root / 'r.sqlite3'}"
    assert main(["--db", db, "register", "--serial", LOWER, "--model", "m300", "--operator-id", "OP-1",
                 "--valid-from", "2020-01-01T00:00:00Z"]) == 0
    scene = Scene(profile=shipped_profiles()["m300"], range_m=300.0, radial_speed_mps=2.0, snr_db=15.0)
    rec, _ = simulate_flight(scene, get_preset("paper"), 3, Broadcast(serial=LOWER))
    return {"db": db, "root": root, "file": write_recording(rec, root / "flight.h5")}


def _claim(capsys, args: list[str]) -> tuple[int, dict]:
    capsys.readouterr()
    code = main(args + ["--json"])
    return code, json.loads(capsys.readouterr().out)


def test_register_stores_the_normal_form(world, capsys):
    assert main(["--db", world["db"], "registry", "show", LOWER, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["serial"] == UPPER


@pytest.mark.parametrize("how", ["--serial", "--claims", "remote id"])
def test_a_lower_case_claim_is_the_registered_drone(world, capsys, how):
    args = ["--db", world["db"], "check", str(world["file"])]
    if how == "--serial":
        args += ["--serial", LOWER]
    elif how == "--claims":
        claims = world["root"] / "claims.csv"
        claims.write_text(f"file,serial\nflight.h5,{LOWER}\n")
        args += ["--claims", str(claims)]
    code, out = _claim(capsys, args)
    report = out[0] if isinstance(out, list) else out
    assert report["claim"]["serial"] == UPPER, report
    assert "unregistered" not in report["reasons"] and report["registry"]["registered"], report
    assert code in (0, 4), report


def test_a_malformed_serial_is_bad_input(world, capsys):
    code = main(["--db", world["db"], "check", str(world["file"]), "--serial", "not-a-serial"])
    err = capsys.readouterr().err
    assert code == 2 and "not a UAS ID" in err and len(err.strip().splitlines()) == 1


def test_registry_import_reads_the_normal_form(world, capsys):
    good = world["root"] / "ok.csv"
    good.write_text("serial,model\n1581b00000000081,m600\n")
    assert main(["--db", world["db"], "registry", "import", str(good)]) == 0
    assert main(["--db", world["db"], "registry", "show", "1581B00000000081"]) == 0
    bad = world["root"] / "bad.csv"
    bad.write_text("serial,model\nnot-a-serial,m600\n")
    capsys.readouterr()
    assert main(["--db", world["db"], "registry", "import", str(bad)]) == 2
    assert "not-a-serial" in capsys.readouterr().err
