"""Long computations as jobs, each in a process of its own.

**Jobs** (:class:`JobManager`): a job is a named callable, ``"module:function"`` with the signature
``fn(params: dict, ctx: JobContext) -> dict``, run in a process of its own (its own process group, so the worker
processes it starts are stopped with it). The callable reports progress with ``ctx.progress(fraction, message)``
and writes result files (JSON, CSV, Markdown, PNG...) into ``ctx.out_dir``; its returned dict is the job's
result. At most ``job_workers`` jobs run at once, the others wait as ``queued``; at most ``max_queued_jobs`` are
unfinished (else :class:`ServiceBusy`). Each job has a wall-time cap (``min(requested, max_job_seconds)`` [s]):
past it the process group is killed and the job is ``timed_out``. ``DELETE /v1/jobs/{id}`` kills it too
(``cancelled``). State, progress and results live in the registry (``jobs`` table); jobs that were unfinished
when the service stopped are marked ``failed`` (``interrupted``) at the next start.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import importlib
import logging
import math
import multiprocessing
import os
import signal
import time
import traceback
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from starlette.concurrency import run_in_threadpool

from softsig_service import registry as repo
from softsig_service.config import Settings
from softsig_service.errors import InvalidInput, SoftsigError
from softsig_service.registry.db import Registry
from softsig_service.registry.models import utcnow
from softsig_service.services.compute import _worker_init, error_payload, rebuild_error
from softsig_service.services.lifeline import follow_parent
from softsig_service.services.observability import Metrics
from softsig_service.services.problems import softsig_problem
from softsig_service.services.serialize import to_jsonable

log = logging.getLogger("softsig.jobs")
_MP = multiprocessing.get_context("spawn")


MEDIA_TYPES = {
    ".json": "application/json",
    ".csv": "text/csv",
    ".md": "text/markdown",
    ".png": "image/png",
    ".txt": "text/plain",
    ".svg": "image/svg+xml",
    ".pdf": "application/pdf",
    ".mp4": "video/mp4",
    ".jsonl": "application/x-ndjson",
}


def media_type(name: str) -> str:
    """Media type of a result file by its suffix (``application/octet-stream`` when unknown)."""
    return MEDIA_TYPES.get(Path(name).suffix.lower(), "application/octet-stream")


# ----------------------------------------------------------------------------------------------------------


# ----------------------------------------------------------------------------------------------------------
# jobs: worker side
# ----------------------------------------------------------------------------------------------------------


class JobContext:
    """What a job callable gets besides its parameters: its result folder and a progress reporter."""

    def __init__(self, job_id: str, out_dir: Path, conn: Connection | None) -> None:
        self.job_id = job_id
        self.out_dir = out_dir
        self._conn = conn
        self._last = -math.inf
        self._last_fraction = -1.0

    def progress(self, fraction: float, message: str = "") -> None:
        """Report progress in [0, 1] (sent at most every 0.2 s, and always when it reaches 1)."""
        f = min(max(float(fraction), 0.0), 1.0) if math.isfinite(fraction) else 0.0
        now = time.monotonic()
        if self._conn is None or (now - self._last < 0.2 and f < 1.0):
            return
        self._last, self._last_fraction = now, f
        with contextlib.suppress(OSError, ValueError):
            self._conn.send(("progress", f, str(message)[:500]))


def _job_main(job_id: str, target: str, params: dict[str, Any], out_dir: str, conn: Connection) -> None:
    """Entry point of a job's process."""
    with contextlib.suppress(OSError, AttributeError):
        os.setpgrp()  # its own process group: killing the group stops the workers it starts
    follow_parent(whole_group=True)  # the job and its workers die with the service
    _worker_init()
    try:
        module, _, name = target.partition(":")
        fn = getattr(importlib.import_module(module), name)
        result = fn(params, JobContext(job_id, Path(out_dir), conn))
        conn.send(("result", to_jsonable(result if result is not None else {})))
    except SoftsigError as exc:
        conn.send(("error", error_payload(exc)))
    except BaseException as exc:
        conn.send(("crash", f"{type(exc).__name__}: {exc}", traceback.format_exc()[-4000:]))
    finally:
        conn.close()


# ----------------------------------------------------------------------------------------------------------
# jobs: service side
# ----------------------------------------------------------------------------------------------------------


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


def _kill_group(proc: BaseProcess) -> None:
    pid = proc.pid
    if pid is None:
        return
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(pid, sig)
        except (ProcessLookupError, PermissionError):
            with contextlib.suppress(Exception):
                proc.terminate() if sig == signal.SIGTERM else proc.kill()
        except OSError:
            pass
        proc.join(2.0)
        if not proc.is_alive():
            # the group may outlive its leader: make sure the rest is gone too
            with contextlib.suppress(OSError):
                os.killpg(pid, signal.SIGKILL)
            return


class JobManager:
    """Runs jobs in worker processes; state in the registry (see the module docstring)."""

    def __init__(
        self, registry: Registry, settings: Settings, kinds: Mapping[str, JobKind], jobs_dir: Path, metrics: Metrics
    ) -> None:
        self.registry = registry
        self.settings = settings
        self.kinds = dict(kinds)
        self.jobs_dir = jobs_dir
        self.metrics = metrics
        self._slots = asyncio.Semaphore(settings.job_workers)
        self._tasks: dict[str, asyncio.Task[None]] = {}
        self._cancel: dict[str, asyncio.Event] = {}
        self._procs: dict[str, BaseProcess] = {}

    async def start(self) -> None:
        """Mark jobs left unfinished by a previous run as failed."""
        self.jobs_dir.mkdir(parents=True, exist_ok=True)
        n = await run_in_threadpool(
            repo.interrupt_unfinished_jobs, self.registry, "the service stopped while the job was queued or running"
        )
        if n:
            log.warning("marked %d unfinished jobs of a previous run as failed", n)

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
        """Queue a job of ``kind``; it starts when a slot is free.

        ``params`` are stored with the job (clients see them); ``private`` is added to them for the worker only
        (server paths and the like).
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
            )
        )
        self.out_dir(record.id).mkdir(parents=True, exist_ok=True)
        self._cancel[record.id] = asyncio.Event()
        worker_params = {**params, **(private or {})}
        self._tasks[record.id] = asyncio.create_task(self._run(record.id, self.kinds[kind], worker_params, limit))
        return record

    async def cancel(self, job_id: str) -> repo.JobRecord:
        """Cancel a queued or running job (:class:`Conflict` if it has finished)."""
        record = await run_in_threadpool(repo.request_cancel, self.registry, job_id)
        event = self._cancel.get(job_id)
        if event is not None:
            event.set()
        else:  # not ours (left over): nothing runs it
            await self._finish(job_id, record.kind, "cancelled", message="cancelled")
        return record

    async def wait(self, job_id: str, timeout: float | None = None) -> None:
        """Wait for a job started by this manager to finish (tests and shutdown)."""
        task = self._tasks.get(job_id)
        if task is not None:
            await asyncio.wait_for(asyncio.shield(task), timeout)

    async def shutdown(self) -> None:
        """Kill running jobs and mark every unfinished job failed."""
        for proc in list(self._procs.values()):
            await run_in_threadpool(_kill_group, proc)
        for task in list(self._tasks.values()):
            task.cancel()
        for task in list(self._tasks.values()):
            with contextlib.suppress(BaseException):
                await task
        await run_in_threadpool(repo.interrupt_unfinished_jobs, self.registry, "the service shut down")

    async def _finish(self, job_id: str, kind: str, status: str, **fields: Any) -> None:
        rec = await run_in_threadpool(
            lambda: repo.update_job(self.registry, job_id, status=status, finished_at=utcnow(), **fields)
        )
        if rec is not None:
            self.metrics.jobs_finished.labels(kind, status).inc()

    async def _run(self, job_id: str, kind: JobKind, params: dict[str, Any], limit: float) -> None:
        cancel = self._cancel[job_id]
        try:
            if not await self._acquire_slot(cancel):
                await self._finish(job_id, kind.name, "cancelled", message="cancelled before it started")
                return
            try:
                if cancel.is_set():
                    await self._finish(job_id, kind.name, "cancelled", message="cancelled before it started")
                    return
                await self._execute(job_id, kind, params, limit, cancel)
            finally:
                self._slots.release()
        except Exception as exc:  # a bug in the manager: record it on the job rather than lose it
            log.exception("job %s failed in the manager", job_id)
            with contextlib.suppress(Exception):
                await self._finish(job_id, kind.name, "failed", error={"type": "internal-error", "detail": str(exc)})
        finally:
            self._tasks.pop(job_id, None)
            self._cancel.pop(job_id, None)

    async def _acquire_slot(self, cancel: asyncio.Event) -> bool:
        """Wait for a free slot (True) or for the job's cancellation while it is queued (False)."""
        acquire = asyncio.ensure_future(self._slots.acquire())
        stop = asyncio.ensure_future(cancel.wait())
        try:
            await asyncio.wait({acquire, stop}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            stop.cancel()
            if not acquire.done():
                acquire.cancel()
        return bool(acquire.done() and not acquire.cancelled())

    async def _execute(
        self, job_id: str, kind: JobKind, params: dict[str, Any], limit: float, cancel: asyncio.Event
    ) -> None:
        recv, send = _MP.Pipe(duplex=False)
        proc = _MP.Process(
            target=_job_main, args=(job_id, kind.target, params, str(self.out_dir(job_id)), send), daemon=False
        )
        await run_in_threadpool(proc.start)
        send.close()
        self._procs[job_id] = proc
        self.metrics.jobs_running.inc()
        await run_in_threadpool(
            lambda: repo.update_job(self.registry, job_id, status="running", started_at=utcnow(), message="started")
        )
        deadline = time.monotonic() + limit
        outcome: tuple[Any, ...] | None = None
        last_write = 0.0
        pending: tuple[float, str] | None = None
        try:
            while outcome is None:
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
                        functools.partial(repo.update_job, self.registry, job_id, progress=frac, message=text)
                    )
                if cancel.is_set():
                    await run_in_threadpool(_kill_group, proc)
                    await self._finish(job_id, kind.name, "cancelled", message="cancelled")
                    return
                if now > deadline:
                    await run_in_threadpool(_kill_group, proc)
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
                await run_in_threadpool(_kill_group, proc)
            await self._conclude(job_id, kind, params, outcome)
        finally:
            self._procs.pop(job_id, None)
            self.metrics.jobs_running.dec()
            recv.close()

    async def _conclude(self, job_id: str, kind: JobKind, params: dict[str, Any], outcome: tuple[Any, ...]) -> None:
        if outcome[0] == "result":
            result = dict(outcome[1])
            if kind.on_result is not None:
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


def list_files(folder: Path) -> list[tuple[str, int]]:
    """Result files under ``folder`` (recursively): (relative POSIX path, size [bytes]), sorted."""
    if not folder.is_dir():
        return []
    out = []
    for p in sorted(folder.rglob("*")):
        if p.is_file() and not p.is_symlink():
            out.append((p.relative_to(folder).as_posix(), p.stat().st_size))
    return out


def resolve_file(folder: Path, name: str) -> Path | None:
    """The file ``name`` inside ``folder``, or None if it is not a regular file there (no escapes, no links)."""
    if not name or name.startswith(("/", "\\")) or ".." in Path(name).parts:
        return None
    path = (folder / name).resolve()
    if not path.is_relative_to(folder.resolve()) or not path.is_file() or (folder / name).is_symlink():
        return None
    return path
