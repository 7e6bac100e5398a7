"""Versioned signatures of a hand: append-only rows numbered 1..N per hand without gaps.

A signature's ETag is ``"<hand>.v<version>"``. Versions are allocated per hand (closure and stiffness share one
sequence) by ``UPDATE hands SET signature_count = signature_count + 1 ... RETURNING`` in the transaction that
inserts the row: concurrent writers queue on the hand's row (PostgreSQL) or on SQLite's write lock, and a
rolled-back insert rolls the counter back too, so versions are 1..N without gaps. Rows are never updated.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import bindparam, func, select, update

from softsig_service.errors import Conflict, NotFound, PreconditionFailed
from softsig_service.registry.db import Registry
from softsig_service.registry.hands import etag_matches, hand_row, incarnation
from softsig_service.registry.models import HandRow, SignatureRow
from softsig_service.registry.records import record_from_row


@dataclass(frozen=True)
class SignatureRecord:
    """One stored signature version."""

    hand: str
    version: int
    kind: str
    method: str
    source: str
    hand_revision: int
    params: dict[str, Any]
    data: dict[str, Any]
    created_at: datetime
    hand_created_at: datetime
    object_digest: str | None = None
    """The shape digest of the object of a stiffness signature or capture model (``TableObject.shape_digest``)."""

    @property
    def etag(self) -> str:
        """Strong ETag of this version: ``"<hand>.v<version>.<incarnation of the hand>"``."""
        return f'"{self.hand}.v{self.version}.{incarnation(self.hand_created_at)}"'

    @property
    def criterion(self) -> str | None:
        """The criterion of an ellipsoid closure signature: "absolute" (deltas [m]) or "relative" (dimensionless);
        None for other methods and kinds, and when nothing in the row tells.

        Read from the stored ``params["criterion"]``, else from the signature's own ``params``, else from its
        ``extras["magnitude_unit"]`` ("m": absolute, "1": relative), so ellipsoid versions stored without the
        field (computed when the relative change was the only criterion) read back as "relative".
        """
        if self.kind != "closure" or self.method != "ellipsoid":
            return None
        sig_params = self.data.get("params")
        extras = self.data.get("extras")
        candidates = [self.params.get("criterion")]
        if isinstance(sig_params, dict):
            candidates.append(sig_params.get("criterion"))
        if isinstance(extras, dict):
            candidates.append(_CRITERION_OF_UNIT.get(str(extras.get("magnitude_unit"))))
        return next((c for c in candidates if c in ("absolute", "relative")), None)


_CRITERION_OF_UNIT = {"m": "absolute", "1": "relative"}
"""The ellipsoid criterion of a stored closure signature by the unit of its magnitude."""


def _signature(row: SignatureRow, hand: str) -> SignatureRecord:
    return record_from_row(SignatureRecord, row, hand=hand, hand_created_at=row.hand.created_at)


def add_signature(
    reg: Registry,
    hand: str,
    *,
    kind: str,
    method: str,
    source: str,
    data: dict[str, Any],
    params: dict[str, Any] | None = None,
    hand_revision: int | None = None,
    if_match: str | None = None,
    object_digest: str | None = None,
) -> SignatureRecord:
    """Store a new signature version of ``hand`` (the next number; never overwrites), of the object whose shape
    digest is ``object_digest`` (stiffness signatures and capture models).

    ``hand_revision`` is the revision the signature was computed from: if the hand was replaced meanwhile,
    :class:`Conflict`. ``if_match`` (optional) must match the ETag of the hand's latest version, else
    :class:`PreconditionFailed` (a client that read version N and computed N+1 from it learns that another
    version came first).
    """
    with reg.write() as s:
        row = hand_row(s, hand)
        if hand_revision is not None and row.revision != hand_revision:
            raise Conflict(
                "the hand was replaced while its signature was computed; compute it again",
                field="hand",
                value={"computed_from_revision": hand_revision, "current_revision": row.revision},
            )
        if if_match is not None:
            latest = s.scalars(
                select(SignatureRow).where(SignatureRow.hand_id == row.id).order_by(SignatureRow.version.desc())
            ).first()
            current = _signature(latest, hand).etag if latest is not None else None
            if not etag_matches(current, if_match):
                raise PreconditionFailed(
                    "If-Match does not match the ETag of the hand's latest signature",
                    field="If-Match",
                    value=if_match,
                    choices=[current] if current else None,
                )
        version = s.execute(
            update(HandRow)
            .where(HandRow.id == row.id)
            .values(signature_count=HandRow.signature_count + 1)
            .returning(HandRow.signature_count)
        ).scalar_one()
        sig = SignatureRow(
            hand_id=row.id,
            version=version,
            kind=kind,
            method=method,
            source=source,
            hand_revision=row.revision,
            object_digest=object_digest,
            params=params or {},
            data=data,
        )
        s.add(sig)
        s.flush()
        return _signature(sig, hand)


def list_signatures(
    reg: Registry, hand: str, *, kind: str | None = None, limit: int = 100, offset: int = 0
) -> tuple[list[SignatureRecord], int]:
    """Versions of ``hand`` (newest first), optionally of one kind, and the total count."""
    with reg.read() as s:
        row = hand_row(s, hand)
        q = select(SignatureRow).where(SignatureRow.hand_id == row.id)
        n = select(func.count()).select_from(SignatureRow).where(SignatureRow.hand_id == row.id)
        if kind is not None:
            q = q.where(SignatureRow.kind == kind)
            n = n.where(SignatureRow.kind == kind)
        rows = s.scalars(q.order_by(SignatureRow.version.desc()).limit(limit).offset(offset)).all()
        return [_signature(r, hand) for r in rows], int(s.execute(n).scalar_one())


def get_signature(reg: Registry, hand: str, version: int) -> SignatureRecord:
    """Version ``version`` of ``hand``'s signatures; :class:`NotFound` if there is none."""
    with reg.read() as s:
        row = hand_row(s, hand)
        sig = s.scalars(
            select(SignatureRow).where(SignatureRow.hand_id == row.id, SignatureRow.version == version)
        ).one_or_none()
        if sig is None:
            raise NotFound("no such signature version", field="version", value=version)
        return _signature(sig, hand)


def signature_of_object(
    reg: Registry, hand: str, kind: str, object_digest: str
) -> tuple[SignatureRecord | None, list[int]]:
    """The newest ``kind`` signature of ``hand`` computed on its current revision for the object of shape digest
    ``object_digest`` (None if there is none), and the older revisions of the hand that have one (ascending): one
    indexed query each, nothing read that does not match."""
    with reg.read() as s:
        row = hand_row(s, hand)
        match = (SignatureRow.hand_id == row.id) & (SignatureRow.kind == kind)
        match &= SignatureRow.object_digest == object_digest
        sig = s.scalars(
            select(SignatureRow)
            .where(match & (SignatureRow.hand_revision == row.revision))
            .order_by(SignatureRow.version.desc())
            .limit(1)
        ).first()
        if sig is not None:
            return _signature(sig, hand), []
        stale = s.scalars(select(SignatureRow.hand_revision).where(match).distinct()).all()
        return None, sorted(int(r) for r in stale)


_SIGS, _HANDS_T = SignatureRow.__table__, HandRow.__table__
_NEWEST_OF_OBJECT = (
    select(_SIGS.c.version, _HANDS_T.c.created_at)
    .join(_HANDS_T, _SIGS.c.hand_id == _HANDS_T.c.id)
    .where(
        (_HANDS_T.c.name == bindparam("hand"))
        & (_SIGS.c.kind == bindparam("kind"))
        & (_SIGS.c.object_digest == bindparam("digest"))
        & (_SIGS.c.hand_revision == _HANDS_T.c.revision)
    )
    .order_by(_SIGS.c.version.desc())
    .limit(1)
)


def newest_of_object(reg: Registry, hand: str, kind: str, object_digest: str) -> tuple[int, str] | None:
    """The version and ETag (:attr:`SignatureRecord.etag`) of :func:`signature_of_object`'s signature, or None
    (no such hand, or no such signature): one indexed query (:meth:`Registry.fetch_one`), no JSON decoded, for a
    reader that keeps what it makes of the signature's data by its ETag (which names its content)."""
    row = reg.fetch_one(_NEWEST_OF_OBJECT, {"hand": hand, "kind": kind, "digest": object_digest})
    if row is None:
        return None
    version, created_at = row
    return int(version), f'"{hand}.v{version}.{incarnation(created_at)}"'


def fill_object_digests(reg: Registry, digest_of: Callable[[dict[str, Any]], str | None]) -> int:
    """Give every stiffness signature and capture model stored without an object digest the digest
    ``digest_of(params["object"])`` (None: left without); returns how many were filled."""
    with reg.write() as s:
        rows = s.scalars(
            select(SignatureRow).where(
                SignatureRow.kind.in_(("stiffness", "capture")), SignatureRow.object_digest.is_(None)
            )
        ).all()
        n = 0
        for row in rows:
            obj = (row.params or {}).get("object")
            digest = digest_of(obj) if isinstance(obj, dict) else None
            if digest is not None:
                row.object_digest, n = digest, n + 1
        return n


def latest_signature(reg: Registry, hand: str, *, kind: str | None = None) -> SignatureRecord:
    """The newest signature of ``hand`` (of ``kind`` if given); :class:`NotFound` if there is none."""
    with reg.read() as s:
        row = hand_row(s, hand)
        q = select(SignatureRow).where(SignatureRow.hand_id == row.id)
        if kind is not None:
            q = q.where(SignatureRow.kind == kind)
        sig = s.scalars(q.order_by(SignatureRow.version.desc())).first()
        if sig is None:
            raise NotFound("the hand has no signature of this kind yet", field="kind", value=kind)
        return _signature(sig, hand)
