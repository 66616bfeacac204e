"""Registry queries: model profiles and identities, single and bulk (CSV).

Functions take a Session and never commit: the caller's `session_scope` makes
each command one transaction, so a failed bulk import writes nothing.
Everything is validated before anything is written.
"""

from __future__ import annotations

import csv
import io
from datetime import datetime, timezone
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from sqlalchemy import select
from sqlalchemy.exc import DBAPIError, IntegrityError
from sqlalchemy.orm import Session

from registry.errors import RegistryError
from registry.models import Identity, ModelProfile, utcnow
from registry.serials import validate_uas_id
from signatures.profiles import UavProfile

CSV_COLUMNS = ("serial", "id_type", "model", "operator_id", "valid_from", "valid_until", "notes")
IdType = Literal["serial", "caa_registration", "utm_uuid", "specific_session"]


def describe_validation_error(exc: ValidationError) -> str:
    """The first error of a pydantic ValidationError as one line (`field: reason`)."""
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"])
    msg = err["msg"].removeprefix("Value error, ")
    return f"{loc}: {msg}" if loc else msg


class NewIdentity(BaseModel):
    """A validated identity to register (CLI flags or one CSV row)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    serial: str
    id_type: IdType = "serial"
    model: str = Field(min_length=1, max_length=32)
    operator_id: str | None = Field(default=None, max_length=20, pattern=r"^[\x20-\x7e]+$")
    public_key: bytes | None = Field(default=None, min_length=32, max_length=32)
    valid_from: datetime | None = None
    valid_until: datetime | None = None
    notes: str | None = Field(default=None, max_length=2000)

    @field_validator("valid_from", "valid_until")
    @classmethod
    def _aware(cls, v: datetime | None) -> datetime | None:
        if v is not None and v.tzinfo is None:
            v = v.replace(tzinfo=timezone.utc)  # naive input is read as UTC
        return v.astimezone(timezone.utc) if v is not None else None

    @model_validator(mode="after")
    def _check(self) -> "NewIdentity":
        object.__setattr__(self, "serial", validate_uas_id(self.serial, self.id_type))
        start = self.valid_from or utcnow()
        if self.valid_until is not None and self.valid_until <= start:
            raise ValueError("valid_until must be after valid_from")
        return self


class IdentityRecord(BaseModel):
    """A registered identity with its declared airframe (what the decision layer reads)."""

    model_config = ConfigDict(frozen=True, ser_json_bytes="hex")

    serial: str
    id_type: IdType
    operator_id: str | None
    model: str
    profile: UavProfile
    public_key: bytes | None
    status: Literal["active", "revoked"]
    valid_from: datetime
    valid_until: datetime | None
    created_at: datetime
    updated_at: datetime
    notes: str | None

    def is_valid_at(self, when: datetime) -> bool:
        """Active and inside its validity window at `when`."""
        return (self.status == "active" and self.valid_from <= when
                and (self.valid_until is None or when < self.valid_until))


def _profile(row: ModelProfile) -> UavProfile:
    return UavProfile(slug=row.slug, name=row.name, rotors=row.rotors, arms=row.arms,
                      blades_per_rotor=row.blades_per_rotor, blade_length_m=row.blade_length_m,
                      rotor_rate_hz=row.rotor_rate_hz, propeller_distance_m=row.propeller_distance_m)


def _record(row: Identity) -> IdentityRecord:
    return IdentityRecord(
        serial=row.serial, id_type=row.id_type, operator_id=row.operator_id, model=row.model_slug,
        profile=_profile(row.profile), public_key=row.public_key, status=row.status,
        valid_from=row.valid_from, valid_until=row.valid_until, created_at=row.created_at,
        updated_at=row.updated_at, notes=row.notes)


def _flush(session: Session, what: str) -> None:
    """Flush, turning constraint violations (e.g. a concurrent duplicate) into RegistryError."""
    try:
        session.flush()
    except IntegrityError as exc:
        session.rollback()
        msg = str(exc.orig).strip().splitlines()[0] if exc.orig else "constraint violated"
        if "unique" in msg.lower() or "duplicate" in msg.lower():
            raise RegistryError(f"{what}: already registered") from None
        raise RegistryError(f"{what}: rejected by the database ({msg})") from None
    except DBAPIError as exc:
        session.rollback()
        raise RegistryError(f"{what}: database error ({str(exc.orig).splitlines()[0]})") from None


# ------------------------------------------------------------------ profiles
def list_profiles(session: Session) -> list[UavProfile]:
    """All model profiles, ordered by slug (the radar side reads these)."""
    return [_profile(r) for r in session.scalars(select(ModelProfile).order_by(ModelProfile.slug))]


def get_profile(session: Session, slug: str) -> UavProfile | None:
    row = session.get(ModelProfile, slug)
    return _profile(row) if row else None


def register_profile(session: Session, profile: UavProfile) -> UavProfile:
    """Add a new airframe; an existing slug is an error (profiles are never silently changed)."""
    if session.get(ModelProfile, profile.slug) is not None:
        raise RegistryError(f"model {profile.slug!r}: already registered")
    session.add(ModelProfile(**profile.model_dump()))
    _flush(session, f"model {profile.slug!r}")
    return profile


# ------------------------------------------------------------------ identities
def _known_models(session: Session) -> set[str]:
    return set(session.scalars(select(ModelProfile.slug)))


def _row(new: NewIdentity, now: datetime) -> Identity:
    return Identity(serial=new.serial, id_type=new.id_type, operator_id=new.operator_id,
                    model_slug=new.model, public_key=new.public_key, status="active",
                    valid_from=new.valid_from or now, valid_until=new.valid_until,
                    created_at=now, updated_at=now, notes=new.notes)


def register_identity(session: Session, new: NewIdentity) -> IdentityRecord:
    """Add one identity; unknown model or duplicate serial raise RegistryError."""
    if new.model not in _known_models(session):
        raise RegistryError(f"unknown model {new.model!r} (register it first with --rotors ...)")
    if get_identity(session, new.serial) is not None:
        raise RegistryError(f"serial {new.serial}: already registered")
    row = _row(new, utcnow())
    session.add(row)
    _flush(session, f"serial {new.serial}")
    return _record(row)


def get_identity(session: Session, serial: str) -> IdentityRecord | None:
    """The identity registered under `serial` (exact, or normalised CTA-2063-A form)."""
    row = session.scalar(select(Identity).where(Identity.serial == serial.strip()))
    if row is None and serial.strip().upper() != serial.strip():
        row = session.scalar(select(Identity).where(Identity.serial == serial.strip().upper()))
    return _record(row) if row else None


def list_identities(session: Session, status: str | None = None) -> list[IdentityRecord]:
    q = select(Identity).order_by(Identity.serial)
    if status is not None:
        q = q.where(Identity.status == status)
    return [_record(r) for r in session.scalars(q)]


def revoke_identity(session: Session, serial: str, reason: str | None = None) -> IdentityRecord:
    """Mark an identity revoked (kept for the audit trail, never deleted)."""
    row = session.scalar(select(Identity).where(Identity.serial == serial.strip().upper())) or \
        session.scalar(select(Identity).where(Identity.serial == serial.strip()))
    if row is None:
        raise RegistryError(f"serial {serial}: not registered")
    if row.status == "revoked":
        raise RegistryError(f"serial {row.serial}: already revoked")
    row.status = "revoked"
    row.updated_at = utcnow()
    if reason:
        row.notes = f"{row.notes}\n" if row.notes else ""
        row.notes += f"revoked: {reason}"
    _flush(session, f"serial {row.serial}")
    return _record(row)


# ------------------------------------------------------------------ CSV
def _parse_time(text: str, column: str) -> datetime | None:
    text = text.strip()
    if not text:
        return None
    try:
        return datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        raise ValueError(f"{column}: {text!r} is not an ISO 8601 date/time") from None


def parse_csv(text: str) -> list[NewIdentity]:
    """Validate every row of an import file; any bad row raises (with its line number)."""
    reader = csv.DictReader(io.StringIO(text))
    header = tuple(h.strip() for h in reader.fieldnames or ())
    missing = [c for c in ("serial", "model") if c not in header]
    unknown = [c for c in header if c not in CSV_COLUMNS]
    if missing or unknown:
        raise RegistryError(f"CSV header {','.join(header) or '(empty)'}: "
                            f"expected columns {','.join(CSV_COLUMNS)}")
    rows, seen = [], {}
    for line, raw in enumerate(reader, start=2):
        if None in raw:
            raise RegistryError(f"line {line}: more fields than columns")
        cells = {k.strip(): (v or "").strip() for k, v in raw.items()}
        try:
            new = NewIdentity(
                serial=cells["serial"], id_type=cells.get("id_type") or "serial",
                model=cells["model"], operator_id=cells.get("operator_id") or None,
                valid_from=_parse_time(cells.get("valid_from", ""), "valid_from"),
                valid_until=_parse_time(cells.get("valid_until", ""), "valid_until"),
                notes=cells.get("notes") or None)
        except ValidationError as exc:
            raise RegistryError(f"line {line}: {describe_validation_error(exc)}") from None
        except (RegistryError, ValueError) as exc:
            raise RegistryError(f"line {line}: {exc}") from None
        if new.serial in seen:
            raise RegistryError(f"line {line}: serial {new.serial} repeats line {seen[new.serial]}")
        seen[new.serial] = line
        rows.append(new)
    return rows


def import_csv(session: Session, text: str) -> int:
    """Register every row of a CSV file in the caller's single transaction, or none."""
    rows = parse_csv(text)
    models = _known_models(session)
    for line, new in enumerate(rows, start=2):
        if new.model not in models:
            raise RegistryError(f"line {line}: unknown model {new.model!r}")
    existing = set(session.scalars(select(Identity.serial).where(
        Identity.serial.in_([r.serial for r in rows]))))
    if existing:
        raise RegistryError(f"serial {sorted(existing)[0]}: already registered "
                            f"({len(existing)} of the file's serials are)")
    now = utcnow()
    session.add_all(_row(r, now) for r in rows)
    _flush(session, "import")
    return len(rows)


def export_csv(session: Session) -> str:
    """All identities in the import format (public keys are not part of it)."""
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in list_identities(session):
        w.writerow([r.serial, r.id_type, r.model, r.operator_id or "",
                    r.valid_from.isoformat(), r.valid_until.isoformat() if r.valid_until else "",
                    r.notes or ""])
    return out.getvalue()
