"""Repository functions of the registry: hands, signature versions, plans and jobs.

Every function opens its own short session on a :class:`~softsig_service.registry.db.Registry` and returns plain,
immutable records (never ORM objects), so callers in any thread can use the result after the session is closed.
Errors are :class:`~softsig_service.errors.SoftsigError` subclasses naming the field: :class:`HandNotFound`,
:class:`NotFound`, :class:`Conflict`, :class:`PreconditionFailed`.

Versions and ETags:

* a hand's ETag is ``"<name>.r<revision>"``; replacing a hand's files increments ``revision``;
* a signature's ETag is ``"<hand>.v<version>"``. Versions are allocated per hand (closure and stiffness share
  one sequence) by ``UPDATE hands SET signature_count = signature_count + 1 ... RETURNING`` in the transaction
  that inserts the row: concurrent writers queue on the hand's row (PostgreSQL) or on SQLite's write lock, and a
  rolled-back insert rolls the counter back too, so versions are 1..N without gaps. Rows are never updated.

``If-Match`` values are compared strongly; ``*`` matches any current representation.
"""

from __future__ import annotations

import uuid
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import func, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from softsig_service.errors import Conflict, HandNotFound, NotFound, PreconditionFailed
from softsig_service.registry.db import Registry
from softsig_service.registry.models import HandRow, JobRow, PlanRow, SignatureRow, utcnow

JOB_STATUSES: tuple[str, ...] = ("queued", "running", "succeeded", "failed", "cancelled", "timed_out")
UNFINISHED: tuple[str, ...] = ("queued", "running")


def etag_matches(current: str | None, if_match: str) -> bool:
    """Whether an ``If-Match`` header value matches ``current`` (strong comparison; ``*`` = any existing)."""
    if current is None:
        return False
    tags = [t.strip() for t in if_match.split(",") if t.strip()]
    return any(t == "*" or t == current for t in tags)


# ----------------------------------------------------------------------------------------------------------
# hands
# ----------------------------------------------------------------------------------------------------------


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
    def etag(self) -> str:
        """Strong ETag of this revision of the hand."""
        return f'"{self.name}.r{self.revision}"'


def _hand(row: HandRow) -> HandRecord:
    return HandRecord(
        name=row.name,
        builtin=row.builtin,
        revision=row.revision,
        manifest_path=row.manifest_path,
        folder=row.folder,
        files=list(row.files or []),
        info=dict(row.info or {}),
        signature_count=row.signature_count,
        created_at=row.created_at,
        updated_at=row.updated_at,
    )


def _hand_row(session: Session, name: str, field: str = "hand") -> HandRow:
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
        return _hand(_hand_row(s, name, field))


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
    is left alone (``"shadowed"``).
    """
    with reg.write() as s:
        row = s.scalars(select(HandRow).where(HandRow.name == name)).one_or_none()
        if row is None:
            s.add(HandRow(name=name, builtin=True, revision=1, manifest_path=manifest_path, info=info, files=[]))
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
        row = _hand_row(s, name)
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
        row = _hand_row(s, name)
        _check_mutable(row, if_match)
        record = _hand(row)
        s.delete(row)
        return record


# ----------------------------------------------------------------------------------------------------------
# signatures
# ----------------------------------------------------------------------------------------------------------


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

    @property
    def etag(self) -> str:
        """Strong ETag of this version."""
        return f'"{self.hand}.v{self.version}"'

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
    return SignatureRecord(
        hand=hand,
        version=row.version,
        kind=row.kind,
        method=row.method,
        source=row.source,
        hand_revision=row.hand_revision,
        params=dict(row.params or {}),
        data=dict(row.data),
        created_at=row.created_at,
    )


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
) -> SignatureRecord:
    """Store a new signature version of ``hand`` (the next number; never overwrites).

    ``hand_revision`` is the revision the signature was computed from: if the hand was replaced meanwhile,
    :class:`Conflict`. ``if_match`` (optional) must match the ETag of the hand's latest version, else
    :class:`PreconditionFailed` (a client that read version N and computed N+1 from it learns that another
    version came first).
    """
    with reg.write() as s:
        row = _hand_row(s, hand)
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
        row = _hand_row(s, hand)
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
        row = _hand_row(s, hand)
        sig = s.scalars(
            select(SignatureRow).where(SignatureRow.hand_id == row.id, SignatureRow.version == version)
        ).one_or_none()
        if sig is None:
            raise NotFound("no such signature version", field="version", value=version)
        return _signature(sig, hand)


def latest_signature(reg: Registry, hand: str, *, kind: str | None = None) -> SignatureRecord:
    """The newest signature of ``hand`` (of ``kind`` if given); :class:`NotFound` if there is none."""
    with reg.read() as s:
        row = _hand_row(s, hand)
        q = select(SignatureRow).where(SignatureRow.hand_id == row.id)
        if kind is not None:
            q = q.where(SignatureRow.kind == kind)
        sig = s.scalars(q.order_by(SignatureRow.version.desc())).first()
        if sig is None:
            raise NotFound("the hand has no signature of this kind yet", field="kind", value=kind)
        return _signature(sig, hand)


# ----------------------------------------------------------------------------------------------------------
# plans
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PlanRecord:
    """A stored plan: the request as received and the planner's result JSON."""

    id: str
    hand: str
    strategy: str
    success: bool
    request: dict[str, Any]
    result: dict[str, Any]
    created_at: datetime


def _plan(row: PlanRow) -> PlanRecord:
    return PlanRecord(
        id=row.id,
        hand=row.hand,
        strategy=row.strategy,
        success=row.success,
        request=dict(row.request),
        result=dict(row.result),
        created_at=row.created_at,
    )


def add_plan(reg: Registry, *, hand: str, strategy: str, success: bool, request: dict[str, Any],
             result: dict[str, Any]) -> PlanRecord:  # fmt: skip
    """Store a plan under a new random id."""
    with reg.write() as s:
        row = PlanRow(
            id=uuid.uuid4().hex, hand=hand, strategy=strategy, success=success, request=request, result=result
        )
        s.add(row)
        s.flush()
        return _plan(row)


def get_plan(reg: Registry, plan_id: str) -> PlanRecord:
    """The plan ``plan_id``; :class:`NotFound` if there is none."""
    with reg.read() as s:
        row = s.get(PlanRow, plan_id)
        if row is None:
            raise NotFound("no such plan", field="plan_id", value=plan_id)
        return _plan(row)


def list_plans(
    reg: Registry, *, hand: str | None = None, limit: int = 50, offset: int = 0
) -> tuple[list[PlanRecord], int]:
    """Stored plans, newest first, optionally of one hand, and the total count."""
    with reg.read() as s:
        q = select(PlanRow)
        n = select(func.count()).select_from(PlanRow)
        if hand is not None:
            q, n = q.where(PlanRow.hand == hand), n.where(PlanRow.hand == hand)
        rows = s.scalars(q.order_by(PlanRow.created_at.desc(), PlanRow.id).limit(limit).offset(offset)).all()
        return [_plan(r) for r in rows], int(s.execute(n).scalar_one())


# ----------------------------------------------------------------------------------------------------------
# jobs
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class JobRecord:
    """A job's state: status (:data:`JOB_STATUSES`), progress in [0, 1], result or error, times."""

    id: str
    kind: str
    status: str
    progress: float
    message: str
    params: dict[str, Any]
    result: dict[str, Any] | None
    error: dict[str, Any] | None
    time_limit: float
    cancel_requested: bool
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None

    @property
    def finished(self) -> bool:
        """Whether the job has reached a final status."""
        return self.status not in UNFINISHED


def _job(row: JobRow) -> JobRecord:
    return JobRecord(
        id=row.id,
        kind=row.kind,
        status=row.status,
        progress=row.progress,
        message=row.message,
        params=dict(row.params),
        result=dict(row.result) if row.result is not None else None,
        error=dict(row.error) if row.error is not None else None,
        time_limit=row.time_limit,
        cancel_requested=row.cancel_requested,
        created_at=row.created_at,
        started_at=row.started_at,
        finished_at=row.finished_at,
    )


def add_job(reg: Registry, *, kind: str, params: dict[str, Any], time_limit: float, max_unfinished: int) -> JobRecord:
    """Queue a new job; :class:`Conflict`-free but :class:`~softsig_service.errors.ServiceBusy` when
    ``max_unfinished`` jobs are queued or running already."""
    from softsig_service.errors import ServiceBusy

    with reg.write() as s:
        busy = s.execute(select(func.count()).select_from(JobRow).where(JobRow.status.in_(UNFINISHED))).scalar_one()
        if busy >= max_unfinished:
            raise ServiceBusy(f"{busy} jobs are queued or running; try again later", field="jobs", value=busy)
        row = JobRow(
            id=uuid.uuid4().hex, kind=kind, status="queued", progress=0.0, message="", params=params,
            time_limit=time_limit,
        )  # fmt: skip
        s.add(row)
        s.flush()
        return _job(row)


def get_job(reg: Registry, job_id: str) -> JobRecord:
    """The job ``job_id``; :class:`NotFound` if there is none."""
    with reg.read() as s:
        row = s.get(JobRow, job_id)
        if row is None:
            raise NotFound("no such job", field="job_id", value=job_id)
        return _job(row)


def list_jobs(
    reg: Registry, *, kind: str | None = None, status: str | None = None, limit: int = 50, offset: int = 0
) -> tuple[list[JobRecord], int]:
    """Jobs, newest first, optionally filtered, and the total count."""
    with reg.read() as s:
        q = select(JobRow)
        n = select(func.count()).select_from(JobRow)
        if kind is not None:
            q, n = q.where(JobRow.kind == kind), n.where(JobRow.kind == kind)
        if status is not None:
            q, n = q.where(JobRow.status == status), n.where(JobRow.status == status)
        rows = s.scalars(q.order_by(JobRow.created_at.desc(), JobRow.id).limit(limit).offset(offset)).all()
        return [_job(r) for r in rows], int(s.execute(n).scalar_one())


_JOB_FIELDS = frozenset({"status", "progress", "message", "result", "error", "started_at", "finished_at"})


def update_job(reg: Registry, job_id: str, *, only_unfinished: bool = True, **fields: Any) -> JobRecord | None:
    """Set fields of a job (status, progress, message, result, error, started_at, finished_at).

    With ``only_unfinished`` a job that already reached a final status is left alone and None is returned (a late
    progress message cannot resurrect a cancelled job).
    """
    bad = set(fields) - _JOB_FIELDS
    if bad:
        raise ValueError(f"not job fields: {sorted(bad)}")
    with reg.write() as s:
        row = s.get(JobRow, job_id)
        if row is None:
            raise NotFound("no such job", field="job_id", value=job_id)
        if only_unfinished and row.status not in UNFINISHED:
            return None
        for k, v in fields.items():
            setattr(row, k, v)
        s.flush()
        return _job(row)


def request_cancel(reg: Registry, job_id: str) -> JobRecord:
    """Flag a queued or running job for cancellation; :class:`Conflict` if it has finished."""
    with reg.write() as s:
        row = s.get(JobRow, job_id)
        if row is None:
            raise NotFound("no such job", field="job_id", value=job_id)
        if row.status not in UNFINISHED:
            raise Conflict("the job has finished; there is nothing to cancel", field="job_id", value=row.status)
        row.cancel_requested = True
        s.flush()
        return _job(row)


def interrupt_unfinished_jobs(reg: Registry, reason: str) -> int:
    """Mark every queued or running job failed (the service restarted under them); returns how many."""
    with reg.write() as s:
        rows = s.scalars(select(JobRow).where(JobRow.status.in_(UNFINISHED))).all()
        for row in rows:
            row.status = "failed"
            row.error = {"type": "interrupted", "title": "Interrupted", "detail": reason}
            row.finished_at = utcnow()
        return len(rows)
