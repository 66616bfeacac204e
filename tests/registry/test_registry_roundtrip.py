"""Registry export -> import into a fresh database is lossless (JSON), and CSV keeps
status and public keys; on SQLite, and on PostgreSQL when AUTHN_TEST_POSTGRES_URL is set
(reported as skipped, with the reason, when it is not)."""

from __future__ import annotations

import io
import json
import os
import uuid
from datetime import datetime, timezone

import pytest

from registry.db import dispose_engines
from registry.dbapi import transaction
from registry.errors import RegistryError
from registry.models import Identity, ModelProfile
from registry.store import (
    NewIdentity,
    export_csv,
    export_document,
    export_json,
    get_identity,
    import_csv,
    import_json,
    list_identities,
    list_profiles,
    parse_import,
    register_identity,
    register_profile,
    revoke_identity,
)
from signatures.profiles import UavProfile, shipped_profiles
from tests.registry.test_registry_cli import run

PG_URL = os.environ.get("AUTHN_TEST_POSTGRES_URL")
KEY = bytes(range(32))
NOTES = 'survey, "north" field\nsecond line: ÄÖ 測試 🛸'
X8 = UavProfile(slug="x8", name="Octo X8 — coaxial", rotors=8, arms=4, blade_length_m=0.38,
                rotor_rate_hz=45.123456789, propeller_distance_m=1.2)
H6 = UavProfile(slug="h6", name="Hexa (unused)", rotors=6, arms=6, blades_per_rotor=3,
                blade_length_m=0.25, rotor_rate_hz=60.0, propeller_distance_m=0.9)
S_KEY, S_REVOKED, S_CAA = "1581F5FJD12345678901", "1581F5FJD12345678902", "FIN-87ASTRDGE12K"
S_UUID, S_SESSION = "0f1e2d3c-4b5a-6978-8796-a5b4c3d2e1f0", "01AB23CD"


@pytest.fixture(params=["sqlite", "postgresql"])
def new_db(request, tmp_path):
    """Factory of empty (never migrated) database URLs on one backend, like conftest's db_url."""
    if request.param == "postgresql" and not PG_URL:
        pytest.skip("AUTHN_TEST_POSTGRES_URL is not set: no PostgreSQL server to round-trip through")
    made: list[str] = []

    def make_sqlite() -> str:
        path = tmp_path / f"registry{len(made)}.sqlite3"
        made.append(str(path))
        return f"sqlite:///{path}"

    def make_pg() -> str:
        from sqlalchemy import create_engine
        from sqlalchemy.engine import make_url

        from registry.db import resolve_url

        name = f"authn_test_{uuid.uuid4().hex[:12]}"
        admin = create_engine(resolve_url(PG_URL), isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            conn.exec_driver_sql(f'CREATE DATABASE "{name}"')
        admin.dispose()
        made.append(name)
        return make_url(resolve_url(PG_URL)).set(database=name).render_as_string(hide_password=False)

    yield make_sqlite if request.param == "sqlite" else make_pg
    dispose_engines()
    if request.param == "postgresql":
        from sqlalchemy import create_engine

        from registry.db import resolve_url

        admin = create_engine(resolve_url(PG_URL), isolation_level="AUTOCOMMIT")
        with admin.connect() as conn:
            for name in made:
                conn.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


def populate(url: str) -> None:
    """Every kind of record the export must carry."""
    with transaction(url) as s:
        register_profile(s, X8)
        register_profile(s, H6)  # custom, used by no identity: still exported
        register_identity(s, NewIdentity(
            serial=S_KEY, model="x8", operator_id="FIN87astrdge12k", public_key=KEY,
            valid_from=datetime(2024, 1, 1, 6, 30, 15, 123456, tzinfo=timezone.utc),
            valid_until=datetime(2031, 6, 30, tzinfo=timezone.utc), notes=NOTES))
        register_identity(s, NewIdentity(serial=S_REVOKED, model="m300", public_key=bytes(32)))
        register_identity(s, NewIdentity(serial=S_CAA, id_type="caa_registration", model="m600",
                                         notes=""))
        register_identity(s, NewIdentity(serial=S_UUID, id_type="utm_uuid", model="phantom4"))
        register_identity(s, NewIdentity(serial=S_SESSION, id_type="specific_session", model="x8"))
    with transaction(url) as s:
        revoke_identity(s, S_REVOKED, "stolen, reported 2025-03-01")


def snapshot(url: str) -> tuple[list[dict], list[dict]]:
    """Every field of every identity (with its profile) and every profile."""
    with transaction(url) as s:
        return ([r.to_dict() for r in list_identities(s)],
                [p.to_dict() for p in list_profiles(s)])


def exported(new_db, export):
    """(a populated registry, an empty one, what `export` makes of the first)."""
    src, dst = new_db(), new_db()
    populate(src)
    with transaction(src) as s:
        return src, dst, export(s)


def test_json_round_trip_is_lossless(new_db):
    src, dst, text = exported(new_db, export_json)
    with transaction(dst) as s:
        result = import_json(s, text)
    assert (result.identities, result.profiles_added, result.profiles_existing) == (5, 2, 3)
    identities, profiles = snapshot(src)
    assert snapshot(dst) == (identities, profiles)
    assert len(identities) == 5 and len(profiles) == 5
    by_serial = {r["serial"]: r for r in identities}
    assert by_serial[S_REVOKED]["status"] == "revoked"
    assert by_serial[S_REVOKED]["updated_at"] > by_serial[S_REVOKED]["created_at"]
    assert by_serial[S_KEY]["public_key"] == KEY and by_serial[S_KEY]["notes"] == NOTES
    assert by_serial[S_KEY]["profile"] == X8.to_dict() and by_serial[S_CAA]["notes"] == ""
    with transaction(dst) as s:
        assert get_identity(s, S_REVOKED).status == "revoked"
        again = export_document(s)
    first = json.loads(text)
    assert {k: v for k, v in again.items() if k != "exported_at"} == \
        {k: v for k, v in first.items() if k != "exported_at"}


def test_json_document_shape(new_db):
    src = new_db()
    populate(src)
    with transaction(src) as s:
        doc = json.loads(export_json(s))
    assert doc["format"] == "authn-registry/1" and set(doc) == {"format", "exported_at", "profiles",
                                                                  "identities"}
    assert [p["slug"] for p in doc["profiles"]] == ["h6", "m300", "m600", "phantom4", "x8"]
    rec = next(r for r in doc["identities"] if r["serial"] == S_KEY)
    assert rec["public_key"] == KEY.hex()  # lower-case hex
    assert set(rec) == {"serial", "id_type", "model", "operator_id", "public_key", "status",
                        "valid_from", "valid_until", "notes", "created_at", "updated_at"}
    assert rec["valid_from"] == "2024-01-01T06:30:15.123456+00:00"
    # a column added to the schema later must be added to the export too
    columns = {c.name for c in Identity.__table__.columns} - {"id", "model_slug"} | {"model"}
    assert set(rec) == columns
    assert set(doc["profiles"][0]) == {c.name for c in ModelProfile.__table__.columns}


def test_csv_round_trip_keeps_status_and_key(new_db):
    src, dst, text = exported(new_db, export_csv)
    assert text.splitlines()[0] == ("serial,id_type,model,operator_id,valid_from,valid_until,notes,"
                                    "status,public_key")
    with transaction(dst) as s:
        register_profile(s, X8)  # CSV carries no profiles
        assert import_csv(s, text) == 5
    skip = {"created_at", "updated_at", "notes"}  # not in CSV; '' notes read back as none
    (a, _), (b, _) = snapshot(src), snapshot(dst)
    assert [{k: v for k, v in r.items() if k not in skip} for r in a] == \
        [{k: v for k, v in r.items() if k not in skip} for r in b]
    assert [r["notes"] or None for r in a] == [r["notes"] for r in b]
    with transaction(dst) as s:
        assert get_identity(s, S_REVOKED).status == "revoked"
        assert get_identity(s, S_KEY).public_key == KEY


def test_csv_without_the_profile_fails_naming_json(new_db):
    src, dst, text = exported(new_db, export_csv)
    with pytest.raises(RegistryError, match=r"line \d+: unknown model 'x8' \(CSV carries no profiles"), \
            transaction(dst) as s:
        import_csv(s, text)
    assert snapshot(dst)[0] == []


def test_old_csv_without_status_and_key_still_imports(new_db):
    db = new_db()
    old = ("serial,id_type,model,operator_id,valid_from,valid_until,notes\n"
           f"{S_KEY},serial,m300,OP-1,2024-01-01T00:00:00Z,,\"a, b\nc\"\n")
    with transaction(db) as s:
        assert import_csv(s, old) == 1
        rec = get_identity(s, S_KEY)
    assert rec.status == "active" and rec.public_key is None and rec.notes == "a, b\nc"


def test_existing_identical_profile_accepted_conflicting_refused_atomically(new_db):
    src, dst, doc = exported(new_db, export_document)
    with transaction(dst) as s:
        register_profile(s, X8)  # identical: fine
    changed = json.loads(json.dumps(doc))
    next(p for p in changed["profiles"] if p["slug"] == "m300")["rotor_rate_hz"] = 41.0
    with pytest.raises(RegistryError, match=r"^profiles\[1\] \(slug m300\): conflicts with the registered "
                                            r"model 'm300' \(rotor_rate_hz 41.0 in the file, 40.0 registered\)"), \
            transaction(dst) as s:
        import_json(s, json.dumps(changed))
    with transaction(dst) as s:
        assert list_identities(s) == [] and "h6" not in {p.slug for p in list_profiles(s)}
        result = import_json(s, json.dumps(doc))
    assert (result.profiles_added, result.profiles_existing) == (1, 4)


def test_a_bad_last_record_writes_nothing(new_db):
    src, dst, doc = exported(new_db, export_document)
    doc["identities"].append({"serial": "1581F5FJD12345678909", "model": "nope"})
    with pytest.raises(RegistryError, match=r"identities\[5\] \(serial 1581F5FJD12345678909\): unknown model"), \
            transaction(dst) as s:
        import_json(s, json.dumps(doc))
    assert snapshot(dst) == ([], [p.to_dict() for p in sorted(shipped_profiles().values(),
                                                                   key=lambda p: p.slug)])
    with transaction(dst) as s:  # already-registered serials: refused as a whole too
        register_identity(s, NewIdentity(serial=S_UUID, id_type="utm_uuid", model="m300"))
    doc["identities"].pop()
    with pytest.raises(RegistryError, match=f"serial {S_UUID}: already registered"), transaction(dst) as s:
        import_json(s, json.dumps(doc))
    assert [r["serial"] for r in snapshot(dst)[0]] == [S_UUID]


def _doc(**identity) -> str:
    rec = {"serial": S_KEY, "model": "m300", **identity}
    return json.dumps({"format": "authn-registry/1", "profiles": [], "identities": [rec]})


@pytest.mark.parametrize("text, match", [
    ("{not json", r"^not JSON \(.* at line 1\)$"),
    ("[]", "expected a JSON object"),
    ('{"profiles": []}', r"^format: expected 'authn-registry/1', found None$"),
    ('{"format": "authn-registry/2"}', "found 'authn-registry/2'"),
    ('{"format": "authn-registry/1", "identities": {}}', r"^identities: "),
    ('{"format": "authn-registry/1", "extra": 1}', r"^extra: Extra inputs"),
    (_doc(public_key="00" * 31), rf"^identities\[0\] \(serial {S_KEY}\): public_key: expected 64 hex digits"),
    (_doc(public_key=KEY.hex().upper() + "0"), r"public_key: expected 64 hex"),
    (_doc(status="lost"), rf"identities\[0\] \(serial {S_KEY}\): status: Input should be 'active' or 'revoked'"),
    (_doc(valid_from=1700000000), r"valid_from: 1700000000 is not an ISO 8601 date/time string"),
    (_doc(valid_until="soon"), r"valid_until: 'soon' is not an ISO 8601"),
    (_doc(valid_from="2025-01-02", valid_until="2025-01-01"), "valid_until must be after valid_from"),
    (_doc(created_at="2025-01-02", updated_at="2025-01-01"), "updated_at must not be before created_at"),
    (_doc(colour="red"), r"identities\[0\] \(serial .*\): colour: Extra inputs"),
    (_doc(serial="1581F5FJD1234"), r"identities\[0\] \(serial 1581F5FJD1234\): .*length character"),
    (_doc(operator_id="Ä" * 3), r"operator_id: String should match"),
    (json.dumps({"format": "authn-registry/1", "identities": [{"model": "m300"}]}),
     r"^identities\[0\]: serial: Field required$"),
    (json.dumps({"format": "authn-registry/1", "identities": [
        {"serial": S_KEY, "model": "m300"}, {"serial": S_KEY.lower(), "model": "m600"}]}),
     rf"identities\[1\] \(serial {S_KEY.lower()}\): serial {S_KEY} repeats identities\[0\]"),
    (json.dumps({"format": "authn-registry/1", "profiles": [{**X8.to_dict(), "rotors": 3}]}),
     r"^profiles\[0\] \(slug x8\): rotors must be a multiple of arms"),
    (json.dumps({"format": "authn-registry/1", "profiles": [X8.to_dict(), X8.to_dict()]}),
     r"profiles\[1\] \(slug x8\): slug 'x8' repeats profiles\[0\]"),
    (json.dumps({"format": "authn-registry/1", "profiles": [{**X8.to_dict(), "slug": "bird"}]}),
     r"reserved"),
])
def test_json_validation_errors_are_one_line_and_name_the_record(text, match):
    with pytest.raises(RegistryError, match=match) as info:
        parse_import(text)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text, match", [
    (f"{S_KEY},serial,m300\n", r"^CSV line 1 \(1581F5FJD12345678901,serial,m300\) is not a header row"),
    (f"{S_KEY},m300\n{S_REVOKED},m300\n", "is not a header row"),
    ("", "CSV file is empty"),
    ("\n\n", "CSV file is empty"),
    ("\nserial,model\n", "CSV line 1 is empty"),
    ("serial,id_type\n", r"missing column\(s\) model"),
    ("serial,model,colour\n", "unknown column 'colour'"),
    ("serial,model,model\n", "column 'model' appears twice"),
    (f"serial,model,status\n{S_KEY},m300,lost\n", "line 2: status: Input should be"),
    (f"serial,model,public_key\n{S_KEY},m300,abc\n", "line 2: public_key: expected 64 hex digits"),
    (f'serial,model,notes\n{S_KEY},m300,"a\nb"\n{S_KEY},m300,\n', "line 4: serial .* repeats line 2"),
])
def test_csv_errors_including_a_missing_header(text, match):
    with pytest.raises(RegistryError, match=match) as info:
        parse_import(text, "csv")
    assert "\n" not in str(info.value)


def test_csv_header_names_are_case_insensitive_and_status_key_columns_read(new_db):
    db = new_db()
    text = f"Serial,MODEL,Status,Public_Key\n{S_KEY},m300,revoked,{KEY.hex().upper()}\n"
    with transaction(db) as s:
        assert import_csv(s, text) == 1
        rec = get_identity(s, S_KEY)
    assert rec.status == "revoked" and rec.public_key == KEY


def test_revoke_reason_may_not_make_notes_unexportable(new_db):
    db = new_db()
    with transaction(db) as s:
        register_identity(s, NewIdentity(serial=S_KEY, model="m300", notes="x" * 1990))
    with pytest.raises(RegistryError, match="longer than 2000"), transaction(db) as s:
        revoke_identity(s, S_KEY, "a long reason")
    with transaction(db) as s:
        assert get_identity(s, S_KEY).status == "active"


# ------------------------------------------------------------------ through the CLI
def test_cli_export_import_round_trip(capsys, new_db, tmp_path):
    src, dst = new_db(), new_db()
    key = tmp_path / "key.hex"
    key.write_text(KEY.hex())
    assert run(capsys, src, "register", "--serial", S_KEY, "--model", "x8", "--model-name", "Octo X8",
               "--rotors", "8", "--arms", "4", "--blade-length", "0.38", "--rotor-rate", "45",
               "--propeller-distance", "1.2", "--public-key", str(key), "--operator-id", "FIN87astrdge12k",
               "--valid-from", "2024-01-01T00:00:00Z", "--valid-until", "2030-01-01T00:00:00Z",
               "--notes", NOTES)[0] == 0
    assert run(capsys, src, "register", "--serial", S_REVOKED, "--model", "m300")[0] == 0
    assert run(capsys, src, "registry", "revoke", S_REVOKED, "--reason", "stolen")[0] == 0
    out = tmp_path / "registry.json"
    assert run(capsys, src, "registry", "export", "--out", str(out))[0] == 0
    assert json.loads(out.read_text(encoding="utf-8"))["format"] == "authn-registry/1"
    assert NOTES.splitlines()[1] in out.read_text(encoding="utf-8")  # unicode kept readable
    code, msg, err = run(capsys, dst, "registry", "import", str(out))
    assert code == 0, err
    assert msg.strip() == f"imported 2 identities from {out} (1 new model profiles, 3 already registered)"
    for serial in (S_KEY, S_REVOKED):
        a = json.loads(run(capsys, src, "registry", "show", serial, "--json")[1])
        b = json.loads(run(capsys, dst, "registry", "show", serial, "--json")[1])
        assert a == b
    shown = json.loads(run(capsys, dst, "registry", "list", "--status", "revoked", "--json")[1])
    assert [r["serial"] for r in shown] == [S_REVOKED]
    assert json.loads(run(capsys, src, "registry", "models", "--json")[1]) == \
        json.loads(run(capsys, dst, "registry", "models", "--json")[1])
    code, _, err = run(capsys, dst, "registry", "import", str(out))  # again: refused, one line
    assert code == 2 and err == f"error: {out}: serial {S_KEY}: already registered (2 of the file's serials are)\n"


def test_cli_stdout_json_by_default_csv_by_suffix_or_flag_with_profile_warning(capsys, new_db, tmp_path):
    src, dst = new_db(), new_db()
    populate(src)
    code, text, err = run(capsys, src, "registry", "export")
    assert code == 0 and json.loads(text)["format"] == "authn-registry/1" and err == ""
    code, csv_text, err = run(capsys, src, "registry", "export", "--format", "csv")
    assert code == 0 and csv_text.startswith("serial,id_type,model,")
    assert err.startswith("warning: CSV carries no model profiles; custom model(s) h6, x8 ")
    path = tmp_path / "fleet.csv"
    assert run(capsys, src, "registry", "export", "--out", str(path))[0] == 0
    assert path.read_text(encoding="utf-8") == csv_text
    code, _, err = run(capsys, dst, "registry", "import", str(path))
    assert code == 2 and "unknown model 'x8' (CSV carries no profiles: import a JSON export)" in err
    assert err.count("\n") == 1
    code, _, err = run(capsys, dst, "registry", "export", "--format", "xml")
    assert code == 2 and "--format 'xml'" in err


def test_cli_import_from_stdin_and_forced_format(capsys, new_db, monkeypatch, tmp_path):
    src, dst, text = exported(new_db, export_json)
    monkeypatch.setattr("sys.stdin", io.StringIO("\ufeff" + text))
    code, out, err = run(capsys, dst, "registry", "import", "-")
    assert code == 0, err
    assert snapshot(dst) == snapshot(src)
    path = tmp_path / "registry.json"
    path.write_text(text, encoding="utf-8")
    code, _, err = run(capsys, new_db(), "registry", "import", "--format", "csv", str(path))
    assert code == 2 and "is not a header row" in err and err.count("\n") == 1


@pytest.mark.parametrize("content", [f"{S_KEY},serial,m300\n", f"{S_KEY}\n"])
def test_cli_headerless_csv_is_refused_not_ignored(capsys, new_db, tmp_path, content):
    db = new_db()
    path = tmp_path / "fleet.csv"
    path.write_text(content)
    code, out, err = run(capsys, db, "registry", "import", str(path))
    assert code == 2 and out == ""
    assert err.startswith(f"error: {path}: CSV line 1 (") and "is not a header row" in err
    assert err.count("\n") == 1
    assert json.loads(run(capsys, db, "registry", "list", "--json")[1]) == []


def test_a_record_and_the_check_path_read_the_same_identity(tmp_path) -> None:
    """The registry's full record and the check path's raw read give one identity model
    (`registry.dbapi.IdentityFacts`): the decision's view of a record is its `facts`."""
    from registry.dbapi import Database
    from registry.dbapi import transaction
    from registry.store import NewIdentity, get_identity, register_identity

    url = f"sqlite:///{tmp_path / 'r.sqlite3'}"
    with transaction(url) as s:
        register_identity(s, NewIdentity(serial="1581D5FKD229400R0V", model="m300", operator_id="OP-1"))
    with transaction(url) as s:
        record = get_identity(s, "1581D5FKD229400R0V")
    assert Database(url).identity("1581D5FKD229400R0V") == record.facts
