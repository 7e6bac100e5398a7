"""Work that must not run in the event loop: a process pool for short computations, and jobs for long ones.

**Compute pool** (:class:`ComputePool`): a ``ProcessPoolExecutor`` (spawn start method, ``compute_workers``
processes) for work a request waits for — checking an uploaded hand model, simulating a closure for a signature,
computing a signature from markers, drawing a plan's image. Each call has a wall-time cap
(``compute_timeout`` [s]); a call that overruns it, or a worker that dies, gets the pool's processes killed and a
new pool started. A :class:`~softsig_service.errors.SoftsigError` raised in a worker comes back as the same class
with its field, value and choices (exceptions with keyword arguments do not survive pickling, so they travel as
data).

**Jobs** (:class:`JobManager`): a job is a named callable, ``"module:function"`` with the signature
``fn(params: dict, ctx: JobContext) -> dict``, run in a process of its own (its own process group, so the worker
processes it starts are stopped with it). The callable reports progress with ``ctx.progress(fraction, message)``
and writes result files (JSON, CSV, Markdown, PNG...) into ``ctx.out_dir``; its returned dict is the job's
result. At most ``job_workers`` jobs run at once, the others wait as ``queued``; at most ``max_queued_jobs`` are
unfinished (else :class:`ServiceBusy`). Each job has a wall-time cap (``min(requested, max_job_seconds)`` [s]):
past it the process group is killed and the job is ``timed_out``. ``DELETE /v1/jobs/{id}`` kills it too
(``cancelled``). State, progress and results live in the registry (``jobs`` table); jobs that were unfinished
when the service stopped are marked ``failed`` (``interrupted``) at the next start.

The module also holds the worker-side tasks (plain functions, importable by a spawned process).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import importlib
import io
import logging
import math
import multiprocessing
import os
import signal
import time
import traceback
from collections.abc import Callable, Mapping
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

from starlette.concurrency import run_in_threadpool

from softsig_service import errors
from softsig_service.api.logging import Metrics
from softsig_service.api.schemas import to_jsonable
from softsig_service.config import ModelLimits, Settings
from softsig_service.errors import InvalidHandModel, InvalidInput, ServiceBusy, SoftsigError, TimeLimitExceeded
from softsig_service.registry import repository as repo
from softsig_service.registry.db import Registry
from softsig_service.registry.models import utcnow

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
# errors across processes
# ----------------------------------------------------------------------------------------------------------


def error_payload(exc: SoftsigError) -> dict[str, Any]:
    """A picklable, JSON-ready description of a :class:`SoftsigError`."""
    from softsig_service.api.problems import short_value

    return {
        "class": type(exc).__name__,
        "message": exc.message,
        "field": exc.field,
        "value": short_value(exc.value),
        "choices": exc.choices,
    }


def rebuild_error(payload: Mapping[str, Any]) -> SoftsigError:
    """The :class:`SoftsigError` described by :func:`error_payload`."""
    cls = getattr(errors, str(payload.get("class")), SoftsigError)
    if not (isinstance(cls, type) and issubclass(cls, SoftsigError)):
        cls = SoftsigError
    return cls(
        str(payload.get("message", "error")),
        field=payload.get("field"),
        value=payload.get("value"),
        choices=payload.get("choices"),
    )


def _capture(fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[str, Any]:
    try:
        return "ok", fn(*args)
    except SoftsigError as exc:
        return "error", error_payload(exc)


def _worker_init() -> None:
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()


def _noop() -> None:
    return None


# ----------------------------------------------------------------------------------------------------------
# the compute pool
# ----------------------------------------------------------------------------------------------------------


class ComputePool:
    """Worker processes for computations a request waits for (see the module docstring)."""

    def __init__(self, workers: int, timeout: float) -> None:
        self.workers = workers
        self.timeout = timeout
        self._executor: concurrent.futures.ProcessPoolExecutor | None = None
        self._closed = False

    def _pool(self) -> concurrent.futures.ProcessPoolExecutor:
        if self._closed:
            raise ServiceBusy("the service is shutting down", field=None)
        if self._executor is None:
            self._executor = concurrent.futures.ProcessPoolExecutor(
                max_workers=self.workers, mp_context=_MP, initializer=_worker_init
            )
        return self._executor

    def warm(self) -> None:
        """Start the worker processes now (in the background) rather than on the first call."""
        for _ in range(self.workers):
            self._pool().submit(_noop)

    @property
    def alive(self) -> bool:
        """Whether the pool can take work (it starts its processes again after a timeout or a crash)."""
        return not self._closed

    def _recycle(self) -> None:
        ex, self._executor = self._executor, None
        if ex is None:
            return
        procs = list(getattr(ex, "_processes", {}).values())
        for p in procs:
            with contextlib.suppress(Exception):
                p.kill()
        ex.shutdown(wait=False, cancel_futures=True)

    async def run(self, fn: Callable[..., Any], *args: Any, what: str, field: str | None = None) -> Any:
        """Run ``fn(*args)`` in a worker; re-raise its :class:`SoftsigError`; cap the wall time.

        ``what`` names the computation in errors, ``field`` the request field a timeout or crash is blamed on.
        """
        pool = self._pool()
        future = pool.submit(_capture, fn, args)
        try:
            status, payload = await asyncio.wait_for(asyncio.wrap_future(future), self.timeout)
        except TimeoutError:
            if self._executor is pool:
                self._recycle()
            raise TimeLimitExceeded(
                f"{what} took longer than the limit of {self.timeout:g} s", field=field, value=self.timeout
            ) from None
        except BrokenProcessPool:
            if self._executor is pool:
                self._recycle()
            raise ServiceBusy(f"a worker process died during {what}; retry", field=field) from None
        if status == "error":
            raise rebuild_error(payload)
        return payload

    def shutdown(self) -> None:
        """Stop the worker processes."""
        self._closed = True
        self._recycle()


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
    from softsig_service.api.problems import softsig_problem

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


# ----------------------------------------------------------------------------------------------------------
# worker-side tasks (run in the compute pool)
# ----------------------------------------------------------------------------------------------------------


def _compile(manifest_path: str, limits: ModelLimits) -> Any:
    from softsig_service.hands.manifest import load_manifest
    from softsig_service.hands.model import compile_hand

    path = Path(manifest_path)
    manifest = load_manifest(path, max_bytes=limits.max_model_bytes)
    return compile_hand(manifest, path.parent, limits)


def inspect_hand(manifest_path: str, limits: ModelLimits) -> dict[str, Any]:
    """Load a hand from its manifest (every path and size check of the hand library) and summarise it.

    Any failure of a user's model is reported as :class:`InvalidHandModel` (never a server error).
    """
    from softsig_service.hands.summary import hand_info

    try:
        hand = _compile(manifest_path, limits)
        info = hand_info(hand)
    except SoftsigError:
        raise
    except Exception as exc:
        raise InvalidHandModel(f"the model could not be loaded: {type(exc).__name__}: {exc}", field="model") from None
    info.pop("folder", None)  # a server path: not for clients
    return dict(to_jsonable(info))


def closure_signature(
    manifest_path: str, limits: ModelLimits, method: str, criterion: str = "absolute"
) -> dict[str, Any]:
    """Simulate the hand's free closure and compute its closure signature by ``method`` (hand frame);
    ``criterion`` is the ellipsoid method's ("absolute" [m] or "relative")."""
    from softsig_service.hands.closure import simulate_closure
    from softsig_service.hands.summary import closure_summary
    from softsig_service.signatures.closure import compute_closure_signature

    hand = _compile(manifest_path, limits)
    traj = simulate_closure(hand, surface_points=None if method == "mesh" else 0)
    cs = compute_closure_signature(traj, method, criterion=criterion)  # type: ignore[arg-type]
    return {"signature": to_jsonable(cs.to_json_dict()), "closure": to_jsonable(closure_summary(traj))}


def markers_signature(
    text: str, fmt: str, method: str, expected_points: list[str] | None, hand: str, criterion: str = "absolute"
) -> dict[str, Any]:
    """Parse uploaded marker trajectories (CSV ``time,point,x,y,z`` or trajectory JSON; hand frame, metres,
    seconds) and compute the closure signature by ``method`` (``criterion``: the ellipsoid method's)."""
    from softsig_service.hands.summary import closure_summary
    from softsig_service.signatures.closure import compute_closure_signature
    from softsig_service.signatures.markers import parse_markers_csv, parse_markers_json

    if fmt == "csv":
        traj = parse_markers_csv(text, hand=hand, expected_points=expected_points)
    else:
        traj = parse_markers_json(text, expected_points=expected_points)
    cs = compute_closure_signature(traj, method, criterion=criterion)  # type: ignore[arg-type]
    return {"signature": to_jsonable(cs.to_json_dict()), "closure": to_jsonable(closure_summary(traj))}


def render_plan_png(plan: dict[str, Any], manifest_path: str | None) -> bytes:
    """A top view (world x-y, metres) of a plan: the object's footprint and principal axes, the open hand's
    reference points at the grasp pose, the flange axes, the closure signature's axis and the approach start.

    Drawn with Matplotlib (no OpenGL needed). Returns PNG bytes.
    """
    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Ellipse, Polygon

    from softsig_service.geometry.transforms import Pose
    from softsig_service.objects import convex_hull_2d, object_from_json

    obj = object_from_json(plan["object"])
    fig = Figure(figsize=(7.2, 6.4), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    c = obj.center
    R = obj.pose[:3, :3]

    def world_xy(points_obj: Any) -> Any:
        return (np.asarray(points_obj) @ R.T + c)[:, :2]

    style = {"facecolor": "#d9c9a3", "edgecolor": "#6b5a33", "lw": 1.5, "alpha": 0.9, "label": "object footprint"}
    hx, hy, _ = obj.half_extents
    yaw_deg = math.degrees(obj.yaw)
    if obj.kind == "mesh":
        assert obj.vertices is not None
        hull = convex_hull_2d(obj.vertices[:, :2])
        ax.add_patch(Polygon(world_xy(np.c_[hull, np.zeros(len(hull))]), closed=True, **style))
    elif obj.kind in ("sphere", "ellipsoid") or (obj.kind == "cylinder" and obj.standing):
        ax.add_patch(Ellipse((c[0], c[1]), 2 * hx, 2 * hy, angle=yaw_deg, **style))
    else:
        corners = np.array([[-hx, -hy, 0], [hx, -hy, 0], [hx, hy, 0], [-hx, hy, 0]])
        ax.add_patch(Polygon(world_xy(corners), closed=True, **style))
    reach = max(obj.extent_major, 0.08)
    for axis, name, colour in ((obj.o1, "o1 (major)", "#555555"), (obj.o2, "o2 (minor)", "#999999")):
        a, b = c[:2] - 0.6 * reach * axis[:2], c[:2] + 0.6 * reach * axis[:2]
        ax.plot([a[0], b[0]], [a[1], b[1]], ls="--", color=colour, lw=1, label=name)

    grasp = plan.get("grasp_pose")
    if grasp is not None:
        T = Pose.from_wire(grasp).matrix()
        Rg, p = T[:3, :3], T[:3, 3]
        cs_axis = cs_anchor = None
        if manifest_path is not None:
            from softsig_service.planning.planner import planning_model

            solver = plan.get("solver") or {}
            method = str(solver.get("cs_method", "ellipsoid"))
            criterion = "relative" if solver.get("cs_criterion") == "relative" else "absolute"
            model = planning_model(manifest_path, method, None, criterion)
            pts = model.points_open @ Rg.T + p
            if len(pts) >= 3:
                hull = convex_hull_2d(pts[:, :2])
                if len(hull) >= 3:
                    ax.add_patch(Polygon(hull, closed=True, facecolor="#7fa7d9", alpha=0.25, edgecolor="#2d5d9f",
                                         label="open hand (reference points)"))  # fmt: skip
            ax.scatter(pts[:, 0], pts[:, 1], s=18, color="#2d5d9f", zorder=5)
            cs_axis = Rg @ model.signature.axis
            cs_anchor = Rg @ model.signature.anchor + p
        ax.add_patch(Circle((p[0], p[1]), 0.004, color="black", zorder=6, label="flange (tool0)"))
        L = 0.05
        ax.annotate("", xy=(p[0] + L * Rg[0, 0], p[1] + L * Rg[1, 0]), xytext=(p[0], p[1]),
                    arrowprops={"arrowstyle": "->", "color": "#c0392b", "lw": 2})  # fmt: skip
        ax.annotate("", xy=(p[0] + L * Rg[0, 1], p[1] + L * Rg[1, 1]), xytext=(p[0], p[1]),
                    arrowprops={"arrowstyle": "->", "color": "#27ae60", "lw": 2})  # fmt: skip
        ax.plot([], [], color="#c0392b", lw=2, label="hand +x")
        ax.plot([], [], color="#27ae60", lw=2, label="hand +y")
        if cs_axis is not None and cs_anchor is not None:
            h = cs_axis[:2]
            if float(np.linalg.norm(h)) > 1e-9:
                a, b = cs_anchor[:2] - 0.07 * h, cs_anchor[:2] + 0.07 * h
                ax.plot([a[0], b[0]], [a[1], b[1]], color="#8e44ad", lw=3, label="closure signature axis")
        pre = plan.get("pre_grasp_pose")
        if pre is not None:
            q = Pose.from_wire(pre).matrix()[:3, 3]
            ax.scatter([q[0]], [q[1]], marker="x", s=50, color="#e67e22", zorder=6,
                       label=f"pre-grasp (z = {q[2]:.3f} m)")  # fmt: skip
    else:
        ax.text(c[0], c[1] - 0.9 * reach, "no grasp pose", ha="center", color="#c0392b")
    span = max(0.16, 1.4 * reach)
    ax.set_xlim(c[0] - span, c[0] + span)
    ax.set_ylim(c[1] - span, c[1] + span)
    base = -c[:2]
    if float(np.linalg.norm(base)) > 1e-6:
        d = base / np.linalg.norm(base)
        tip = c[:2] + 0.9 * span * d
        start = c[:2] + 0.65 * span * d
        ax.annotate(
            "UR5 base",
            xy=(float(tip[0]), float(tip[1])),
            xytext=(float(start[0]), float(start[1])),
            ha="center",
            fontsize=8,
            arrowprops={"arrowstyle": "->", "color": "#7f8c8d"},
        )
    ax.set_aspect("equal")
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.set_xlabel("x [m] (base_link)")
    ax.set_ylabel("y [m] (base_link)")
    status = "success" if plan.get("success") else "failed: " + ", ".join(plan.get("reasons") or [])
    quality = plan.get("quality") or {}
    err = quality.get("alignment_error")
    sub = f"alignment error {math.degrees(err):.2f} deg" if isinstance(err, int | float) else ""
    ax.set_title(f"{plan.get('hand')} / {obj.name or obj.kind} / strategy {plan.get('strategy')}: {status}\n{sub}",
                 fontsize=10)  # fmt: skip
    ax.legend(loc="upper right", fontsize=7, framealpha=0.85)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# ----------------------------------------------------------------------------------------------------------
# job callables (run in a job's own process)
# ----------------------------------------------------------------------------------------------------------


def run_stiffness_signature(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """The stiffness signature of a hand on an object (DESIGN §5): grasp in MuJoCo, 6x6 grasp stiffness at the
    object's centre (hand frame, linear first), break forces of the pull test in the default 26 directions.

    ``params``: ``manifest_path``, ``limits`` (the service's model limits) and ``object`` (object JSON). Writes
    ``stiffness_signature.json`` into the job's folder.
    """
    import json

    from softsig_service.objects import object_from_json
    from softsig_service.simulation.stiffness_signature import compute_stiffness_signature

    ctx.progress(0.0, "loading the hand")
    hand = _compile(str(params["manifest_path"]), ModelLimits(**params["limits"]))
    obj = object_from_json(params["object"])
    ctx.progress(0.05, "grasping and pulling")
    ss = compute_stiffness_signature(hand, obj)
    data = to_jsonable(ss.to_json_dict())
    ctx.out_dir.mkdir(parents=True, exist_ok=True)
    (ctx.out_dir / "stiffness_signature.json").write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    ctx.progress(1.0, "done")
    return {"signature": data}


def run_validation(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """Validate a plan in MuJoCo (DESIGN §7): ``trials`` rollouts of :func:`~softsig_service.simulation.rollout.
    run_trial` (plan on the nominal pose, object perturbed by yaw ~ N(0, sigma_r^2) [rad], x, y ~ N(0, sigma_t^2)
    [m]), trial ``k`` seeded as ``softsig validate`` seeds it (same seed, same outcomes).

    ``params``: ``hand_ref`` (name or manifest path), ``object`` (object JSON), ``strategy``, ``sigma_r``,
    ``sigma_t``, ``trials``, ``seed``. Writes ``validation.json`` (every trial's record) and ``outcomes.csv``.
    """
    import csv
    import json

    from softsig_service.experiments.campaign_spec import trial_seed
    from softsig_service.experiments.trial import run_trial
    from softsig_service.objects import object_from_json

    obj = object_from_json(params["object"])
    trials, seed = int(params["trials"]), int(params["seed"])
    results = []
    ctx.progress(0.0, f"0 of {trials} trials")
    for k in range(trials):
        result = run_trial(
            str(params["hand_ref"]), obj, params["strategy"], seed=trial_seed(seed, (), k),
            sigma_r=float(params["sigma_r"]), sigma_t=float(params["sigma_t"]),
        )  # fmt: skip
        results.append(result)
        ctx.progress((k + 1) / trials, f"{k + 1} of {trials} trials")
    outcomes = [
        {"seed": r.seed, "success": r.success, "reason": r.reason, "lift_height": r.lift_height} for r in results
    ]
    data = {
        "hand": params["hand"],
        "object": obj.to_json(),
        "strategy": params["strategy"],
        "sigma_r": float(params["sigma_r"]),
        "sigma_t": float(params["sigma_t"]),
        "seed": seed,
        "trials": trials,
        "successes": sum(r.success for r in results),
        "outcomes": outcomes,
    }
    ctx.out_dir.mkdir(parents=True, exist_ok=True)
    full = {**data, "details": [to_jsonable(r.to_json_dict()) for r in results]}
    (ctx.out_dir / "validation.json").write_text(json.dumps(full, indent=1) + "\n", encoding="utf-8")
    with (ctx.out_dir / "outcomes.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=["trial", "seed", "success", "reason", "lift_height"])
        writer.writeheader()
        for k, o in enumerate(outcomes):
            writer.writerow({"trial": k, **o})
    return data


def run_experiment(params: dict[str, Any], ctx: JobContext) -> dict[str, Any]:
    """The reference experiment (DESIGN §7, the paper's Table I) with
    :func:`~softsig_service.experiments.campaign.run_campaign`: 3 conditions x 3 objects x S and C x ``trials``,
    in ``workers`` processes (default: the campaign's own choice, every core). Its files (``campaign.json``,
    ``trials.jsonl``, ``results.json``, ``results.csv``, ``report.md``, ``table1.png``) go to the job's folder.

    ``params``: ``hand_ref``, ``trials`` (per cell), ``seed``, ``workers``.
    """
    from softsig_service.experiments.campaign import run_campaign
    from softsig_service.experiments.campaign_spec import CampaignSpec

    spec = CampaignSpec(hand=str(params["hand_ref"]), trials=int(params["trials"]), seed=int(params["seed"]))
    total = len(spec.trial_specs())
    ctx.progress(0.0, f"0 of {total} trials")

    def progress(done: int, of: int) -> None:
        ctx.progress(done / of if of else 1.0, f"{done} of {of} trials")

    result = run_campaign(spec, ctx.out_dir, workers=params.get("workers"), progress=progress)
    return {
        "name": params.get("name", "table1"),
        "hand": params["hand"],
        "trials_per_cell": spec.trials,
        "seed": spec.seed,
        "complete": result.complete,
        "ran": result.ran,
        "skipped": result.skipped,
        "wall_time": result.wall_time,
        "summary": to_jsonable(result.summary),
        "files": sorted(Path(f).name for f in result.files.values()),
    }
