"""Work that must not run in the event loop but that a request waits for.

**Compute pool** (:class:`ComputePool`): a ``ProcessPoolExecutor`` (spawn start method, ``compute_workers``
processes) for work a request waits for — checking an uploaded hand model, simulating a closure for a signature,
computing a signature from markers, drawing a plan's image. Each call has a wall-time cap
(``compute_timeout`` [s]); a call that overruns it, or a worker that dies, gets the pool's processes killed and a
new pool started. A :class:`~softsig_service.errors.SoftsigError` raised in a worker comes back as the same class
with its field, value and choices (exceptions with keyword arguments do not survive pickling, so they travel as
data).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import multiprocessing
import traceback
from collections.abc import Callable, Mapping
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from softsig_service import errors
from softsig_service.errors import ComputeFailed, ServiceBusy, SoftsigError, TimeLimitExceeded
from softsig_service.services.lifeline import follow_parent
from softsig_service.services.observability import request_id_var
from softsig_service.services.problems import short_value

_MP = multiprocessing.get_context("spawn")
log = logging.getLogger("softsig.compute")


# errors across processes
# ----------------------------------------------------------------------------------------------------------


def error_payload(exc: SoftsigError) -> dict[str, Any]:
    """A picklable, JSON-ready description of a :class:`SoftsigError`."""

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
    except (Exception, RecursionError):  # a bug or an input nobody foresaw: the traceback goes to the log only
        return "crash", traceback.format_exc(limit=20)[-20_000:]


def _worker_init() -> None:
    from softsig_service.gl_backend import prepare_mujoco

    prepare_mujoco()


def _pool_init() -> None:
    """Initializer of a compute-pool worker: it dies with the service, and MuJoCo is prepared."""
    follow_parent()
    _worker_init()


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
                max_workers=self.workers, mp_context=_MP, initializer=_pool_init
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
        if status == "crash":
            log.error("unexpected error in a worker %s (request %s):\n%s", what, request_id_var.get(), payload)
            raise ComputeFailed(
                f"{what} failed on this input; the request id identifies the failure in the service's log",
                field=field,
            )
        return payload

    def shutdown(self) -> None:
        """Stop the worker processes."""
        self._closed = True
        self._recycle()
