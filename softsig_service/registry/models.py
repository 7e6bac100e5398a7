"""The registry's tables (SQLAlchemy 2 ORM): hands, their versioned signatures, stored plans and jobs.

* ``hands`` — one row per hand the service knows: the built-in hands (registered at first start, read-only) and
  hands uploaded over the API (their files in a folder of their own under the data dir). ``revision`` counts
  replacements of a hand's files and makes its ETag; ``signature_count`` is the last signature version handed out
  (versions are allocated by incrementing it inside the inserting transaction, so they are 1..N without gaps).
* ``signatures`` — closure and stiffness signatures, one row per version, never updated or overwritten. A row
  records the hand revision it was computed from.
* ``plans`` — every stored grasp plan (request and result JSON).
* ``jobs`` — validations, experiments and other long work run in worker processes: status, progress, result.

Times are stored as UTC (``created_at`` etc.); JSON columns hold the service's wire shapes.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import JSON, Boolean, DateTime, Float, ForeignKey, Index, Integer, String, Text, UniqueConstraint
from sqlalchemy.engine import Dialect
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship
from sqlalchemy.types import TypeDecorator


def utcnow() -> datetime:
    """The current time, timezone-aware UTC."""
    return datetime.now(UTC)


class UTCDateTime(TypeDecorator[datetime]):
    """A timestamp stored as UTC and always read back timezone-aware (SQLite keeps no zone)."""

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            value = value.replace(tzinfo=UTC)
        return value.astimezone(UTC)

    def process_result_value(self, value: datetime | None, dialect: Dialect) -> datetime | None:
        if value is None:
            return None
        return value.replace(tzinfo=UTC) if value.tzinfo is None else value.astimezone(UTC)


class Base(DeclarativeBase):
    """Declarative base of the registry's tables."""


class HandRow(Base):
    """A registered hand (built in or uploaded)."""

    __tablename__ = "hands"

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    name: Mapped[str] = mapped_column(String(64), unique=True, nullable=False)
    builtin: Mapped[bool] = mapped_column(Boolean, nullable=False, default=False)
    revision: Mapped[int] = mapped_column(Integer, nullable=False, default=1)
    manifest_path: Mapped[str] = mapped_column(Text, nullable=False)
    folder: Mapped[str | None] = mapped_column(Text, nullable=True)
    """The folder the service owns (uploaded hands); None for built-in hands."""
    files: Mapped[list[Any]] = mapped_column(JSON, nullable=False, default=list)
    info: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False, default=dict)
    signature_count: Mapped[int] = mapped_column(Integer, nullable=False, default=0)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)
    updated_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)

    signatures: Mapped[list[SignatureRow]] = relationship(
        back_populates="hand", cascade="all, delete-orphan", passive_deletes=True
    )


class SignatureRow(Base):
    """One version of a hand's closure or stiffness signature."""

    __tablename__ = "signatures"
    __table_args__ = (
        UniqueConstraint("hand_id", "version", name="uq_signature_version"),
        Index("ix_signatures_hand_kind_version", "hand_id", "kind", "version"),
        Index("ix_signatures_hand_kind_object", "hand_id", "kind", "object_digest", "hand_revision"),
    )

    id: Mapped[int] = mapped_column(Integer, primary_key=True)
    hand_id: Mapped[int] = mapped_column(ForeignKey("hands.id", ondelete="CASCADE"), nullable=False)
    version: Mapped[int] = mapped_column(Integer, nullable=False)
    kind: Mapped[str] = mapped_column(String(16), nullable=False)
    method: Mapped[str] = mapped_column(String(64), nullable=False)
    source: Mapped[str] = mapped_column(String(16), nullable=False)
    hand_revision: Mapped[int] = mapped_column(Integer, nullable=False)
    object_digest: Mapped[str | None] = mapped_column(String(64), nullable=True)
    """``TableObject.shape_digest`` of the object a stiffness signature or capture model was computed on."""
    params: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False, default=dict)
    data: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)

    hand: Mapped[HandRow] = relationship(back_populates="signatures")


class PlanRow(Base):
    """A stored grasp plan."""

    __tablename__ = "plans"
    __table_args__ = (Index("ix_plans_created_at", "created_at"),)

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    hand: Mapped[str] = mapped_column(String(64), nullable=False)
    strategy: Mapped[str] = mapped_column(String(1), nullable=False)
    success: Mapped[bool] = mapped_column(Boolean, nullable=False)
    request: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False)
    result: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)


class ObjectRow(Base):
    """A registered object: its geometry as the planner takes it (a mesh, a primitive), sent once."""

    __tablename__ = "objects"
    __table_args__ = (Index("ix_objects_created_at", "created_at"),)

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    name: Mapped[str] = mapped_column(String(64), nullable=False)
    source: Mapped[str] = mapped_column(String(16), nullable=False)
    spec: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False)
    table_height: Mapped[float] = mapped_column(Float, nullable=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)


class JobRow(Base):
    """A job: long work run in a worker process."""

    __tablename__ = "jobs"
    __table_args__ = (Index("ix_jobs_status", "status"), Index("ix_jobs_created_at", "created_at"))

    id: Mapped[str] = mapped_column(String(32), primary_key=True)
    kind: Mapped[str] = mapped_column(String(32), nullable=False)
    status: Mapped[str] = mapped_column(String(16), nullable=False)
    progress: Mapped[float] = mapped_column(Float, nullable=False, default=0.0)
    message: Mapped[str] = mapped_column(Text, nullable=False, default="")
    params: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False)
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    error: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    time_limit: Mapped[float] = mapped_column(Float, nullable=False)
    cancel_requested: Mapped[bool] = mapped_column(Boolean, nullable=False, default=False)
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)
    started_at: Mapped[datetime | None] = mapped_column(UTCDateTime, nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(UTCDateTime, nullable=True)
    private: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    """Parameters for the worker only (server paths); never shown to clients."""
    owner: Mapped[str | None] = mapped_column(String(100), nullable=True)
    """The service process holding the job's lease (``host:pid:nonce``), None while queued."""
    lease_expires_at: Mapped[datetime | None] = mapped_column(UTCDateTime, nullable=True)
    """When the owner's lease ends unless its heartbeat renews it; then another process may claim the job."""
    attempts: Mapped[int] = mapped_column(Integer, nullable=False, default=0, server_default="0")
    """How many times a process has claimed the job."""


class IdempotencyRow(Base):
    """The first response to a request that carried an ``Idempotency-Key`` (replayed to its retries).

    ``scope`` is a hash of the caller's API key, the method and path, and the key itself; ``request_hash`` the
    SHA-256 of the request body. ``status`` is None while the first request is still being served.
    """

    __tablename__ = "idempotency_keys"
    __table_args__ = (Index("ix_idempotency_created_at", "created_at"),)

    scope: Mapped[str] = mapped_column(String(64), primary_key=True)
    request_hash: Mapped[str | None] = mapped_column(String(64), nullable=True)
    status: Mapped[int | None] = mapped_column(Integer, nullable=True)
    headers: Mapped[dict[str, Any]] = mapped_column(JSON, nullable=False, default=dict)
    body: Mapped[str] = mapped_column(Text, nullable=False, default="")
    created_at: Mapped[datetime] = mapped_column(UTCDateTime, nullable=False, default=utcnow)
