"""Registry queries: model profiles and identities, single and bulk (JSON and CSV).

Functions take a `registry.dbapi.Database` inside the caller's `registry.dbapi.transaction`
and never commit: each command is one transaction, so a failed bulk import writes nothing.
Everything is validated before anything is written.

Bulk formats
------------
JSON (`authn-registry/1`, the default and the lossless one)::

    {"format": "authn-registry/1",
     "exported_at": "2026-01-01T00:00:00+00:00",
     "profiles":   [{"slug": "x8", "name": "Octo X8", "rotors": 8, "arms": 4,
                     "blades_per_rotor": 2, "blade_length_m": 0.38,
                     "rotor_rate_hz": 45.0, "propeller_distance_m": 1.2}, ...],
     "identities": [{"serial": "1581F5FJD12345678901", "id_type": "serial",
                     "model": "x8", "operator_id": null,
                     "public_key": "<64 hex digits> or null",
                     "status": "active" | "revoked",
                     "valid_from": "...", "valid_until": "..." | null,
                     "notes": "..." | null,
                     "created_at": "...", "updated_at": "..."}, ...]}

Public keys are lower-case hex (the 32 raw Ed25519 bytes, as `registry show
--json` prints them); times are ISO 8601 with offset, written in UTC (naive
times are read as UTC). The export holds every model profile of the registry,
shipped ones included: import adds the missing ones, accepts one identical to a
registered profile and refuses one that differs (profiles are never changed
silently). `created_at`/`updated_at` are exported and restored: they are part
of the record, not bookkeeping of one database -- `updated_at` of a revoked
identity is when it was revoked, and a restore from backup must not make every
identity look registered today. They are optional on import (default: now).

CSV (`serial,id_type,model,operator_id,valid_from,valid_until,notes,status,
public_key`; header row required, only serial and model must be filled) is the
hand-edited bulk-onboarding format. Files without the last two columns (the
old format) still import (status active, no key). CSV carries no model
profiles and no created_at/updated_at: use JSON for a backup or a migration.
"""

from __future__ import annotations

import csv
import io
import json
import re
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import Any, Literal

from core.checked import Checked, Invalid, choice, moment, rule, text
from core.errors import BadInput
from core.parsing import JsonTooDeep, first_error, in_utc_range, loads_json, parse_iso_time
from core.uasid import as_heard
from registry.dbapi import Database, IdentityFacts, utcnow
from registry.errors import DatabaseFault, RegistryError
from registry.serials import validate_uas_id
from signatures.profiles import UavProfile

#: CSV columns in export order; the last two are new, files without them still import.
CSV_COLUMNS = ("serial", "id_type", "model", "operator_id", "valid_from", "valid_until", "notes",
               "status", "public_key")
#: The `format` tag of a JSON registry document.
REGISTRY_FORMAT = "authn-registry/1"
NOTES_MAX = 2000
IdType = Literal["serial", "caa_registration", "utm_uuid", "specific_session"]
Status = Literal["active", "revoked"]
_HEX_KEY = re.compile(r"^[0-9a-fA-F]{64}$")


def describe_validation_error(exc: Invalid) -> str:
    """The first error of a `core.checked.Invalid` as one line (`field: reason`)."""
    loc, msg, _ = first_error(exc)
    return f"{loc}: {msg}" if loc else msg


def _iso_time(value: Any) -> Any:
    """ISO 8601 text -> datetime ('' -> None); numbers are refused, not read as epoch seconds."""
    if isinstance(value, str):
        text = value.strip()
        if not text:
            return None
        try:
            return parse_iso_time(text, "time")  # naive = UTC
        except BadInput as exc:  # not ISO 8601, or out of range in UTC: say which
            raise ValueError(str(exc).removeprefix("time: ")) from None
    if value is None or isinstance(value, datetime):
        return value
    raise ValueError(f"{value!r} is not an ISO 8601 date/time string")


def _utc_time(value: Any) -> datetime | None:
    """A time of a record: ISO 8601 text or a datetime, naive read as UTC, held in UTC."""
    when = _iso_time(value)
    if when is None:
        return None
    if when.tzinfo is None:
        when = when.replace(tzinfo=timezone.utc)  # naive input is read as UTC
    if not in_utc_range(when):  # would overflow converting to UTC
        raise ValueError("out of range (UTC times from 0001-01-02 to 9999-12-30)")
    return when.astimezone(timezone.utc)


def _public_key(value: Any) -> bytes | None:
    """Text (JSON, CSV) is 64 hex digits ('' for none); bytes (a key file's) are the 32 raw bytes."""
    if isinstance(value, str):
        value = value.strip()
        if not value:
            return None
        if not _HEX_KEY.match(value):
            raise ValueError("expected 64 hex digits (a 32-byte Ed25519 public key)")
        return bytes.fromhex(value)
    if value is None:
        return None
    if not isinstance(value, (bytes, bytearray, memoryview)):
        raise ValueError("Input should be a valid bytes")
    key = bytes(value)
    if len(key) != 32:
        raise ValueError(f"Data should have at {'least' if len(key) < 32 else 'most'} 32 bytes")
    return key


def _profile_value(value: Any) -> UavProfile:
    if not isinstance(value, UavProfile):
        raise ValueError("Input should be a UavProfile")
    return value


@dataclass(frozen=True, kw_only=True)
class NewIdentity(Checked):
    """A validated identity to register (CLI flags, one CSV row, one JSON record, a service body).

    `status`, `created_at` and `updated_at` are for restoring an export; a new
    registration leaves them at their defaults (active, now).
    """

    serial: str = text()
    id_type: IdType = choice("serial", "caa_registration", "utm_uuid", "specific_session", default="serial")
    model: str = text(min_length=1, max_length=32)
    operator_id: str | None = text(None, max_length=20, pattern=r"^[\x20-\x7e]+$", optional=True)
    public_key: bytes | None = rule(_public_key, None)
    status: Status = choice("active", "revoked", default="active")
    valid_from: datetime | None = rule(_utc_time, None)
    valid_until: datetime | None = rule(_utc_time, None)
    notes: str | None = text(None, max_length=NOTES_MAX, optional=True)
    created_at: datetime | None = rule(_utc_time, None)
    updated_at: datetime | None = rule(_utc_time, None)

    def _check(self) -> None:
        object.__setattr__(self, "serial", validate_uas_id(self.serial, self.id_type))
        start = self.valid_from or utcnow()
        if self.valid_until is not None and self.valid_until <= start:
            raise ValueError("valid_until must be after valid_from")
        if self.created_at and self.updated_at and self.updated_at < self.created_at:
            raise ValueError("updated_at must not be before created_at")


@dataclass(frozen=True, kw_only=True)
class IdentityRecord(Checked):
    """The registry's full record of an identity (operator, airframe profile, notes, times): what
    the registry commands and the service show (`to_dict(json=True)`: key as hex, times ISO 8601).
    A decision reads its subset, `facts` (`registry.dbapi.IdentityFacts`, read straight from the
    database on the check path)."""

    serial: str = text()
    id_type: IdType = choice("serial", "caa_registration", "utm_uuid", "specific_session")
    operator_id: str | None = text(optional=True)
    model: str = text()
    profile: UavProfile = rule(_profile_value)
    public_key: bytes | None = rule(_public_key, None)
    status: Status = choice("active", "revoked")
    valid_from: datetime = moment()
    valid_until: datetime | None = moment(optional=True)
    created_at: datetime = moment()
    updated_at: datetime = moment()
    notes: str | None = text(optional=True)

    @property
    def facts(self) -> IdentityFacts:
        """What a decision reads of this identity."""
        return IdentityFacts(self.serial, self.id_type, self.model, self.status, self.valid_from,
                             self.valid_until, self.public_key)


_PROFILE_COLUMNS = ("slug", "name", "rotors", "arms", "blades_per_rotor", "blade_length_m", "rotor_rate_hz",
                    "propeller_distance_m")
_IDENTITY_COLUMNS = ("serial", "id_type", "operator_id", "model_slug", "public_key", "status", "valid_from",
                     "valid_until", "created_at", "updated_at", "notes")
_TIMES = ("valid_from", "valid_until", "created_at", "updated_at")
_SELECT_IDENTITY = ("SELECT " + ", ".join(f"i.{c}" for c in _IDENTITY_COLUMNS) + ", "
                    + ", ".join(f"p.{c}" for c in _PROFILE_COLUMNS)
                    + " FROM identities i JOIN model_profiles p ON p.slug = i.model_slug")


def _insert(table: str, columns: tuple[str, ...]) -> str:
    return f"INSERT INTO {table} ({', '.join(columns)}) VALUES ({', '.join(':' + c for c in columns)})"


def _profile(row: tuple) -> UavProfile:
    return UavProfile(**dict(zip(_PROFILE_COLUMNS, row)))


def _record(row: tuple) -> IdentityRecord:
    n = len(_IDENTITY_COLUMNS)
    i = dict(zip(_IDENTITY_COLUMNS, row[:n]))
    return IdentityRecord.from_dict({
        "serial": i["serial"], "id_type": i["id_type"], "operator_id": i["operator_id"], "model": i["model_slug"],
        "profile": _profile(row[n:]), "public_key": bytes(i["public_key"]) if i["public_key"] is not None else None,
        "status": i["status"], "notes": i["notes"], **{c: Database.from_db_time(i[c]) for c in _TIMES}})


# ------------------------------------------------------------------ profiles
def list_profiles(db: Database) -> list[UavProfile]:
    """All model profiles, ordered by slug (the radar side reads these)."""
    return [_profile(r) for r in db.fetch(f"SELECT {', '.join(_PROFILE_COLUMNS)} FROM model_profiles ORDER BY slug")]


def custom_profiles(db: Database) -> list[UavProfile]:
    """Profiles that are not one of the shipped ones (what a CSV export cannot carry)."""
    from signatures.profiles import shipped_profiles

    shipped = shipped_profiles()
    return [p for p in list_profiles(db) if shipped.get(p.slug) != p]


def register_profile(db: Database, profile: UavProfile) -> UavProfile:
    """Add a new airframe; an existing slug is an error (profiles are never silently changed)."""
    if db.fetch("SELECT 1 FROM model_profiles WHERE slug = :slug", {"slug": profile.slug}):
        raise RegistryError(f"model {profile.slug!r}: already registered")
    db.execute(_insert("model_profiles", _PROFILE_COLUMNS), profile.to_dict(), what=f"model {profile.slug!r}")
    return profile


# ------------------------------------------------------------------ identities
def _known_models(db: Database) -> set[str]:
    return {str(r[0]) for r in db.fetch("SELECT slug FROM model_profiles")}


def _row(db: Database, new: NewIdentity, now: datetime) -> dict[str, Any]:
    """The identities row of `new` as insert parameters (times in the database's form)."""
    created = new.created_at or (min(now, new.updated_at) if new.updated_at else now)
    times = {"valid_from": new.valid_from or now, "valid_until": new.valid_until, "created_at": created,
             "updated_at": new.updated_at or created}
    return {"serial": new.serial, "id_type": new.id_type, "operator_id": new.operator_id, "model_slug": new.model,
            "public_key": new.public_key, "status": new.status, "notes": new.notes,
            **{k: db.to_db_time(v) if v is not None else None for k, v in times.items()}}


def register_identity(db: Database, new: NewIdentity) -> IdentityRecord:
    """Add one identity; unknown model or duplicate serial raise RegistryError."""
    if new.model not in _known_models(db):
        raise RegistryError(f"unknown model {new.model!r} (register it first with --rotors ...)")
    if get_identity(db, new.serial) is not None:
        raise RegistryError(f"serial {new.serial}: already registered")
    db.execute(_insert("identities", _IDENTITY_COLUMNS), _row(db, new, utcnow()), what=f"serial {new.serial}")
    return _written(db, new.serial)


def _written(db: Database, serial: str) -> IdentityRecord:
    """The identity this transaction has just written, read back as stored."""
    rec = get_identity(db, serial)
    if rec is None:  # rows are never deleted, and this transaction holds the write lock
        raise DatabaseFault(f"serial {serial}: not found after writing it")
    return rec


def get_identity(db: Database, serial: str) -> IdentityRecord | None:
    """The identity registered under `serial`, read in its normal form (`core.uasid.as_heard`)."""
    rows = db.fetch(_SELECT_IDENTITY + " WHERE i.serial = :serial", {"serial": as_heard(serial)})
    return _record(rows[0]) if rows else None


def list_identities(db: Database, status: str | None = None) -> list[IdentityRecord]:
    """Every identity (or those with `status`), by serial."""
    if status is None:
        return [_record(r) for r in db.fetch(_SELECT_IDENTITY + " ORDER BY i.serial")]
    return [_record(r) for r in db.fetch(_SELECT_IDENTITY + " WHERE i.status = :status ORDER BY i.serial",
                                         {"status": status})]


def revoke_identity(db: Database, serial: str, reason: str | None = None) -> IdentityRecord:
    """Mark an identity revoked (kept for the audit trail, never deleted)."""
    rec = get_identity(db, serial)
    if rec is None:
        raise RegistryError(f"serial {serial}: not registered")
    if rec.status == "revoked":
        raise RegistryError(f"serial {rec.serial}: already revoked")
    notes = rec.notes
    if reason:
        notes = (f"{notes}\n" if notes else "") + f"revoked: {reason}"
        if len(notes) > NOTES_MAX:  # an export of it would not import again
            raise RegistryError(f"serial {rec.serial}: --reason would make the notes longer "
                                f"than {NOTES_MAX} characters")
    db.execute("UPDATE identities SET status = :status, updated_at = :now, notes = :notes WHERE serial = :serial",
               {"status": "revoked", "now": db.to_db_time(utcnow()), "notes": notes, "serial": rec.serial},
               what=f"serial {rec.serial}")
    return _written(db, rec.serial)


# ------------------------------------------------------------------ bulk import
@dataclass
class RegistryImport:
    """A validated import file: (label, item) pairs, the label naming the record in errors."""

    format: Literal["json", "csv"]
    profiles: list[tuple[str, UavProfile]] = field(default_factory=list)
    identities: list[tuple[str, NewIdentity]] = field(default_factory=list)


@dataclass(frozen=True)
class ImportResult:
    identities: int
    profiles_added: int
    profiles_existing: int
    identities_skipped: int = 0  # already registered, left as they are (`skip_existing`)


def _check_unique_serials(items: list[tuple[str, NewIdentity]]) -> None:
    seen: dict[str, str] = {}
    for label, new in items:
        if new.serial in seen:
            raise RegistryError(f"{label}: serial {new.serial} repeats {seen[new.serial]}")
        seen[new.serial] = label


def _csv_header_error(shown: list[str]) -> RegistryError | None:
    names = [n.lower() for n in shown]
    if not any(names):
        return RegistryError("CSV line 1 is empty: the first line must name the columns "
                             f"(serial,model and optionally {','.join(CSV_COLUMNS[1:])})")
    unknown = [n for n in names if n not in CSV_COLUMNS]
    missing = [c for c in ("serial", "model") if c not in names]
    if unknown and missing:  # most likely a data row: never read it as a header and go on
        return RegistryError(
            f"CSV line 1 ({','.join(shown)[:60]}) is not a header row: the first line must name the "
            f"columns, e.g. serial,id_type,model (all: {','.join(CSV_COLUMNS)})")
    if unknown:
        return RegistryError(f"CSV header: unknown column {unknown[0]!r} "
                             f"(columns: {','.join(CSV_COLUMNS)})")
    if missing:
        return RegistryError(f"CSV header {','.join(shown)}: missing column(s) {','.join(missing)}")
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        return RegistryError(f"CSV header: column {repeated[0]!r} appears twice")
    return None


def parse_csv(text: str) -> list[NewIdentity]:
    """Validate every row of a CSV import file; any bad row raises (with its line number)."""
    return [new for _, new in _parse_csv(text)]


def _parse_csv(text: str) -> list[tuple[str, NewIdentity]]:
    text = text.lstrip("\ufeff")
    if not text.strip():
        raise RegistryError("CSV file is empty: the first line must name the columns "
                            "(serial,model at least)")
    reader = csv.reader(io.StringIO(text))
    try:
        header = next(reader)
        err = _csv_header_error([h.strip() for h in header])
        if err:
            raise err
        names = [h.strip().lower() for h in header]  # column names are case-insensitive
        rows: list[tuple[str, NewIdentity]] = []
        prev_end = reader.line_num
        for raw in reader:
            start, prev_end = prev_end + 1, reader.line_num
            label = f"line {start}"
            if not raw or not any(c.strip() for c in raw):
                continue  # blank line
            if len(raw) > len(names):
                raise RegistryError(f"{label}: more fields than columns")
            cells = dict(zip(names, (c.strip() for c in raw)))
            try:
                new = NewIdentity.from_dict({
                    "serial": cells.get("serial", ""), "id_type": cells.get("id_type") or "serial",
                    "model": cells.get("model", ""), "operator_id": cells.get("operator_id") or None,
                    "public_key": cells.get("public_key") or None,
                    "status": cells.get("status") or "active",
                    "valid_from": cells.get("valid_from") or None,
                    "valid_until": cells.get("valid_until") or None,
                    "notes": cells.get("notes") or None})
            except Invalid as exc:
                raise RegistryError(f"{label}: {describe_validation_error(exc)}") from None
            except (RegistryError, ValueError) as exc:
                raise RegistryError(f"{label}: {exc}") from None
            rows.append((label, new))
    except csv.Error as exc:
        raise RegistryError(f"line {reader.line_num}: not valid CSV ({exc})") from None
    _check_unique_serials(rows)
    return rows


#: The top level of a JSON registry document (besides `format`): each key's check, in order.
_DOCUMENT_LISTS = ("profiles", "identities")


def _document(data: dict[str, Any]) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The profiles and identities of a JSON registry document, its top level checked (records
    are validated one by one); errors are worded as the records' are."""
    try:
        _utc_time(data.get("exported_at"))
    except ValueError as exc:
        raise RegistryError(f"exported_at: {exc}") from None
    lists = []
    for key in _DOCUMENT_LISTS:
        items = data.get(key, [])
        if not isinstance(items, list):
            raise RegistryError(f"{key}: Input should be a valid list")
        bad = next((i for i, item in enumerate(items) if not isinstance(item, dict)), None)
        if bad is not None:
            raise RegistryError(f"{key}.{bad}: Input should be a valid dictionary")
        lists.append(items)
    extra = next((k for k in data if k not in ("format", "exported_at", *_DOCUMENT_LISTS)), None)
    if extra is not None:
        raise RegistryError(f"{extra}: Extra inputs are not permitted")
    return lists[0], lists[1]


def _record_label(kind: str, i: int, raw: dict[str, Any], key: str) -> str:
    name = raw.get(key)
    return f"{kind}[{i}] ({key} {name})" if isinstance(name, str) and name else f"{kind}[{i}]"


def _validated(model: type[Checked], raw: dict[str, Any], label: str) -> Any:
    """One record of an import file through its `core.checked` dataclass (UavProfile,
    NewIdentity); errors name the record."""
    try:
        return model.from_dict(raw)
    except Invalid as exc:
        raise RegistryError(f"{label}: {describe_validation_error(exc)}") from None
    except (RegistryError, ValueError) as exc:
        raise RegistryError(f"{label}: {exc}") from None


def parse_json(text: str) -> RegistryImport:
    """Validate a JSON registry document (see the module docstring); any bad record raises."""
    try:
        data = loads_json(text.lstrip("\ufeff"))
    except JsonTooDeep as exc:
        raise RegistryError(str(exc)) from None
    except json.JSONDecodeError as exc:
        raise RegistryError(f"not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(data, dict):
        raise RegistryError(f"expected a JSON object with format {REGISTRY_FORMAT!r}, "
                            "profiles and identities")
    if data.get("format") != REGISTRY_FORMAT:
        raise RegistryError(f"format: expected {REGISTRY_FORMAT!r}, found {data.get('format')!r}")
    profiles, identities = _document(data)
    out = RegistryImport(format="json")
    seen_slugs: dict[str, str] = {}
    for i, raw in enumerate(profiles):
        label = _record_label("profiles", i, raw, "slug")
        p = _validated(UavProfile, raw, label)
        if p.slug in seen_slugs:
            raise RegistryError(f"{label}: slug {p.slug!r} repeats {seen_slugs[p.slug]}")
        seen_slugs[p.slug] = label
        out.profiles.append((label, p))
    for i, raw in enumerate(identities):
        label = _record_label("identities", i, raw, "serial")
        new = _validated(NewIdentity, raw, label)
        out.identities.append((label, new))
    _check_unique_serials(out.identities)
    return out


def sniff_format(text: str) -> Literal["json", "csv"]:
    """JSON if the text starts (after a BOM and blanks) with '{' or '[', else CSV."""
    return "json" if text.lstrip("\ufeff \t\r\n")[:1] in ("{", "[") else "csv"


def parse_import(text: str, fmt: str = "auto") -> RegistryImport:
    """Validate an import file in `fmt` (json, csv, or auto: sniffed from the content)."""
    if fmt == "auto":
        fmt = sniff_format(text)
    if fmt == "json":
        return parse_json(text)
    if fmt == "csv":
        return RegistryImport(format="csv", identities=_parse_csv(text))
    raise RegistryError(f"--format {fmt!r}: expected auto, json or csv")


def _profile_difference(a: UavProfile, b: UavProfile) -> str:
    for name, value in a.to_dict().items():
        other = getattr(b, name)
        if value != other:
            return f"{name} {value!r} in the file, {other!r} registered"
    return "identical"


def import_records(db: Database, data: RegistryImport, skip_existing: bool = False) -> ImportResult:
    """Write a validated import in the caller's single transaction, or nothing.

    Profiles: missing ones are added, identical registered ones accepted,
    conflicting ones refused. Identities: every model must be registered or in
    the file; no serial may be registered already (with `skip_existing`, registered
    serials are left as they are and counted: a second import of a file is a no-op).
    Status and timestamps are kept as given (a revoked identity stays revoked).
    """
    registered = {p.slug: p for p in list_profiles(db)}
    added, existing = [], 0
    for label, p in data.profiles:
        have = registered.get(p.slug)
        if have is None:
            added.append(p)
        elif have == p:
            existing += 1
        else:
            raise RegistryError(f"{label}: conflicts with the registered model {p.slug!r} "
                                f"({_profile_difference(p, have)}); profiles are never changed by import")
    models = set(registered) | {p.slug for p in added}
    for label, new in data.identities:
        if new.model not in models:
            hint = "" if data.format == "json" else " (CSV carries no profiles: import a JSON export)"
            raise RegistryError(f"{label}: unknown model {new.model!r}{hint}")
    serials = [new.serial for _, new in data.identities]
    taken: set[str] = set()
    for i in range(0, len(serials), 500):  # stay below the bind-parameter limits
        chunk = {f"s{k}": s for k, s in enumerate(serials[i:i + 500])}
        marks = ", ".join(":" + k for k in chunk)
        taken |= {str(r[0]) for r in db.fetch(f"SELECT serial FROM identities WHERE serial IN ({marks})", chunk)}
    if taken and not skip_existing:
        raise RegistryError(f"serial {sorted(taken)[0]}: already registered "
                            f"({len(taken)} of the file's serials are)")
    new_ones = [new for _, new in data.identities if new.serial not in taken]
    db.execute_many(_insert("model_profiles", _PROFILE_COLUMNS), [p.to_dict() for p in added],
                    what="import (profiles)")
    now = utcnow()
    db.execute_many(_insert("identities", _IDENTITY_COLUMNS), [_row(db, new, now) for new in new_ones], what="import")
    return ImportResult(identities=len(new_ones), profiles_added=len(added),
                        profiles_existing=existing, identities_skipped=len(data.identities) - len(new_ones))


def import_csv(db: Database, text: str) -> int:
    """Register every row of a CSV file in the caller's single transaction, or none."""
    return import_records(db, parse_import(text, "csv")).identities


def import_json(db: Database, text: str) -> ImportResult:
    """Restore a JSON registry document in the caller's single transaction, or nothing."""
    return import_records(db, parse_json(text))


# ------------------------------------------------------------------ export
def _iso(t: datetime | None) -> str | None:
    return t.astimezone(timezone.utc).isoformat() if t is not None else None


def export_document(db: Database) -> dict[str, Any]:
    """Every profile and every identity, every field: what `import_json` restores."""
    return {
        "format": REGISTRY_FORMAT,
        "exported_at": _iso(utcnow()),
        "profiles": [p.to_dict() for p in list_profiles(db)],
        "identities": [{
            "serial": r.serial, "id_type": r.id_type, "model": r.model,
            "operator_id": r.operator_id,
            "public_key": r.public_key.hex() if r.public_key is not None else None,
            "status": r.status, "valid_from": _iso(r.valid_from), "valid_until": _iso(r.valid_until),
            "notes": r.notes, "created_at": _iso(r.created_at), "updated_at": _iso(r.updated_at),
        } for r in list_identities(db)],
    }


def export_json(db: Database) -> str:
    """The JSON registry document as UTF-8 text (non-ASCII kept readable)."""
    return json.dumps(export_document(db), indent=2, ensure_ascii=False) + "\n"


def export_csv(db: Database) -> str:
    """All identities in the CSV import format (no profiles, no created_at/updated_at)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in list_identities(db):
        w.writerow([r.serial, r.id_type, r.model, r.operator_id or "",
                    _iso(r.valid_from), _iso(r.valid_until) or "", r.notes or "",
                    r.status, r.public_key.hex() if r.public_key is not None else ""])
    return out.getvalue()
