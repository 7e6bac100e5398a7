"""Jobs in the registry: long work run in worker processes, its status, progress, result or error."""

from __future__ import annotations

import uuid
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete, func, select

from softsig_service.errors import Conflict, NotFound
from softsig_service.registry.db import Registry
from softsig_service.registry.models import JobRow, utcnow

JOB_STATUSES: tuple[str, ...] = ("queued", "running", "succeeded", "failed", "cancelled", "timed_out")
UNFINISHED: tuple[str, ...] = ("queued", "running")


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


def purge_jobs(reg: Registry, older_than: timedelta) -> list[str]:
    """Remove the finished jobs that finished more than ``older_than`` ago; their ids."""
    with reg.write() as s:
        cutoff = utcnow() - older_than
        done = JobRow.status.not_in(UNFINISHED) & (JobRow.finished_at < cutoff)
        ids = list(s.scalars(select(JobRow.id).where(done)).all())
        if ids:
            s.execute(delete(JobRow).where(JobRow.id.in_(ids)))
        return ids
