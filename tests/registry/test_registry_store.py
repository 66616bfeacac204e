"""Registry queries and database-level constraints, on every backend."""

from __future__ import annotations

from datetime import datetime, timedelta, timezone

import pytest
from sqlalchemy import text
from sqlalchemy.exc import DBAPIError

from registry.db import get_engine
from registry.dbapi import transaction
from registry.errors import RegistryError
from registry.keys import parse_public_key
from registry.store import (
    NewIdentity,
    export_csv,
    get_identity,
    import_csv,
    list_identities,
    list_profiles,
    register_identity,
    register_profile,
    revoke_identity,
)
from signatures.profiles import UavProfile, shipped_profiles

SERIAL = "1581F5FJD12345678901"


def test_migration_seeds_exactly_the_shipped_profiles(db_url):
    with transaction(db_url) as db:
        assert {p.slug: p for p in list_profiles(db)} == shipped_profiles()


def test_register_get_revoke(db_url):
    key = bytes(range(32))
    until = datetime(2031, 1, 1, tzinfo=timezone.utc)
    with transaction(db_url) as s:
        rec = register_identity(s, NewIdentity(serial=SERIAL.lower(), model="m600", operator_id="FIN87astrdge12k",
                                               public_key=key, valid_until=until, notes="survey"))
    assert rec.serial == SERIAL  # normalised to upper case
    with transaction(db_url) as s:
        got = get_identity(s, SERIAL)
    assert got.profile == shipped_profiles()["m600"]
    assert got.public_key == key and got.valid_until == until and got.status == "active"
    assert got.created_at.tzinfo is not None and got.valid_from <= datetime.now(timezone.utc)
    assert got.valid_from <= datetime.now(timezone.utc) < got.valid_until
    with transaction(db_url) as s:
        revoked = revoke_identity(s, SERIAL, "lost")
    assert revoked.status == "revoked" and "revoked: lost" in revoked.notes
    with transaction(db_url) as s:
        assert get_identity(s, SERIAL).status == "revoked"
        assert [r.serial for r in list_identities(s, "revoked")] == [SERIAL]
        assert list_identities(s, "active") == []
        with pytest.raises(RegistryError, match="already revoked"):
            revoke_identity(s, SERIAL)
        with pytest.raises(RegistryError, match="not registered"):
            revoke_identity(s, "1581F5FJD99999999999")


def test_duplicate_and_unknown_model_are_refused(db_url):
    with transaction(db_url) as s:
        register_identity(s, NewIdentity(serial=SERIAL, model="m300"))
    with pytest.raises(RegistryError, match="already registered"), transaction(db_url) as s:
        register_identity(s, NewIdentity(serial=SERIAL, model="m300"))
    with pytest.raises(RegistryError, match="unknown model"), transaction(db_url) as s:
        register_identity(s, NewIdentity(serial="1581F5FJD12345678902", model="nope"))


def test_new_profile_then_identity(db_url):
    x8 = UavProfile(slug="x8", name="Octo X8", rotors=8, arms=4, blade_length_m=0.38,
                    rotor_rate_hz=45.0, propeller_distance_m=1.2)
    with transaction(db_url) as s:
        register_profile(s, x8)
        register_identity(s, NewIdentity(serial=SERIAL, model="x8"))
    with transaction(db_url) as s:
        assert get_identity(s, SERIAL).profile == x8
        with pytest.raises(RegistryError, match="already registered"):
            register_profile(s, x8)


@pytest.mark.parametrize("sql", [
    "INSERT INTO model_profiles VALUES ('bad', 'Bad', 0, 1, 2, 0.3, 40, 0.5)",  # no rotors
    "INSERT INTO model_profiles VALUES ('bad', 'Bad', 4, 4, 2, 9.0, 40, 0.5)",  # 9 m blades
    "INSERT INTO model_profiles VALUES ('bad', 'Bad', 4, 4, 2, 0.3, 0.5, 0.5)",  # rotor rate
    "INSERT INTO model_profiles VALUES ('bird', 'Bird', 4, 4, 2, 0.3, 40, 0.5)",  # reserved slug
    "INSERT INTO identities (serial, id_type, model_slug, status, valid_from, created_at, updated_at)"
    " VALUES ('X', 'serial', 'no_such_model', 'active', '2024-01-01', '2024-01-01', '2024-01-01')",
    "INSERT INTO identities (serial, id_type, model_slug, status, valid_from, created_at, updated_at)"
    " VALUES ('X', 'serial', 'm300', 'lost', '2024-01-01', '2024-01-01', '2024-01-01')",
    "INSERT INTO identities (serial, id_type, model_slug, status, valid_from, created_at, updated_at)"
    " VALUES ('X', 'imei', 'm300', 'active', '2024-01-01', '2024-01-01', '2024-01-01')",
    "INSERT INTO identities (serial, id_type, model_slug, status, valid_from, valid_until, created_at,"
    " updated_at) VALUES ('X', 'serial', 'm300', 'active', '2024-01-02', '2024-01-01', '2024-01-01',"
    " '2024-01-01')",
])
def test_database_enforces_constraints(db_url, sql):
    engine = get_engine(db_url)
    with pytest.raises(DBAPIError), engine.begin() as conn:
        conn.execute(text(sql))


def test_public_key_length_and_unique_serial_in_database(db_url):
    engine = get_engine(db_url)
    row = ("INSERT INTO identities (serial, id_type, model_slug, status, valid_from, created_at,"
           " updated_at, public_key) VALUES (:s, 'serial', 'm300', 'active', :t, :t, :t, :k)")
    t = datetime(2024, 1, 1, tzinfo=timezone.utc)
    with pytest.raises(DBAPIError), engine.begin() as conn:
        conn.execute(text(row), {"s": "A", "t": t, "k": b"short"})
    with engine.begin() as conn:
        conn.execute(text(row), {"s": "A", "t": t, "k": bytes(32)})
    with pytest.raises(DBAPIError), engine.begin() as conn:
        conn.execute(text(row), {"s": "A", "t": t, "k": None})


def test_audit_log_is_append_only(db_url):
    engine = get_engine(db_url)
    ins = ("INSERT INTO audit_log (seq, created_at, kind, serial, decision, payload, prev_hash, entry_hash)"
           " VALUES (1, :t, 'decision', 'S', 'accept', '{}', :p, :h)")
    with engine.begin() as conn:
        conn.execute(text(ins), {"t": datetime.now(timezone.utc), "p": "0" * 64, "h": "a" * 64})
    for sql in ("UPDATE audit_log SET decision = 'reject'", "DELETE FROM audit_log"):
        with pytest.raises(DBAPIError, match="append-only"), engine.begin() as conn:
            conn.execute(text(sql))
    with pytest.raises(DBAPIError), engine.begin() as conn:  # kind outside the enum
        conn.execute(text(ins.replace("'decision'", "'other'").replace("(1,", "(2,")),
                     {"t": datetime.now(timezone.utc), "p": "a" * 64, "h": "b" * 64})
    with engine.connect() as conn:
        assert conn.execute(text("SELECT count(*) FROM audit_log")).scalar_one() == 1


CSV = """serial,id_type,model,operator_id,valid_from,valid_until,notes
1581F5FJD12345678901,serial,m300,OP-1,2024-01-01T00:00:00Z,2030-01-01T00:00:00Z,first
1581F5FJD12345678902,,phantom4,,,,
FA3ABC1234,caa_registration,m600,OP-2,2024-06-01,,"note, with comma"
"""


def test_import_export_round_trip(db_url):
    with transaction(db_url) as s:
        assert import_csv(s, CSV) == 3
    with transaction(db_url) as s:
        out = export_csv(s)
        rec = get_identity(s, "FA3ABC1234")
    assert rec.id_type == "caa_registration" and rec.notes == "note, with comma"
    assert rec.valid_from == datetime(2024, 6, 1, tzinfo=timezone.utc)
    lines = out.splitlines()
    assert lines[0] == "serial,id_type,model,operator_id,valid_from,valid_until,notes,status,public_key"
    assert lines[1] == ("1581F5FJD12345678901,serial,m300,OP-1,2024-01-01T00:00:00+00:00,"
                        "2030-01-01T00:00:00+00:00,first,active,")
    assert len(lines) == 4


@pytest.mark.parametrize("bad_row, match", [
    ("1581F5FJD1234,serial,m300,,,,", "line 4: .*length character"),
    ("1581F5FJD12345678909,serial,nope,,,,", "line 4: unknown model"),
    ("1581F5FJD12345678901,serial,m300,,,,", "repeats line 2"),
    ("1581F5FJD12345678909,serial,m300,,2024-01-02,2024-01-01,", "valid_until must be after"),
    ("1581F5FJD12345678909,serial,m300,,yesterday,,", "not an ISO 8601"),
    ("1581F5FJD12345678909,serial,m300,,,,,extra", "more fields"),
])
def test_failed_import_writes_nothing(db_url, bad_row, match):
    text_ = CSV.splitlines()[0] + "\n" + "\n".join(CSV.splitlines()[1:3]) + "\n" + bad_row + "\n"
    with pytest.raises(RegistryError, match=match), transaction(db_url) as s:
        import_csv(s, text_)
    with transaction(db_url) as s:
        assert list_identities(s) == []


def test_import_refuses_already_registered_serials_atomically(db_url):
    with transaction(db_url) as s:
        register_identity(s, NewIdentity(serial="1581F5FJD12345678902", model="m300"))
    with pytest.raises(RegistryError, match="already registered"), transaction(db_url) as s:
        import_csv(s, CSV)
    with transaction(db_url) as s:
        assert [r.serial for r in list_identities(s)] == ["1581F5FJD12345678902"]


def test_public_key_formats():
    raw = bytes(range(1, 33))
    pem = (b"-----BEGIN PUBLIC KEY-----\nMCowBQYDK2VwAyEA" +
           __import__("base64").b64encode(bytes.fromhex("302a300506032b6570032100") + raw)[16:] +
           b"\n-----END PUBLIC KEY-----\n")
    assert parse_public_key(raw) == raw
    assert parse_public_key(raw.hex().encode() + b"\n") == raw
    assert parse_public_key(pem) == raw
    for bad in (b"abc", bytes(31), b"-----BEGIN PUBLIC KEY-----\nAAAA\n-----END PUBLIC KEY-----"):
        with pytest.raises(RegistryError):
            parse_public_key(bad)


def test_naive_and_reversed_validity_rejected_before_writing():
    with pytest.raises(ValueError, match="after valid_from"):
        NewIdentity(serial=SERIAL, model="m300", valid_from=datetime(2025, 1, 1),
                    valid_until=datetime(2024, 1, 1))
    past = datetime.now(timezone.utc) - timedelta(days=1)
    with pytest.raises(ValueError, match="after valid_from"):
        NewIdentity(serial=SERIAL, model="m300", valid_until=past)
