"""``signatures.object_digest``: the shape digest of the object a stiffness signature or capture model was computed
on, so that strategy R finds the capture model of a hand's revision and object with one indexed query. Versions
stored before get theirs from their stored object (``params.object``) when the service starts
(:func:`softsig_service.registry.signatures.fill_object_digests`; the digest is the objects layer's, above this one).
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision: str | None = "0003"


def upgrade() -> None:
    """Upgrade the schema (the service fills the digests of stored versions at its start: ``fill_object_digests``)."""
    with op.batch_alter_table("signatures") as batch:
        batch.add_column(sa.Column("object_digest", sa.String(length=64), nullable=True))
    op.create_index(
        "ix_signatures_hand_kind_object", "signatures", ["hand_id", "kind", "object_digest", "hand_revision"]
    )


def downgrade() -> None:
    """Downgrade the schema."""
    op.drop_index("ix_signatures_hand_kind_object", table_name="signatures")
    with op.batch_alter_table("signatures") as batch:
        batch.drop_column("object_digest")
