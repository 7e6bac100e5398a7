"""Jobs in the registry: long work run in worker processes, its status, progress, result or error.

**Leases.** Any process of the service may run any job. A process *claims* a job (:func:`claim_job`): the oldest
queued one, or a running one whose lease has expired because the process that held it died. The claim sets the
job's ``owner`` and a lease of ``lease`` [s], which the owner's heartbeat renews (:func:`renew_lease`). Only the
owner may report progress or finish the job (:func:`update_job` with ``owner``): a process that lost its lease
(paused past it, or cut off from the database) cannot overwrite what the new owner does. A job claimed
``max_attempts`` times whose owner died every time is failed (``interrupted``) instead of being claimed again.
The claim is one write transaction: SQLite serialises writers (``BEGIN IMMEDIATE``); PostgreSQL locks the row it
claims (``FOR UPDATE SKIP LOCKED``), so two processes never claim the same job.
"""

from __future__ import annotations

import uuid
from collections.abc import Collection
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import delete, func, select

from softsig_service.errors import Conflict, ServiceBusy
from softsig_service.registry.db import Registry
from softsig_service.registry.models import JobRow, utcnow
from softsig_service.registry.records import get_record, inserted, record_from_row, record_page, row_or_not_found

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
    owner: str | None = None
    lease_expires_at: datetime | None = None
    attempts: int = 0

    @property
    def finished(self) -> bool:
        """Whether the job has reached a final status."""
        return self.status not in UNFINISHED


def _job(row: JobRow) -> JobRecord:
    return record_from_row(JobRecord, row)


def add_job(
    reg: Registry,
    *,
    kind: str,
    params: dict[str, Any],
    time_limit: float,
    max_unfinished: int,
    private: dict[str, Any] | None = None,
) -> JobRecord:
    """Queue a new job; :class:`~softsig_service.errors.ServiceBusy` when ``max_unfinished`` jobs are queued or
    running already. ``private`` are parameters for the worker only (never shown to clients)."""
    with reg.write() as s:
        busy = s.execute(select(func.count()).select_from(JobRow).where(JobRow.status.in_(UNFINISHED))).scalar_one()
        if busy >= max_unfinished:
            raise ServiceBusy(f"{busy} jobs are queued or running; try again later", field="jobs", value=busy)
        row = JobRow(
            id=uuid.uuid4().hex, kind=kind, status="queued", progress=0.0, message="", params=params,
            time_limit=time_limit, private=private, attempts=0,
        )  # fmt: skip
        return _job(inserted(s, row))


def get_job(reg: Registry, job_id: str) -> JobRecord:
    """The job ``job_id``; :class:`NotFound` if there is none."""
    return get_record(reg, JobRow, job_id, _job, field="job_id", what="job")


def list_jobs(
    reg: Registry, *, kind: str | None = None, status: str | None = None, limit: int = 50, offset: int = 0
) -> tuple[list[JobRecord], int]:
    """Jobs, newest first, optionally filtered, and the total count."""
    return record_page(reg, JobRow, _job, limit=limit, offset=offset, kind=kind, status=status)


_JOB_FIELDS = frozenset({"status", "progress", "message", "result", "error", "started_at", "finished_at"})


def update_job(
    reg: Registry, job_id: str, *, only_unfinished: bool = True, owner: str | None = None, **fields: Any
) -> JobRecord | None:
    """Set fields of a job (status, progress, message, result, error, started_at, finished_at).

    With ``only_unfinished`` a job that already reached a final status is left alone and None is returned (a late
    progress message cannot resurrect a cancelled job). With ``owner`` the job must be held by that process
    (module docstring), else it is left alone and None is returned; a final status ends the lease.
    """
    bad = set(fields) - _JOB_FIELDS
    if bad:
        raise ValueError(f"not job fields: {sorted(bad)}")
    with reg.write() as s:
        row = row_or_not_found(s, JobRow, job_id, field="job_id", what="job")
        if only_unfinished and row.status not in UNFINISHED:
            return None
        if owner is not None and row.owner != owner:
            return None
        for k, v in fields.items():
            setattr(row, k, v)
        if row.status not in UNFINISHED:
            row.lease_expires_at = None
        s.flush()
        return _job(row)


@dataclass(frozen=True)
class Claim:
    """A job claimed by a process: its record and its worker-only parameters."""

    record: JobRecord
    private: dict[str, Any]


def claim_job(reg: Registry, owner: str, lease: float, *, kinds: Collection[str], max_attempts: int) -> Claim | None:
    """Claim the oldest job of one of ``kinds`` that is queued or whose lease has expired (module docstring), for
    ``owner`` with a lease of ``lease`` [s]; None when there is none. On the way, a claimable job whose
    cancellation was requested becomes ``cancelled``, and one already claimed ``max_attempts`` times ``failed``.

    An idle service asks this every ``job_poll_interval`` in every process: a read finds whether there is anything
    to claim before a write transaction (SQLite's write lock) is taken."""

    def claimable(now: datetime) -> Any:
        expired = JobRow.lease_expires_at.is_(None) | (JobRow.lease_expires_at < now)
        return ((JobRow.status == "queued") | ((JobRow.status == "running") & expired)) & JobRow.kind.in_(list(kinds))

    with reg.read() as s:
        if s.execute(select(JobRow.id).where(claimable(utcnow())).limit(1)).first() is None:
            return None
    with reg.write() as s:
        while True:
            now = utcnow()
            query = select(JobRow).where(claimable(now))
            row = s.scalars(
                query.order_by(JobRow.created_at, JobRow.id).limit(1).with_for_update(skip_locked=True)
            ).first()
            if row is None:
                return None
            if row.cancel_requested:
                row.status, row.message, row.finished_at = "cancelled", "cancelled", now
                row.owner = row.lease_expires_at = None
                continue
            if row.attempts >= max_attempts:
                row.status, row.finished_at, row.lease_expires_at = "failed", now, None
                row.message = f"the process running it stopped {row.attempts} times"
                row.error = {
                    "type": "interrupted",
                    "title": "Interrupted",
                    "detail": f"the service process running the job stopped {row.attempts} times",
                }
                continue
            resumed = row.status == "running"
            row.status, row.owner = "running", owner
            row.lease_expires_at = now + timedelta(seconds=lease)
            row.attempts += 1
            row.started_at = row.started_at or now
            row.message = f"resumed (attempt {row.attempts})" if resumed or row.attempts > 1 else "started"
            s.flush()
            return Claim(record=_job(row), private=dict(row.private or {}))


def renew_lease(reg: Registry, job_id: str, owner: str, lease: float) -> JobRecord | None:
    """Extend ``owner``'s lease on a running job by ``lease`` [s] from now; None if the job is no longer ``owner``'s
    or has finished (the caller must stop it). The record tells whether a cancellation was requested."""
    with reg.write() as s:
        row = s.get(JobRow, job_id)
        if row is None or row.owner != owner or row.status != "running":
            return None
        row.lease_expires_at = utcnow() + timedelta(seconds=lease)
        s.flush()
        return _job(row)


def release_jobs(reg: Registry, owner: str, *, job_ids: Collection[str] | None = None) -> int:
    """Hand ``owner``'s running jobs (all, or ``job_ids``) back to the queue, e.g. at a graceful shutdown: another
    process, or this service's next start, claims them again. Returns how many."""
    with reg.write() as s:
        q = select(JobRow).where(JobRow.owner == owner, JobRow.status == "running")
        if job_ids is not None:
            q = q.where(JobRow.id.in_(list(job_ids)))
        rows = s.scalars(q).all()
        for row in rows:
            row.status, row.owner, row.lease_expires_at = "queued", None, None
            row.message = "waiting to resume: the service process running it stopped"
        return len(rows)


def request_cancel(reg: Registry, job_id: str) -> JobRecord:
    """Flag a queued or running job for cancellation; :class:`Conflict` if it has finished. A queued job nobody
    holds is cancelled at once; a running one by the process that holds it (it sees the flag on its heartbeat)."""
    with reg.write() as s:
        row = row_or_not_found(s, JobRow, job_id, field="job_id", what="job")
        if row.status not in UNFINISHED:
            raise Conflict("the job has finished; there is nothing to cancel", field="job_id", value=row.status)
        row.cancel_requested = True
        if row.status == "queued" and row.owner is None:
            row.status, row.message, row.finished_at = "cancelled", "cancelled before it started", utcnow()
        s.flush()
        return _job(row)


def purge_jobs(reg: Registry, older_than: timedelta) -> list[str]:
    """Remove the finished jobs that finished more than ``older_than`` ago; their ids."""
    with reg.write() as s:
        cutoff = utcnow() - older_than
        done = JobRow.status.not_in(UNFINISHED) & (JobRow.finished_at < cutoff)
        ids = list(s.scalars(select(JobRow.id).where(done)).all())
        if ids:
            s.execute(delete(JobRow).where(JobRow.id.in_(ids)))
        return ids
