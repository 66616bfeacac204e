"""SQLAlchemy 2 typed ORM of the registry and audit schema.

Constraints live in the database (unique serial, foreign keys, CHECKs on
physical ranges and enumerations) so that no client, ours or another, can
store a row the product would misread.
"""

from __future__ import annotations

from datetime import datetime, timezone

from sqlalchemy import (
    BigInteger,
    CheckConstraint,
    Double,
    ForeignKey,
    Integer,
    LargeBinary,
    MetaData,
    String,
    Text,
    CHAR,
    DateTime,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.engine import Dialect
from sqlalchemy.types import TypeDecorator

NAMING = {
    "ix": "ix_%(column_0_label)s",
    "uq": "uq_%(table_name)s_%(column_0_name)s",
    "ck": "ck_%(table_name)s_%(constraint_name)s",
    "fk": "fk_%(table_name)s_%(column_0_name)s_%(referred_table_name)s",
    "pk": "pk_%(table_name)s",
}


class UtcDateTime(TypeDecorator):
    """Timezone-aware UTC datetimes on every backend (SQLite stores naive text)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            raise ValueError("naive datetime: timestamps must be timezone-aware")
        value = value.astimezone(timezone.utc)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=timezone.utc)
        return value.astimezone(timezone.utc)


class Base(DeclarativeBase):
    metadata = MetaData(naming_convention=NAMING)


class ModelProfile(Base):
    """Declared airframe: its physical parameters (signatures/profiles.py)."""

    __tablename__ = "model_profiles"

    slug: Mapped[str] = mapped_column(String(32), primary_key=True)
    name: Mapped[str] = mapped_column(String(100))
    rotors: Mapped[int] = mapped_column(Integer)
    arms: Mapped[int] = mapped_column(Integer)
    blades_per_rotor: Mapped[int] = mapped_column(Integer)
    blade_length_m: Mapped[float] = mapped_column(Double)
    rotor_rate_hz: Mapped[float] = mapped_column(Double)
    propeller_distance_m: Mapped[float] = mapped_column(Double)

    __table_args__ = (
        CheckConstraint("length(slug) BETWEEN 1 AND 32", name="slug_length"),
        CheckConstraint("slug NOT IN ('bird', 'none', 'unknown')", name="slug_not_reserved"),
        CheckConstraint("length(name) BETWEEN 1 AND 100", name="name_length"),
        CheckConstraint("rotors BETWEEN 1 AND 16", name="rotors_range"),
        CheckConstraint("arms BETWEEN 1 AND 16", name="arms_range"),
        CheckConstraint("blades_per_rotor BETWEEN 1 AND 8", name="blades_range"),
        CheckConstraint("blade_length_m > 0.01 AND blade_length_m <= 3.0", name="blade_length_range"),
        CheckConstraint("rotor_rate_hz > 1.0 AND rotor_rate_hz <= 500.0", name="rotor_rate_range"),
        CheckConstraint("propeller_distance_m > 0.05 AND propeller_distance_m <= 10.0",
                        name="propeller_distance_range"),
    )


class Identity(Base):
    """An authorised (or revoked) Remote ID identity."""

    __tablename__ = "identities"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    serial: Mapped[str] = mapped_column(String(64), unique=True)
    id_type: Mapped[str] = mapped_column(String(20))
    operator_id: Mapped[str | None] = mapped_column(String(20))
    model_slug: Mapped[str] = mapped_column(
        String(32), ForeignKey("model_profiles.slug", ondelete="RESTRICT"), index=True)
    public_key: Mapped[bytes | None] = mapped_column(LargeBinary(32))
    status: Mapped[str] = mapped_column(String(8), default="active")
    valid_from: Mapped[datetime] = mapped_column(UtcDateTime)
    valid_until: Mapped[datetime | None] = mapped_column(UtcDateTime)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime)
    notes: Mapped[str | None] = mapped_column(Text)

    profile: Mapped[ModelProfile] = relationship(lazy="joined")

    __table_args__ = (
        CheckConstraint("length(serial) BETWEEN 1 AND 64", name="serial_length"),
        CheckConstraint(
            "id_type IN ('serial', 'caa_registration', 'utm_uuid', 'specific_session')",
            name="id_type_enum"),
        CheckConstraint("status IN ('active', 'revoked')", name="status_enum"),
        CheckConstraint("public_key IS NULL OR length(public_key) = 32", name="public_key_length"),
        CheckConstraint("valid_until IS NULL OR valid_until > valid_from", name="validity_window"),
    )


class AuditLog(Base):
    """Hash-chained, append-only decision log (written by the decision layer); kind 'registry'
    entries record registry changes made through `authn serve` (revision 0003)."""

    __tablename__ = "audit_log"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    seq: Mapped[int] = mapped_column(BigInteger, unique=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime)
    kind: Mapped[str] = mapped_column(String(16))
    serial: Mapped[str | None] = mapped_column(Text)
    decision: Mapped[str | None] = mapped_column(String(16))
    payload: Mapped[str] = mapped_column(Text)
    prev_hash: Mapped[str] = mapped_column(CHAR(64))
    entry_hash: Mapped[str] = mapped_column(CHAR(64), unique=True)
    leaf_hash: Mapped[str | None] = mapped_column(CHAR(64))  # RFC 9162 leaf hash (revision 0002)
    leaf_bytes: Mapped[bytes | None] = mapped_column(LargeBinary)  # what is hashed, authn.audit.leaf (revision 0008)

    __table_args__ = (
        CheckConstraint("kind IN ('decision', 'error', 'registry', 'audit')", name="kind_enum"),
        CheckConstraint("decision IS NULL OR decision IN ('accept', 'reject', 'inconclusive')", name="decision_enum"),
    )


class AuditPolicy(Base):
    """Each distinct Cedar policy text a decision was made under, once, by SHA-256 (for replay)."""

    __tablename__ = "audit_policies"

    sha256: Mapped[str] = mapped_column(CHAR(64), primary_key=True)
    text: Mapped[str] = mapped_column(Text)
    first_seen: Mapped[datetime] = mapped_column(UtcDateTime)


class AuditTreeHead(Base):
    """Signed tree heads of the audit log's Merkle tree (RFC 9162): one per append transaction
    (every entry is covered by a signature), and on the periodic ones (every K entries / T
    seconds) the frontier that lets the next head continue without rehashing the whole log.
    Written by authn.audit."""

    __tablename__ = "audit_tree_heads"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    tree_size: Mapped[int] = mapped_column(BigInteger, index=True)
    timestamp_ms: Mapped[int] = mapped_column(BigInteger)
    root_hash: Mapped[str] = mapped_column(CHAR(64))
    log_key_id: Mapped[str] = mapped_column(CHAR(64))
    signature: Mapped[str] = mapped_column(Text)
    frontier: Mapped[str | None] = mapped_column(Text)  # JSON: the tree's right edge (see authn.audit)
    origin: Mapped[str | None] = mapped_column(Text)  # the log the head names; NULL: authn-sth/1 (revision 0005)


class AuditLogMeta(Base):
    """Facts about the audit log itself (revision 0005): `origin`, the name its checkpoints
    carry, written once by the first append. Written by authn.audit."""

    __tablename__ = "audit_log_meta"

    name: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class AuditBatch(Base):
    """One keyed append transaction of the audit log (revision 0004): a retried append whose
    key is here already committed, so it writes nothing (`authn check --cluster` retries a
    partition whose worker died). Written by authn.audit."""

    __tablename__ = "audit_batches"

    key: Mapped[str] = mapped_column(String(200), primary_key=True)
    first_seq: Mapped[int] = mapped_column(BigInteger)
    n: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime)

    __table_args__ = (CheckConstraint("n >= 0", name="n_non_negative"),)


class ApiKey(Base):
    """A key of `authn serve` (`authn keys api create`): its role and the SHA-256 of its token;
    the token itself is shown once and never stored."""

    __tablename__ = "api_keys"

    id: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=True)
    name: Mapped[str | None] = mapped_column(String(100))
    role: Mapped[str] = mapped_column(String(16))
    key_hash: Mapped[str] = mapped_column(CHAR(64), unique=True)
    created_at: Mapped[datetime] = mapped_column(UtcDateTime)
    revoked_at: Mapped[datetime | None] = mapped_column(UtcDateTime)

    __table_args__ = (CheckConstraint("role IN ('operator', 'admin')", name="role_enum"),)
