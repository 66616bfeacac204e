"""Audit decisions may be `inconclusive`: the radar's evidence reached neither bound of the sequential
test (docs/policies.md), never an accept. audit_log's decision CHECK admits it and the column widens
to 16 characters. Rows are kept as they are (their hashed bytes do not change).
"""

from alembic import op

from registry.migrations.triggers import replace_in_table

revision = "0006"
down_revision = "0005"

_OLD = "decision IS NULL OR decision IN ('accept', 'reject')"
_NEW = "decision IS NULL OR decision IN ('accept', 'reject', 'inconclusive')"


def _decisions(old: str, new: str, width: int, was: int) -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"ALTER TABLE audit_log ALTER COLUMN decision TYPE VARCHAR({width})")
    replace_in_table(op, "audit_log", [(f"decision VARCHAR({was})", f"decision VARCHAR({width})"), (old, new)],
                     "ck_audit_log_decision_enum")


def upgrade() -> None:
    _decisions(_OLD, _NEW, 16, 8)


def downgrade() -> None:
    # fails (CHECK) while `inconclusive` entries exist: they are kept
    _decisions(_NEW, _OLD, 8, 16)
