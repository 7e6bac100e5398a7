"""Hands in the registry: registration, built-in hands, replacement and deletion under ETags.

A hand's ETag is ``"<name>.r<revision>"``; replacing a hand's files increments ``revision``. ``If-Match`` values
are compared strongly; ``*`` matches any current representation. Built-in hands are read-only.
"""

from __future__ import annotations

import contextlib
import hashlib
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import bindparam, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from softsig_service.errors import Conflict, HandNotFound, PreconditionFailed
from softsig_service.registry.db import Registry
from softsig_service.registry.models import HandRow, utcnow
from softsig_service.registry.records import record_from_row


def etag_matches(current: str | None, if_match: str) -> bool:
    """Whether an ``If-Match`` header value matches ``current`` (strong comparison; ``*`` = any existing)."""
    if current is None:
        return False
    tags = [t.strip() for t in if_match.split(",") if t.strip()]
    return any(t == "*" or t == current for t in tags)


def incarnation(created_at: datetime) -> str:
    """Eight hex digits naming one life of a hand: a hash of its creation time (microseconds, UTC). A hand deleted
    and registered again under its name gets new ETags for itself and its signature versions."""
    return hashlib.sha256(created_at.astimezone(UTC).isoformat().encode()).hexdigest()[:8]


def revision_token(name: str, revision: int, created_at: datetime) -> str:
    """``<name>.r<revision>.<incarnation>``: names one revision of one life of a hand (the ETag's text, the key of
    the planner's caches of the hand)."""
    return f"{name}.r{revision}.{incarnation(created_at)}"


@dataclass(frozen=True)
class HandRecord:
    """A registered hand: its manifest on disk, the summary of its model (``info``) and registry metadata."""

    name: str
    builtin: bool
    revision: int
    manifest_path: str
    folder: str | None
    files: list[dict[str, Any]]
    info: dict[str, Any]
    signature_count: int
    created_at: datetime
    updated_at: datetime

    @property
    def token(self) -> str:
        """This revision's :func:`revision_token`, unique also across a delete and a re-creation under the same
        name (:func:`incarnation`)."""
        return revision_token(self.name, self.revision, self.created_at)

    @property
    def etag(self) -> str:
        """Strong ETag of this revision of the hand: ``"<name>.r<revision>.<incarnation>"`` (:attr:`token`)."""
        return f'"{self.token}"'


@dataclass(frozen=True)
class HandRef:
    """What a plan needs of a registered hand: its name, its revision and its manifest file on disk."""

    name: str
    revision: int
    manifest_path: str
    token: str = ""
    """Names this revision of the hand, unique also across a delete and a re-creation (its ETag's text): what the
    planner's caches of the hand are keyed by."""


_HANDS = HandRow.__table__
_REF_QUERY = select(_HANDS.c.name, _HANDS.c.revision, _HANDS.c.manifest_path, _HANDS.c.created_at).where(
    _HANDS.c.name == bindparam("name")
)


_STAMP_QUERY = select(
    _HANDS.c.name, _HANDS.c.revision, _HANDS.c.created_at, _HANDS.c.updated_at, _HANDS.c.signature_count
).where(_HANDS.c.name == bindparam("name"))


def hand_stamp(reg: Registry, name: str) -> tuple[Any, ...] | None:
    """What every field of hand ``name``'s record is determined by: ``(name, revision, created_at, updated_at,
    signature_count)`` (a new revision for new files or info, a new incarnation for a re-creation, the count and
    time for a new signature); None if there is none. One indexed row, no JSON column decoded (SQLAlchemy Core):
    the key of a reader's cache of what it makes of the record (:func:`stamp_of`). Read by
    :meth:`Registry.fetch_one`."""
    return reg.fetch_one(_STAMP_QUERY, {"name": name})


def stamp_of(record: HandRecord) -> tuple[Any, ...]:
    """:func:`hand_stamp` of the row ``record`` was read from."""
    return (record.name, record.revision, record.created_at, record.updated_at, record.signature_count)


def _hand(row: HandRow) -> HandRecord:
    return record_from_row(HandRecord, row)


def hand_row(session: Session, name: str, field: str = "hand") -> HandRow:
    """The row of hand ``name`` in ``session``; :class:`HandNotFound` naming ``field`` if there is none."""
    row = session.scalars(select(HandRow).where(HandRow.name == name)).one_or_none()
    if row is None:
        names = session.scalars(select(HandRow.name).order_by(HandRow.name)).all()
        raise HandNotFound("unknown hand", field=field, value=name, choices=names)
    return row


def list_hands(reg: Registry) -> list[HandRecord]:
    """Every registered hand, by name."""
    with reg.read() as s:
        return [_hand(r) for r in s.scalars(select(HandRow).order_by(HandRow.name))]


def get_hand(reg: Registry, name: str, *, field: str = "hand") -> HandRecord:
    """The hand ``name``; :class:`HandNotFound` (with the registered names as choices) if there is none."""
    with reg.read() as s:
        return _hand(hand_row(s, name, field))


def hand_ref(reg: Registry, name: str, *, field: str = "hand") -> HandRef:
    """The name, revision and manifest of hand ``name``; :class:`HandNotFound` as :func:`get_hand` if there is none.

    One indexed row of four columns (:meth:`Registry.fetch_one`): no ORM session, no JSON column decoded (a plan
    request's path, where :func:`get_hand` costs several times as much)."""
    row = reg.fetch_one(_REF_QUERY, {"name": name})
    if row is None:  # HandNotFound with the registered names as choices (or a hand registered meanwhile)
        rec = get_hand(reg, name, field=field)
        return HandRef(rec.name, rec.revision, rec.manifest_path, rec.token)
    ref_name, revision, manifest_path, created_at = row
    return HandRef(ref_name, revision, manifest_path, revision_token(ref_name, revision, created_at))


def hand_names(reg: Registry) -> list[str]:
    """Names of the registered hands."""
    with reg.read() as s:
        return list(s.scalars(select(HandRow.name).order_by(HandRow.name)))


def add_hand(
    reg: Registry,
    *,
    name: str,
    manifest_path: str,
    info: dict[str, Any],
    files: Sequence[dict[str, Any]] = (),
    folder: str | None = None,
    builtin: bool = False,
) -> HandRecord:
    """Register a new hand; :class:`Conflict` if the name is taken."""
    try:
        with reg.write() as s:
            if s.scalars(select(HandRow.id).where(HandRow.name == name)).first() is not None:
                raise Conflict("a hand of this name is registered already", field="manifest.name", value=name)
            row = HandRow(
                name=name,
                builtin=builtin,
                revision=1,
                manifest_path=manifest_path,
                folder=folder,
                files=list(files),
                info=info,
                signature_count=0,
            )
            s.add(row)
            s.flush()
            return _hand(row)
    except IntegrityError:
        raise Conflict("a hand of this name is registered already", field="manifest.name", value=name) from None


def sync_builtin_hand(reg: Registry, *, name: str, manifest_path: str, info: dict[str, Any]) -> str:
    """Register a built-in hand if missing, refresh its path and summary if they changed.

    Returns ``"added"``, ``"updated"`` (revision incremented) or ``"unchanged"``. A user's hand of the same name
    is left alone (``"shadowed"``). Safe when several service workers start at once: the one whose insert loses
    the race on the hand's unique name (PostgreSQL) looks again and finds the row the winner added.
    """
    try:
        return _sync_builtin_hand(reg, name=name, manifest_path=manifest_path, info=info)
    except IntegrityError:
        return _sync_builtin_hand(reg, name=name, manifest_path=manifest_path, info=info)


def _sync_builtin_hand(reg: Registry, *, name: str, manifest_path: str, info: dict[str, Any]) -> str:
    with reg.write() as s:
        row = s.scalars(select(HandRow).where(HandRow.name == name)).one_or_none()
        if row is None:
            s.add(HandRow(name=name, builtin=True, revision=1, manifest_path=manifest_path, info=info, files=[]))
            s.flush()
            return "added"
        if not row.builtin:
            return "shadowed"
        if row.manifest_path == manifest_path and row.info == info:
            return "unchanged"
        row.manifest_path = manifest_path
        row.info = info
        row.revision += 1
        row.updated_at = utcnow()
        return "updated"


def _check_mutable(row: HandRow, if_match: str | None) -> None:
    if row.builtin:
        raise Conflict("built-in hands cannot be replaced or deleted", field="hand", value=row.name)
    if if_match is not None and not etag_matches(_hand(row).etag, if_match):
        raise PreconditionFailed(
            "If-Match does not match the hand's current ETag", field="If-Match", value=if_match,
            choices=[_hand(row).etag],
        )  # fmt: skip


def replace_hand(
    reg: Registry,
    name: str,
    *,
    if_match: str | None,
    manifest_path: str,
    folder: str,
    files: Sequence[dict[str, Any]],
    info: dict[str, Any],
) -> tuple[HandRecord, str | None]:
    """Replace an uploaded hand's files (revision + 1); returns the new record and the old folder to remove."""
    with reg.write() as s:
        row = hand_row(s, name)
        _check_mutable(row, if_match)
        old = row.folder
        row.manifest_path = manifest_path
        row.folder = folder
        row.files = list(files)
        row.info = info
        row.revision += 1
        row.updated_at = utcnow()
        s.flush()
        return _hand(row), old


def delete_hand(reg: Registry, name: str, *, if_match: str | None) -> HandRecord:
    """Delete an uploaded hand and its signatures; returns the deleted record (its folder is the caller's)."""
    with reg.write() as s:
        row = hand_row(s, name)
        _check_mutable(row, if_match)
        record = _hand(row)
        s.delete(row)
        return record


def remove_hand_folder(folder: str | Path | None) -> None:
    """Remove a stored revision's folder, and the hand's folder above it when that is left empty."""
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)
        with contextlib.suppress(OSError):
            Path(folder).parent.rmdir()
