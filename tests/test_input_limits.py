"""Inputs at the edge of what Python can hold are bad input, not crashes: times whose UTC
instant falls outside years 1..9999 (exit 2 on the CLI, 422 from the service, never an
OverflowError), and JSON nested deeper than 64 levels (exit 2, never a RecursionError)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from authn.cli import main
from core.parsing import MAX_JSON_DEPTH, JsonTooDeep, loads_json, parse_iso_time

SERIAL = "1581F5FJD12345678901"
OUT_OF_RANGE = ["0001-01-01T00:00:00+23:59", "0001-01-01T00:00:00+00:01", "9999-12-31T23:59:59-23:59"]


def run(capsys, db: str, *args: str) -> tuple[int, str, str]:
    code = main(["--db", db, *args])
    out, err = capsys.readouterr()
    return code, out, "".join(line for line in err.splitlines(keepends=True)
                              if not line.startswith("authn: created new database "))


def _one_error_line(err: str, needle: str) -> None:
    assert err.startswith("error: ") and err.count("\n") == 1 and needle in err, err
    assert "Traceback" not in err and "Overflow" not in err and "Recursion" not in err, err


@pytest.fixture
def db(tmp_path: Path) -> str:
    return f"sqlite:///{tmp_path / 'r.sqlite3'}"


# --- dates ---------------------------------------------------------------------------------

@pytest.mark.parametrize("when", OUT_OF_RANGE)
def test_parse_iso_time_refuses_what_utc_cannot_hold(when: str) -> None:
    from core.errors import BadInput

    with pytest.raises(BadInput, match="out of range"):
        parse_iso_time(when, "--valid-from")
    assert parse_iso_time("0001-01-03T00:00:00+23:59", "x").year == 1  # two days in: fine


@pytest.mark.parametrize("option", ["--valid-from", "--valid-until"])
@pytest.mark.parametrize("when", OUT_OF_RANGE)
def test_register_out_of_range_time_is_one_line_exit_2(capsys, db: str, option: str, when: str) -> None:
    code, _, err = run(capsys, db, "register", "--serial", SERIAL, "--model", "m300", option, when)
    assert code == 2
    _one_error_line(err, f"{option}: {when!r} is out of range")


def test_audit_list_since_out_of_range_is_exit_2(capsys, db: str) -> None:
    code, _, err = run(capsys, db, "audit", "list", "--since", OUT_OF_RANGE[0])
    assert code == 2
    _one_error_line(err, "--since")


@pytest.mark.parametrize("fmt", ["csv", "json"])
def test_import_out_of_range_time_is_one_line_exit_2(capsys, db: str, tmp_path: Path, fmt: str) -> None:
    path = tmp_path / f"fleet.{fmt}"
    if fmt == "csv":
        path.write_text(f"serial,model,valid_from\n{SERIAL},m300,{OUT_OF_RANGE[0]}\n")
    else:
        path.write_text(json.dumps({"format": "authn-registry/1", "profiles": [], "identities": [
            {"serial": SERIAL, "model": "m300", "valid_from": OUT_OF_RANGE[0]}]}))
    code, _, err = run(capsys, db, "registry", "import", str(path))
    assert code == 2
    _one_error_line(err, "out of range")


def test_new_identity_refuses_a_datetime_that_overflows_in_utc() -> None:
    """The service hands NewIdentity parsed datetimes, not text: same refusal."""
    from datetime import datetime, timedelta, timezone

    from core.checked import Invalid
    from registry.store import NewIdentity

    early = datetime(1, 1, 1, tzinfo=timezone(timedelta(hours=23, minutes=59)))
    with pytest.raises(Invalid, match="out of range"):
        NewIdentity(serial=SERIAL, model="m300", valid_from=early)


def test_service_answers_422_not_500(tmp_path: Path) -> None:
    """POST /v1/identities with a valid_from before year 1 in UTC: 422 {"error": ...}, no traceback."""
    from authn.service.keys import create_key
    from tests.service.server import server_env, start

    db = f"sqlite:///{tmp_path / 'svc.sqlite3'}"
    _, token = create_key(db, "admin", "limits-test")
    keys = tmp_path / "keys"
    keys.mkdir()
    srv = start(db, tmp_path / "serve.log", server_env(keys))
    try:
        with srv.client(token) as client:
            for field, when in (("valid_from", OUT_OF_RANGE[0]), ("valid_until", OUT_OF_RANGE[2])):
                r = client.post("/v1/identities", json={"serial": SERIAL, "model": "m300", field: when})
                assert r.status_code == 422, r.text
                body = r.json()
                assert list(body) == ["error"] and field in body["error"] and "out of range" in body["error"]
            r = client.post("/v1/identities", json={"serial": SERIAL, "model": "m300",
                                                    "valid_from": "2026-01-01T00:00:00+00:00"})
            assert r.status_code == 201, r.text
    finally:
        log = srv.stop()
    assert "Traceback" not in log and "OverflowError" not in log, log[-3000:]


# --- JSON nesting --------------------------------------------------------------------------

def _deep(depth: int) -> str:
    return "[" * depth + "]" * depth


def test_loads_json_limit() -> None:
    assert loads_json(_deep(MAX_JSON_DEPTH)) is not None
    assert loads_json('{"a": [1, {"b": 2}]}') == {"a": [1, {"b": 2}]}
    for depth in (MAX_JSON_DEPTH + 1, 5000, 100_000):  # parsed then measured / json's own RecursionError
        with pytest.raises(JsonTooDeep, match=f"nesting deeper than {MAX_JSON_DEPTH} levels"):
            loads_json(_deep(depth))
    with pytest.raises(json.JSONDecodeError):
        loads_json("{nope")


@pytest.mark.parametrize("depth", [MAX_JSON_DEPTH + 1, 100_000])
def test_registry_import_of_deep_json_is_one_line_exit_2(capsys, db: str, tmp_path: Path, depth: int) -> None:
    path = tmp_path / "deep.json"
    path.write_text('{"format": "authn-registry/1", "profiles": [], "identities": ' + _deep(depth) + "}")
    code, _, err = run(capsys, db, "registry", "import", str(path))
    assert code == 2
    _one_error_line(err, f"{path}: nesting deeper than {MAX_JSON_DEPTH} levels")


def test_trust_registry_file_of_deep_json_is_exit_2(capsys, db: str, tmp_path: Path) -> None:
    deep = tmp_path / "trust.json"
    deep.write_text('{"registries": ' + _deep(100_000) + "}")
    flight = tmp_path / "f.h5"
    flight.write_text("x")
    code, _, err = run(capsys, db, "check", str(flight), "--serial", "1581BDEM00000002", "--trust-registry", str(deep))
    assert code == 2
    _one_error_line(err, "nesting deeper than")


@pytest.mark.parametrize("depth", [MAX_JSON_DEPTH + 1, 5000])
@pytest.mark.parametrize("reader", ["radar", "profiles", "dca1000", "modelcard"])
def test_other_json_readers_refuse_deep_documents(tmp_path: Path, reader: str, depth: int) -> None:
    from core.errors import AuthnException

    path = tmp_path / ("card.json" if reader == "modelcard" else "doc.json")
    path.write_text('{"a": ' + _deep(depth) + "}")
    with pytest.raises(AuthnException, match="nesting deeper than 64 levels"):
        if reader == "radar":
            from signatures.radar import load_waveform
            load_waveform(path)
        elif reader == "profiles":
            from signatures.profiles import load_profiles
            load_profiles(path)
        elif reader == "dca1000":
            from signatures.importers.dca1000 import load_config
            load_config(path)
        else:
            from signatures.classify.modelcard import read_card
            read_card(tmp_path)


# --- numbers -------------------------------------------------------------------------------

ABSURD_NUMBERS = {"5001 digits": "9" * 5001, "negative 5001 digits": "-" + "9" * 5001, "1e400": "1e400",
                  "NaN": "NaN", "-Infinity": "-Infinity"}


@pytest.mark.parametrize("number", list(ABSURD_NUMBERS))
def test_loads_json_refuses_numbers_no_field_can_hold(number: str) -> None:
    with pytest.raises(json.JSONDecodeError) as caught:
        loads_json('{"a": [1, 2.5, ' + ABSURD_NUMBERS[number] + "]}")
    assert caught.value.pos == 15  # where the number is


def test_loads_json_keeps_ordinary_numbers() -> None:
    from core.parsing import MAX_JSON_INT_DIGITS

    big = "9" * MAX_JSON_INT_DIGITS
    assert loads_json(f'[{big}, -0.5, 1e300, 0]') == [int(big), -0.5, 1e300, 0]


@pytest.mark.parametrize("where", ["identities", "profiles"])
@pytest.mark.parametrize("number", list(ABSURD_NUMBERS))
def test_registry_import_of_absurd_numbers_is_one_line_exit_2(capsys, db: str, tmp_path: Path, where: str,
                                                              number: str) -> None:
    """A 5001-digit integer was a ValueError (exit 3); 1e400 and NaN slipped through as floats."""
    record = ('{"slug": "x", "rotor_count": ' if where == "profiles" else
              '{"serial": "' + SERIAL + '", "model": "m300", "operator_id": ') + ABSURD_NUMBERS[number] + "}"
    path = tmp_path / "fleet.json"
    path.write_text('{"format": "authn-registry/1", "profiles": [' + (record if where == "profiles" else "")
                    + '], "identities": [' + (record if where == "identities" else "") + "]}")
    code, _, err = run(capsys, db, "registry", "import", str(path))
    assert code == 2
    _one_error_line(err, f"{path}: not JSON")
