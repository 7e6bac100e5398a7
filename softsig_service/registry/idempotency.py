"""Idempotency keys: the first response to a creating request, kept so that a retry gets the same answer.

A key's record moves through two states: *pending* (``status`` None: the first request is being served) and
*complete* (its status, the headers that matter and the body). Records older than ``ttl`` [s] are expired:
looked up as absent and removed by :func:`purge_expired_keys`.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete
from sqlalchemy.exc import IntegrityError

from softsig_service.registry.db import Registry
from softsig_service.registry.models import IdempotencyRow, utcnow

DEFAULT_TTL = 24 * 3600.0
"""How long [s] a key's first response is replayed."""


def _cutoff(ttl: float) -> datetime:
    """Records created before this time (UTC) have expired."""
    return utcnow() - timedelta(seconds=ttl)


@dataclass(frozen=True)
class StoredResponse:
    """A key's record: ``status`` None while the first request is in progress."""

    request_hash: str | None
    status: int | None
    headers: dict[str, Any]
    body: str


def find_key(reg: Registry, scope: str, *, ttl: float = DEFAULT_TTL) -> StoredResponse | None:
    """The record of ``scope``, or None if there is none or it expired."""
    with reg.read() as s:
        row = s.get(IdempotencyRow, scope)
        if row is None or row.created_at < _cutoff(ttl):
            return None
        return StoredResponse(row.request_hash, row.status, dict(row.headers), row.body)


def claim_key(reg: Registry, scope: str, *, ttl: float = DEFAULT_TTL) -> bool:
    """Mark ``scope`` pending; False when another request holds it (pending or complete, not expired)."""
    try:
        with reg.write() as s:
            row = s.get(IdempotencyRow, scope)
            if row is not None:
                if row.created_at >= _cutoff(ttl):
                    return False
                s.delete(row)
                s.flush()
            s.add(IdempotencyRow(scope=scope, created_at=utcnow()))
        return True
    except IntegrityError:  # another process claimed it between the read and the insert
        return False


def complete_key(reg: Registry, scope: str, *, request_hash: str, status: int, headers: dict[str, Any],
                 body: str) -> None:  # fmt: skip
    """Store the first response of ``scope``."""
    with reg.write() as s:
        row = s.get(IdempotencyRow, scope)
        if row is None:
            row = IdempotencyRow(scope=scope, created_at=utcnow())
            s.add(row)
        row.request_hash, row.status, row.headers, row.body = request_hash, status, headers, body


def release_key(reg: Registry, scope: str) -> None:
    """Forget ``scope`` (its first request failed: a retry runs again)."""
    with reg.write() as s:
        s.execute(delete(IdempotencyRow).where(IdempotencyRow.scope == scope))


def purge_expired_keys(reg: Registry, *, ttl: float = DEFAULT_TTL) -> int:
    """Remove the records older than ``ttl`` [s]; how many were removed."""
    with reg.write() as s:
        result = s.execute(delete(IdempotencyRow).where(IdempotencyRow.created_at < _cutoff(ttl)))
        return int(getattr(result, "rowcount", 0) or 0)
