"""Long computations as jobs, each in a process of its own.

**Jobs** (:class:`JobManager`): a job is a named callable, ``"module:function"`` with the signature
``fn(params: dict, ctx: JobContext) -> dict``, run in a process of its own (its own process group, so the worker
processes it starts are stopped with it). The callable reports progress with ``ctx.progress(fraction, message)``
and writes result files (JSON, CSV, Markdown, PNG...) into ``ctx.out_dir``; its returned dict is the job's
result. At most ``max_queued_jobs`` are unfinished (else :class:`ServiceBusy`).

**Several processes, one registry.** A submitted job is only queued in the registry (``jobs`` table); every
process of the service runs a :class:`JobManager` that claims queued jobs while it has a free slot (at most
``job_workers`` at once), with a lease that a heartbeat thread renews (:mod:`softsig_service.services.leases`,
:mod:`softsig_service.registry.jobs`). A
process that dies (``kill -9``, a crash) takes its job processes with it (they follow their parent) and leaves
its jobs to whichever process claims them once their lease (``job_lease`` [s]) has expired; the job runs again
from the start in its folder (an experiment resumes from the trials it already stored). Only the process holding
a job's lease writes its progress and result. A graceful shutdown hands its running jobs back to the queue.

Each run of a job has a wall-time cap (``min(requested, max_job_seconds)`` [s]): past it the process group is
killed and the job is ``timed_out``. ``POST /v1/jobs/{id}/cancel`` kills it too (``cancelled``).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import multiprocessing
import os
import socket
import time
import uuid
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.config import Settings
from softsig_service.errors import InvalidInput, SoftsigError
from softsig_service.registry.db import Registry
from softsig_service.registry.models import utcnow
from softsig_service.services.compute import rebuild_error
from softsig_service.services.job_process import job_main, kill_group
from softsig_service.services.leases import LeaseKeeper
from softsig_service.services.observability import Metrics
from softsig_service.services.problems import softsig_problem
from softsig_service.services.serialize import to_jsonable

log = logging.getLogger("softsig.jobs")
_MP = multiprocessing.get_context("spawn")


SHUTDOWN_WAIT = 15.0
"""[s] the longest a shutdown waits for the dispatcher and for each group of job tasks to end."""


@dataclass(frozen=True)
class JobKind:
    """A kind of job: the callable ``"module:function"`` run in the worker, and an optional hook run in the
    service (in a thread) on its result: ``on_result(registry, params, result) -> result``, e.g. to store it."""

    name: str
    target: str
    description: str = ""
    on_result: Callable[[Registry, dict[str, Any], dict[str, Any]], dict[str, Any]] | None = field(
        default=None, compare=False
    )


class JobManager:
    """Claims jobs from the registry and runs each in a worker process (see the module docstring)."""

    def __init__(
        self,
        registry: Registry,
        settings: Settings,
        kinds: Mapping[str, JobKind],
        jobs_dir: Path,
        metrics: Metrics,
        *,
        owner: str | None = None,
    ) -> None:
        self.registry = registry
        self.settings = settings
        self.kinds = dict(kinds)
        self.jobs_dir = jobs_dir
        self.metrics = metrics
        self.owner = owner or f"{socket.gethostname()[:60]}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        """This process's name on the leases it holds (``host:pid:nonce``)."""
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._cancel: dict[str, asyncio.Event] = {}
        self._procs: dict[str, BaseProcess] = {}
        self._wake = asyncio.Event()
        self._dispatcher: asyncio.Task[None] | None = None
        self._stopping = False
        self.leases = LeaseKeeper(registry, self.owner, settings.job_lease, self.heartbeat)
        """Renews the leases of this process's running jobs on a thread of its own (:mod:`.leases`)."""

    @property
    def heartbeat(self) -> float:
        """[s] between two renewals of a running job's lease (and looks at its cancellation flag)."""
        return min(self.settings.job_lease / 3.0, self.settings.job_poll_interval)

    async def start(self) -> None:
        """Start claiming jobs: queued ones, and those whose process died (their lease expired)."""
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        self.leases.start()
        self._dispatcher = asyncio.create_task(self._dispatch())

    def out_dir(self, job_id: str) -> Path:
        """The result folder of a job."""
        return self.jobs_dir / job_id

    async def submit(
        self,
        kind: str,
        params: dict[str, Any],
        time_limit: float | None = None,
        *,
        private: dict[str, Any] | None = None,
    ) -> repo.JobRecord:
        """Queue a job of ``kind``; a process of the service with a free slot claims and runs it.

        ``params`` are stored with the job (clients see them); ``private`` is stored apart and added to them for
        the worker only (server paths and the like).
        """
        if kind not in self.kinds:
            raise InvalidInput("unknown job kind", field="kind", value=kind, choices=self.kinds)
        cap = self.settings.max_job_seconds
        limit = cap if time_limit is None else min(float(time_limit), cap)
        record = await run_in_threadpool(
            lambda: repo.add_job(
                self.registry,
                kind=kind,
                params=to_jsonable(params),
                time_limit=limit,
                max_unfinished=self.settings.max_queued_jobs,
                private=to_jsonable(private) if private else None,
            )
        )
        self.out_dir(record.id).mkdir(parents=True, exist_ok=True)
        self._wake.set()
        return record

    async def cancel(self, job_id: str) -> repo.JobRecord:
        """Cancel a queued or running job (:class:`Conflict` if it has finished). A running job is stopped by the
        process that holds it: at once if that is this one, else at its next heartbeat."""
        record = await run_in_threadpool(repo.request_cancel, self.registry, job_id)
        event = self._cancel.get(job_id)
        if event is not None:
            event.set()
        elif record.status == "cancelled":
            self.metrics.jobs_finished.labels(record.kind, "cancelled").inc()
        return record

    async def wait(self, job_id: str, timeout: float | None = None) -> None:
        """Wait until a job has finished, whichever process runs it (tests and tools)."""

        async def finished() -> None:
            while True:
                task = self._tasks.get(job_id)
                if task is not None:
                    with contextlib.suppress(asyncio.CancelledError):
                        await asyncio.shield(task)
                rec = await run_in_threadpool(repo.get_job, self.registry, job_id)
                if rec.finished:
                    return
                await asyncio.sleep(0.05)

        await asyncio.wait_for(finished(), timeout)

    async def shutdown(self) -> None:
        """Stop claiming, kill the running jobs' processes and hand their jobs back to the queue (the service's
        next start, or another of its processes, resumes them)."""
        # the flag ends the dispatcher's loop even where a cancellation is lost (Python 3.11's asyncio.wait_for can
        # swallow one), and every wait below is bounded: a shutdown must not hang
        self._stopping = True
        self._wake.set()
        if self._dispatcher is not None:
            self._dispatcher.cancel()
            await asyncio.wait({self._dispatcher}, timeout=SHUTDOWN_WAIT)
        for proc in list(self._procs.values()):
            await run_in_threadpool(kill_group, proc)
        tasks = list(self._tasks.values())
        for task in tasks:
            task.cancel()
        if tasks:
            await asyncio.wait(tasks, timeout=SHUTDOWN_WAIT)
        n = await run_in_threadpool(repo.release_jobs, self.registry, self.owner)
        await run_in_threadpool(self.leases.stop)
        if n:
            log.warning("handed %d running jobs back to the queue at shutdown", n)

    def _claim(self) -> repo.Claim | None:
        """Claim a job and hold its lease at once, on the claiming thread (the event loop may be slow to resume)."""
        claim = repo.claim_job(
            self.registry, self.owner, self.settings.job_lease,
            kinds=tuple(self.kinds), max_attempts=self.settings.job_max_attempts,
        )  # fmt: skip
        if claim is not None:
            self.leases.hold(claim.record.id)
        return claim

    async def _dispatch(self) -> None:
        """Claim jobs while a slot is free; look again when woken (a submission, a finished job) or every
        ``job_poll_interval`` (jobs queued by other processes, expired leases)."""
        while not self._stopping:
            self._wake.clear()
            claim = None
            if len(self._tasks) < self.settings.job_workers:
                try:
                    claim = await run_in_threadpool(self._claim)
                except Exception:  # the database is busy or away: try again later
                    log.exception("claiming a job failed")
            if claim is not None and not self._stopping:  # (a claim made while stopping is handed back)
                job_id = claim.record.id
                self._cancel[job_id] = asyncio.Event()
                self._tasks[job_id] = asyncio.create_task(self._run(claim))
                continue
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._wake.wait(), self.settings.job_poll_interval)

    async def _finish(self, job_id: str, kind: str, status: str, **fields: Any) -> None:
        rec = await run_in_threadpool(
            lambda: repo.update_job(
                self.registry, job_id, owner=self.owner, status=status, finished_at=utcnow(), **fields
            )
        )
        if rec is not None:
            self.metrics.jobs_finished.labels(kind, status).inc()
        else:
            log.warning("job %s: not finished as %s, this process no longer holds it", job_id, status)

    async def _run(self, claim: repo.Claim) -> None:
        rec = claim.record
        job_id = rec.id
        try:
            kind = self.kinds[rec.kind]
            if rec.attempts > 1:
                log.warning("job %s: resumed (attempt %d)", job_id, rec.attempts)
            params = {**rec.params, **claim.private}
            await self._execute(job_id, kind, params, rec.time_limit, self._cancel[job_id])
        except Exception as exc:  # a bug in the manager: record it on the job rather than lose it
            log.exception("job %s failed in the manager", job_id)
            with contextlib.suppress(Exception):
                await self._finish(job_id, rec.kind, "failed", error={"type": "internal-error", "detail": str(exc)})
        finally:
            self.leases.release(job_id)
            self._tasks.pop(job_id, None)
            self._cancel.pop(job_id, None)
            self._wake.set()

    async def _execute(
        self, job_id: str, kind: JobKind, params: dict[str, Any], limit: float, cancel: asyncio.Event
    ) -> None:
        out_dir = self.out_dir(job_id)
        out_dir.mkdir(parents=True, exist_ok=True)
        recv, send = _MP.Pipe(duplex=False)
        proc = _MP.Process(target=job_main, args=(job_id, kind.target, params, str(out_dir), send), daemon=False)
        await run_in_threadpool(proc.start)
        send.close()
        self._procs[job_id] = proc
        self.metrics.jobs_running.inc()
        deadline = time.monotonic() + limit
        outcome: tuple[Any, ...] | None = None
        last_write = 0.0
        pending: tuple[float, str] | None = None
        try:
            while outcome is None:
                if self._stopping:  # the shutdown hands the job back to the queue: record nothing
                    await run_in_threadpool(kill_group, proc)
                    return
                while outcome is None and recv.poll():
                    try:
                        msg = recv.recv()
                    except (EOFError, OSError):
                        outcome = ("crash", "the job's process exited without a result", "")
                        break
                    if msg[0] == "progress":
                        pending = (float(msg[1]), str(msg[2]))
                    else:
                        outcome = msg
                if outcome is not None:
                    break
                now = time.monotonic()
                if pending is not None and now - last_write >= 0.5:
                    frac, text = pending
                    pending, last_write = None, now
                    await run_in_threadpool(
                        functools.partial(
                            repo.update_job, self.registry, job_id, owner=self.owner, progress=frac, message=text
                        )
                    )
                lease = self.leases.state(job_id)
                if not lease.held:  # another process holds it now, or it was finished: stop, write nothing
                    log.warning("job %s: lease lost; stopping this process's run of it", job_id)
                    await run_in_threadpool(kill_group, proc)
                    return
                if lease.cancel_requested:
                    cancel.set()
                if cancel.is_set():
                    await run_in_threadpool(kill_group, proc)
                    await self._finish(job_id, kind.name, "cancelled", message="cancelled")
                    return
                if now > deadline:
                    await run_in_threadpool(kill_group, proc)
                    await self._finish(
                        job_id, kind.name, "timed_out", message=f"stopped at the wall-time cap of {limit:g} s",
                        error={"type": "urn:softsig:problem:time-limit-exceeded", "title": "Time limit exceeded",
                               "detail": f"the job ran longer than {limit:g} s", "field": "time_limit"},
                    )  # fmt: skip
                    return
                if not proc.is_alive() and not recv.poll():
                    outcome = ("crash", f"the job's process exited (code {proc.exitcode}) without a result", "")
                    break
                await asyncio.sleep(0.05)
            await run_in_threadpool(proc.join, 10.0)
            if proc.is_alive():
                await run_in_threadpool(kill_group, proc)
            await self._conclude(job_id, kind, params, outcome)
        finally:
            self._procs.pop(job_id, None)
            self.metrics.jobs_running.dec()
            recv.close()

    async def _conclude(self, job_id: str, kind: JobKind, params: dict[str, Any], outcome: tuple[Any, ...]) -> None:
        if self._stopping and outcome[0] != "result":  # killed by the shutdown: handed back, not failed
            return
        if outcome[0] == "result":
            result = dict(outcome[1])
            if kind.on_result is not None:
                held = await run_in_threadpool(
                    repo.renew_lease, self.registry, job_id, self.owner, self.settings.job_lease
                )
                if held is None:  # only the holder of the lease may store what the job produced
                    log.warning("job %s: lease lost before its result was stored; dropping this run's result", job_id)
                    return
                try:
                    hook = kind.on_result
                    result = await run_in_threadpool(lambda: hook(self.registry, params, result))
                except SoftsigError as exc:
                    await self._finish(job_id, kind.name, "failed", message=exc.message, error=_problem(exc))
                    return
            await self._finish(job_id, kind.name, "succeeded", progress=1.0, message="done", result=result)
        elif outcome[0] == "error":
            err = rebuild_error(outcome[1])
            await self._finish(job_id, kind.name, "failed", message=err.message, error=_problem(err))
        else:
            log.error("job %s crashed: %s\n%s", job_id, outcome[1], outcome[2] if len(outcome) > 2 else "")
            await self._finish(
                job_id, kind.name, "failed", message=str(outcome[1]),
                error={"type": "urn:softsig:problem:job-crashed", "title": "Job crashed", "detail": str(outcome[1])},
            )  # fmt: skip


def _problem(exc: SoftsigError) -> dict[str, Any]:
    _, body = softsig_problem(exc)
    body.pop("request_id", None)
    return body
