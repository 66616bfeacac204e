"""Initial schema: model profiles (seeded), identities, append-only audit log.

Revision 0001 (the first), 2025-11-22.
"""

import sqlalchemy as sa
from alembic import op

from registry.migrations.triggers import create_append_only, drop_append_only
from registry.models import UtcDateTime

revision = "0001"
down_revision = None

#: The shipped profiles (signatures/data/profiles.json) as of this revision, frozen here so that this
#: revision never changes.
SHIPPED_PROFILES = [
    {"slug": "m600", "name": "DJI Matrice 600", "rotors": 6, "arms": 6, "blades_per_rotor": 2,
     "blade_length_m": 0.50, "rotor_rate_hz": 36.6667, "propeller_distance_m": 1.13},
    {"slug": "m300", "name": "DJI Matrice 300", "rotors": 4, "arms": 4, "blades_per_rotor": 2,
     "blade_length_m": 0.40, "rotor_rate_hz": 40.0, "propeller_distance_m": 0.885},
    {"slug": "phantom4", "name": "DJI Phantom 4", "rotors": 4, "arms": 4, "blades_per_rotor": 2,
     "blade_length_m": 0.30, "rotor_rate_hz": 58.3333, "propeller_distance_m": 0.35},
]


def upgrade() -> None:
    profiles = op.create_table(
        "model_profiles",
        sa.Column("slug", sa.String(32), nullable=False),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("rotors", sa.Integer(), nullable=False),
        sa.Column("arms", sa.Integer(), nullable=False),
        sa.Column("blades_per_rotor", sa.Integer(), nullable=False),
        sa.Column("blade_length_m", sa.Double(), nullable=False),
        sa.Column("rotor_rate_hz", sa.Double(), nullable=False),
        sa.Column("propeller_distance_m", sa.Double(), nullable=False),
        sa.CheckConstraint("length(slug) BETWEEN 1 AND 32", name=op.f("ck_model_profiles_slug_length")),
        sa.CheckConstraint("slug NOT IN ('bird', 'none', 'unknown')",
                           name=op.f("ck_model_profiles_slug_not_reserved")),
        sa.CheckConstraint("length(name) BETWEEN 1 AND 100", name=op.f("ck_model_profiles_name_length")),
        sa.CheckConstraint("rotors BETWEEN 1 AND 16", name=op.f("ck_model_profiles_rotors_range")),
        sa.CheckConstraint("arms BETWEEN 1 AND 16", name=op.f("ck_model_profiles_arms_range")),
        sa.CheckConstraint("blades_per_rotor BETWEEN 1 AND 8", name=op.f("ck_model_profiles_blades_range")),
        sa.CheckConstraint("blade_length_m > 0.01 AND blade_length_m <= 3.0",
                           name=op.f("ck_model_profiles_blade_length_range")),
        sa.CheckConstraint("rotor_rate_hz > 1.0 AND rotor_rate_hz <= 500.0",
                           name=op.f("ck_model_profiles_rotor_rate_range")),
        sa.CheckConstraint("propeller_distance_m > 0.05 AND propeller_distance_m <= 10.0",
                           name=op.f("ck_model_profiles_propeller_distance_range")),
        sa.PrimaryKeyConstraint("slug", name=op.f("pk_model_profiles")),
    )
    op.create_table(
        "identities",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("serial", sa.String(64), nullable=False),
        sa.Column("id_type", sa.String(20), nullable=False),
        sa.Column("operator_id", sa.String(20), nullable=True),
        sa.Column("model_slug", sa.String(32), nullable=False),
        sa.Column("public_key", sa.LargeBinary(32), nullable=True),
        sa.Column("status", sa.String(8), nullable=False),
        sa.Column("valid_from", UtcDateTime(), nullable=False),
        sa.Column("valid_until", UtcDateTime(), nullable=True),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.Column("updated_at", UtcDateTime(), nullable=False),
        sa.Column("notes", sa.Text(), nullable=True),
        sa.CheckConstraint("length(serial) BETWEEN 1 AND 64", name=op.f("ck_identities_serial_length")),
        sa.CheckConstraint(
            "id_type IN ('serial', 'caa_registration', 'utm_uuid', 'specific_session')",
            name=op.f("ck_identities_id_type_enum")),
        sa.CheckConstraint("status IN ('active', 'revoked')", name=op.f("ck_identities_status_enum")),
        sa.CheckConstraint("public_key IS NULL OR length(public_key) = 32",
                           name=op.f("ck_identities_public_key_length")),
        sa.CheckConstraint("valid_until IS NULL OR valid_until > valid_from",
                           name=op.f("ck_identities_validity_window")),
        sa.ForeignKeyConstraint(["model_slug"], ["model_profiles.slug"], ondelete="RESTRICT",
                                name=op.f("fk_identities_model_slug_model_profiles")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_identities")),
        sa.UniqueConstraint("serial", name=op.f("uq_identities_serial")),
    )
    op.create_index(op.f("ix_identities_model_slug"), "identities", ["model_slug"])
    create_append_only(
        op, "audit_log",
        sa.Column("id", sa.Integer(), autoincrement=True, nullable=False),
        sa.Column("seq", sa.BigInteger(), nullable=False),
        sa.Column("created_at", UtcDateTime(), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("serial", sa.Text(), nullable=True),
        sa.Column("decision", sa.String(8), nullable=True),
        sa.Column("payload", sa.Text(), nullable=False),
        sa.Column("prev_hash", sa.CHAR(64), nullable=False),
        sa.Column("entry_hash", sa.CHAR(64), nullable=False),
        sa.CheckConstraint("kind IN ('decision', 'error')", name=op.f("ck_audit_log_kind_enum")),
        sa.CheckConstraint("decision IS NULL OR decision IN ('accept', 'reject')",
                           name=op.f("ck_audit_log_decision_enum")),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_audit_log")),
        sa.UniqueConstraint("seq", name=op.f("uq_audit_log_seq")),
        sa.UniqueConstraint("entry_hash", name=op.f("uq_audit_log_entry_hash")),
    )
    op.bulk_insert(profiles, SHIPPED_PROFILES)


def downgrade() -> None:
    drop_append_only(op, "audit_log")
    op.drop_index(op.f("ix_identities_model_slug"), table_name="identities")
    op.drop_table("identities")
    op.drop_table("model_profiles")
