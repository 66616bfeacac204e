"""Audit entries of kind `audit`: the log's own events, the one today being `authn audit recover`
signing entries no signed head vouched for (docs/audit.md). audit_log's kind CHECK admits it;
rows are kept as they are (their hashed bytes do not change).
"""

from alembic import op

from registry.migrations.triggers import replace_in_table

revision = "0007"
down_revision = "0006"

_OLD = "kind IN ('decision', 'error', 'registry')"
_NEW = "kind IN ('decision', 'error', 'registry', 'audit')"


def upgrade() -> None:
    replace_in_table(op, "audit_log", [(_OLD, _NEW)], "ck_audit_log_kind_enum")


def downgrade() -> None:
    # fails (CHECK) while `audit` entries exist: they are kept
    replace_in_table(op, "audit_log", [(_NEW, _OLD)], "ck_audit_log_kind_enum")
